//! The scalar oracle: phase 1 and phase 3 point by point, as the specification
//! reads; the fast path must equal it (`tests/fast_path.rs`).

use super::*;

/// Where the light of the oracle's phase 1 comes from: the level before it, and from
/// outside the grid the sources (`from_virtual`: the light of the virtual level above
/// or below the grid; else the outside light at level `src_level`).
pub(crate) struct Gather<'a, 's> {
    pub(crate) prev: &'a LevelLight,
    pub(crate) src: &'a Sources<'s>,
    pub(crate) from_virtual: bool,
    pub(crate) src_level: i32,
    /// The halo's partial paths ([`RingPaths`]), when they are traced: a tap at a halo
    /// point with one reads its exit light at the source level.
    pub(crate) ring: Option<&'a RingPaths>,
}

impl Ctx {
    /// Steps 1-2, written as the crate docs say them: the oracle of
    /// [`Ctx::phase1_fast`] ([`run_scalar`]), the level's transmittance powers and
    /// `ln p` in `cells`; `first`: the first pass (points' sinks start afresh).
    pub(crate) fn phase1_scalar<S: Sink>(
        &self,
        from: &Gather<'_, '_>,
        (cells, first): ((LevelPows<'_>, &[f32]), bool),
        Removals { removed, t_after }: Removals<'_>,
        LevelRows { cur, g, rows }: LevelRows<'_, S>,
    ) -> RowFlux {
        let (pows, lnp) = cells;
        let nx = self.nx as usize;
        let (row_len, p) = (cur.row_len(), cur.pitch());
        cur.rows_mut()
            .par_chunks_mut(row_len)
            .zip(removed.par_chunks_mut(ring_pitch(nx) * SLOTS * 3))
            .zip(t_after.par_chunks_mut(nx))
            .zip(g.par_chunks_mut(nx))
            .zip(rows.par_iter_mut())
            .enumerate()
            .for_each(|(z, ((((cur_row, rem_row), ta_row), g_row), row_out))| {
                let z = z as i32;
                let mut rf = RowFlux::default();
                if first {
                    // The first pass sets every point (its memory may hold anything).
                    g_row.fill(S::default());
                }
                for x in 0..self.nx {
                    let xi = x as usize;
                    let mut rem = [Vec3::ZERO; SLOTS];
                    for (c, chn) in self.ch.iter().enumerate() {
                        // Step 1: gather from the source point and its smoothing taps.
                        let (qx, qz) = (x - chn.step.x, z - chn.step.z);
                        let (ins, outs) = self.gather_edge(from, (chn, c), (qx, qz));
                        rf.inside += ins.as_dvec3() * chn.mu as f64;
                        rf.outside += outs.as_dvec3() * chn.mu as f64;
                        let light = ins + outs;
                        // Step 2: transmit along the path, recording what each cell removes.
                        let (t, t_mid, after) =
                            self.transmit((pows, lnp), chn, (x, z), None, light, &mut rem);
                        ta_row[xi][c] = after;
                        row_set(cur_row, p, xi, c, light * t);
                        g_row[xi].add(chn, light * t_mid);
                    }
                    for (slot, v) in rem.iter().enumerate() {
                        for col in 0..3 {
                            rem_row[slot_index(nx, (0, xi), slot, col)] = v[col];
                        }
                    }
                }
                fill_rings(rem_row, nx, self.periodic);
                *row_out = rf;
            });
        sum_rows(rows)
    }

    /// Step 2 for one point and channel: along the path cell by cell, each cell removes
    /// `light T_k (1 - τ_k)` (written into `rem`); returns the path's transmittance
    /// `T`, the transmittance to the point's centre `T_mid` and `T_after`. Path cells
    /// are found by [`Ctx::col`], or by index from the point's index `inner` when every
    /// cell of the path lies inside the grid.
    #[inline]
    pub(crate) fn transmit(
        &self,
        (pows, lnp): (LevelPows<'_>, &[f32]),
        chn: &Channel,
        (x, z): (i32, i32),
        inner: Option<usize>,
        light: Vec3,
        rem: &mut [Vec3; SLOTS],
    ) -> (f32, f32, f32) {
        let exps = path_exponents();
        let mut t = 1.0f32;
        let mut t_mid = 1.0f32;
        let mut after = 1.0f32;
        let mut past_centre = false;
        for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
            let ci = match inner {
                Some(pi) => Some((pi as i32 + dx + self.nx * dz) as usize),
                None => self.col(x + dx, z + dz),
            };
            let (tr, half) = match ci {
                Some(ci) => {
                    let tr = pows.get(ci, chn.pow[k]);
                    (tr, seg_mean(tr, -exps[chn.pow[k]] * lnp[ci]))
                }
                None => (1.0, 1.0),
            };
            rem[chn.first_slot + k] = light * (t * (1.0 - tr));
            if past_centre {
                after *= tr;
            }
            if dx == 0 && dz == 0 {
                t_mid = t * half;
                past_centre = true;
            }
            t *= tr;
        }
        (t, t_mid, after)
    }
}

impl Ctx {
    /// Step 1, tap by tap (light from inside the grid, light from outside): the
    /// scalar oracle's gather everywhere, the fast path's near the sides.
    #[inline]
    pub(crate) fn gather_edge(
        &self,
        from: &Gather<'_, '_>,
        (chn, c): (&Channel, usize),
        (qx, qz): (i32, i32),
    ) -> (Vec3, Vec3) {
        let Gather {
            prev,
            src,
            from_virtual,
            src_level,
            ring,
        } = *from;
        let s = self.smoothing;
        let taps = [
            (qx, qz, 1.0 - s),
            (qx + 1, qz, 0.25 * s),
            (qx - 1, qz, 0.25 * s),
            (qx, qz + 1, 0.25 * s),
            (qx, qz - 1, 0.25 * s),
        ];
        let mut ins = Vec3::ZERO;
        let mut outs = Vec3::ZERO;
        for (tx, tz, w) in taps {
            if w == 0.0 {
                continue;
            }
            match self.col(tx, tz) {
                Some(i) => ins += prev.at(i, c) * w,
                None if from_virtual => outs += src.virtual_light(tx, tz, chn) * w,
                None if let Some(v) = ring.and_then(|r| r.exit(self, tx, tz, c)) => outs += v * w,
                None => outs += src.outside(tx, src_level, tz, chn) * w,
            }
        }
        (ins, outs)
    }
}

impl Ctx {
    /// [`Ctx::phase3_row`] written out for the scalar oracle ([`run_scalar`]): point by
    /// point, channel by channel, along each path cell by cell ([`Ctx::col`]).
    pub(crate) fn phase3_row_scalar<S: Sink>(
        &self,
        z: i32,
        (src, emits): (&[Vec3], &[bool]),
        (src_hi, prof): (&[[Vec3; 2]], &crate::profile::Profiles),
        (pows, lnp): (LevelPows<'_>, &[f32]),
        p: usize,
        (cur_row, pre_row, g_row): (&mut [f32], &mut [f32], &mut [S]),
    ) {
        let nx = self.nx as usize;
        let mw = medium::weights(up_pass(self.ch));
        // A segment's transmittance and emission (light per unit `ω_b σ_c`); beyond
        // open sides empty.
        let profile = self.medium == MediumEmission::Profile;
        let seg = |q: Option<usize>, pow: usize, slot: usize| -> (f32, Vec3) {
            match q {
                Some(q) if emits[q] => {
                    let tr = pows.get(q, pow);
                    let mut e = src[q] * (1.0 - tr);
                    if profile {
                        let w = prof.get(q).emit[slot];
                        e += src_hi[q][0] * w[0] + src_hi[q][1] * w[1];
                    }
                    (tr, e)
                }
                Some(q) => (pows.get(q, pow), Vec3::ZERO),
                None => (1.0, Vec3::ZERO),
            }
        };
        for x in 0..self.nx {
            let xi = x as usize;
            let ci = xi + nx * z as usize;
            for (c, chn) in self.ch.iter().enumerate() {
                let mut acc = Vec3::ZERO;
                let mut centre = Vec3::ZERO;
                for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                    for col in 0..3 {
                        pre_row[slot_index(nx, (0, xi), chn.first_slot + k, col)] = acc[col];
                    }
                    let slot = chn.first_slot + k;
                    let (tr, e) = seg(self.col(x + dx, z + dz), chn.pow[k], slot);
                    if dx == 0 && dz == 0 {
                        let half = seg_mean(
                            pows.get(ci, chn.pow[k]),
                            -path_exponents()[chn.pow[k]] * lnp[ci],
                        );
                        centre = acc * half;
                        if emits[ci] {
                            centre += src[ci] * (1.0 - half);
                            if profile {
                                let w = prof.get(ci).mean[slot];
                                centre += src_hi[ci][0] * w[0] + src_hi[ci][1] * w[1];
                            }
                        }
                    }
                    acc = acc * tr + e;
                }
                let om = mw.omega[c];
                if acc != Vec3::ZERO {
                    row_add(cur_row, p, xi, c, acc * om);
                }
                if centre != Vec3::ZERO {
                    g_row[xi].add(chn, centre * om);
                }
            }
        }
    }
}
