//! Phase 1 of a level, the fast path: gather the light arriving from the level
//! before along each channel, transmit it through the level's cells.

use super::*;

/// What phase 1 of a level reads: the light of the level before it (whether to tally
/// its flux, whether to hint the next row's sink into cache), the light from outside
/// the sides, the level's transmittance planes, its quiet points, and whether this is
/// the first pass (points' sinks start afresh).
pub(crate) struct Phase1In<'a> {
    pub(crate) prev: &'a LevelLight,
    pub(crate) count: bool,
    pub(crate) fetch_ahead: bool,
    pub(crate) ghost: Option<&'a LevelLight>,
    pub(crate) planes: &'a Planes,
    pub(crate) quiet: Option<&'a [bool]>,
    pub(crate) first: bool,
}

impl Ctx {
    /// Steps 1-2 as [`Ctx::phase1_scalar`], bit for bit in the light, faster: step 1
    /// channel by channel over whole rows of [`LevelLight`]'s planes, a loop the
    /// compiler vectorises, with no side logic: taps beyond the sides read `prev`'s ring
    /// (wrapped light on periodic sides, zero otherwise) and, where light enters from
    /// outside (`ghost`: open sides or a given halo, in a pass that takes boundary
    /// light), the outside light from `ghost`'s ring, for the columns whose taps reach
    /// it. Adding a zero is exact, so the sums equal the oracle's tap-by-tap sums that
    /// skip those taps. Then step 2 point by point, where a point whose 5 × 5
    /// neighbourhood of cells is empty (`quiet`, or `None`: the whole level is empty;
    /// every path cell of every channel passes all light) skips the transmit step: its
    /// light passes unchanged, nothing is removed (its removal slots are not written:
    /// only non-empty cells read slots, and only those of points whose paths cross
    /// them, which are never quiet). Flux tallies sum in another order than the
    /// oracle's (equal to `f64` rounding). `fetch_ahead`: each row's gather hints the
    /// next row's sink into cache ([`Ahead`]).
    pub(crate) fn phase1_fast<S: Sink>(
        &self,
        input: Phase1In<'_>,
        Removals { removed, t_after }: Removals<'_>,
        LevelRows { cur, g, rows }: LevelRows<'_, S>,
        fin: Finish<'_>,
    ) -> RowFlux {
        let Phase1In {
            prev,
            count,
            fetch_ahead,
            ghost,
            planes,
            quiet,
            first,
        } = input;
        let nx = self.nx as usize;
        let p = cur.pitch();
        let extra = removed
            .par_chunks_mut(ring_pitch(nx) * SLOTS * 3)
            .zip(t_after.par_chunks_mut(nx));
        self.level_rows(
            cur,
            extra,
            g,
            rows,
            (fin, false),
            |z, cur_row, (rem_row, ta_row), g_row, rf| {
                if first {
                    // The first pass sets every point (its memory may hold anything).
                    g_row.fill(S::default());
                } else {
                    touch(g_row);
                }
                let ahead = fetch_ahead.then(|| Ahead::after(g_row));
                vectorised!(self.gather_row_channels(z, (prev, count, ahead), ghost, cur_row, rf));
                let unchanged = vectorised!(self.transmit_row(
                    z,
                    planes,
                    quiet,
                    p,
                    TransmitRow {
                        cur: cur_row,
                        rem: rem_row,
                        ta: ta_row,
                        g: g_row
                    }
                ));
                if unchanged && ghost.is_none() {
                    // The light it sends on is what it gathered (no light from
                    // outside was added after the sum of `inside`).
                    rf.sent = rf.inside;
                    rf.sent_known = true;
                }
            },
        )
    }

    /// The parallel loop over a level's rows (tasks of [`Ctx::rows_per_task`] rows,
    /// `uneven` as there):
    /// `body(z, row of cur, extra's item, row of g, flux tallies)` for every row `z`,
    /// then, in the level's last phase, [`Ctx::finish_row`]; the rows' tallies summed
    /// in row order.
    pub(crate) fn level_rows<S: Sink, T: Send>(
        &self,
        cur: &mut LevelLight,
        extra: impl IndexedParallelIterator<Item = T>,
        g: &mut [S],
        rows: &mut [RowFlux],
        (fin, uneven): (Finish<'_>, bool),
        body: impl Fn(i32, &mut [f32], T, &mut [S], &mut RowFlux) + Sync,
    ) -> RowFlux {
        let nx = self.nx as usize;
        let (min_rows, max_rows) = self.rows_per_task(uneven);
        let (row_len, p) = (cur.row_len(), cur.pitch());
        let (last_phase, avg, dom, wrap) = (fin.last_phase, fin.avg, fin.dom, fin.wrap_columns);
        let resolve = fin.resolve.map(|d| (d, fin.clamp, fin.from_planes));
        cur.rows_mut()
            .par_chunks_mut(row_len)
            .zip(extra)
            .zip(g.par_chunks_mut(nx))
            .zip(rows.par_iter_mut())
            .zip(avg.par_chunks_mut(nx))
            .zip(dom.par_chunks_mut(nx))
            .enumerate()
            .with_min_len(min_rows)
            .with_max_len(max_rows)
            .for_each(
                |(z, (((((cur_row, x), g_row), row_out), avg_row), dom_row))| {
                    let mut rf = RowFlux::default();
                    body(z as i32, cur_row, x, g_row, &mut rf);
                    if last_phase {
                        self.finish_row((cur_row, p), g_row, (avg_row, dom_row), resolve, &mut rf);
                        if wrap {
                            wrap_columns(cur_row, p, nx);
                        }
                    }
                    *row_out = rf;
                },
            );
        sum_rows(rows)
    }

    /// Step 1 of [`Ctx::phase1_fast`] for row `z` (its own function, so that profiles
    /// show it); the flux gathered from inside the grid summed into `rf.inside` if
    /// `count` (a level whose flux is known, [`conserves_flux`], leaves it); `ahead`
    /// fetched a share a channel.
    #[inline(always)]
    pub(crate) fn gather_row_channels(
        &self,
        z: i32,
        (prev, count, ahead): (&LevelLight, bool, Option<Ahead>),
        ghost: Option<&LevelLight>,
        cur_row: &mut [f32],
        rf: &mut RowFlux,
    ) {
        let nx = self.nx as usize;
        let p = prev.pitch();
        let (nxi, nzi) = (self.nx, self.nz);
        let s = self.smoothing;
        let (w0, w1) = (1.0 - s, 0.25 * s);
        let mut outs = [0f32; GATHER_BLOCK];
        // Step 1, channel by channel, over the whole row.
        for (c, chn) in self.ch.iter().enumerate() {
            let (sx, qz) = (chn.step.x, (z - chn.step.z) as isize);
            let mu = chn.mu as f64;
            // Source column of x = 0 in the planes (ring included).
            let q0 = (PAD as i32 - sx - 1) as usize;
            if let Some(a) = ahead {
                a.fetch(c, CHANNELS);
            }
            for k in 0..3 {
                let plane = (c * 3 + k) * p;
                let out = &mut cur_row[plane + PAD..][..nx];
                #[inline(always)]
                fn taps(
                    l: &LevelLight,
                    at: usize,
                    n: usize,
                    qz: isize,
                ) -> (&[f32], &[f32], &[f32]) {
                    let row = |z: isize| &l.row(z)[at..][..n];
                    (row(qz), row(qz + 1), row(qz - 1))
                }
                gather_row(out, taps(prev, plane + q0, nx + 2, qz), w0, w1);
                if count {
                    rf.inside[k] += sum_f64(out) * mu;
                }
                let Some(gh) = ghost else { continue };
                let (mid, above, below) = taps(gh, plane + q0, nx + 2, qz);
                if qz >= 1 && qz < nzi as isize - 1 {
                    // A row whose source rows lie inside: only its first and last few
                    // columns' taps reach beyond the sides. Point by point, as
                    // `gather_row` adds the taps (a block loop's set-up cost more than
                    // these few points: half of a 16-point node's extra time under a
                    // given halo went there).
                    let xa = (1 + sx).clamp(0, nxi) as usize;
                    let xb = ((nxi - 1 + sx).clamp(xa as i32, nxi) as usize).max(xa);
                    let mut sum = 0f64;
                    for x in (0..xa).chain(xb..nx) {
                        let v = if w1 == 0.0 {
                            mid[x + 1] * w0
                        } else {
                            mid[x + 1] * w0
                                + mid[x + 2] * w1
                                + mid[x] * w1
                                + above[x + 1] * w1
                                + below[x + 1] * w1
                        };
                        sum += v as f64;
                        out[x] += v;
                    }
                    rf.outside[k] += sum * mu;
                    continue;
                }
                // A row whose source rows lie beyond a side: every column, in blocks.
                for chunk in (0..nx).step_by(outs.len()) {
                    let n = (nx - chunk).min(outs.len());
                    let o = &mut outs[..n];
                    gather_row(o, (&mid[chunk..], &above[chunk..], &below[chunk..]), w0, w1);
                    rf.outside[k] += sum_f64(o) * mu;
                    for (t, v) in out[chunk..][..n].iter_mut().zip(o.iter()) {
                        *t += v;
                    }
                }
            }
        }
    }

    /// Step 2 of [`Ctx::phase1_fast`] for row `z` of a level whose planes have pitch `p`:
    /// [`Ctx::transmit`] for every point and channel, the same operations in the same
    /// order, run channel by channel over blocks of the row and segment by segment
    /// (`planes`: the level's transmittances with a ring) so that the loops vectorise.
    /// A row whose points are all quiet passes its light unchanged (and `true` says so).
    #[inline(always)]
    pub(crate) fn transmit_row<S: Sink>(
        &self,
        z: i32,
        planes: &Planes,
        quiet: Option<&[bool]>,
        p: usize,
        TransmitRow {
            cur: cur_row,
            rem: rem_row,
            ta: ta_row,
            g: g_row,
        }: TransmitRow<'_, S>,
    ) -> bool {
        const B: usize = GATHER_BLOCK;
        let nx = self.nx as usize;
        let all_quiet = quiet.is_none_or(|q| q[nx * z as usize..][..nx].iter().all(|&b| b));
        if all_quiet {
            for (xi, g_pt) in g_row.iter_mut().enumerate() {
                g_pt.add_channels(self.ch, |c| row_get(cur_row, p, xi, c));
            }
            return true;
        }
        let mut x0 = 0;
        // Set per channel for the block's `b` points only.
        let (mut t, mut t_mid, mut after) = ([1f32; B], [1f32; B], [1f32; B]);
        let (mut lost, mut mean) = ([0f32; B], [[0f32; B]; 3]);
        while x0 < nx {
            let b = B.min(nx - x0);
            {
                for (c, chn) in self.ch.iter().enumerate() {
                    for a in [&mut t, &mut t_mid, &mut after] {
                        a[..b].fill(1.0);
                    }
                    let mut past_centre = false;
                    let light: [&[f32]; 3] = crate::isa::array_from(
                        #[inline(always)]
                        |col| &cur_row[(c * 3 + col) * p + PAD + x0..][..b],
                    );
                    for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                        let tr = planes.row(Planes::POW + chn.pow[k], z + dz, x0 as i32 + dx, b);
                        let slot = chn.first_slot + k;
                        // What the segment takes of the light entering the path (once,
                        // not per colour).
                        for i in 0..b {
                            lost[i] = t[i] * (1.0 - tr[i]);
                        }
                        for (col, l) in light.iter().enumerate() {
                            let out = &mut rem_row[slot_index(nx, (0, x0), slot, col)..][..b];
                            for i in 0..b {
                                out[i] = l[i] * lost[i];
                            }
                        }
                        if past_centre {
                            for i in 0..b {
                                after[i] *= tr[i];
                            }
                        }
                        if dx == 0 && dz == 0 {
                            let lnp = planes.row(Planes::LNP, z, x0 as i32, b);
                            let e = path_exponents()[chn.pow[k]];
                            for i in 0..b {
                                t_mid[i] = t[i] * seg_mean(tr[i], -e * lnp[i]);
                            }
                            past_centre = true;
                        }
                        for i in 0..b {
                            t[i] *= tr[i];
                        }
                    }
                    // The point's mean light into its bin, and the light that leaves, colour
                    // by colour along the block (as `Vec3`s, point by point, these ran one
                    // float at a time).
                    for (col, m) in mean.iter_mut().enumerate() {
                        let l = &mut cur_row[(c * 3 + col) * p + PAD + x0..][..b];
                        for i in 0..b {
                            m[i] = l[i] * t_mid[i];
                            l[i] *= t[i];
                        }
                    }
                    for i in 0..b {
                        ta_row[x0 + i][c] = after[i];
                        let m = Vec3::new(mean[0][i], mean[1][i], mean[2][i]);
                        g_row[x0 + i].add(chn, m);
                    }
                }
            }
            x0 += b;
        }
        fill_rings(rem_row, nx, self.periodic);
        false
    }
}

impl Ctx {
    /// Points whose 5 × 5 neighbourhood of cells (wrapped on periodic sides; cells
    /// beyond open sides count as empty) holds no material: `lnp` is the level's
    /// `ln(pass)`, 0 for empty cells.
    pub(crate) fn quiet(&self, lnp: &[f32], out: &mut [bool], rows_ok: &mut [bool]) {
        let (nx, nz) = (self.nx, self.nz);
        for z in 0..nz {
            for x in 0..nx {
                rows_ok[(x + nx * z) as usize] =
                    (-2..=2).all(|dx| self.col(x + dx, z).is_none_or(|i| lnp[i] == 0.0));
            }
        }
        for z in 0..nz {
            for x in 0..nx {
                out[(x + nx * z) as usize] =
                    (-2..=2).all(|dz| self.col(x, z + dz).is_none_or(|i| rows_ok[i]));
            }
        }
    }
}
