//! A sweep's working memory: what a sweeper keeps between sweeps (`Spare`), the
//! per-level planes, the per-sweep work buffers.

use super::*;

/// Output memory of an earlier sweep, reused by the next one of the same size (see
/// [`crate::CpuSweeper::recycle`]): a fresh output's pages must be faulted in and
/// zeroed by the kernel, some 25 ms of a 64³ sweep with 26 bins on the 2-core VM.
#[derive(Clone, Default)]
pub(crate) struct Spare {
    pub(crate) bins: Vec<BinLight>,
    pub(crate) average: Vec<AverageLight>,
    pub(crate) dominant: Vec<DominantDir>,
    /// The horizon halves' output, and the split sink they are computed in (kept: the
    /// bins and halves are copied out of it).
    pub(crate) horizon: Vec<lightgrid_core::HorizonLight>,
    pub(crate) split: Vec<super::sink::SplitBins>,
    pub(crate) work: Option<Work>,
}

impl std::fmt::Debug for Spare {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Spare")
            .field("bins", &self.bins.len())
            .field("average", &self.average.len())
            .field("dominant", &self.dominant.len())
            .field("horizon", &self.horizon.len())
            .field("split", &self.split.len())
            .field("work", &self.work.as_ref().map(|w| (w.prev.nx, w.prev.nz)))
            .finish()
    }
}

/// The working buffers of a sweep, allocated once (per level, and per point for the
/// pending light), and kept for the next sweep of the same size in [`Spare`].
/// A level's per-cell values as padded planes for phase 3's row loops: the
/// transmittance of every path exponent ([`Planes::POW`] + exponent) and the source
/// rule's source per colour ([`Planes::SRC`] + colour; 0 where a cell does not emit),
/// each a plane of `(nx + 2R) × (nz + 2R)` with a ring of `R` cells beyond the sides:
/// wrapped on periodic sides, else empty space (transmittance 1, no source), as
/// [`Ctx::col`] resolves a cell beyond a side.
#[derive(Clone)]
pub(crate) struct Planes {
    /// Every level's transmittance and `ln(pass)` planes ([`Planes::PER_LEVEL`] a
    /// level), written at the level's first visit of a sweep (`Work::set_up`).
    pub(crate) v: Vec<f32>,
    /// The source planes of the level being swept.
    pub(crate) src: Vec<f32>,
    /// The level whose planes [`Planes::row`] reads.
    pub(crate) level: usize,
    pub(crate) nx: usize,
    pub(crate) nz: usize,
    /// [`MediumEmission::Profile`]: what each cell's `P_1`, `P_2` source terms emit into
    /// the segment of each stencil slot; per row of the level: slot, colour, column (no
    /// ring; 0 where the cell does not emit; empty under other rules). Written by phase
    /// 2 as it solves each cell's source ([`Ctx::phase2_row`]).
    pub(crate) ex: Vec<f32>,
}

impl Planes {
    /// The ring: the farthest stencil offset.
    pub(crate) const R: usize = RING;
    pub(crate) const POW: usize = 0;
    /// The cells' `ln(pass)` (0 beyond open sides), for [`seg_mean`].
    pub(crate) const LNP: usize = MAX_EXPONENTS;
    /// Planes kept per level.
    pub(crate) const PER_LEVEL: usize = MAX_EXPONENTS + 1;
    pub(crate) const SRC: usize = Self::PER_LEVEL;

    pub(crate) fn new(nx: usize, nz: usize, levels: usize) -> Self {
        let plane = (nx + 2 * Self::R) * (nz + 2 * Self::R);
        Self {
            v: vec![0.0; levels * Self::PER_LEVEL * plane],
            src: vec![0.0; 3 * plane],
            level: 0,
            nx,
            nz,
            ex: Vec::new(),
        }
    }

    /// Floats of one plane.
    #[inline(always)]
    pub(crate) fn plane_len(&self) -> usize {
        self.width() * (self.nz + 2 * Self::R)
    }

    /// Plane `plane` of the current level ([`Planes::level`]; the source planes are
    /// the level being swept's).
    #[inline(always)]
    pub(crate) fn plane(&self, plane: usize) -> &[f32] {
        let n = self.plane_len();
        if plane >= Self::SRC {
            &self.src[(plane - Self::SRC) * n..][..n]
        } else {
            &self.v[(self.level * Self::PER_LEVEL + plane) * n..][..n]
        }
    }

    /// [`Planes::plane`], to write.
    #[inline(always)]
    pub(crate) fn plane_mut(&mut self, plane: usize) -> &mut [f32] {
        let n = self.plane_len();
        if plane >= Self::SRC {
            &mut self.src[(plane - Self::SRC) * n..][..n]
        } else {
            &mut self.v[(self.level * Self::PER_LEVEL + plane) * n..][..n]
        }
    }

    #[inline(always)]
    pub(crate) fn width(&self) -> usize {
        self.nx + 2 * Self::R
    }

    /// `len` values of `plane` from column `x` of row `z` (`-R ≤ x`, `x + len ≤ nx + R`,
    /// `-R ≤ z < nz + R`).
    #[inline(always)]
    pub(crate) fn row(&self, plane: usize, z: i32, x: i32, len: usize) -> &[f32] {
        let w = self.width();
        let r = (z + Self::R as i32) as usize * w;
        &self.plane(plane)[r + (x + Self::R as i32) as usize..][..len]
    }

    /// Fills the current level's transmittance planes from its cells' `ln(pass)`
    /// `lnp`: plane [`Planes::POW`] + `e` holds `pass^x_e` (`exp(x_e ln pass)`, 1
    /// where the cell is empty) for the path exponent `x_e` of [`path_exponents`],
    /// plane [`Planes::LNP`] `lnp` itself; a plane a task (a few planes a task on
    /// small levels).
    pub(crate) fn fill_pows(&mut self, ctx: &Ctx, lnp: &[f32]) {
        let exps = path_exponents();
        let n = self.plane_len();
        let level = &mut self.v[self.level * Self::PER_LEVEL * n..][..Self::PER_LEVEL * n];
        level
            .par_chunks_mut(n)
            .with_min_len(MIN_POINTS_PER_TASK.div_ceil(n.max(1)))
            .enumerate()
            .for_each(|(k, plane)| {
                if k == Self::LNP {
                    fill_plane(ctx, plane, 0.0, |q| lnp[q]);
                } else {
                    let e = exps[k];
                    fill_plane(ctx, plane, 1.0, |q| {
                        let l = lnp[q];
                        if l == 0.0 { 1.0 } else { (e * l).exp() }
                    });
                }
            });
    }

    /// The current level's transmittances ([`LevelPows`]).
    #[inline(always)]
    pub(crate) fn pows(&self) -> LevelPows<'_> {
        LevelPows::of(&self.v, self.level, (self.nx, self.nz))
    }

    /// Fills the source planes from the level's sources (0 where a cell does not emit).
    pub(crate) fn fill_src(&mut self, ctx: &Ctx, src: &[Vec3], emits: &[bool]) {
        self.fill(ctx, Self::SRC, 3, 0.0, |q, col| {
            if emits[q] { src[q][col] } else { 0.0 }
        });
    }

    /// `len` values of [`Planes::ex`] for `slot`, colour `col`, row `z`, columns `x..x +
    /// len` (`-RING ≤ x`, `x + len ≤ nx + RING`; the ring holds the wrapped columns on
    /// periodic sides, 0 beyond open ones; a row beyond an open side is 0).
    #[inline(always)]
    pub(crate) fn ex_row(
        &self,
        ctx: &Ctx,
        (slot, col): (usize, usize),
        z: i32,
        x: i32,
        len: usize,
    ) -> &[f32] {
        static ZERO: [f32; GATHER_BLOCK] = [0.0; GATHER_BLOCK];
        let Some(zr) = ctx.row_of(z) else {
            return &ZERO[..len];
        };
        tap(&self.ex, self.nx, (zr, slot, col), x, len)
    }

    /// Planes `first..first + count`: `value(cell, plane - first)` at every cell of
    /// the ring and the level (the cell [`Ctx::col`] finds), `outside` beyond open sides.
    pub(crate) fn fill(
        &mut self,
        ctx: &Ctx,
        first: usize,
        count: usize,
        outside: f32,
        value: impl Fn(usize, usize) -> f32,
    ) {
        for k in 0..count {
            fill_plane(ctx, self.plane_mut(first + k), outside, |q| value(q, k));
        }
    }
}

/// One plane of `ctx`'s level with its ring ([`Planes`]): `value(cell)` at every cell
/// of the ring and the level (the cell [`Ctx::col`] finds), `outside` beyond open sides.
fn fill_plane(ctx: &Ctx, plane: &mut [f32], outside: f32, value: impl Fn(usize) -> f32) {
    let (nx, nz) = (ctx.nx as usize, ctx.nz as usize);
    let r = Planes::R as i32;
    let (w, h) = (nx + 2 * Planes::R, nz + 2 * Planes::R);
    // Column and row of the level each ring position reads (`None`: outside).
    let axis = |i: usize, n: i32| -> Option<usize> {
        let v = i as i32 - r;
        if ctx.periodic {
            Some(v.rem_euclid(n) as usize)
        } else {
            (0..n).contains(&v).then_some(v as usize)
        }
    };
    let xs: Vec<Option<usize>> = (0..w).map(|i| axis(i, ctx.nx)).collect();
    for zz in 0..h {
        let dst = &mut plane[zz * w..][..w];
        match axis(zz, ctx.nz) {
            None => dst.fill(outside),
            Some(z) => {
                for (d, x) in dst.iter_mut().zip(&xs) {
                    *d = x.map_or(outside, |x| value(x + nx * z));
                }
            }
        }
    }
}

/// A level's transmittance of every path exponent, read from its planes
/// ([`Planes::POW`]): `get(q, e)` is what cell `q` (its index within the level) passes
/// along a path of exponent `path_exponents()[e]`. The one store of the transmittances
/// (a copy a point beside the planes, written at every level's first visit, was 1.3 MB
/// more work memory in a 32³ sweep).
#[derive(Clone, Copy)]
pub(crate) struct LevelPows<'a> {
    v: &'a [f32],
    plane: usize,
    w: usize,
    nx: usize,
}

impl<'a> LevelPows<'a> {
    /// Level `level`'s transmittances in the planes `v` ([`Planes::v`]) of a grid of
    /// `nx × nz` levels.
    #[inline(always)]
    pub(crate) fn of(v: &'a [f32], level: usize, (nx, nz): (usize, usize)) -> Self {
        let w = nx + 2 * Planes::R;
        let plane = w * (nz + 2 * Planes::R);
        Self {
            v: &v[level * Planes::PER_LEVEL * plane..][..MAX_EXPONENTS * plane],
            plane,
            w,
            nx,
        }
    }

    /// Cell `q`'s transmittance along a path of exponent index `e` (the oracle's
    /// read, by the cell's index).
    #[inline(always)]
    pub(crate) fn get(&self, q: usize, e: usize) -> f32 {
        let (x, z) = (q % self.nx, q / self.nx);
        self.v[e * self.plane + (z + Planes::R) * self.w + x + Planes::R]
    }

    /// The transmittances of every exponent of the cell of column `x`, row `z` (the row
    /// loops know both: no division).
    #[inline(always)]
    pub(crate) fn at(&self, x: usize, z: usize) -> [f32; MAX_EXPONENTS] {
        let o = (z + Planes::R) * self.w + x + Planes::R;
        std::array::from_fn(|e| self.v[e * self.plane + o])
    }
}

#[derive(Clone)]
pub(crate) struct Work {
    pub(crate) prev: LevelLight,
    pub(crate) cur: LevelLight,
    /// The upward light left at the levels above all material for a later pass to
    /// carry (its ring as `prev`'s).
    pub(crate) above: LevelLight,
    /// Light from outside the sides in its ring, zero inside ([`LevelLight`]), and the
    /// source level it was last filled for (`None`: not filled).
    pub(crate) ghost: LevelLight,
    pub(crate) ghost_for: Option<(bool, i32)>,
    /// The ring points some channel's taps reach ([`GhostRing`]), found once for a
    /// level size and channel set.
    pub(crate) ring: GhostRing,
    /// Slot planes (per row: slot, colour, column) of two uses in turn: phase 1 writes
    /// what every point's path lost in each of its segments, which phase 2 reads; then
    /// phase 3 writes over them what each point's path carries into each of its
    /// segments (`pre`), which it reads itself. One buffer: phase 3 writes after phase
    /// 2's last read, and the next level's phase 1 writes every row its phase 2 reads
    /// (a row within two of a cell with material holds a point that is not quiet, and
    /// phase 1 writes such rows whole, rings included). Two buffers were 661 KB more
    /// of fresh memory in a 32³ sweep.
    pub(crate) removed: Vec<f32>,
    /// Per row: phase 3 wrote its `pre` into [`Work::removed`] this level (some point
    /// of the row is near an emitting cell).
    pub(crate) pre_rows: Vec<bool>,
    pub(crate) planes: Planes,
    pub(crate) t_after: Vec<[f32; CHANNELS]>,
    pub(crate) rows: Vec<RowFlux>,
    /// Points with no material within two cells of their level ([`Ctx::quiet`];
    /// written with the transmittance planes).
    pub(crate) quiet: Vec<bool>,
    pub(crate) quiet_rows: Vec<bool>,
    /// Per level: `pows`, `quiet` and the level's transmittance planes
    /// ([`Planes::level`]) hold its values this sweep.
    pub(crate) set_up: Vec<bool>,
    /// The source rule's source per cell of the level ([`crate::medium`]) and whether a
    /// cell emits.
    pub(crate) src: Vec<Vec3>,
    pub(crate) emits: Vec<bool>,
    /// [`MediumEmission::Profile`]: the level's cells' profiles for this pass and the
    /// source's coefficients of `P_1`, `P_2` in height (empty under other rules).
    pub(crate) prof: crate::profile::Profiles,
    pub(crate) src_hi: Vec<[Vec3; 2]>,
    /// Scattered light waiting to be emitted in downward / upward channels.
    pub(crate) pend_down: PendingLevels,
    pub(crate) pend_up: PendingLevels,
    /// Accelerated sweeps ([`crate::accel`]): the upward share of what collides in a
    /// downward pass, for the next pair of passes (empty otherwise).
    pub(crate) pend_next: PendingLevels,
    /// Per level: some pending light of it was written (zeroed again on reuse).
    pub(crate) pend_dirty: Vec<bool>,
    /// The halo's partial paths ([`RingPaths`]) and their light at the level being
    /// swept.
    pub(crate) ring_paths: RingPaths,
    pub(crate) ring_level: RingLevel,
}

impl Work {
    pub(crate) fn new(nx: usize, nz: usize, n: usize) -> Self {
        let level_len = nx * nz;
        Self {
            prev: LevelLight::new(nx, nz),
            cur: LevelLight::new(nx, nz),
            above: LevelLight::new(nx, nz),
            ghost: LevelLight::new(nx, nz),
            ghost_for: None,
            ring: GhostRing::default(),
            removed: vec![0.0; nz * ring_pitch(nx) * SLOTS * 3],
            pre_rows: vec![false; nz],
            planes: Planes::new(nx, nz, n / level_len.max(1)),
            t_after: vec![[1.0; CHANNELS]; level_len],
            rows: vec![RowFlux::default(); nz],
            quiet: vec![false; n],
            quiet_rows: vec![false; level_len],
            set_up: vec![false; n / level_len.max(1)],
            src: vec![Vec3::ZERO; level_len],
            emits: vec![false; level_len],
            prof: Default::default(),
            src_hi: Vec::new(),
            pend_down: PendingLevels::new(level_len, n / level_len.max(1)),
            pend_up: PendingLevels::new(level_len, n / level_len.max(1)),
            pend_next: PendingLevels::default(),
            pend_dirty: vec![false; n / level_len.max(1)],
            ring_paths: RingPaths::default(),
            ring_level: RingLevel::default(),
        }
    }

    /// `old` made ready for a new sweep if its levels have the size (the level buffers
    /// and the levels of pending light that were written zeroed, the per-level and
    /// per-point buffers made as long as the grid's levels need, in the memory they
    /// had where it is large enough: a hierarchy's nodes differ in height, and kept for
    /// one height alone every node's sweep faulted in and zeroed fresh pages), else new
    /// buffers with `old`'s cell profiles (they depend on a cell's depth of medium
    /// alone, not on the grid).
    pub(crate) fn reuse(old: Option<Work>, nx: usize, nz: usize, n: usize) -> Self {
        match old {
            Some(mut w) if w.prev.nx == nx && w.prev.nz == nz => {
                w.prev.v.fill(0.0);
                w.cur.v.fill(0.0);
                w.ghost.v.fill(0.0);
                w.ghost_for = None;
                for (j, dirty) in w.pend_dirty.iter_mut().enumerate() {
                    if std::mem::take(dirty) {
                        w.pend_down.clear_level(j);
                        w.pend_up.clear_level(j);
                        if j < w.pend_next.levels.len() {
                            w.pend_next.clear_level(j);
                        }
                    }
                }
                w.resize_levels(n / (nx * nz).max(1));
                w
            }
            old => {
                let mut w = Self::new(nx, nz, n);
                if let Some(old) = old {
                    w.prof = old.prof;
                }
                w
            }
        }
    }

    /// The buffers sized by the grid's levels made `levels` long (what they held is
    /// written before it is read: the planes and `quiet` at a level's set-up,
    /// which `set_up` marks; pending light clear, every level of it written zeroed
    /// before).
    fn resize_levels(&mut self, levels: usize) {
        let n = levels * self.prev.nx * self.prev.nz;
        self.planes
            .v
            .resize(levels * Planes::PER_LEVEL * self.planes.plane_len(), 0.0);
        self.quiet.resize(n, false);
        self.set_up.clear();
        self.set_up.resize(levels, false);
        self.pend_dirty.resize(levels, false);
        self.pend_down.levels.resize(levels, Vec::new());
        self.pend_up.levels.resize(levels, Vec::new());
        if !self.pend_next.levels.is_empty() {
            self.pend_next.levels.resize(levels, Vec::new());
        }
    }

    /// The first level of a pass gathers from the virtual level beyond the grid: its
    /// channel light goes into `prev`.
    pub(crate) fn fill_from_boundary(&mut self, src: &Sources, ctx: &Ctx) {
        let p = self.prev.pitch();
        for z in 0..ctx.nz {
            let row = self.prev.row_mut(z as isize);
            for x in 0..ctx.nx {
                for (c, chn) in ctx.ch.iter().enumerate() {
                    row_set(row, p, x as usize, c, src.virtual_light(x, z, chn));
                }
            }
        }
    }

    /// The ring of `ghost`: what the oracle's [`Ctx::gather_edge`] reads for a tap at
    /// each column beyond the sides. Without a halo that is the virtual level's light,
    /// the same for every level of a pass (filled once a pass); with one, the halo's
    /// light at the source level, and the virtual level's for the pass's first level.
    ///
    /// Each channel's part of the ring is filled only where its taps reach
    /// ([`ghost_reach`]); the rest of its planes keep what they held, which no tap
    /// reads. (Filled whole, the ring was a tenth of a 16-point node's sweep: five
    /// columns around a 16 × 16 level for every channel, where a channel's taps reach
    /// one to five on one side.)
    pub(crate) fn fill_ghost(
        &mut self,
        src: &Sources,
        ctx: &Ctx,
        from_virtual: bool,
        src_level: i32,
    ) {
        let key = (src.up, if src.halo.is_none() { 0 } else { src_level });
        if self.ghost_for == Some(key) {
            return;
        }
        self.ghost_for = Some(key);
        self.ring.make_for(ctx);
        let p = self.ghost.pitch();
        let pad = PAD as isize;
        // With a halo, each ring point's value within a level is found once for the
        // level size ([`GhostRing::halo`]): [`Sources::outside_bins`] without its
        // lookup a point.
        // The first level of a pass gathers from the virtual level beyond the grid
        // beyond its sides too: the light above the top (below the bottom) is the
        // boundary's there, not the halo's top (bottom) level's, which crossed that
        // level's cells.
        let halo = match (
            src.active && !from_virtual,
            src.boundary.sides.halo(),
            &src.halo,
        ) {
            (true, Some(h), Some(layout)) => {
                let lv = src_level.clamp(0, src.dims.y as i32 - 1) as usize;
                let base = lv * layout.per_level();
                Some((h, src.boundary.sides.halo_down(), base))
            }
            _ => None,
        };
        for (k, &(x, z, mask)) in self.ring.points.iter().enumerate() {
            // The point's bins, found once for its channels.
            let bins = match (halo, self.ring.halo[k]) {
                (Some((h, down, base)), Some(off)) => {
                    let i = base + off as usize;
                    Some(SourceBins {
                        light: &h[i],
                        down: down.map(|d| &d[i]),
                        full_sphere: true,
                    })
                }
                (Some(_), None) => None,
                _ if from_virtual => src.virtual_bins(x, z),
                _ => src.outside_bins(x, src_level, z),
            };
            let row = self.ghost.row_mut(z as isize);
            let col = (x as isize + pad) as usize;
            let mut m = mask;
            while m != 0 {
                let c = m.trailing_zeros() as usize;
                m &= m - 1;
                let v = Sources::value(bins, &ctx.ch[c]);
                let b = c * 3 * p + col;
                row[b] = v.x;
                row[b + p] = v.y;
                row[b + 2 * p] = v.z;
            }
        }
    }
}

impl Work {
    /// The halo's partial paths' exit light at the source level written over their
    /// points' halo light in `ghost` ([`RingPaths`]); the next fill fills afresh.
    pub(crate) fn ghost_ring_exits(&mut self) {
        let rp = &self.ring_paths;
        if !rp.prev_valid {
            return;
        }
        let p = self.ghost.pitch();
        for (e, en) in rp.entries.iter().enumerate() {
            let v = rp.prev[e];
            let row = self.ghost.row_mut(en.z as isize);
            let b = en.c * 3 * p + (en.x as isize + PAD as isize) as usize;
            row[b] = v.x;
            row[b + p] = v.y;
            row[b + 2 * p] = v.z;
        }
        self.ghost_for = None;
    }
}

// A ring point's channels are the bits of a `u32`.
const _: () = assert!(CHANNELS <= 32);

/// The points of a level's ring (beyond its sides, within [`PAD`]) that some
/// channel's taps reach ([`ghost_reach`]), each with the channels that reach it (bit
/// `c`): what [`Work::fill_ghost`] writes, found once for a level size and channel
/// set (the ring was scanned whole, every channel tested at every point, at each
/// fill: a third of the fill's time on a 16-point node).
#[derive(Clone, Debug, Default)]
pub(crate) struct GhostRing {
    /// The level size and channel set the points are for.
    key: Option<(i32, i32, usize)>,
    pub(crate) points: Vec<(i32, i32, u32)>,
    /// Each point's index within a level of a side halo
    /// ([`lightgrid_core::HaloLayout::index`] at level 0; `None` beyond the halo).
    pub(crate) halo: Vec<Option<u32>>,
}

impl GhostRing {
    /// The points for `ctx`'s level size and channels (kept where they are already).
    pub(crate) fn make_for(&mut self, ctx: &Ctx) {
        let key = (ctx.nx, ctx.nz, ctx.ch.as_ptr() as usize);
        if self.key == Some(key) {
            return;
        }
        self.key = Some(key);
        self.points.clear();
        self.halo.clear();
        let layout = lightgrid_core::HaloLayout::new(UVec3::new(
            ctx.nx.max(0) as u32,
            1,
            ctx.nz.max(0) as u32,
        ));
        let (nx, nz) = (ctx.nx as isize, ctx.nz as isize);
        let pad = PAD as isize;
        let reach: [GhostReach; CHANNELS] =
            std::array::from_fn(|c| ghost_reach(&ctx.ch[c], nx, nz));
        for z in -pad..nz + pad {
            for x in -pad..nx + pad {
                if (0..nx).contains(&x) && (0..nz).contains(&z) {
                    continue;
                }
                let mask = reach
                    .iter()
                    .enumerate()
                    .filter(|(_, r)| r.holds(x, z))
                    .fold(0u32, |m, (c, _)| m | 1 << c);
                if mask != 0 {
                    self.points.push((x as i32, z as i32, mask));
                    self.halo
                        .push(layout.index(x as i32, 0, z as i32).map(|i| i as u32));
                }
            }
        }
    }
}

/// The columns and rows of `ghost` (ring and inside) that a channel's taps read
/// ([`Ctx::gather_row_channels`]): a point `(x, z)` of the level gathers from the
/// source level's columns `x − step.x − 1 ..= x − step.x + 1` and rows
/// `z − step.z − 1 ..= z − step.z + 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct GhostReach {
    pub(crate) x: (isize, isize),
    pub(crate) z: (isize, isize),
}

impl GhostReach {
    #[inline(always)]
    pub(crate) fn holds(self, x: isize, z: isize) -> bool {
        (self.x.0..=self.x.1).contains(&x) && (self.z.0..=self.z.1).contains(&z)
    }
}

/// [`GhostReach`] of channel `chn` on an `nx × nz` level.
pub(crate) fn ghost_reach(chn: &Channel, nx: isize, nz: isize) -> GhostReach {
    let (sx, sz) = (chn.step.x as isize, chn.step.z as isize);
    GhostReach {
        x: (-sx - 1, nx - sx),
        z: (-sz - 1, nz - sz),
    }
}
