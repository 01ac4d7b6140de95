//! The cell profiles a process has computed, and a sweeper's view of them: [`Store`]
//! keeps each distinct `(pass, ln p)`'s [`CellProfile`] once for every sweeper of the
//! process, [`Profiles`] hands a level's cells theirs.

use std::sync::Arc;

use super::CellProfile;

/// A map from `(upward, ln p bits)` to an index, hashed by [`DepthHasher`].
type DepthMap =
    std::collections::HashMap<(bool, u32), u32, std::hash::BuildHasherDefault<DepthHasher>>;

/// The hash of [`DepthMap`]'s keys: the key's bits through splitmix64's finaliser. The
/// sweep looks up every cell of a level with media in every pass; with the standard
/// library's SipHash (built against adversarial keys, which a sweep's own grid is not)
/// the lookups took 3.2 µs of a 16 × 16 level's 125 µs.
#[derive(Default)]
struct DepthHasher(u64);

impl std::hash::Hasher for DepthHasher {
    fn finish(&self) -> u64 {
        let mut x = self.0;
        x ^= x >> 30;
        x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x ^= x >> 27;
        x = x.wrapping_mul(0x94d0_49bb_1331_11eb);
        x ^ (x >> 31)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u8(b);
        }
    }
    fn write_u8(&mut self, v: u8) {
        self.0 = (self.0 << 8) | v as u64;
    }
    fn write_u32(&mut self, v: u32) {
        self.0 = (self.0 << 32) | v as u64;
    }
}

/// The cell profiles every sweeper of a process shares: each distinct `(pass, ln p)`
/// entered once, at a slot of its own, and computed once by whichever sweeper first
/// needs it (a hierarchy's forks meet the same depths of medium: each used to integrate
/// them again and hold its own copy, 1.2 µs and 1.2 KiB a profile). Slots come in
/// chunks allocated as they are first used; once [`Profiles::KEEP`] are entered, a
/// level's other values are computed for that level alone ([`Profiles`]).
pub(crate) struct Store {
    /// The slot of each `(upward, ln p bits)` entered.
    ids: std::sync::Mutex<DepthMap>,
    chunks: Box<[std::sync::OnceLock<Chunk>]>,
    cap: usize,
}

/// [`Store::CHUNK`] slots of a store.
type Chunk = Box<[std::sync::OnceLock<CellProfile>]>;

impl Store {
    /// Slots a chunk (80 KiB: a chunk is written whole when it is made, and a first
    /// sweep of a few depths faulted in 1.2 MiB with 1024).
    const CHUNK: usize = 64;

    fn new(cap: usize) -> Self {
        Self {
            ids: Default::default(),
            chunks: (0..cap.div_ceil(Self::CHUNK))
                .map(|_| std::sync::OnceLock::new())
                .collect(),
            cap,
        }
    }

    /// The process's store (a fresh one after [`Store::retire`]).
    fn current() -> Arc<Store> {
        Self::shared()
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get_or_insert_with(|| Arc::new(Store::new(Profiles::KEEP)))
            .clone()
    }

    fn shared() -> &'static std::sync::Mutex<Option<Arc<Store>>> {
        static CURRENT: std::sync::Mutex<Option<Arc<Store>>> = std::sync::Mutex::new(None);
        &CURRENT
    }

    /// `old` is full of another scene's profiles: if it is still the process's store, a
    /// fresh one replaces it (sweepers that hold `old` keep it until their next sweep).
    fn retire(old: &Arc<Store>) {
        let mut current = Self::shared().lock().unwrap_or_else(|e| e.into_inner());
        if current.as_ref().is_some_and(|c| Arc::ptr_eq(c, old)) {
            *current = None;
        }
    }

    /// Entered profiles.
    fn len(&self) -> usize {
        self.ids.lock().unwrap_or_else(|e| e.into_inner()).len()
    }

    /// The slots of `keys`, each entered if it was not while there is room (`None`
    /// where there was none).
    fn enter(&self, keys: impl Iterator<Item = (bool, u32)>) -> Vec<Option<u32>> {
        let mut ids = self.ids.lock().unwrap_or_else(|e| e.into_inner());
        keys.map(|key| {
            if let Some(&id) = ids.get(&key) {
                return Some(id);
            }
            let next = ids.len();
            (next < self.cap).then(|| {
                ids.insert(key, next as u32);
                next as u32
            })
        })
        .collect()
    }

    /// Slot `id` (its chunk allocated if it was not).
    fn slot(&self, id: u32) -> &std::sync::OnceLock<CellProfile> {
        let id = id as usize;
        &self.chunks[id / Self::CHUNK].get_or_init(|| {
            (0..Self::CHUNK)
                .map(|_| std::sync::OnceLock::new())
                .collect()
        })[id % Self::CHUNK]
    }

    /// The profile at slot `id`, computed ([`Profiles::level`] computes a slot before
    /// any cell reads it).
    #[inline]
    fn get(&self, id: u32) -> &CellProfile {
        let id = id as usize;
        self.chunks[id / Self::CHUNK]
            .get()
            .and_then(|c| c[id % Self::CHUNK].get())
            .expect("a level's profiles are computed when it is set")
    }
}

/// The profiles of one level's cells for one pass, as the sweep reads them
/// ([`Profiles::get`]). [`CellProfile::new`] costs about a microsecond: each distinct
/// `(pass, ln p)` is computed once a process and kept across levels, passes, sweeps
/// and sweepers ([`Store`], up to [`Profiles::KEEP`] of them); once that many are kept,
/// a level's values not among them are computed for that level alone, and a sweep that
/// found fewer of its values kept than it computed so retires the store (another
/// scene's values: the next sweeps start a fresh one). The values are
/// [`CellProfile::new`]'s, bit for bit.
#[derive(Clone)]
pub(crate) struct Profiles {
    store: Arc<Store>,
    /// Whether `store` is this sweeper's own (tests), not the process's.
    own: bool,
    /// Slots in `store` this sweeper has seen computed.
    known: DepthMap,
    /// Per cell of the level: its slot in `store`, or [`Profiles::LOCAL`] and its index
    /// in `local`.
    of: Vec<u32>,
    /// The level's profiles the store had no room for.
    local: Vec<CellProfile>,
    /// The level's values not known before it: where they go in `of` while the level
    /// is set.
    new: DepthMap,
    /// Profiles this sweeper computed ([`CellProfile::new`] calls).
    computed: u64,
    /// This sweep's distinct values per level found kept, and computed for a level
    /// alone.
    kept_now: u64,
    alone_now: u64,
}

impl Default for Profiles {
    fn default() -> Self {
        Self::with_store(Store::current(), false)
    }
}

impl Profiles {
    /// Profiles kept a process (1240 bytes each: 77.5 MiB at most; a scene holds as
    /// many as it has distinct depths of medium times two directions,
    /// [`crate::sweep::sweep_bytes`] counts them).
    pub(crate) const KEEP: usize = 65536;
    /// In `of`: an index in `local`.
    const LOCAL: u32 = 1 << 31;

    fn with_store(store: Arc<Store>, own: bool) -> Self {
        Self {
            store,
            own,
            known: DepthMap::default(),
            of: Vec::new(),
            local: Vec::new(),
            new: DepthMap::default(),
            computed: 0,
            kept_now: 0,
            alone_now: 0,
        }
    }

    /// Profiles with a store of their own holding at most `cap` (tests: counts that
    /// other tests' sweeps in the same process do not change).
    #[cfg(test)]
    pub(crate) fn own(cap: usize) -> Self {
        Self::with_store(Arc::new(Store::new(cap)), true)
    }

    /// A sweep begins. A full store from which the last sweep found fewer values than
    /// it computed for a level alone holds another scene's profiles (a renderer
    /// sweeping one area after another): it is retired, so that this scene's are
    /// kept. A sweeper takes up the process's current store.
    pub(crate) fn begin_sweep(&mut self) {
        let full = self.store.len() >= self.store.cap;
        let mut next = None;
        if full && self.alone_now > self.kept_now {
            if self.own {
                next = Some(Arc::new(Store::new(self.store.cap)));
            } else {
                Store::retire(&self.store);
            }
        }
        if let Some(next) = next.or_else(|| (!self.own).then(Store::current))
            && !Arc::ptr_eq(&next, &self.store)
        {
            self.store = next;
            self.known.clear();
        }
        (self.kept_now, self.alone_now) = (0, 0);
    }

    /// Sets the level's profiles: cell `q` gets the profile of `ln p` `lnp[q]` where
    /// `medium(q)`, of a clear cell (`ln p = 0`) elsewhere.
    pub(crate) fn level(&mut self, up: bool, lnp: &[f32], medium: impl Fn(usize) -> bool) {
        use rayon::prelude::*;
        self.local.clear();
        let todo = self.assign(up, lnp, &medium);
        if todo.is_empty() {
            return;
        }
        // Enter the level's new values; those entered are computed where no sweeper
        // has yet (`get_or_init`: a slot another sweeper is computing is waited for),
        // the others for this level alone.
        let slots = self.store.enter(todo.iter().map(|&l| (up, l.to_bits())));
        let mut alone = Vec::new();
        let resolved: Vec<u32> = slots
            .iter()
            .zip(&todo)
            .map(|(slot, &l)| match *slot {
                Some(id) => id,
                None => {
                    alone.push(l);
                    Self::LOCAL | (alone.len() - 1) as u32
                }
            })
            .collect();
        let store = &*self.store;
        let computed = std::sync::atomic::AtomicU64::new(0);
        resolved
            .par_iter()
            .zip(todo.par_iter())
            .filter(|(id, _)| **id & Self::LOCAL == 0)
            .for_each(|(&id, &l)| {
                store.slot(id).get_or_init(|| {
                    computed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    crate::isa::vectorised!(CellProfile::of(up, l))
                });
            });
        self.local.par_extend(
            alone
                .par_iter()
                .map(|&l| crate::isa::vectorised!(CellProfile::of(up, l))),
        );
        self.computed += computed.into_inner() + alone.len() as u64;
        self.alone_now += alone.len() as u64;
        for (&id, &l) in resolved.iter().zip(&todo) {
            if id & Self::LOCAL == 0 {
                self.known.insert((up, l.to_bits()), id);
            }
        }
        for id in &mut self.of {
            if *id & Self::LOCAL != 0 && *id & Self::PENDING != 0 {
                *id = resolved[(*id & !(Self::LOCAL | Self::PENDING)) as usize];
            }
        }
    }

    /// In `of` while a level is set: an index in the level's new values.
    const PENDING: u32 = 1 << 30;

    /// Profiles computed so far ([`CellProfile::new`] calls).
    #[cfg(test)]
    pub(crate) fn computed(&self) -> u64 {
        self.computed
    }

    /// Sets `of` for the level: the slots of values known, and for the others their
    /// index among the level's new values (`LOCAL | PENDING | index`), which it returns
    /// in that order.
    fn assign(&mut self, up: bool, lnp: &[f32], medium: &impl Fn(usize) -> bool) -> Vec<f32> {
        self.of.clear();
        self.new.clear();
        let mut todo: Vec<f32> = Vec::new();
        let mut last: Option<(u32, u32)> = None;
        for (q, &l) in lnp.iter().enumerate() {
            let l = if medium(q) { l } else { 0.0 };
            let bits = l.to_bits();
            let id = match last {
                Some((b, id)) if b == bits => id,
                _ => {
                    let key = (up, bits);
                    let id = if let Some(&id) = self.known.get(&key) {
                        self.kept_now += 1;
                        id
                    } else if let Some(&id) = self.new.get(&key) {
                        id
                    } else {
                        let id = Self::LOCAL | Self::PENDING | todo.len() as u32;
                        self.new.insert(key, id);
                        todo.push(l);
                        id
                    };
                    last = Some((bits, id));
                    id
                }
            };
            self.of.push(id);
        }
        todo
    }

    /// The profile of cell `q` of the level last set.
    #[inline]
    pub(crate) fn get(&self, q: usize) -> &CellProfile {
        let id = self.of[q];
        if id & Self::LOCAL != 0 {
            &self.local[(id & !Self::LOCAL) as usize]
        } else {
            self.store.get(id)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::SLOTS;

    /// The level set hands out `CellProfile::new`'s values bit for bit, for media and
    /// clear cells, both passes, across levels that evict what it kept.
    #[test]
    fn profiles_match_new_across_levels() {
        let same = |a: &CellProfile, b: &CellProfile| {
            let f = |p: &CellProfile| {
                let mut v: Vec<u32> = Vec::new();
                for s in 0..SLOTS {
                    for m in [p.coll[s], p.emit[s], p.mean[s]] {
                        v.extend(m.iter().map(|x| x.to_bits()));
                    }
                }
                v.extend(p.g.iter().flatten().map(|x| x.to_bits()));
                v.extend(p.k.iter().flatten().map(|x| x.to_bits()));
                v.push(p.o.to_bits());
                v
            };
            f(a) == f(b)
        };
        let mut set = Profiles::own(Profiles::KEEP);
        // Runs of equal values, repeats across levels, and a level of all-distinct
        // values larger than `KEEP`.
        let small: Vec<f32> = (0..64).map(|i| -0.1 * (i / 8) as f32).collect();
        let large: Vec<f32> = (0..Profiles::KEEP + 10)
            .map(|i| -(i as f32) * 1e-3)
            .collect();
        for (up, lnp) in [
            (false, &small),
            (true, &small),
            (false, &large),
            (true, &small),
        ] {
            let medium = |q: usize| q % 5 != 3;
            set.level(up, lnp, medium);
            for (q, &l) in lnp.iter().enumerate() {
                let want = CellProfile::new(up, if medium(q) { l } else { 0.0 });
                assert!(same(set.get(q), &want), "cell {q} up {up}");
            }
        }
        // Profiles are kept across levels while they fit: a level of values already
        // held computes nothing, even when the level has more cells than `KEEP`.
        let held = set.store.len();
        let wide: Vec<f32> = (0..Profiles::KEEP + 10).map(|i| small[i % 64]).collect();
        set.level(true, &wide, |_| true);
        set.level(true, &small, |_| true);
        assert_eq!(set.store.len(), held, "profiles recomputed for values held");
        let computed = set.computed;
        set.level(false, &wide, |_| true);
        assert_eq!(
            set.computed, computed,
            "profiles recomputed for values held"
        );
        // A clear cell's profile is the transparent one, not whatever was there.
        assert!(!same(
            &CellProfile::new(false, -1.0),
            &CellProfile::new(false, 0.0)
        ));
    }

    /// A sweep whose levels hold more distinct values than fit, visited in the same
    /// order every pass (a downward level, an upward one), computes again only the
    /// values beyond the kept ones, not the whole set (each level evicted everything
    /// before), and hands out `CellProfile::new`'s values bit for bit all along.
    #[test]
    fn profiles_beyond_keep_computed_again_alone() {
        let n = Profiles::KEEP / 2 + 800;
        let lnp: Vec<f32> = (0..n).map(|i| -(i as f32 + 1.0) * 1e-4).collect();
        let mut set = Profiles::own(Profiles::KEEP);
        let mut per_cycle = Vec::new();
        for cycle in 0..3 {
            let before = set.computed;
            for up in [false, true] {
                set.level(up, &lnp, |_| true);
                if cycle == 1 {
                    for (q, &l) in lnp.iter().enumerate().step_by(7) {
                        let (a, b) = (set.get(q), CellProfile::new(up, l));
                        assert_eq!(a.o.to_bits(), b.o.to_bits(), "cell {q} up {up}");
                        assert_eq!(a.k, b.k, "cell {q} up {up}");
                        assert_eq!(a.emit, b.emit, "cell {q} up {up}");
                        assert_eq!(a.coll, b.coll, "cell {q} up {up}");
                        assert_eq!(a.mean, b.mean, "cell {q} up {up}");
                    }
                }
            }
            per_cycle.push(set.computed - before);
        }
        let beyond = (2 * n - Profiles::KEEP) as u64;
        assert_eq!(per_cycle, [2 * n as u64, beyond, beyond]);
    }

    /// A full set of one scene's profiles gives way to the next scene's: the first
    /// sweep of the new scene computes its values level by level, the second starts
    /// afresh and keeps them, the third computes nothing. A scene that reads most of
    /// a full set every sweep keeps it.
    #[test]
    fn profiles_of_another_scene_replace_a_full_set() {
        let n = Profiles::KEEP;
        let a: Vec<f32> = (0..n).map(|i| -(i as f32 + 1.0) * 1e-4).collect();
        // (Beyond `a`'s range: no value of one is the other's.)
        let b: Vec<f32> = (0..64).map(|i| -7.0 - i as f32 * 0.01).collect();
        let mut set = Profiles::own(Profiles::KEEP);
        let sweep = |set: &mut Profiles, lnp: &[f32]| {
            set.begin_sweep();
            let before = set.computed;
            set.level(false, lnp, |_| true);
            set.level(false, lnp, |_| true);
            set.computed - before
        };
        // Scene A fills the set, and keeps it while it reads it all.
        assert_eq!(sweep(&mut set, &a), n as u64);
        assert_eq!(sweep(&mut set, &a), 0);
        // Scene B: computed per level (the set is full of A's), then kept.
        assert_eq!(sweep(&mut set, &b), 2 * b.len() as u64);
        assert_eq!(sweep(&mut set, &b), b.len() as u64);
        assert_eq!(sweep(&mut set, &b), 0);
        for (q, &l) in b.iter().enumerate() {
            let (x, y) = (set.get(q), CellProfile::new(false, l));
            assert_eq!((x.o.to_bits(), x.k, x.mean), (y.o.to_bits(), y.k, y.mean));
        }
    }
}
