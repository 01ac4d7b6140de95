//! The pass loop: levels top-down then bottom-up, pass after pass, to convergence.

use super::*;

/// The inputs of one sweep and where its resolved values go.
pub(crate) struct Run<'a> {
    pub(crate) material: &'a MaterialGrid,
    pub(crate) boundary: &'a Boundary,
    pub(crate) source: Option<&'a CellSource>,
    pub(crate) options: &'a SweepOptions,
    pub(crate) fast: bool,
    pub(crate) avg: &'a mut [AverageLight],
    pub(crate) dom: &'a mut [DominantDir],
    /// Working buffers of an earlier sweep (taken, and given back after the passes).
    pub(crate) work: Option<Work>,
}

impl Run<'_> {
    /// The passes, accumulating into `g` (whose contents are overwritten: the first
    /// pass sets every point), then [`resolve`]: level by level as the last pass (when it
    /// is known to be the last: the pass limit) finishes each level, while its values
    /// are still in cache, else over the grid afterwards. Returns `g`, whether every
    /// value was valid, the balance and the stats.
    ///
    /// The passes run on a worker of rayon's pool (`rayon::scope`): a level's parallel
    /// loops then start from inside the pool, and a level small enough for one task runs
    /// on that worker at once instead of waking another thread for it.
    pub(crate) fn run<S: Sink>(&mut self, g: Vec<S>) -> (Vec<S>, bool, EnergyBalance, SweepStats) {
        rayon::scope(|_| run_with(self, g))
    }
}

pub(crate) fn run_with<S: Sink>(
    run: &mut Run<'_>,
    mut g: Vec<S>,
) -> (Vec<S>, bool, EnergyBalance, SweepStats) {
    let (material, boundary, source, options, fast) = (
        run.material,
        run.boundary,
        run.source,
        run.options,
        run.fast,
    );
    let want_dom = options.outputs.dominant;
    let mut ok = true;
    let mut resolved = false;
    let desc = *material.desc();
    let dims = desc.dims();
    let (nx, ny, nz) = (dims.x as i32, dims.y as i32, dims.z as i32);
    let cells = material.data();
    let fixed = Fixed::of(material, boundary);
    let mut w = Work::reuse(
        run.work.take(),
        nx as usize,
        nz as usize,
        desc.point_count(),
    );
    w.prof.begin_sweep();
    let mut bal = EnergyBalance::default();
    let mut stats = SweepStats::default();
    if let Some(src) = source {
        // Step 4 for the beam's deposit: absorb (1 - a), and the rest waits in both
        // directions' pending light (each pass emits its half, as for removed light).
        for (i, (&r, mat)) in src.removed().iter().zip(cells).enumerate() {
            if r == Vec3::ZERO {
                continue;
            }
            bal.source_in += r.as_dvec3();
            bal.absorbed += (r * (Vec3::ONE - mat.reflectance)).as_dvec3();
            if options.medium == MediumEmission::Profile
                && medium::applies(options.medium, mat.pass)
            {
                // The beam's first collisions have the height moments of a beam
                // entering the cell through its top (or bottom) face.
                let (j, absorbed) = crate::profile::beam_source(mat, src.dir(), r);
                bal.absorbed += absorbed.as_dvec3();
                w.pend_down[i] = Pending::of_coeffs(j);
                w.pend_up[i] = Pending::of_coeffs(j);
                w.pend_dirty[i / desc.level_len()] = true;
                continue;
            }
            let s = r * mat.reflectance;
            let p = Pending {
                s,
                m: [s * src.dir().x, s * src.dir().y, s * src.dir().z],
            };
            w.pend_down[i] = p;
            w.pend_up[i] = p;
            w.pend_dirty[i / desc.level_len()] = true;
        }
    }

    // A sink this large stays in no cache between passes: each row's next row is
    // fetched ahead (`Ahead`).
    let fetch_ahead = std::mem::size_of_val(&g[..]) >= FETCH_AHEAD_BYTES;
    // Diffusion acceleration (`crate::accel`): its operator, built when the passes
    // switch to it (a sweep that converges fast pays nothing), and the correction
    // outstanding in the media's waiting light.
    let may_accelerate = crate::accel::wanted(options) && fixed.level_medium.iter().any(|&m| m);
    let mut dsa: Option<crate::accel::Diffusion> = None;
    let mut debt = Debt::new(None);
    // How the passes run (accelerated from the first pair whose light waiting fell
    // slowly), the waiting light after the last pair, and for how many pairs in a row
    // it grew.
    let mut mode = Mode::Plain;
    // The quadratic source in height (`crate::profile`) is not positive everywhere: its
    // light is resolved after the sweep, clamped at 0, as an accelerated sweep's.
    let signed_light = options.medium == MediumEmission::Profile;
    let mut waited = f64::INFINITY;
    let mut grew = 0;

    // Upward light above all material (the crate docs, "Skipped work"): the levels
    // above the top level with material only carry light up, so an upward pass that
    // another upward pass follows, and in which no light enters them from the sides,
    // stops below them and leaves what it sends on in `w.above` (`above`: its flux);
    // the last upward pass carries the sum through them once. If the sweep ends
    // otherwise (converged, or a last downward pass, which resolves those levels,
    // comes next), a run of its own carries it first.
    let defer = options.skip_empty_levels && fixed.top_material >= 0 && fixed.top_material + 1 < ny;
    let mut above: Option<DVec3> = None;
    let mut pass = 0;
    let mut converged = false;
    loop {
        let ends = converged || pass >= options.max_passes;
        let carry = above.is_some() && (ends || (pass + 1 == options.max_passes && pass % 2 == 0));
        if ends && !carry {
            break;
        }
        let up = carry || pass % 2 == 1;
        let (first, final_pass) = (
            pass == 0 && !carry,
            pass + 1 == options.max_passes && !carry,
        );
        let ch = channels(up);
        let src = Sources {
            boundary,
            active: pass < 2 && !carry,
            up,
            dims,
            halo: fixed.halo,
        };
        let ctx = Ctx::new(nx, nz, fixed.periodic, options, ch, mode);
        // The last plain pass resolves each level as it ends (clamping light of either
        // sign at 0 first); after accelerated passes the light is resolved after the
        // sweep.
        let last = final_pass && mode == Mode::Plain;
        if !carry {
            stats.passes += 1;
        }
        // This upward pass stops below the levels above all material (unless light
        // enters them from the sides: the passes' convergence test counts it as it
        // enters).
        let side_light = src.active
            && match &boundary.sides {
                SideBoundary::Periodic => false,
                SideBoundary::Open => boundary.bottom != BinLight::ZERO,
                SideBoundary::Given(_) => true,
            };
        let stops = up && defer && !carry && !final_pass && !side_light;
        let mut pending = DVec3::ZERO;
        // The flux the last level's final light sends on.
        let mut sent_on = DVec3::ZERO;
        // Levels copied in a row just before this one (all with the same light).
        let mut copied_in_row = 0;
        // `w.prev`'s rows hold their wrapped columns in the ring already
        // ([`Finish::wrap_columns`]; sums with `w.above` keep that).
        let mut prev_columns_wrapped = false;
        let start = if carry { fixed.top_material + 1 } else { 0 };
        for li in start..ny {
            let j = if up { li } else { ny - 1 - li };
            if up && defer && j == fixed.top_material + 1 {
                if stops {
                    match above.as_mut() {
                        Some(sent) => {
                            w.above.add(&w.prev);
                            *sent += sent_on;
                        }
                        None => {
                            w.above.v.copy_from_slice(&w.prev.v);
                            above = Some(sent_on);
                        }
                    }
                    break;
                }
                if let Some(sent) = above.take() {
                    if carry {
                        std::mem::swap(&mut w.prev, &mut w.above);
                    } else {
                        w.prev.add(&w.above);
                    }
                    sent_on += sent;
                }
            }
            let from_virtual = li == 0;
            let range = desc.level_range(j as u32);
            if from_virtual {
                w.fill_from_boundary(&src, &ctx);
                prev_columns_wrapped = false;
            }
            // Skip: a level above all material, in a downward pass, under a laterally
            // uniform boundary (or with no boundary light at all), receives exactly what
            // it passes on. Copy instead of computing.
            if options.skip_empty_levels
                && !up
                && j > fixed.top_material
                && (fixed.laterally_uniform || !src.active)
            {
                let v: Level = std::array::from_fn(|c| src.virtual_light(0, 0, &ch[c]));
                // Booked as a computed level books it: of what its points gather, the
                // share from source points beyond open sides enters through the sides,
                // and as much of what the level above sent on left through them.
                let (inside, outside) = ctx.uniform_gather(&v);
                if from_virtual {
                    bal.top_in += inside;
                } else {
                    bal.side_out += outside;
                }
                bal.side_in += outside;
                // Every point of the level receives the same light: one sink value.
                let mut one = S::default();
                for (c, chn) in ch.iter().enumerate() {
                    one.add(chn.bin, chn.unit, v[c]);
                }
                if first {
                    g[range.clone()]
                        .par_chunks_mut(MIN_POINTS_PER_TASK)
                        .for_each(|gc| gc.fill(one));
                } else if src.active {
                    g[range.clone()]
                        .par_chunks_mut(MIN_POINTS_PER_TASK)
                        .for_each(|gc| {
                            touch(gc);
                            for gp in gc {
                                gp.add_channels(ch, |c| v[c]);
                            }
                        });
                }
                // From the third copied level on, `cur` is the level two back, which
                // holds `v` already (nothing writes a level's light while it is `prev`
                // of a copied level).
                if copied_in_row < 2 {
                    w.cur.fill(&v);
                }
                copied_in_row += 1;
                sent_on = (0..CHANNELS)
                    .map(|c| v[c].as_dvec3() * ch[c].mu as f64)
                    .sum::<DVec3>()
                    * desc.level_len() as f64;
                stats.levels_copied += 1;
                std::mem::swap(&mut w.prev, &mut w.cur);
                prev_columns_wrapped = false;
                if last && first {
                    // One pass: the level's points are all `one`.
                    let (valid, a, d) = one.resolve(want_dom);
                    ok &= valid & a.is_finite() & d.is_finite();
                    run.avg[range.clone()].fill(AverageLight(a));
                    run.dom[range].fill(DominantDir(d));
                } else if last {
                    ok &= resolve(
                        &g[range.clone()],
                        &mut run.avg[range.clone()],
                        &mut run.dom[range],
                        want_dom,
                    );
                }
                continue;
            }
            stats.levels_computed += 1;
            copied_in_row = 0;
            // The next level of this pass has no material: this level's rows wrap
            // their ring columns for it as they end ([`Finish::wrap_columns`]).
            let wrap_in_rows = fast
                && fixed.periodic
                && li + 1 < ny
                && !fixed.level_material[(if up { j + 1 } else { j - 1 }) as usize];
            let src_level = if up { j - 1 } else { j + 1 };
            let sent = sent_on;
            // A level without material: every point is quiet, and nothing scatters.
            let material_here = fixed.level_material[j as usize] || !fast;
            // Levels with media under the profile rule: their cells' profiles, and
            // the emission planes phase 2 writes.
            let profile_level =
                options.medium == MediumEmission::Profile && fixed.level_medium[j as usize];
            // The level's per-cell values and the ring of the light it gathers from:
            // the transmittances on one thread while the other wraps the ring, finds
            // the quiet points and the media's profiles (each a short step of one
            // thread that left the other waiting, a tenth of a 16³ sweep). The
            // transmittances, their planes and the quiet points are the same in every
            // pass: found at a level's first visit of the sweep, kept for the others
            // (`Work::set_up`).
            {
                let lnp = &fixed.lnp[range.clone()];
                let level = &cells[range.clone()];
                let first_visit = material_here && !w.set_up[j as usize];
                w.set_up[j as usize] |= material_here;
                w.planes.level = j as usize;
                let Work {
                    pows,
                    planes,
                    prev,
                    quiet,
                    quiet_rows,
                    prof,
                    ..
                } = &mut w;
                let (pows, quiet) = (&mut pows[range.clone()], &mut quiet[range.clone()]);
                let mut each_pass = || {
                    if fast && fixed.periodic {
                        // The level before wrapped its rows' columns as they ended if
                        // this level has no material (`Finish::wrap_columns`).
                        if prev_columns_wrapped {
                            prev.wrap_ring_rows();
                        } else {
                            prev.wrap_ring();
                        }
                    }
                    if profile_level {
                        prof.level(up, lnp, |q| medium::applies(options.medium, level[q].pass));
                    }
                };
                if first_visit {
                    rayon::join(
                        || {
                            level_powers(pows, lnp);
                            planes.fill_pows(&ctx, pows, lnp);
                        },
                        || {
                            each_pass();
                            if fast {
                                ctx.quiet(lnp, quiet, quiet_rows);
                            }
                        },
                    );
                } else {
                    each_pass();
                }
            }
            // Its flux is what the level before it sent on: booked so, not summed.
            let conserved = conserves_flux(
                fixed.periodic,
                fixed.level_material[j as usize],
                from_virtual,
            );
            let mut f1 = if fast {
                // Light from outside the sides: the ring of `ghost`.
                let ghost_on = src.active && !fixed.periodic;
                if ghost_on {
                    w.fill_ghost(&src, &ctx, from_virtual, src_level);
                }
                let quiet = material_here.then_some(&w.quiet[range.clone()]);
                ctx.phase1_fast(
                    (&w.prev, !conserved, fetch_ahead),
                    ghost_on.then_some(&w.ghost),
                    &w.planes,
                    quiet,
                    first,
                    &mut w.cur,
                    &mut w.removed,
                    &mut w.t_after,
                    &mut g[range.clone()],
                    &mut w.rows,
                    Finish {
                        avg: &mut run.avg[range.clone()],
                        dom: &mut run.dom[range.clone()],
                        last_phase: !material_here,
                        resolve: last.then_some(want_dom),
                        clamp: signed_light,
                        from_planes: first && !material_here,
                        wrap_columns: wrap_in_rows,
                    },
                )
            } else {
                ctx.phase1_scalar(
                    &w.prev,
                    &src,
                    from_virtual,
                    src_level,
                    (&w.pows[range.clone()], &fixed.lnp[range.clone()]),
                    first,
                    &mut w.cur,
                    &mut w.removed,
                    &mut w.t_after,
                    &mut g[range.clone()],
                    &mut w.rows,
                )
            };
            if conserved {
                (f1.inside, f1.sent) = (sent, sent);
            }
            if from_virtual {
                if up {
                    bal.bottom_in += f1.inside;
                } else {
                    bal.top_in += f1.inside;
                }
            } else {
                // Light that left the previous level but reached no point of this one
                // crossed a side face.
                // (Clamped at 0 against rounding, unless light of either sign flows.)
                let side = sent - f1.inside;
                bal.side_out += if mode == Mode::Plain {
                    side.max(DVec3::ZERO)
                } else {
                    side
                };
            }
            bal.side_in += f1.outside;
            if !material_here {
                // Phase 1 finished the level.
                sent_on = f1.sent;
                ok &= !f1.bad;
                std::mem::swap(&mut w.prev, &mut w.cur);
                prev_columns_wrapped = wrap_in_rows;
                continue;
            }
            w.pend_dirty[j as usize] = true;
            // Accelerated: a downward pass leaves the upward share of what collides in
            // it in `pend_next` (the next pair's), so the upward pass emits only what
            // the last pair left; its own collisions go to `pend_down` and `pend_up`.
            let (same, other) = match (up, mode == Mode::Accelerated) {
                (true, _) => (&mut w.pend_up, &mut w.pend_down),
                (false, false) => (&mut w.pend_down, &mut w.pend_up),
                (false, true) => (&mut w.pend_down, &mut w.pend_next),
            };
            // The source rules emit from media in a third phase.
            let phase3 = matches!(
                options.medium,
                MediumEmission::Source | MediumEmission::Profile
            ) && fixed.level_medium[j as usize];
            if profile_level {
                let n = range.len();
                if w.src_hi.len() != n {
                    w.src_hi = vec![[Vec3::ZERO; 2]; n];
                }
                // Phase 3's emission planes, written (zeroed row by row first) by phase
                // 2 on the fast path; grown once, kept across levels.
                w.planes.ex.resize(
                    if fast {
                        SLOTS * 3 * nz as usize * ring_pitch(nx as usize)
                    } else {
                        0
                    },
                    0.0,
                );
            }
            let f2 = ctx.phase2(
                (&w.removed, !fast),
                (&w.t_after, &w.pows[range.clone()]),
                &cells[range.clone()],
                &fixed.exposed[range.clone()],
                &mut w.cur,
                same.level_mut(j as usize),
                other.level_mut(j as usize),
                (
                    &mut w.src,
                    &mut w.emits,
                    &mut w.src_hi,
                    &w.prof,
                    if profile_level {
                        &mut w.planes.ex[..]
                    } else {
                        &mut []
                    },
                ),
                &mut g[range.clone()],
                &mut w.rows,
                Finish {
                    avg: &mut run.avg[range.clone()],
                    dom: &mut run.dom[range.clone()],
                    last_phase: !phase3,
                    resolve: last.then_some(want_dom),
                    clamp: signed_light,
                    from_planes: false,
                    wrap_columns: wrap_in_rows,
                },
            );
            bal.absorbed += f2.absorbed;
            pending += f2.pending;
            // (The scalar oracle runs phase 2 on levels without material too.)
            sent_on = if conserved { sent } else { f2.sent };
            ok &= !f2.bad;
            if phase3 {
                let f3 = ctx.phase3(
                    (&w.src, &w.emits),
                    (&w.src_hi, &w.prof),
                    (
                        &w.pows[range.clone()],
                        &fixed.lnp[range.clone()],
                        &mut w.planes,
                    ),
                    &cells[range.clone()],
                    &mut w.cur,
                    (&mut w.pre, &mut w.pre_rows),
                    (same.level_mut(j as usize), other.level_mut(j as usize)),
                    &mut g[range.clone()],
                    &mut w.rows,
                    Finish {
                        avg: &mut run.avg[range.clone()],
                        dom: &mut run.dom[range.clone()],
                        last_phase: true,
                        resolve: last.then_some(want_dom),
                        clamp: signed_light,
                        from_planes: false,
                        wrap_columns: wrap_in_rows,
                    },
                    !fast,
                );
                bal.absorbed += f3.absorbed;
                bal.side_out += f3.side_out;
                pending += f3.pending;
                sent_on = f3.sent;
                ok &= !f3.bad;
            }
            std::mem::swap(&mut w.prev, &mut w.cur);
            prev_columns_wrapped = wrap_in_rows;
        }
        // What leaves the last level leaves the grid.
        let leaving = sent_on;
        if carry {
            bal.top_out += leaving;
            continue;
        }
        resolved = last;
        if !up {
            bal.bottom_out += leaving;
        } else if !stops {
            bal.top_out += leaving;
        }
        // With acceleration: what waits net of the correction not yet taken back, and
        // the convergence test on the largest waiting light of either sign, after
        // each pair.
        let waiting = if let Some(d) = dsa.as_ref().filter(|_| mode != Mode::Plain) {
            let before = debt.waiting(d, &w, cells, &fixed, options.medium);
            bal.pending = before.net;
            if up && mode == Mode::Accelerated {
                // Two pairs in a row that left more waiting: the estimate does
                // not suit this medium; back to plain passes (light of either
                // sign now).
                let now = before.abs.max_element();
                grew = if now > waited { grew + 1 } else { 0 };
                waited = now;
                if grew >= 2 {
                    debt.release(d, &mut w, (&fixed.lnp, cells, options.medium));
                    mode = Mode::Fallback;
                } else {
                    stats.corrections += 1;
                    debt.correct(d, &mut w, (&fixed.lnp, cells, options.medium));
                }
            }
            if up { before.abs } else { DVec3::INFINITY }
        } else {
            bal.pending = pending;
            if may_accelerate && up {
                // Plain passes while the light waiting falls fast; accelerated from
                // the first pair after which it fell by less than
                // `crate::accel::SWITCH`.
                let now = pending.max_element();
                if now > crate::accel::SWITCH * waited
                    && now > options.tolerance as f64 * bal.input().max_element()
                    && pass + 1 < options.max_passes
                    && let Some(d) = crate::accel::Diffusion::of(material, fixed.periodic, options)
                {
                    if w.pend_next.len() != desc.point_count() {
                        w.pend_next = PendingLevels::new(desc.level_len(), ny as usize);
                    }
                    debt = Debt::new(Some(&d));
                    mode = Mode::Accelerated;
                    stats.corrections += 1;
                    debt.correct(&d, &mut w, (&fixed.lnp, cells, options.medium));
                    dsa = Some(d);
                }
                waited = now;
            }
            pending
        };
        let input = bal.input().max_element();
        converged = waiting.max_element() <= options.tolerance as f64 * input && pass >= 1;
        pass += 1;
    }
    if !resolved && (mode != Mode::Plain || signed_light) {
        // What the accelerated passes left: light off by up to the tolerance either
        // way, so a point in the dark may hold a little below 0. (A quadratic source
        // in height may dip below 0 within a cell, and a near-transparent cell's mean
        // light round below 0.)
        g.par_chunks_mut(RESOLVE_CHUNK)
            .for_each(|c| c.iter_mut().for_each(S::clamp));
    }
    if !resolved {
        ok = resolve(&g, run.avg, run.dom, want_dom);
    }
    run.work = Some(w);
    (g, ok, bal, stats)
}

/// What a sweep derives once from its inputs.
/// How a sweep's passes run ([`crate::accel`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Mode {
    /// The plain passes.
    Plain,
    /// Accelerated: one generation per pair, with the diffusion estimate.
    Accelerated,
    /// Plain passes again after acceleration failed to converge, with light of
    /// either sign.
    Fallback,
}

pub(crate) struct Fixed {
    /// ln(pass) per cell: -inf for opaque cells, whose exp(f * l * -inf) is exactly 0
    /// (f * l > 0 always, so no 0 * inf).
    pub(crate) lnp: Vec<f32>,
    /// Exposed-face masks of opaque cells ([`exposure`]).
    pub(crate) exposed: Vec<u8>,
    /// The highest level holding material (-1: none).
    pub(crate) top_material: i32,
    /// Per level: some cell of it holds material (`p < 1`).
    pub(crate) level_material: Vec<bool>,
    /// Per level: some cell of it is a medium (`0 < p < 1`).
    pub(crate) level_medium: Vec<bool>,
    /// The boundary is the same at every column (uniform top, open or periodic sides).
    pub(crate) laterally_uniform: bool,
    pub(crate) periodic: bool,
    pub(crate) halo: Option<lightgrid_core::HaloLayout>,
}

impl Fixed {
    pub(crate) fn of(material: &MaterialGrid, boundary: &Boundary) -> Self {
        let desc = material.desc();
        let cells = material.data();
        let periodic = matches!(boundary.sides, SideBoundary::Periodic);
        // On every core: a logarithm a cell and the levels' scans took a millisecond of
        // one core at 64³ every sweep.
        let (level_material, level_medium): (Vec<bool>, Vec<bool>) = (0..desc.levels())
            .into_par_iter()
            .map(|j| {
                let level = &cells[desc.level_range(j)];
                (
                    level.iter().any(|m| !m.is_empty()),
                    level.iter().any(|m| m.pass > 0.0 && m.pass < 1.0),
                )
            })
            .unzip();
        let top_material = level_material
            .iter()
            .rposition(|&m| m)
            .map_or(-1, |j| j as i32);
        Self {
            top_material,
            lnp: cells.par_iter().map(|m| m.pass.ln()).collect(),
            exposed: exposure(material, periodic),
            level_material,
            level_medium,
            laterally_uniform: matches!(boundary.top, TopBoundary::Uniform(_))
                && matches!(boundary.sides, SideBoundary::Open | SideBoundary::Periodic),
            periodic,
            halo: matches!(boundary.sides, SideBoundary::Given(_))
                .then(|| lightgrid_core::HaloLayout::new(desc.dims())),
        }
    }
}
