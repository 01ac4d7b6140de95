//! The platform code: cache hints (`_mm_prefetch`), huge-page advice (`madvise`)
//! and the buffers it backs. Two of the crate's `unsafe` blocks live here.

/// Reads one value of every cache line of `v` in a loop of independent loads, so that
/// the lines come from memory many at a time before the row's loops add to them (those
/// loops waited on one point's lines at a time: half of a later pass's adds to the
/// 26-bin output).
#[inline]
pub(crate) fn touch<T: bytemuck::Pod>(v: &[T]) {
    let bytes: &[u8] = bytemuck::cast_slice(v);
    let mut x = 0u8;
    for line in bytes.chunks(64) {
        x ^= line[0];
    }
    std::hint::black_box(x);
}

/// Sinks (a sweep's output while its passes run) of at least this many bytes have
/// each row's next row hinted into cache as the row's gather runs, a share per channel
/// (the crate docs, "Eighth round"): they do not stay in cache between passes (a 64³
/// grid's 26 bins take 82 MB; four passes 5–7 % faster). Smaller ones do, and the
/// hints only cost (the 16 × 64 × 16 canopy's 5 MB: 3 % slower with them).
pub const FETCH_AHEAD_BYTES: usize = 16 << 20;

/// Memory a row's loops will add to after the current row's: the next row of a level's
/// sink, which follows the current one in memory. [`Ctx::gather_row_channels`] hints it
/// into cache a share per channel ([`Ahead::fetch`]), so that the lines arrive while
/// the gather computes; [`touch`] then finds them there. (Read by `touch` alone, the
/// row's lines came from memory while nothing else ran: the largest single cost of a
/// later pass, 12 % of four passes at 64³. All hinted at once, they stalled the gather.)
#[derive(Clone, Copy)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))] // hints are x86-64 only
pub(crate) struct Ahead {
    pub(crate) start: *const u8,
    pub(crate) bytes: usize,
}

impl Ahead {
    /// As many bytes as `v` holds, right after it.
    pub(crate) fn after<T>(v: &[T]) -> Self {
        Self {
            start: v.as_ptr_range().end.cast(),
            bytes: std::mem::size_of_val(v),
        }
    }

    /// Byte offsets of share `i` of `n`: whole cache lines, the shares in order
    /// covering every line once.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub(crate) fn share(self, i: usize, n: usize) -> std::ops::Range<usize> {
        let lines = self.bytes.div_ceil(64);
        let at = |i: usize| (lines * i / n).min(lines) * 64;
        at(i)..at(i + 1)
    }

    /// Hints share `i` of `n` into the core's second-level cache.
    #[inline]
    pub(crate) fn fetch(self, i: usize, n: usize) {
        #[cfg(target_arch = "x86_64")]
        for off in self.share(i, n).step_by(64) {
            prefetch_hint(self.start.wrapping_add(off));
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (i, n);
    }
}

/// One of the workspace's two `unsafe` blocks (the other: [`advise_huge_pages`]):
/// `prefetcht1`, a hint that loads nothing into a register and never faults, whatever
/// the address (so `at` may lie past an allocation's end).
/// `std` offers no safe prefetch (`core::intrinsics::prefetch_read_data` is unstable),
/// and the crates that wrap one need nightly or expose `unsafe` themselves.
#[cfg(target_arch = "x86_64")]
#[inline]
#[allow(unsafe_code)]
pub(crate) fn prefetch_hint(at: *const u8) {
    use std::arch::x86_64::{_MM_HINT_T1, _mm_prefetch};
    // SAFETY: `_mm_prefetch` only hints the cache; it reads no memory the program sees
    // and cannot fault.
    unsafe { _mm_prefetch::<_MM_HINT_T1>(at.cast()) }
}

/// `spare`'s memory made `n` values long if it has room for them (their contents are
/// overwritten, never read), else [`fresh_buffer`]. A hierarchy's nodes differ in
/// height: kept for one size alone, a node's sweep wrote fresh pages (faulted in and
/// zeroed by the kernel) for nearly every node.
pub(crate) fn take_buffer<T: bytemuck::Zeroable + Clone>(spare: &mut Vec<T>, n: usize) -> Vec<T> {
    if spare.capacity() >= n && n > 0 {
        let mut v = std::mem::take(spare);
        v.resize(n, T::zeroed());
        v
    } else {
        fresh_buffer(n)
    }
}

/// A zeroed vector of `n` values from pages the kernel maps on first touch, by the
/// threads that first write them; on Linux advised to be backed by 2 MB pages
/// ([`advise_huge_pages`]). A sweep without `recycle` writes a fresh 82 MB output at
/// 64³ (26 bins): with 4 KB pages its 20 000 page faults took about 23 ms of a 33 ms
/// one-pass sweep (19 ms with 2 MB pages; 10 ms recycled).
pub(crate) fn fresh_buffer<T: bytemuck::Zeroable + Clone>(n: usize) -> Vec<T> {
    let mut v = bytemuck::zeroed_vec(n);
    advise_huge_pages(&mut v);
    v
}

/// `madvise(MADV_HUGEPAGE)` on the whole 2 MB pages inside `v` (Linux; a no-op
/// elsewhere, for buffers holding no such page, and where the kernel has transparent
/// huge pages off). Touching 82 MB of fresh memory: 31 ms with 4 KB pages, 4.5 ms with
/// 2 MB ones (one thread, this VM, whose kernel backs only advised ranges with them).
#[allow(unsafe_code)]
pub(crate) fn advise_huge_pages<T>(v: &mut [T]) {
    #[cfg(target_os = "linux")]
    if let Some(r) = huge_pages_inside(v.as_mut_ptr() as usize, std::mem::size_of_val(v)) {
        // SAFETY: `r` lies inside `v`'s allocation ([`huge_pages_inside`]), which this
        // function borrows mutably; MADV_HUGEPAGE changes how the kernel backs those
        // pages, never their contents, and the result (an error where huge pages are
        // off) is advice only.
        unsafe { libc::madvise(r.start as *mut libc::c_void, r.len(), libc::MADV_HUGEPAGE) };
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

/// The addresses of the whole 2 MB pages inside `bytes` bytes from address `start`
/// (`None` if none fits).
pub(crate) fn huge_pages_inside(start: usize, bytes: usize) -> Option<std::ops::Range<usize>> {
    const HUGE: usize = 2 << 20;
    let (a, b) = (start.next_multiple_of(HUGE), (start + bytes) / HUGE * HUGE);
    (b > a).then_some(a..b)
}
