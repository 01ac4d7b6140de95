//! Phase 3 of a level: the emission carried along each path's segments inside the
//! level, and what collides again.

use super::*;

/// What phase 3 of a level reads: the cells' sources and which cells emit, under the
/// profile rule their `P_1`, `P_2` coefficients and profiles, the level's `ln p`, cells
/// and exposed faces (its transmittances are [`Planes::pows`]), and whether the scalar
/// oracle runs it.
#[derive(Clone, Copy)]
pub(crate) struct Phase3In<'a> {
    pub(crate) src: &'a [Vec3],
    pub(crate) emits: &'a [bool],
    pub(crate) src_hi: &'a [[Vec3; 2]],
    pub(crate) prof: &'a crate::profile::Profiles,
    pub(crate) lnp: &'a [f32],
    pub(crate) cells: &'a [lightgrid_core::Material],
    /// The cells' exposed faces ([`exposure`]).
    pub(crate) exposed: &'a [u8],
    pub(crate) scalar: bool,
}

impl Ctx {
    /// Phase 3 of a level under the source rule ([`crate::medium`]): every path
    /// gains what its segments' sources emit, attenuated by the segments after them
    /// (and `pre` keeps what each path carries into each of its segments); the level is
    /// finished ([`Finish`]); then every cell with material collects what it stops of
    /// its level-mates' emission (scattered light for the next passes).
    ///
    /// The emission runs channel by channel over blocks of a row, segment by segment
    /// ([`Planes`] of the level's transmittances and sources, with a ring beyond the
    /// sides), so that its loops vectorise; each point's sums are the same operations
    /// in the same order as a walk along its paths, so the light is the same bit for bit.
    pub(crate) fn phase3<S: Sink>(
        &self,
        input: Phase3In<'_>,
        planes: &mut Planes,
        (pre, pre_rows): (&mut [f32], &mut [bool]),
        (pend_same, pend_other): (&mut [Pending], &mut [Pending]),
        LevelRows { cur, g, rows }: LevelRows<'_, S>,
        fin: Finish<'_>,
    ) -> RowFlux {
        let Phase3In {
            src,
            emits,
            src_hi,
            prof,
            lnp,
            scalar,
            ..
        } = input;
        let hi = (src_hi, prof);
        let nx = self.nx as usize;
        let p = cur.pitch();
        let profile = self.medium == MediumEmission::Profile;
        planes.fill_src(self, src, emits);
        let planes = &*planes;
        let pows = planes.pows();
        // Rows whose paths carry anything: within [`RING`] rows of an emitting cell, as
        // far as a path reaches (every row, scalar).
        let emitting: Vec<bool> = emits.chunks(nx).map(|r| r.contains(&true)).collect();
        let reach = RING as i32;
        for (z, r) in pre_rows.iter_mut().enumerate() {
            *r = scalar
                || (-reach..=reach)
                    .any(|d| self.row_of(z as i32 + d).is_some_and(|zr| emitting[zr]));
        }
        let pre_rows = &*pre_rows;
        let emitted = self.level_rows(
            cur,
            pre.par_chunks_mut(ring_pitch(nx) * SLOTS * 3),
            g,
            rows,
            (fin, true),
            |z, cur_row, pre_row, g_row, _| {
                if scalar {
                    self.phase3_row_scalar(
                        z,
                        (src, emits),
                        hi,
                        (pows, lnp),
                        p,
                        (cur_row, pre_row, g_row),
                    );
                } else if pre_rows[z as usize] {
                    let hi = profile.then_some((hi.0, hi.1, emits));
                    vectorised!(self.phase3_row(z, (planes, hi), p, cur_row, pre_row, g_row));
                } else {
                    return;
                }
                fill_rings(pre_row, nx, self.periodic);
            },
        );
        let pre = &*pre;
        pend_same
            .par_chunks_mut(nx)
            .zip(pend_other.par_chunks_mut(nx))
            .zip(rows.par_iter_mut())
            .enumerate()
            .with_max_len(self.rows_per_task(true).1)
            .for_each(|(z, ((same_row, other_row), rf))| {
                *rf = RowFlux::default();
                vectorised!(self.collide_row(
                    z as i32,
                    &input,
                    planes,
                    (pre, pre_rows),
                    (same_row, other_row),
                    rf,
                ));
            });
        RowFlux {
            sent: emitted.sent,
            bad: emitted.bad,
            ..sum_rows(rows)
        }
    }

    /// [`Ctx::phase3`]'s emission for row `z`: the row's paths gain their segments'
    /// emission; `pre_row[(slot · 3 + colour) · ring_pitch + RING + x]` ([`plane_index`]'s
    /// layout) is what the path of point `x`
    /// carries into the segment of stencil slot `slot` (written for the segments after
    /// a path's first, the only ones [`Ctx::collide_row`] reads).
    #[inline(always)]
    pub(crate) fn phase3_row<S: Sink>(
        &self,
        z: i32,
        (planes, hi): (&Planes, Option<ProfileRows<'_>>),
        p: usize,
        cur_row: &mut [f32],
        pre_row: &mut [f32],
        g_row: &mut [S],
    ) {
        const B: usize = 64;
        let nx = self.nx as usize;
        let mw = medium::weights(up_pass(self.ch));
        let mut x0 = 0;
        // Set by each channel's first segment (`acc`) and its own cell's (`centre`:
        // every stencil holds it), not zeroed first (a call to `memset` per array and
        // channel).
        let (mut acc, mut centre) = ([[0f32; B]; 3], [[0f32; B]; 3]);
        let mut mean = [0f32; B];
        while x0 < nx {
            let b = B.min(nx - x0);
            // The profiles of the block's emitting cells, found once for every channel
            // (not once a channel: a lookup through the store's slots for each of a
            // pass's 17 centre slots).
            let block_prof: [Option<&crate::profile::CellProfile>; B] = match hi {
                Some((_, prof, emits)) => crate::isa::array_from(
                    #[inline(always)]
                    |i| {
                        let q = x0 + i + nx * z as usize;
                        (i < b && emits[q]).then(|| prof.get(q))
                    },
                ),
                None => [None; B],
            };
            // One block of any width `b` (not specialised by `with_width`: a large body,
            // compiled once, as the optimiser did before the vector dispatch).
            {
                for (c, chn) in self.ch.iter().enumerate() {
                    for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                        let slot = chn.first_slot + k;
                        let at = |plane: usize| planes.row(plane, z + dz, x0 as i32 + dx, b);
                        let tr = at(Planes::POW + chn.pow[k]);
                        // What the path carries out of this segment is what it carries
                        // into the next one: stored as it is computed (a path carries
                        // nothing into its first segment, and the collisions read only
                        // the later ones).
                        let next = k + 1 < chn.stencil.len();
                        if dx == 0 && dz == 0 {
                            let lnp = at(Planes::LNP);
                            let e = path_exponents()[chn.pow[k]];
                            for i in 0..b {
                                mean[i] = seg_mean(tr[i], -e * lnp[i]);
                            }
                            let half = &mean[..b];
                            for col in 0..3 {
                                let sv = at(Planes::SRC + col);
                                let (a, ce) = (&acc[col], &mut centre[col]);
                                if k == 0 {
                                    // Nothing carried in: `0 · h + v` is `v` (but for
                                    // the sign of a zero).
                                    for i in 0..b {
                                        ce[i] = sv[i] * (1.0 - half[i]);
                                    }
                                } else {
                                    for i in 0..b {
                                        ce[i] = a[i] * half[i] + sv[i] * (1.0 - half[i]);
                                    }
                                }
                            }
                            // The point's own cell's `P_1`, `P_2` share of its mean light.
                            if let Some((src_hi, _, _)) = hi {
                                for (i, pr) in block_prof[..b].iter().enumerate() {
                                    if let Some(pr) = pr {
                                        let q = x0 + i + nx * z as usize;
                                        let w = pr.mean[slot];
                                        let m = src_hi[q][0] * w[0] + src_hi[q][1] * w[1];
                                        for (col, ce) in centre.iter_mut().enumerate() {
                                            ce[i] += m[col];
                                        }
                                    }
                                }
                            }
                        }
                        for (col, a) in acc.iter_mut().enumerate() {
                            let sv = at(Planes::SRC + col);
                            let ex = hi.map(|_| {
                                planes.ex_row(self, (slot, col), z + dz, x0 as i32 + dx, b)
                            });
                            let out = next.then(|| {
                                &mut pre_row[slot_index(nx, (0, x0), slot + 1, col)..][..b]
                            });
                            if k == 0 {
                                Self::segment::<true>(&mut a[..b], (tr, sv, ex), out);
                            } else {
                                Self::segment::<false>(&mut a[..b], (tr, sv, ex), out);
                            }
                        }
                    }
                    let om = mw.omega[c];
                    for (col, a) in acc.iter().enumerate() {
                        let out = &mut cur_row[(c * 3 + col) * p + PAD + x0..][..b];
                        for i in 0..b {
                            out[i] += a[i] * om;
                        }
                    }
                    for i in 0..b {
                        let ce = Vec3::new(centre[0][i], centre[1][i], centre[2][i]);
                        if ce != Vec3::ZERO {
                            g_row[x0 + i].add(chn, ce * om);
                        }
                    }
                }
            }
            x0 += b;
        }
    }
}

impl Ctx {
    /// One segment of phase 3's emission for a block of paths: `a` (what each path
    /// carries) becomes `a·τ + (s·(1 − τ) + e)` with the segment's transmittances `tr`,
    /// sources `sv` and the profile rule's emission `e` (or `a·τ + s·(1 − τ)` without it),
    /// also stored into `next` (what the paths carry into their next segment) where given.
    /// `FIRST`: a path's first segment, which nothing enters: `a` set to `s·(1 − τ) +
    /// e` (`0·τ + v` is `v` but for the sign of a zero; zeroing `a` first was a call to
    /// `memset` per channel and colour). One loop a case, so that each vectorises and
    /// stores as it goes (a copy of `a` afterwards was a call to `memcpy` per slot and
    /// colour: 2.3 % of the bench forest).
    #[inline(always)]
    pub(crate) fn segment<const FIRST: bool>(
        a: &mut [f32],
        (tr, sv, ex): (&[f32], &[f32], Option<&[f32]>),
        next: Option<&mut [f32]>,
    ) {
        let b = a.len();
        let (tr, sv) = (&tr[..b], &sv[..b]);
        match (ex, next) {
            (Some(ex), Some(next)) => {
                let (ex, next) = (&ex[..b], &mut next[..b]);
                for i in 0..b {
                    let own = sv[i] * (1.0 - tr[i]) + ex[i];
                    a[i] = if FIRST { own } else { a[i] * tr[i] + own };
                    next[i] = a[i];
                }
            }
            (Some(ex), None) => {
                let ex = &ex[..b];
                for i in 0..b {
                    let own = sv[i] * (1.0 - tr[i]) + ex[i];
                    a[i] = if FIRST { own } else { a[i] * tr[i] + own };
                }
            }
            (None, Some(next)) => {
                let next = &mut next[..b];
                for i in 0..b {
                    let own = sv[i] * (1.0 - tr[i]);
                    a[i] = if FIRST { own } else { a[i] * tr[i] + own };
                    next[i] = a[i];
                }
            }
            (None, None) => {
                for i in 0..b {
                    let own = sv[i] * (1.0 - tr[i]);
                    a[i] = if FIRST { own } else { a[i] * tr[i] + own };
                }
            }
        }
    }

    /// [`Ctx::phase3`]'s collisions for row `z`: each cell with material (a medium, or
    /// an opaque cell: a surface) stops its level-mates' emission on the horizontal
    /// paths it crosses as segment `j` (the path of point `x − d_j`, which carries
    /// `pre` at slot `j` into it), and scatters it as what it removes in phase 1. Run
    /// channel by channel over blocks of the row (rows of `pre` not written this level,
    /// `!pre_rows[z]`, carry nothing); what a cell emits into the paths of points beyond
    /// an open side leaves through the side.
    #[inline(always)]
    pub(crate) fn collide_row(
        &self,
        z: i32,
        input: &Phase3In<'_>,
        planes: &Planes,
        (pre, pre_rows): (&[f32], &[bool]),
        (same_row, other_row): (&mut [Pending], &mut [Pending]),
        rf: &mut RowFlux,
    ) {
        let Phase3In {
            src,
            emits,
            src_hi,
            prof,
            cells,
            exposed,
            ..
        } = *input;
        let pows = planes.pows();
        const B: usize = GATHER_BLOCK;
        let nx = self.nx as usize;
        let row_cells = &cells[nx * z as usize..][..nx];
        if row_cells.iter().all(|m| m.pass >= 1.0) {
            return;
        }
        let mw = medium::weights(up_pass(self.ch));
        let profile = self.medium == MediumEmission::Profile;
        let mut x0 = 0;
        // Zeroed per block for its `b` points only.
        let mut got_s = [[0f32; B]; 3];
        let mut got_m = [[[0f32; B]; 3]; 3];
        // Profile: the collisions' height moments (P_1, P_2) per colour.
        let mut got_h = [[[0f32; B]; 3]; 2];
        let mut cw = [[0f32; B]; 2];
        while x0 < nx {
            let b = B.min(nx - x0);
            // One block of any width `b` (not specialised by `with_width`: a large body,
            // compiled once, as the optimiser did before the vector dispatch).
            {
                for a in got_s.iter_mut().chain(got_m.iter_mut().flatten()) {
                    a[..b].fill(0.0);
                }
                for a in got_h.iter_mut().flatten() {
                    a[..b].fill(0.0);
                }
                // Profile: the block's media's profiles (found once, read for every slot).
                let block_prof: [Option<&crate::profile::CellProfile>; B] = crate::isa::array_from(
                    #[inline(always)]
                    |i| {
                        let ci = x0 + i + nx * z as usize;
                        (i < b && medium::profiled(self.medium, cells[ci].pass))
                            .then(|| prof.get(ci))
                    },
                );
                if self.fetch_profiles() {
                    for pr in block_prof[..b].iter().flatten() {
                        touch(&pr.coll[..]);
                    }
                }
                // The height moments only for a block holding a cell that takes them (a
                // flat cell's are never read): a level's thin media emit the flat
                // source ([`medium::profiled`]).
                let moments = profile && block_prof[..b].iter().any(Option::is_some);
                for (c, chn) in self.ch.iter().enumerate() {
                    let om = mw.omega[c] * chn.mu;
                    // A path carries nothing into its first segment.
                    for (j, &(djx, djz, _)) in chn.stencil.iter().enumerate().skip(1) {
                        let Some(zr) = self.row_of(z - djz).filter(|&zr| pre_rows[zr]) else {
                            continue;
                        };
                        let slot = chn.first_slot + j;
                        let pw = planes.row(Planes::POW + chn.pow[j], z, x0 as i32, b);
                        // Columns of the points `x − d_j` (the ring beyond the row's
                        // ends: wrapped, or nothing beyond an open side).
                        let first = x0 as i32 - djx;
                        // Profile: the block's media's collision moments for this slot
                        // (0 elsewhere: what is tallied there is not read).
                        if moments {
                            for (i, pr) in block_prof[..b].iter().enumerate() {
                                (cw[0][i], cw[1][i]) = pr
                                    .map_or((0.0, 0.0), |pr| (pr.coll[slot][0], pr.coll[slot][1]));
                            }
                        }
                        let unit = chn.unit.to_array();
                        let [m0, m1, m2] = &mut got_m;
                        let [h0, h1] = &mut got_h;
                        for col in 0..3 {
                            let mut sums = Tally {
                                s: &mut got_s[col][..b],
                                m: [&mut m0[col][..b], &mut m1[col][..b], &mut m2[col][..b]],
                                h: moments.then_some([&mut h0[col][..b], &mut h1[col][..b]]),
                            };
                            let from = tap(pre, nx, (zr, slot, col), first, b);
                            sums.add(0..b, from, (&pw[..b], om, unit), &cw);
                        }
                    }
                }
                for i in 0..b {
                    let xi = x0 + i;
                    let ci = xi + nx * z as usize;
                    let mat = cells[ci];
                    if mat.pass >= 1.0 {
                        continue;
                    }
                    if !self.periodic && emits[ci] && self.near_side(xi as i32, z) {
                        let hi = profile.then(|| (src_hi[ci], prof.get(ci)));
                        self.lost_through_sides(xi as i32, z, src[ci], hi, pows, rf);
                    }
                    let v = |a: &[[f32; B]; 3]| Vec3::new(a[0][i], a[1][i], a[2][i]);
                    let got = Pending {
                        s: v(&got_s),
                        m: [v(&got_m[0]), v(&got_m[1]), v(&got_m[2])],
                    };
                    if got.s == Vec3::ZERO {
                        continue;
                    }
                    let alb = swept_reflectance(&mat, exposed[ci]);
                    if medium::profiled(self.medium, mat.pass) {
                        // Waits for the next passes of both directions, as an isotropic
                        // source.
                        let r = [got.s, v(&got_h[0]), v(&got_h[1])];
                        rf.absorbed += (got.s * (Vec3::ONE - alb)).as_dvec3();
                        let pr = prof.get(ci);
                        let dj =
                            vectorised!(crate::profile::source_rgb(pr, alb, r, &mut rf.absorbed));
                        let add = Pending::of_coeffs(dj);
                        same_row[xi] = same_row[xi].add(&add);
                        other_row[xi] = other_row[xi].add(&add);
                        rf.pending += self.waiting(
                            crate::profile::flux_rgb(pr, 0, &dj)
                                + crate::profile::flux_rgb(pr, 1, &dj),
                        );
                        continue;
                    }
                    rf.absorbed += (got.s * (Vec3::ONE - alb)).as_dvec3();
                    let sc = got.scaled(alb);
                    same_row[xi] = same_row[xi].add(&sc);
                    other_row[xi] = other_row[xi].add(&sc);
                    // Each direction's pass emits half of it.
                    rf.pending += sc.s.as_dvec3();
                }
            }
            x0 += b;
        }
    }

    /// Whether a cell at `(x, z)` emits along some path that leaves the level through
    /// a side: it lies within [`Planes::R`] of one (the farthest a path moves sideways
    /// a level); farther in, every path stays inside.
    #[inline(always)]
    pub(crate) fn near_side(&self, x: i32, z: i32) -> bool {
        let r = Planes::R as i32;
        !(x >= r && x < self.nx - r && z >= r && z < self.nz - r)
    }

    /// What an emitting cell at `(x, z)` ([`Ctx::near_side`]) with source `src` sends
    /// into the paths of points beyond an open side: their paths are not traced, so it
    /// leaves through the side (`rf.side_out`).
    #[inline(always)]
    pub(crate) fn lost_through_sides(
        &self,
        x: i32,
        z: i32,
        src: Vec3,
        hi: Option<([Vec3; 2], &crate::profile::CellProfile)>,
        pows: LevelPows<'_>,
        rf: &mut RowFlux,
    ) {
        let pows = pows.at(x as usize, z as usize);
        let mw = medium::weights(up_pass(self.ch));
        for (c, chn) in self.ch.iter().enumerate() {
            let om = mw.omega[c] * chn.mu;
            for (j, &(djx, djz, _)) in chn.stencil.iter().enumerate() {
                if self.col(x - djx, z - djz).is_none() {
                    let mut e = src * (1.0 - pows[chn.pow[j]]);
                    if let Some((h, pr)) = hi {
                        let w = pr.emit[chn.first_slot + j];
                        e += h[0] * w[0] + h[1] * w[1];
                    }
                    rf.side_out += (e * om).as_dvec3();
                }
            }
        }
    }
}
