//! Phase 2 of a level: the collisions' removed light gathered into each cell, the
//! cells' emission, and the rows finished (resolved) where this is the last phase.

use super::*;

/// What phase 2 of a level reads: phase 1's removals (slot planes per row; `scalar`:
/// the oracle's, read point by point) and transmittances after each point's own cell,
/// the level's transmittance powers, cells and exposed faces.
#[derive(Clone, Copy)]
pub(crate) struct Phase2In<'a> {
    /// What phase 1 removed from the grid's points' paths (slot planes), and from the
    /// halo's paths where they are traced ([`RingPaths`]): collected together.
    pub(crate) removed: Removed<'a>,
    pub(crate) scalar: bool,
    pub(crate) t_after: &'a [[f32; CHANNELS]],
    pub(crate) pows: LevelPows<'a>,
    pub(crate) cells: &'a [lightgrid_core::Material],
    pub(crate) exposed: &'a [u8],
}

/// [`Phase2In::removed`].
pub(crate) type Removed<'a> = (&'a [f32], RingRead<'a>);

impl Ctx {
    /// Phase 2 of a level (steps 3-6 per cell): what `input` says was removed is
    /// gathered per cell, absorbed, emitted and re-absorbed locally; what waits goes to
    /// `pend` (this pass's direction, the other's); media set their sources in `emit`.
    pub(crate) fn phase2<S: Sink>(
        &self,
        input: Phase2In<'_>,
        (pend_same, pend_other): (&mut [Pending], &mut [Pending]),
        (src, emits, src_hi, prof, ex): EmitRows<'_>,
        LevelRows { cur, g, rows }: LevelRows<'_, S>,
        fin: Finish<'_>,
    ) -> RowFlux {
        let nx = self.nx as usize;
        let p = cur.pitch();
        // Under other rules than Profile `src_hi` and `ex` are empty: rows of nothing.
        let hi_rows: Vec<(&mut [[Vec3; 2]], &mut [f32])> = if src_hi.is_empty() {
            (0..self.nz).map(|_| Default::default()).collect()
        } else if ex.is_empty() {
            src_hi
                .chunks_mut(nx)
                .map(|h| (h, Default::default()))
                .collect()
        } else {
            src_hi
                .chunks_mut(nx)
                .zip(ex.chunks_mut(SLOTS * 3 * ring_pitch(nx)))
                .collect()
        };
        let extra = pend_same
            .par_chunks_mut(nx)
            .zip(pend_other.par_chunks_mut(nx))
            .zip(
                src.par_chunks_mut(nx)
                    .zip(emits.par_chunks_mut(nx))
                    .zip(hi_rows),
            );
        self.level_rows(
            cur,
            extra,
            g,
            rows,
            (fin, true),
            |z,
             cur_row,
             ((same_row, other_row), ((src_row, emits_row), (hi_row, ex_row))),
             g_row,
             rf| {
                *rf = vectorised!(self.phase2_row(
                    (z, p),
                    &input,
                    (cur_row, g_row),
                    (same_row, other_row),
                    (src_row, emits_row, hi_row, prof, ex_row),
                ));
            },
        )
    }

    /// The end of a level's last phase for one row ([`Finish`]).
    #[inline]
    pub(crate) fn finish_row<S: Sink>(
        &self,
        (cur_row, p): (&[f32], usize),
        g_row: &mut [S],
        (avg_row, dom_row): (&mut [AverageLight], &mut [DominantDir]),
        resolve: Option<(bool, bool, bool)>,
        rf: &mut RowFlux,
    ) {
        if !rf.sent_known {
            vectorised!(self.add_sent(cur_row, p, rf));
        }
        if let Some((dominant, clamp, from_planes)) = resolve {
            if clamp {
                g_row.iter_mut().for_each(S::clamp);
            }
            rf.bad |= !if S::ALL_BINS && from_planes {
                vectorised!(resolve_planes(
                    self.ch,
                    cur_row,
                    p,
                    (clamp, dominant),
                    avg_row,
                    dom_row
                ))
            } else {
                vectorised!(S::resolve_all(g_row, avg_row, dom_row, dominant))
            };
        }
    }

    /// Adds what the finished row `cur_row` (pitch `p`) sends on to `rf.sent`: its
    /// channels' light times their `μ`.
    #[inline(always)]
    fn add_sent(&self, cur_row: &[f32], p: usize, rf: &mut RowFlux) {
        let nx = self.nx as usize;
        for (c, chn) in self.ch.iter().enumerate() {
            for k in 0..3 {
                rf.sent[k] += sum_f64(&cur_row[(c * 3 + k) * p + PAD..][..nx]) * chn.mu as f64;
            }
        }
    }

    /// Step 3 for the block `x0..x0 + b` of row `z`: per channel and colour, what each
    /// cell removed from the paths crossing it, `Σ_k removed[x − d_k][slot k]` over the
    /// channel's stencil in order (points beyond an open side add nothing), read from
    /// whole rows of the planes `removed` (per row: slot, colour, column).
    #[inline(always)]
    pub(crate) fn gather_removed(
        &self,
        z: i32,
        (x0, b): (usize, usize),
        (removed, ring): Removed<'_>,
        out: &mut [[[f32; GATHER_BLOCK]; 3]; CHANNELS],
    ) {
        let nx = self.nx as usize;
        // A row of the halo's removals beyond the grid's rows (traced paths alone).
        let mut beyond = [0f32; GATHER_BLOCK];
        for (c, chn) in self.ch.iter().enumerate() {
            let o = &mut out[c];
            // The first tap sets the sums (as [`Ctx::gather_moments`]: no `memset` per
            // colour and channel).
            let mut set = false;
            for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                let zr = self.row_of(z - dz);
                if zr.is_none() && ring.is_none() {
                    continue;
                }
                let first = x0 as i32 - dx;
                for (col, oc) in o.iter_mut().enumerate() {
                    let from = match (zr, ring) {
                        (Some(zr), _) => tap(removed, nx, (zr, chn.first_slot + k, col), first, b),
                        (None, Some((r, l))) => {
                            r.row_beyond((self, l), (first, z - dz), (c, k, col), &mut beyond[..b])
                        }
                        (None, None) => &beyond[..b],
                    };
                    let oc = &mut oc[..b];
                    if set {
                        for i in 0..b {
                            oc[i] += from[i];
                        }
                    } else {
                        // (`0 + v`, the sum from zero: a bare copy was a `memcpy` call.)
                        for i in 0..b {
                            oc[i] = 0.0 + from[i];
                        }
                    }
                }
                set = true;
            }
            if !set {
                for col in o.iter_mut() {
                    col[..b].fill(0.0);
                }
            }
        }
    }

    /// [`MediumEmission::Profile`]: [`Ctx::gather_removed`] into `removed_out` and, from
    /// the same reads of the planes, step 3's height moments for the block `x0..x0 + b`
    /// of row `z`: per moment `h` and colour, `Σ_c μ_c Σ_k removed[x − d_k][slot k] ·
    /// w[slot k][h][x]` (taps in stencil order, points beyond an open side adding
    /// nothing), `w` the block's cells' collision moments per slot
    /// ([`crate::profile::CellProfile::coll`]). Every sum takes its terms in the order
    /// the two gathers took them on their own.
    #[inline(always)]
    pub(crate) fn gather_moments(
        &self,
        z: i32,
        (x0, b): (usize, usize),
        (removed, ring): Removed<'_>,
        w: &[[[f32; GATHER_BLOCK]; 2]; SLOTS],
        removed_out: &mut [[[f32; GATHER_BLOCK]; 3]; CHANNELS],
        out: &mut [[[f32; GATHER_BLOCK]; 3]; 2],
    ) {
        let nx = self.nx as usize;
        for o in out.iter_mut().flatten() {
            o[..b].fill(0.0);
        }
        let mut t = [[[0f32; GATHER_BLOCK]; 3]; 2];
        // A row of the halo's removals beyond the grid's rows (traced paths alone).
        let mut beyond = [0f32; GATHER_BLOCK];
        for (c, (chn, ro)) in self.ch.iter().zip(removed_out.iter_mut()).enumerate() {
            // The first tap sets the channel's sums, the others add to them (zeroed
            // first, each array was a call to `memset` per channel: 1.6 % of the
            // forest). `0 + v·w` is `v·w` but for the sign of a zero.
            let mut set = false;
            for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                let zr = self.row_of(z - dz);
                if zr.is_none() && ring.is_none() {
                    continue;
                }
                let slot = chn.first_slot + k;
                let first = x0 as i32 - dx;
                let (w0, w1) = (&w[slot][0][..b], &w[slot][1][..b]);
                let [t0, t1] = &mut t;
                for col in 0..3 {
                    let from = match (zr, ring) {
                        (Some(zr), _) => tap(removed, nx, (zr, slot, col), first, b),
                        (None, Some((r, l))) => {
                            r.row_beyond((self, l), (first, z - dz), (c, k, col), &mut beyond[..b])
                        }
                        (None, None) => &beyond[..b],
                    };
                    let (r, a0, a1) = (&mut ro[col][..b], &mut t0[col][..b], &mut t1[col][..b]);
                    if set {
                        for i in 0..b {
                            r[i] += from[i];
                            a0[i] += from[i] * w0[i];
                            a1[i] += from[i] * w1[i];
                        }
                    } else {
                        for i in 0..b {
                            // (`0 + v`, as the sum from zero: a bare copy compiled to
                            // a call to `memcpy`.)
                            r[i] = 0.0 + from[i];
                            a0[i] = from[i] * w0[i];
                            a1[i] = from[i] * w1[i];
                        }
                    }
                }
                set = true;
            }
            if !set {
                for col in ro.iter_mut().chain(t.iter_mut().flatten()) {
                    col[..b].fill(0.0);
                }
            }
            for (oh, th) in out.iter_mut().zip(&t) {
                for (oc, tc) in oh.iter_mut().zip(th) {
                    for (o, &v) in oc[..b].iter_mut().zip(&tc[..b]) {
                        *o += v * chn.mu;
                    }
                }
            }
        }
    }

    /// Step 3 for the block of row `z` from column `x0`: what its cells removed from
    /// the paths crossing them, gathered into `scratch` (with the collisions' height
    /// moments where a cell follows the profile rule).
    #[inline(always)]
    fn gather_block(
        &self,
        (z, x0): (i32, usize),
        removed: Removed<'_>,
        row_cells: &[lightgrid_core::Material],
        prof: &crate::profile::Profiles,
        scratch: &mut Phase2Scratch,
    ) {
        let nx = self.nx as usize;
        let b = GATHER_BLOCK.min(nx - x0);
        let is_profile = |m: &lightgrid_core::Material| medium::profiled(self.medium, m.pass);
        let Phase2Scratch {
            by_row,
            by_row_h,
            coll,
        } = scratch;
        if row_cells[x0..x0 + b].iter().any(is_profile) {
            if coll.is_empty() {
                *coll = vec![[[0f32; GATHER_BLOCK]; 2]; SLOTS];
            }
            // Slot by slot, so that the stores run along the block (point by point they
            // went to 98 lines a point).
            let c: [Option<&crate::profile::CellProfile>; GATHER_BLOCK] = crate::isa::array_from(
                #[inline(always)]
                |j| {
                    (j < b && is_profile(&row_cells[x0 + j]))
                        .then(|| prof.get(x0 + j + nx * z as usize))
                },
            );
            if self.fetch_profiles() {
                // (The emission planes below read `emit`.)
                for pr in c[..b].iter().flatten() {
                    touch(&pr.coll[..]);
                    touch(&pr.emit[..]);
                }
            }
            for (slot, w) in coll.iter_mut().enumerate() {
                for (j, c) in c[..b].iter().enumerate() {
                    let v = c.map_or([0.0; 2], |c| c.coll[slot]);
                    (w[0][j], w[1][j]) = (v[0], v[1]);
                }
            }
            let coll: &[[[f32; GATHER_BLOCK]; 2]; SLOTS] =
                coll.as_slice().try_into().expect("SLOTS moments");
            vectorised!(self.gather_moments(z, (x0, b), removed, coll, by_row, by_row_h));
        } else if row_cells[x0..x0 + b].iter().any(|m| m.pass < 1.0) {
            vectorised!(self.gather_removed(z, (x0, b), removed, by_row));
        }
    }

    /// The scalar oracle's height moments of what the profile cell of column `x`
    /// removed (`s_raw`: its flux), path point by path point (the fast path gathers
    /// them by block, [`Ctx::gather_moments`]).
    fn profile_removed(
        &self,
        (x, z): (i32, i32),
        (removed, ring): Removed<'_>,
        pr: &crate::profile::CellProfile,
        s_raw: Vec3,
    ) -> [Vec3; 3] {
        let nx = self.nx as usize;
        let mut r = [s_raw, Vec3::ZERO, Vec3::ZERO];
        for (c, chn) in self.ch.iter().enumerate() {
            let mut t = [Vec3::ZERO; 2];
            for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                let slot = chn.first_slot + k;
                if let Some(pt) = self.col(x - dx, z - dz) {
                    let at = |col: usize| removed[plane_index(nx, pt, slot, col)];
                    let v = Vec3::new(at(0), at(1), at(2));
                    t[0] += v * pr.coll[slot][0];
                    t[1] += v * pr.coll[slot][1];
                } else if let Some((ring, level)) = ring {
                    let v = ring.removed_at((self, level), (x - dx, z - dz), c, k);
                    t[0] += v * pr.coll[slot][0];
                    t[1] += v * pr.coll[slot][1];
                }
            }
            r[1] += t[0] * chn.mu;
            r[2] += t[1] * chn.mu;
        }
        r
    }

    /// Step 6 for a cell emitting `own` with fixed weights (its `lanes`, from `em`): what
    /// leaves the level goes to `cur_row` (pitch `p`), what is emitted into the level to
    /// the point's output, and what the cell stops again is scattered anew in up to
    /// [`LOCAL_ROUNDS`] rounds (waiting for the other pass too, `other`); returns what is
    /// left.
    #[inline(always)]
    fn local_rounds<S: Sink>(
        &self,
        xi: usize,
        (em, lanes, alb, t_after): (&Emission, &PassLanes, Vec3, &[f32; CHANNELS]),
        mut own: Pending,
        other: &mut Pending,
        (cur_row, p, g_row): (&mut [f32], usize, &mut [S]),
        rf: &mut RowFlux,
    ) -> Pending {
        let cw = em.lanes(lanes, self.ch, t_after);
        // Per colour and channel: what leaves the level, what is emitted.
        let mut leave = [[0f32; LANES]; 3];
        let mut emit = [[0f32; LANES]; 3];
        for _ in 0..LOCAL_ROUNDS {
            if own.s == Vec3::ZERO {
                break;
            }
            let mut lost_s = Vec3::ZERO;
            let mut lost_m = [Vec3::ZERO; 3];
            for k in 0..3 {
                let (sk, mk) = (own.s[k], [own.m[0][k], own.m[1][k], own.m[2][k]]);
                let lost = cw.round(lanes, sk, mk, (&mut leave[k], &mut emit[k]), self.signed);
                lost_s[k] = lanes_sum(&lost);
                for a in 0..3 {
                    lost_m[a][k] = lanes_dot(&lost, &lanes.u[a]);
                }
            }
            rf.absorbed += (lost_s * (Vec3::ONE - alb)).as_dvec3();
            own = Pending {
                s: lost_s * alb,
                m: crate::isa::array_map(lost_m, |v| v * alb),
            };
            *other = other.add(&own);
        }
        for (c, chn) in self.ch.iter().enumerate() {
            let lv = Vec3::new(leave[0][c], leave[1][c], leave[2][c]);
            row_add(cur_row, p, xi, c, lv * lanes.length[c]);
            let ev = Vec3::new(emit[0][c], emit[1][c], emit[2][c]);
            g_row[xi].add(chn, ev * lanes.half_length[c]);
        }
        own
    }

    /// Step 3 for the cell of column `x` (point `i` of its block): the flux it removed
    /// from every path crossing it and its moments along the channels' directions, from
    /// the block's gather (`by_row`) or (the scalar oracle) path point by path point.
    #[inline(always)]
    fn removed_by(
        &self,
        (x, z): (i32, i32),
        i: usize,
        ((removed, ring), scalar): (Removed<'_>, bool),
        by_row: &[[[f32; GATHER_BLOCK]; 3]; CHANNELS],
    ) -> (Vec3, [Vec3; 3]) {
        let nx = self.nx as usize;
        let mut s_raw = Vec3::ZERO;
        let mut m_raw = [Vec3::ZERO; 3];
        for (c, chn) in self.ch.iter().enumerate() {
            let r = if scalar {
                let mut r = Vec3::ZERO;
                for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                    if let Some(pt) = self.col(x - dx, z - dz) {
                        let at = |col: usize| removed[plane_index(nx, pt, chn.first_slot + k, col)];
                        r += Vec3::new(at(0), at(1), at(2));
                    } else if let Some((ring, level)) = ring {
                        r += ring.removed_at((self, level), (x - dx, z - dz), c, k);
                    }
                }
                r
            } else {
                let g = &by_row[c];
                Vec3::new(g[0][i], g[1][i], g[2][i])
            };
            let r = r * chn.mu;
            s_raw += r;
            m_raw[0] += r * chn.unit.x;
            m_raw[1] += r * chn.unit.y;
            m_raw[2] += r * chn.unit.z;
        }
        (s_raw, m_raw)
    }

    /// The source rule: the medium cell's source from this direction's `share` of the
    /// scattered light (`crate::medium`), what it absorbs added to `rf`.
    #[inline(always)]
    fn source_of(
        &self,
        share: Vec3,
        (mat, mw, pows): (
            lightgrid_core::Material,
            &medium::Weights,
            &[f32; MAX_EXPONENTS],
        ),
        rf: &mut RowFlux,
    ) -> Vec3 {
        let alb = mat.reflectance;
        let (g, kk) = medium::cell_sums(mw, mat.pass.ln(), pows);
        let mut j = Vec3::ZERO;
        for k in 0..3 {
            let (jk, absorbed) = if self.signed {
                medium::source_signed(g, kk, share[k], alb[k])
            } else {
                medium::source_of(g, kk, share[k].max(0.0), alb[k])
            };
            j[k] = jk;
            rf.absorbed[k] += absorbed as f64;
        }
        j
    }

    /// [`Ctx::phase2`] for row `z` (its own function, so that profiles show it).
    #[inline(always)]
    pub(crate) fn phase2_row<S: Sink>(
        &self,
        (z, p): (i32, usize),
        input: &Phase2In<'_>,
        (cur_row, g_row): (&mut [f32], &mut [S]),
        (same_row, other_row): (&mut [Pending], &mut [Pending]),
        (src_row, emits_row, hi_row, prof, ex_row): EmitRows<'_>,
    ) -> RowFlux {
        let Phase2In {
            removed,
            scalar,
            t_after,
            pows,
            cells,
            exposed,
        } = *input;
        let nx = self.nx as usize;
        let up = up_pass(self.ch);
        let lanes = pass_lanes(up);
        let mw = medium::weights(up);
        let mut rf = RowFlux::default();
        emits_row.fill(false);
        ex_row.fill(0.0);
        hi_row.fill([Vec3::ZERO; 2]); // (the flat source's media among the profile's)
        let row_cells = &cells[nx * z as usize..][..nx];
        let mut scratch = Phase2Scratch::take();
        for x in 0..self.nx {
            let xi = x as usize;
            let ci = xi + nx * z as usize;
            let (i, x0) = (xi % GATHER_BLOCK, xi - xi % GATHER_BLOCK);
            if i == 0 && !scalar {
                self.gather_block((z, x0), removed, row_cells, prof, &mut scratch);
            }
            if cells[ci].pass >= 1.0 {
                // An empty cell removes nothing, so it never holds scattered light.
                continue;
            }
            // Step 3: the flux this cell removed from every path crossing it: gathered
            // for the block of the row, or (the scalar oracle) path point by path point.
            let mat = cells[ci];
            let (s_raw, m_raw) = self.removed_by((x, z), i, (removed, scalar), &scratch.by_row);
            // Step 4: absorb (1 - albedo), keep albedo for scattering (`swept_reflectance`).
            let alb = swept_reflectance(&mat, exposed[ci]);
            rf.absorbed += (s_raw * (Vec3::ONE - alb)).as_dvec3();
            let new = Pending { s: s_raw, m: m_raw }.scaled(alb);
            // Step 5: emit this pass's half of what the cell scatters now and of
            // what earlier passes left for this direction. Step 6: what the cell's
            // own material stops of that emission is removed again (absorbed or
            // scattered anew), in up to LOCAL_ROUNDS rounds; the rest waits.
            // Accelerated (`signed`): the media's collisions wait for the next pair of
            // passes (one generation per pair, as diffusion acceleration assumes);
            // `same_row` then keeps them.
            if medium::profiled(self.medium, mat.pass) {
                // A quadratic source in height (`crate::profile`): the collisions'
                // height moments, walked path point by path point, become an isotropic
                // source; this pass emits what waits for it, the other pass's waits.
                let pr = prof.get(xi + nx * z as usize);
                let r = if scalar {
                    self.profile_removed((x, z), removed, pr, s_raw)
                } else {
                    let v = |a: &[[f32; GATHER_BLOCK]; 3]| Vec3::new(a[0][i], a[1][i], a[2][i]);
                    [s_raw, v(&scratch.by_row_h[0]), v(&scratch.by_row_h[1])]
                };
                let dj = Pending::of_coeffs(vectorised!(crate::profile::source_rgb(
                    pr,
                    alb,
                    r,
                    &mut rf.absorbed
                )));
                // Accelerated (`jacobi`): only what waited is emitted; the new source
                // waits for the next pair, as under the flat rule.
                let emit = if self.jacobi {
                    same_row[xi]
                } else {
                    same_row[xi].add(&dj)
                }
                .coeffs();
                src_row[xi] = emit[0];
                hi_row[xi] = [emit[1], emit[2]];
                emits_row[xi] = emit.iter().any(|v| *v != Vec3::ZERO);
                if emits_row[xi] && !ex_row.is_empty() {
                    write_emission_planes(ex_row, (nx, xi), (emit[1], emit[2]), pr);
                }
                same_row[xi] = if self.jacobi { dj } else { Pending::default() };
                let other = other_row[xi].add(&dj);
                other_row[xi] = other;
                rf.pending += self.waiting(crate::profile::flux_rgb(pr, 1, &other.coeffs()));
                continue;
            }
            let jacobi = self.jacobi && medium::applies(self.medium, mat.pass);
            let mut own = if jacobi {
                same_row[xi]
            } else {
                new.add(&same_row[xi])
            };
            let mut other = other_row[xi].add(&new);
            // The cell's weights, once (a logarithm for a medium), as lanes.
            let em = Emission::new(mat.pass, exposed[ci], self.medium);
            let source_rule = medium::applies(self.medium, mat.pass);
            // The source rule's ½ β (`medium::split`), downward sign.
            let half_beta = if source_rule {
                let b = 0.5 * medium::split(mat.pass.ln());
                if up { -b } else { b }
            } else {
                0.0
            };
            if source_rule {
                // The source rule: this direction's share ½ (S ∓ β M_y) of the scattered
                // light as the cell's source, which its path segments emit in phase 3
                // (`crate::medium`).
                let share = own.s * 0.5 + own.m[1] * half_beta;
                let j = self.source_of(share, (mat, mw, &pows.at(xi, z as usize)), &mut rf);
                src_row[xi] = j;
                emits_row[xi] = j != Vec3::ZERO;
                own = Pending::default();
            } else if own.s != Vec3::ZERO {
                own = self.local_rounds(
                    xi,
                    (&em, lanes, alb, &t_after[ci]),
                    own,
                    &mut other,
                    (cur_row, p, g_row),
                    &mut rf,
                );
            }
            let recycled = own;
            same_row[xi] = if jacobi { new } else { recycled };
            other_row[xi] = other;
            if source_rule {
                // What the other direction's pass will emit (`medium::split`); nothing
                // waits for this one.
                let share = other.s * 0.5 - other.m[1] * half_beta;
                rf.pending += if self.signed {
                    share
                } else {
                    share.max(Vec3::ZERO)
                }
                .as_dvec3();
            } else {
                let other_ch = channels(!up_pass(self.ch));
                rf.pending +=
                    (em.budget(&recycled, self.ch) + em.budget(&other, other_ch)).as_dvec3();
            }
        }
        Phase2Scratch::give_back(scratch);
        if emits_row.contains(&true) && !ex_row.is_empty() {
            fill_rings(ex_row, nx, self.periodic);
        }
        rf
    }
}

/// Phase 3's emission planes (`Planes::ex`) for the profile cell of column `xi` of a
/// row of `nx` (`e`: its source's `P_1`, `P_2` coefficients): per slot, three rows of
/// `nx` and their ring. (Indexed as `(slot · 3 + colour) · pitch + x`, each colour of a
/// `Vec3` looked up and every store checked, the 147 stores were a quarter of phase 2
/// on the forest.)
#[inline(always)]
fn write_emission_planes(
    ex_row: &mut [f32],
    (nx, xi): (usize, usize),
    e: (Vec3, Vec3),
    pr: &crate::profile::CellProfile,
) {
    let (e1, e2) = (e.0.to_array(), e.1.to_array());
    let w = ring_pitch(nx);
    for (rows, wt) in ex_row.chunks_exact_mut(3 * w).zip(&pr.emit) {
        for ((row, a), b) in rows.chunks_exact_mut(w).zip(e1).zip(e2) {
            row[RING + xi] = a * wt[0] + b * wt[1];
        }
    }
}

/// [`Ctx::phase2_row`]'s blocks of gathered removed light, one per thread, kept from
/// row to row: as locals they were zeroed in full for every row (13 KiB, and 25 KiB of
/// profile moments, for a row of 16 points that reads 16 of each 64). Only the points
/// a block gathers are read, and the gathers write them first.
pub(crate) struct Phase2Scratch {
    /// Per channel and colour: what each cell of the block removed ([`Ctx::gather_removed`]).
    pub(crate) by_row: [[[f32; GATHER_BLOCK]; 3]; CHANNELS],
    /// Profile: the height moments of what each cell removed ([`Ctx::gather_moments`]).
    pub(crate) by_row_h: [[[f32; GATHER_BLOCK]; 3]; 2],
    /// Profile: the block's cells' collision moments per slot (empty until a block
    /// has such cells).
    pub(crate) coll: Vec<[[f32; GATHER_BLOCK]; 2]>,
}

thread_local! {
    static PHASE2_SCRATCH: std::cell::Cell<Option<Box<Phase2Scratch>>> =
        const { std::cell::Cell::new(None) };
}

impl Phase2Scratch {
    /// This thread's scratch (a new one the first time).
    pub(crate) fn take() -> Box<Self> {
        PHASE2_SCRATCH.take().unwrap_or_else(|| {
            Box::new(Self {
                by_row: [[[0.0; GATHER_BLOCK]; 3]; CHANNELS],
                by_row_h: [[[0.0; GATHER_BLOCK]; 3]; 2],
                coll: Vec::new(),
            })
        })
    }
    pub(crate) fn give_back(s: Box<Self>) {
        PHASE2_SCRATCH.set(Some(s));
    }
}

/// [`Ctx::collide_row`]'s running sums for one colour of a block of points: what the
/// points' cells stopped (`s`), its first moment (`m`, per axis) and, under the profile
/// rule, its height moments (`h`).
pub(crate) struct Tally<'a> {
    pub(crate) s: &'a mut [f32],
    pub(crate) m: [&'a mut [f32]; 3],
    pub(crate) h: Option<[&'a mut [f32]; 2]>,
}

impl Tally<'_> {
    /// For the block's points `range` (and `v`, what their paths carry into the
    /// segment, one value a point): `r = v·((1 − pw)·om)` joins `s`, `r·unit` joins `m`,
    /// `r·cw` joins `h`, in that order. Slices of one length and no closure, so that
    /// the loop vectorises (as a closure indexing `unit[a]` it ran one float at a
    /// time, a bounds check a term).
    #[inline(always)]
    pub(crate) fn add(
        &mut self,
        range: std::ops::Range<usize>,
        v: &[f32],
        (pw, om, unit): (&[f32], f32, [f32; 3]),
        cw: &[[f32; GATHER_BLOCK]; 2],
    ) {
        let n = range.len();
        let (v, pw) = (&v[..n], &pw[range.clone()][..n]);
        let s = &mut self.s[range.clone()][..n];
        let [m0, m1, m2] = &mut self.m;
        let (m0, m1, m2) = (
            &mut m0[range.clone()][..n],
            &mut m1[range.clone()][..n],
            &mut m2[range.clone()][..n],
        );
        let r = |i: usize| v[i] * ((1.0 - pw[i]) * om);
        for i in 0..n {
            let r = r(i);
            s[i] += r;
            m0[i] += r * unit[0];
            m1[i] += r * unit[1];
            m2[i] += r * unit[2];
        }
        // (A loop of its own, `r` computed again, the same value: each sum still takes
        // its terms in order.)
        if let Some([h0, h1]) = &mut self.h {
            let (h0, h1) = (&mut h0[range.clone()][..n], &mut h1[range.clone()][..n]);
            let (c0, c1) = (&cw[0][range.clone()][..n], &cw[1][range][..n]);
            for i in 0..n {
                let r = r(i);
                h0[i] += r * c0[i];
                h1[i] += r * c1[i];
            }
        }
    }
}
