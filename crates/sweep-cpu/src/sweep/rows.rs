//! The row layout of a level's light: padded rows, rings of wrapped columns, taps
//! into the slot planes, the per-row flux sums.

use super::*;

/// Per-row flux sums, reduced in row order (deterministic for any thread count).
#[derive(Clone, Copy, Default)]
pub(crate) struct RowFlux {
    pub(crate) inside: DVec3,
    pub(crate) outside: DVec3,
    pub(crate) absorbed: DVec3,
    pub(crate) pending: DVec3,
    /// Flux the row's final light sends on to the next level (or out of the grid).
    pub(crate) sent: DVec3,
    /// Flux emitted into the paths of points beyond an open or given side (phase 3):
    /// it leaves through the side.
    pub(crate) side_out: DVec3,
    /// A resolved value was negative, NaN or infinite.
    pub(crate) bad: bool,
    /// `sent` is already set (a row that passed its light on unchanged: what it
    /// gathered, summed in the same order); [`Ctx::finish_row`] leaves it.
    pub(crate) sent_known: bool,
}

impl std::ops::Add for RowFlux {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            inside: self.inside + o.inside,
            outside: self.outside + o.outside,
            absorbed: self.absorbed + o.absorbed,
            pending: self.pending + o.pending,
            sent: self.sent + o.sent,
            side_out: self.side_out + o.side_out,
            bad: self.bad | o.bad,
            sent_known: false,
        }
    }
}

/// What the last phase of a level does for each of its rows once the row's light is
/// final ([`Ctx::finish_row`]): sum the flux it sends on and, in the last pass, resolve
/// the row's output into these rows of the average and dominant grids.
pub(crate) struct Finish<'a> {
    /// The level's rows of the average and dominant grids.
    pub(crate) avg: &'a mut [AverageLight],
    pub(crate) dom: &'a mut [DominantDir],
    /// This phase is the level's last: sum `sent`, and resolve if `resolve`.
    pub(crate) last_phase: bool,
    /// `Some(dominant)`: resolve (the last pass).
    pub(crate) resolve: Option<bool>,
    /// Light below 0 set to 0 before it is resolved (light of either sign flows).
    pub(crate) clamp: bool,
    /// Each point's output holds exactly this pass's channel light, the level's
    /// final light (the first pass's phase 1 of a level without material): resolve
    /// from the level's planes ([`resolve_planes`]).
    pub(crate) from_planes: bool,
    /// Write each row's ring columns ([`wrap_columns`], periodic sides) as the row
    /// ends, while it is in cache: for a next level without material, which would
    /// otherwise wrap them on one thread while the other waits. (A level with material
    /// wraps them beside its transmittances, [`LevelLight::wrap_ring`].)
    pub(crate) wrap_columns: bool,
}

/// What a level's phase writes, row by row: the level's light, the points' sinks and
/// each row's flux tallies.
pub(crate) struct LevelRows<'a, S> {
    pub(crate) cur: &'a mut LevelLight,
    pub(crate) g: &'a mut [S],
    pub(crate) rows: &'a mut [RowFlux],
}

/// What phase 1 records for phases 2 and 3: each path segment's removed light (slot
/// planes per row) and each point's transmittance after its own cell per channel.
pub(crate) struct Removals<'a> {
    pub(crate) removed: &'a mut [f32],
    pub(crate) t_after: &'a mut [[f32; CHANNELS]],
}

/// One row's share of phase 1's outputs ([`Ctx::transmit_row`]).
pub(crate) struct TransmitRow<'a, S> {
    pub(crate) cur: &'a mut [f32],
    pub(crate) rem: &'a mut [f32],
    pub(crate) ta: &'a mut [[f32; CHANNELS]],
    pub(crate) g: &'a mut [S],
}

pub(crate) fn sum_rows(v: &[RowFlux]) -> RowFlux {
    v.iter().fold(RowFlux::default(), |a, b| a + *b)
}

pub(crate) type Level = [Vec3; CHANNELS];

/// Columns (and rows) of the ring around a [`LevelLight`]: a tap of step 1 lies at most
/// four columns (a horizontal channel's step) and one (the smoothing tap) beyond a point.
pub(crate) const PAD: usize = 5;

/// One level's channel light (step 1's `O'`, and the level being built), row by row in
/// planes, with a ring of [`PAD`] columns and rows around the grid: channel `c`, colour
/// `k` of column `(x, z)` (`-PAD <= x < nx + PAD`, the same for `z`) is at
/// `((z + PAD)·CHANNELS·3 + c·3 + k)·pitch + x + PAD`, `pitch = nx + 2·PAD`. One
/// channel's colour along a row is contiguous, so the fast path's gather over a row is
/// a loop over slices that the compiler vectorises; a row is one contiguous chunk
/// (`row_len`) for the parallel tasks. The ring holds the light of the columns a tap
/// beyond the sides reads *from inside the grid*: the wrapped columns on periodic sides
/// ([`LevelLight::wrap_ring`], or row by row as a level ends, [`Finish::wrap_columns`]),
/// zero otherwise; light from outside (open sides, a given
/// halo) comes from a second `LevelLight` whose inside is zero and whose ring holds it.
#[derive(Clone)]
pub(crate) struct LevelLight {
    pub(crate) v: Vec<f32>,
    pub(crate) nx: usize,
    pub(crate) nz: usize,
}

impl LevelLight {
    pub(crate) fn new(nx: usize, nz: usize) -> Self {
        Self {
            v: vec![0.0; CHANNELS * 3 * (nx + 2 * PAD) * (nz + 2 * PAD)],
            nx,
            nz,
        }
    }
    /// Floats from one column to the same column of the next plane.
    #[inline(always)]
    pub(crate) fn pitch(&self) -> usize {
        self.nx + 2 * PAD
    }
    /// Floats per row of points.
    #[inline(always)]
    pub(crate) fn row_len(&self) -> usize {
        CHANNELS * 3 * self.pitch()
    }
    /// The rows of the grid (the ring's rows left out), for the parallel tasks.
    pub(crate) fn rows_mut(&mut self) -> &mut [f32] {
        let r = self.row_len();
        &mut self.v[PAD * r..(PAD + self.nz) * r]
    }
    /// Row `z` (`-PAD <= z < nz + PAD`).
    #[inline(always)]
    pub(crate) fn row(&self, z: isize) -> &[f32] {
        let r = self.row_len();
        &self.v[(z + PAD as isize) as usize * r..][..r]
    }
    #[inline(always)]
    pub(crate) fn row_mut(&mut self, z: isize) -> &mut [f32] {
        let r = self.row_len();
        &mut self.v[(z + PAD as isize) as usize * r..][..r]
    }
    /// Channel `c` of the point with level index `i`.
    #[inline(always)]
    pub(crate) fn at(&self, i: usize, c: usize) -> Vec3 {
        let (x, z) = (i % self.nx, i / self.nx);
        row_get(self.row(z as isize), self.pitch(), x, c)
    }
    /// Every point of the grid: the same channel values `v` (the ring is left as it is).
    pub(crate) fn fill(&mut self, v: &Level) {
        let p = self.pitch();
        let nx = self.nx;
        let r = self.row_len();
        self.rows_mut().par_chunks_mut(r).for_each(|row| {
            for (c, val) in v.iter().enumerate() {
                for k in 0..3 {
                    row[(c * 3 + k) * p + PAD..][..nx].fill(val[k]);
                }
            }
        });
    }
    /// Adds `o`'s light, ring and all.
    pub(crate) fn add(&mut self, o: &LevelLight) {
        let r = self.row_len();
        self.v
            .par_chunks_mut(r)
            .zip(o.v.par_chunks(r))
            .for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(a, b)| *a += b));
    }
    /// The ring from the wrapped columns and rows of the grid (periodic sides).
    pub(crate) fn wrap_ring(&mut self) {
        let (nx, p) = (self.nx, self.pitch());
        for z in 0..self.nz as isize {
            wrap_columns(self.row_mut(z), p, nx);
        }
        self.wrap_ring_rows();
    }
    /// The ring's rows from the wrapped rows of the grid (periodic sides), where each
    /// row's ring columns hold its wrapped columns already ([`wrap_columns`]).
    pub(crate) fn wrap_ring_rows(&mut self) {
        let (nz, r) = (self.nz as isize, self.row_len());
        for z in (-(PAD as isize)..0).chain(nz..nz + PAD as isize) {
            let from = (z.rem_euclid(nz) + PAD as isize) as usize * r;
            let to = (z + PAD as isize) as usize * r;
            self.v.copy_within(from..from + r, to);
        }
    }
}

/// The ring columns of one row of a [`LevelLight`] (planes of pitch `p`, `nx` columns
/// each) from the row's wrapped columns (periodic sides): left the last [`PAD`], right
/// the first.
#[inline(always)]
pub(crate) fn wrap_columns(row: &mut [f32], p: usize, nx: usize) {
    for plane in row.chunks_exact_mut(p) {
        if nx >= PAD {
            // (Element by element: a call to memmove for five floats cost more than
            // the copy.)
            for i in 0..PAD {
                plane[i] = plane[nx + i];
                plane[nx + PAD + i] = plane[PAD + i];
            }
        } else {
            let n = nx as isize;
            for x in (-(PAD as isize)..0).chain(n..n + PAD as isize) {
                plane[(x + PAD as isize) as usize] =
                    plane[(x.rem_euclid(n) + PAD as isize) as usize];
            }
        }
    }
}

/// Points of a row that the row loops of phases 2 and 3 take at a time.
pub(crate) const GATHER_BLOCK: usize = 64;

/// Runs `block(b)` for a block of `b` points with `b` a constant where it is one of the
/// common widths (whole blocks of [`GATHER_BLOCK`], rows of 32 and 16 points): each arm
/// inlines `block` where the optimiser finds it small enough, so that its loops over
/// `0..b` compile without remainder loops or bounds checks. Only the resolve from the
/// planes uses it now. The transmit step, phase 3 and the collisions run one block of
/// any width: on the dispatched vector path ([`crate::isa`]) LLVM does not inline a
/// per-width closure into the AVX2 function unless forced, and forced into all four
/// arms the blocks were 4× larger and the forest 8–11 % slower. The resolve passes an
/// `#[inline(always)]` closure: unforced, it stayed on the baseline path.
#[inline(always)]
pub(crate) fn with_width(b: usize, mut block: impl FnMut(usize)) {
    match b {
        GATHER_BLOCK => block(GATHER_BLOCK),
        32 => block(32),
        16 => block(16),
        b => block(b),
    }
}

/// Columns of ring each side of a row of a level's slot planes ([`Planes::ex`]): the
/// farthest reach of a stencil along a row (`channels_reach_no_farther_than_the_ring`).
pub(crate) const RING: usize = 2;

/// The pitch of a row of `nx` points in a slot plane with its ring ([`RING`]).
#[inline(always)]
pub(crate) fn ring_pitch(nx: usize) -> usize {
    nx + 2 * RING
}

/// The stencil slots whose tap lies beside the point's column (`dx ≠ 0`): the only
/// ones a reader takes ring columns of. The same in both passes (they mirror the
/// vertical only).
pub(crate) fn ring_slots() -> &'static [usize] {
    static SLOTS_OFF_COLUMN: OnceLock<Vec<usize>> = OnceLock::new();
    SLOTS_OFF_COLUMN.get_or_init(|| {
        channels(false)
            .iter()
            .flat_map(|c| {
                let off = c.stencil.iter().enumerate().filter(|(_, t)| t.0 != 0);
                off.map(move |(k, _)| c.first_slot + k)
            })
            .collect()
    })
}

/// Fills the ring of one level row's slot planes (`row`: per slot and colour a row of
/// `nx` points with its ring, [`ring_pitch`]), for the slots that read it
/// ([`ring_slots`]): the wrapped columns on periodic sides, 0 on open ones (a tap
/// beyond an open side adds nothing). A reader then takes a stencil tap's values for
/// a block of a row as one slice, with no columns to wrap or leave out (the bench
/// forest's rows of 16 points ran each tap beside the column as a vector loop over
/// 14 or 15 points, their scalar remainder and one or two wrapped points).
pub(crate) fn fill_rings(row: &mut [f32], nx: usize, periodic: bool) {
    let w = ring_pitch(nx);
    for &slot in ring_slots() {
        for plane in row[slot * 3 * w..][..3 * w].chunks_exact_mut(w) {
            if !periodic {
                plane[..RING].fill(0.0);
                plane[nx + RING..].fill(0.0);
            } else if nx >= RING {
                plane.copy_within(nx..nx + RING, 0);
                plane.copy_within(RING..2 * RING, nx + RING);
            } else {
                for i in (0..RING).chain(nx + RING..w) {
                    let x = (i as isize - RING as isize).rem_euclid(nx as isize) as usize;
                    plane[i] = plane[RING + x];
                }
            }
        }
    }
}

/// Index of point `pt`'s value for stencil slot `slot` and colour `col` in a level's
/// slot planes (removed light, what paths carry, [`Planes::ex`]): per row of `nx`
/// points, slot, colour, column, each row of a slot and colour with its ring
/// ([`ring_pitch`]).
#[inline(always)]
pub(crate) fn plane_index(nx: usize, pt: usize, slot: usize, col: usize) -> usize {
    slot_index(nx, (pt / nx, pt % nx), slot, col)
}

/// [`plane_index`] of column `x` of level row `z` (no division: the row loops').
#[inline(always)]
pub(crate) fn slot_index(nx: usize, (z, x): (usize, usize), slot: usize, col: usize) -> usize {
    ((z * SLOTS + slot) * 3 + col) * ring_pitch(nx) + RING + x
}

/// `len` values of a level's slot planes ([`plane_index`]) for row
/// `zr`, slot and colour, from column `x` (`-RING ≤ x`, `x + len ≤ nx + RING`: the
/// ring's wrapped columns, or zeros beyond an open side, [`fill_rings`]).
#[inline(always)]
pub(crate) fn tap(
    planes: &[f32],
    nx: usize,
    (zr, slot, col): (usize, usize, usize),
    x: i32,
    len: usize,
) -> &[f32] {
    &planes[(slot_index(nx, (zr, 0), slot, col) as isize + x as isize) as usize..][..len]
}

/// Channel `c` of grid column `x` in one row of a [`LevelLight`] of pitch `p`.
#[inline(always)]
pub(crate) fn row_get(row: &[f32], p: usize, x: usize, c: usize) -> Vec3 {
    let b = c * 3 * p + x + PAD;
    Vec3::new(row[b], row[b + p], row[b + 2 * p])
}

#[inline(always)]
pub(crate) fn row_set(row: &mut [f32], p: usize, x: usize, c: usize, v: Vec3) {
    let b = c * 3 * p + x + PAD;
    row[b] = v.x;
    row[b + p] = v.y;
    row[b + 2 * p] = v.z;
}

#[inline(always)]
pub(crate) fn row_add(row: &mut [f32], p: usize, x: usize, c: usize, v: Vec3) {
    let b = c * 3 * p + x + PAD;
    row[b] += v.x;
    row[b + p] += v.y;
    row[b + 2 * p] += v.z;
}

/// Step 1 along a row: `out[i] = (1 - w)·mid[i + 1] + (w/4)·(mid[i + 2] + mid[i] +
/// above[i + 1] + below[i + 1])` (in that order, as the oracle adds its taps), where
/// `mid`, `above` and `below` start one column before the source point of `out[0]`.
#[inline(always)]
pub(crate) fn gather_row(
    out: &mut [f32],
    (mid, above, below): (&[f32], &[f32], &[f32]),
    w0: f32,
    w1: f32,
) {
    let n = out.len();
    let m0 = &mid[1..][..n];
    if w1 == 0.0 {
        for (o, v) in out.iter_mut().zip(m0) {
            *o = v * w0;
        }
        return;
    }
    let (mp, mm) = (&mid[2..][..n], &mid[..n]);
    let (za, zb) = (&above[1..][..n], &below[1..][..n]);
    for i in 0..n {
        out[i] = m0[i] * w0 + mp[i] * w1 + mm[i] * w1 + za[i] * w1 + zb[i] * w1;
    }
}

/// Sum in `f64`, four lanes (so that it vectorises; the order is fixed, so the result
/// is deterministic).
#[inline(always)]
pub(crate) fn sum_f64(v: &[f32]) -> f64 {
    let mut lanes = [0f64; 4];
    let chunks = v.chunks_exact(4);
    let rest = chunks.remainder();
    for ch in chunks {
        for (l, x) in lanes.iter_mut().zip(ch) {
            *l += *x as f64;
        }
    }
    let mut s = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
    for x in rest {
        s += *x as f64;
    }
    s
}
