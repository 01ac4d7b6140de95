//! The halo's partial paths ([`lightgrid_core::SweepOptions::halo_paths`]).
//!
//! With given sides, a sweep of the whole world traces the paths of the halo's points
//! too, and those of the points within two cells of a side cross one or two of the
//! grid's own cells of their level (a horizontal channel's two stencil slots on the
//! grid's side of the point). Untraced, those cells neither stop their light nor
//! collect what they would stop, what they emit into them leaves through the side, and
//! the next level gathers the halo point's mean as if an entering path had ended at
//! its centre. Traced here, in phase 1 (the same code for the fast path and the
//! oracle): a path entering the grid starts from the halo's light at its point (its
//! cell's mean, taken as the light at its centre) and crosses the grid's media after
//! the centre; a path leaving it gathers as the grid's points do and crosses the
//! grid's cells before the centre. Phase 2 collects what they removed with the rest;
//! phase 3 adds what the grid's media emit into an entering path, and the next level's
//! gather reads its light. The grid's opaque cells do not stop an entering path:
//! beyond an opaque cell at a given side the world goes on as it is there, so the
//! halo's light there is a surface's, which leaves over its level-mates (as an opaque
//! cell's top face emits, `SurfaceWeights::free`). The halo's own cells are unknown to
//! the sweep and taken as empty, as everywhere else. Levels without material are not
//! traced: a path leaves them with the light it brought.

use super::*;

/// One halo point's partial path in one channel.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RingEntry {
    pub(crate) x: i32,
    pub(crate) z: i32,
    pub(crate) c: usize,
    /// The stencil slot of the point's centre.
    pub(crate) kc: usize,
    /// The path's slots before its centre cross the grid's cells (it leaves the grid
    /// through the point); else those after it do (it enters).
    pub(crate) leaves: bool,
}

/// Slots on either side of a horizontal channel's centre.
pub(crate) const SIDE: usize = 2;

/// Index in an entry's removals of stencil slot `k` (`kc`: the centre's).
#[inline]
fn side_index(k: usize, kc: usize) -> usize {
    if k < kc { k } else { k - kc - 1 }
}

/// The halo's partial paths of a level size and channel set, and their exit light at
/// the level before.
#[derive(Clone, Debug, Default)]
pub(crate) struct RingPaths {
    key: Option<(i32, i32, bool)>,
    pub(crate) entries: Vec<RingEntry>,
    /// Entry of `(x, z, c)` over the band `-RING .. n + RING` (`u32::MAX`: none).
    map: Vec<u32>,
    /// Exit light of each entry at the level before (`prev_valid`: written for it).
    pub(crate) prev: Vec<Vec3>,
    pub(crate) prev_valid: bool,
}

/// The halo's partial paths' light at the level being swept.
#[derive(Clone, Debug, Default)]
pub(crate) struct RingLevel {
    /// The paths are traced at this level (it holds material).
    pub(crate) traced: bool,
    /// Exit light of each entry (zero for a path that leaves).
    pub(crate) cur: Vec<Vec3>,
    /// What the grid's cells removed from each entry's path, per slot on the grid's
    /// side of its centre ([`side_index`]).
    pub(crate) removed: Vec<[Vec3; SIDE]>,
}

/// The halo's partial paths and their light at the level being swept, as phase 2 reads
/// them.
pub(crate) type RingRead<'a> = Option<(&'a RingPaths, &'a RingLevel)>;

impl RingPaths {
    /// The entries for `ctx`'s level size and channels, found once for them.
    pub(crate) fn make_for(&mut self, ctx: &Ctx, level: &mut RingLevel) {
        let key = (ctx.nx, ctx.nz, up_pass(ctx.ch));
        if self.key == Some(key) {
            return;
        }
        self.key = Some(key);
        self.prev_valid = false;
        self.entries.clear();
        let r = RING as i32;
        let (wx, wz) = ((ctx.nx + 2 * r) as usize, (ctx.nz + 2 * r) as usize);
        self.map = vec![u32::MAX; wx * wz * CHANNELS];
        for z in -r..ctx.nz + r {
            for x in -r..ctx.nx + r {
                if ctx.col(x, z).is_some() {
                    continue;
                }
                for (c, chn) in ctx.ch.iter().enumerate() {
                    let Some(kc) = chn.stencil.iter().position(|t| t.0 == 0 && t.1 == 0) else {
                        continue;
                    };
                    let in_grid = |s: &[(i32, i32, f32)]| {
                        s.iter().any(|t| ctx.col(x + t.0, z + t.1).is_some())
                    };
                    let (before, after) =
                        (in_grid(&chn.stencil[..kc]), in_grid(&chn.stencil[kc + 1..]));
                    if before || after {
                        debug_assert!(kc == SIDE && chn.stencil.len() == 2 * SIDE + 1);
                        let i = ((z + r) as usize * wx + (x + r) as usize) * CHANNELS + c;
                        self.map[i] = self.entries.len() as u32;
                        self.entries.push(RingEntry {
                            x,
                            z,
                            c,
                            kc,
                            leaves: before,
                        });
                    }
                }
            }
        }
        let n = self.entries.len();
        self.prev = vec![Vec3::ZERO; n];
        level.cur = vec![Vec3::ZERO; n];
        level.removed = vec![[Vec3::ZERO; SIDE]; n];
    }

    /// The entry of halo point `(x, z)` in channel `c`, if its path crosses the grid.
    #[inline]
    pub(crate) fn entry(&self, ctx: &Ctx, x: i32, z: i32, c: usize) -> Option<usize> {
        let r = RING as i32;
        if x < -r || z < -r || x >= ctx.nx + r || z >= ctx.nz + r {
            return None;
        }
        let wx = (ctx.nx + 2 * r) as usize;
        let i = ((z + r) as usize * wx + (x + r) as usize) * CHANNELS + c;
        self.map
            .get(i)
            .copied()
            .filter(|&e| e != u32::MAX)
            .map(|e| e as usize)
    }

    /// What the grid's cells removed at stencil slot `k` of channel `c` from the path
    /// of halo point `(x, z)` (zero where it has none there).
    #[inline]
    pub(crate) fn removed_at(
        &self,
        (ctx, level): (&Ctx, &RingLevel),
        (x, z): (i32, i32),
        c: usize,
        k: usize,
    ) -> Vec3 {
        match self.entry(ctx, x, z, c) {
            Some(e) if k != self.entries[e].kc => {
                level.removed[e][side_index(k, self.entries[e].kc)]
            }
            _ => Vec3::ZERO,
        }
    }

    /// [`RingPaths::removed_at`] for the `out.len()` points from column `first` of the
    /// halo's row `z` (beyond the grid's rows), colour `colour`: the fast path's phase 2
    /// reads them there as it reads a row of the slot planes.
    #[inline]
    pub(crate) fn row_beyond<'o>(
        &self,
        at: (&Ctx, &RingLevel),
        (first, z): (i32, i32),
        (c, k, colour): (usize, usize, usize),
        out: &'o mut [f32],
    ) -> &'o [f32] {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.removed_at(at, (first + i as i32, z), c, k)[colour];
        }
        out
    }

    /// The exit light of halo point `(x, z)`'s path in channel `c` at the level before,
    /// where it has one.
    #[inline]
    pub(crate) fn exit(&self, ctx: &Ctx, x: i32, z: i32, c: usize) -> Option<Vec3> {
        if !self.prev_valid {
            return None;
        }
        self.entry(ctx, x, z, c)
            .filter(|&e| !self.entries[e].leaves)
            .map(|e| self.prev[e])
    }

    /// The level done: its exits become the next level's sources.
    pub(crate) fn level_done(&mut self, level: &mut RingLevel) {
        std::mem::swap(&mut self.prev, &mut level.cur);
        self.prev_valid = true;
    }
}

impl Ctx {
    /// Phase 1 of the halo's partial paths at level `j`. A path entering the grid
    /// starts from the halo's light at its point and crosses the grid's cells after
    /// its centre (not stopped by opaque ones, above); a path leaving it gathers as the
    /// grid's points do (`from`) and crosses the grid's cells before its centre. Writes
    /// what each cell removes into `ring.removed` and, for points beside the grid's
    /// rows, into the ring columns of the level's slot planes `planes` (where the fast
    /// path's phase 2 reads them). Returns the flux the grid's cells removed, of light
    /// from inside the grid and from outside.
    pub(crate) fn ring_phase1(
        &self,
        from: &Gather<'_, '_>,
        j: i32,
        (pows, lnp): (LevelPows<'_>, &[f32]),
        (ring, level, planes): (&RingPaths, &mut RingLevel, &mut [f32]),
    ) -> (DVec3, DVec3) {
        let nx = self.nx as usize;
        let (mut inside, mut outside) = (DVec3::ZERO, DVec3::ZERO);
        for (e, en) in ring.entries.iter().enumerate() {
            let chn = &self.ch[en.c];
            let mut rem = [Vec3::ZERO; SIDE];
            let mut t = 1.0f32;
            if en.leaves {
                let (ins, outs) =
                    self.gather_edge(from, (chn, en.c), (en.x - chn.step.x, en.z - chn.step.z));
                let light = ins + outs;
                for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate().take(en.kc) {
                    if let Some(ci) = self.col(en.x + dx, en.z + dz)
                        && lnp[ci] != 0.0
                    {
                        let tr = pows.get(ci, chn.pow[k]);
                        rem[side_index(k, en.kc)] = light * (t * (1.0 - tr));
                        t *= tr;
                    }
                }
                let mu = chn.mu as f64;
                inside += (ins * (1.0 - t)).as_dvec3() * mu;
                outside += (outs * (1.0 - t)).as_dvec3() * mu;
                level.cur[e] = Vec3::ZERO;
            } else {
                let light = from.src.outside(en.x, j, en.z, chn);
                for k in en.kc + 1..chn.stencil.len() {
                    let (dx, dz, _) = chn.stencil[k];
                    // Only media stop it: not opaque cells (above), nor empty ones
                    // (whose transmittance planes a level without material never fills).
                    if let Some(ci) = self.col(en.x + dx, en.z + dz)
                        && lnp[ci] != f32::NEG_INFINITY
                        && lnp[ci] != 0.0
                    {
                        let tr = pows.get(ci, chn.pow[k]);
                        rem[side_index(k, en.kc)] = light * (t * (1.0 - tr));
                        t *= tr;
                    }
                }
                outside += (light * (1.0 - t)).as_dvec3() * chn.mu as f64;
                level.cur[e] = light * t;
            }
            level.removed[e] = rem;
            if (0..self.nz).contains(&en.z) {
                // Beside the grid's rows: into the planes' ring columns (zeros
                // elsewhere, `fill_rings`).
                for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                    if k == en.kc || self.col(en.x + dx, en.z + dz).is_none() {
                        continue;
                    }
                    let slot = chn.first_slot + k;
                    let col = (en.x + RING as i32) as usize;
                    for colour in 0..3 {
                        let i = slot_index(nx, (en.z as usize, 0), slot, colour) - RING;
                        planes[i + col] = rem[side_index(k, en.kc)][colour];
                    }
                }
            }
        }
        (inside, outside)
    }

    /// Phase 3 of the halo's partial paths: what the grid's cells after each centre
    /// emit into them, carried on (attenuated by the path's cells after them) into
    /// their exit light.
    pub(crate) fn ring_phase3(
        &self,
        (src, emits): (&[Vec3], &[bool]),
        (src_hi, prof): (&[[Vec3; 2]], &crate::profile::Profiles),
        (pows, lnp): (LevelPows<'_>, &[f32]),
        (ring, level): (&RingPaths, &mut RingLevel),
    ) {
        let mw = medium::weights(up_pass(self.ch));
        let profile = self.medium == MediumEmission::Profile;
        for (e, en) in ring.entries.iter().enumerate() {
            if en.leaves {
                // What the grid's cells emit into it leaves (`Ctx::lost_through_sides`).
                continue;
            }
            let chn = &self.ch[en.c];
            let mut acc = Vec3::ZERO;
            for k in en.kc + 1..chn.stencil.len() {
                let (dx, dz, _) = chn.stencil[k];
                let Some(q) = self.col(en.x + dx, en.z + dz) else {
                    continue;
                };
                if lnp[q] == f32::NEG_INFINITY || lnp[q] == 0.0 {
                    continue;
                }
                let tr = pows.get(q, chn.pow[k]);
                let mut em = Vec3::ZERO;
                if emits[q] {
                    em = src[q] * (1.0 - tr);
                    if profile {
                        let w = prof.get(q).emit[chn.first_slot + k];
                        em += src_hi[q][0] * w[0] + src_hi[q][1] * w[1];
                    }
                }
                acc = acc * tr + em;
            }
            if acc != Vec3::ZERO {
                level.cur[e] += acc * mw.omega[en.c];
            }
        }
    }
}
