//! The pass loop: levels top-down then bottom-up, pass after pass, to convergence.

use super::*;
use lightgrid_core::GridDesc;

/// The inputs of one sweep and where its resolved values go.
pub(crate) struct Run<'a> {
    pub(crate) material: &'a MaterialGrid,
    /// The material's exposure masks ([`exposure`]), found once (taken by [`Fixed`]).
    pub(crate) exposed: Vec<u8>,
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
    /// on that worker at once instead of waking another thread for it; another worker
    /// is kept awake for the levels' loops ([`Helper`]).
    pub(crate) fn run<S: Sink>(&mut self, g: Vec<S>) -> (Vec<S>, bool, EnergyBalance, SweepStats) {
        rayon::scope(|_| {
            let _sweeping = Sweeping::enter();
            run_with(self, g)
        })
    }
}

pub(crate) fn run_with<S: Sink>(
    run: &mut Run<'_>,
    g: Vec<S>,
) -> (Vec<S>, bool, EnergyBalance, SweepStats) {
    let (work, source) = (run.work.take(), run.source);
    let mut sweep = PassLoop::new(run, work, g);
    if let Some(src) = source {
        sweep.book_source(src);
    }
    sweep.passes();
    let (g, ok, bal, stats, w) = sweep.finish();
    run.work = Some(w);
    (g, ok, bal, stats)
}

/// One sweep's state from pass to pass ([`run_with`]).
struct PassLoop<'r, S> {
    material: &'r MaterialGrid,
    boundary: &'r Boundary,
    options: &'r SweepOptions,
    /// The fast path (else the scalar oracle's phases).
    fast: bool,
    /// Where the last pass resolves each level.
    avg: &'r mut [AverageLight],
    dom: &'r mut [DominantDir],
    g: Vec<S>,
    w: Work,
    fixed: Fixed,
    desc: GridDesc,
    bal: EnergyBalance,
    stats: SweepStats,
    /// Every resolved value so far was valid.
    ok: bool,
    /// The last pass resolved every level as it ended.
    resolved: bool,
    /// A sink this large stays in no cache between passes: each row's next row is
    /// fetched ahead (`Ahead`).
    fetch_ahead: bool,
    /// The quadratic source in height (`crate::profile`) is not positive everywhere:
    /// its light is resolved after the sweep, clamped at 0, as an accelerated sweep's.
    signed_light: bool,
    /// Upward light above all material (the crate docs, "Skipped work"): the levels
    /// above the top level with material only carry light up, so an upward pass that
    /// another upward pass follows, and in which no light enters them from the sides,
    /// stops below them and leaves what it sends on in `w.above` (`above`: its flux);
    /// the last upward pass carries the sum through them once. If the sweep ends
    /// otherwise (converged, or a last downward pass, which resolves those levels,
    /// comes next), a run of its own carries it first.
    defer: bool,
    above: Option<DVec3>,
    accel: Accel,
    /// Keeps a second worker awake through the levels (the sweep ends when it drops).
    helper: Helper,
}

/// Diffusion acceleration (`crate::accel`) across a sweep's passes.
struct Accel {
    /// The sweep's media may be accelerated.
    may: bool,
    /// Its operator, built when the passes switch to it (a sweep that converges fast
    /// pays nothing).
    dsa: Option<crate::accel::Diffusion>,
    /// The correction outstanding in the media's waiting light.
    debt: Debt,
    /// How the passes run (accelerated from the first pair whose light waiting fell
    /// slowly).
    mode: Mode,
    /// The waiting light after the last pair.
    waited: f64,
    /// For how many pairs in a row the waiting light grew.
    grew: u32,
}

/// One pass's fixed choices and its running totals.
struct Pass<'r> {
    up: bool,
    /// The run that carries the deferred upward light through the levels above all
    /// material ([`PassLoop::defer`]).
    carry: bool,
    first: bool,
    /// The last plain pass resolves each level as it ends (clamping light of either
    /// sign at 0 first); after accelerated passes the light is resolved after the sweep.
    last: bool,
    /// This upward pass stops below the levels above all material.
    stops: bool,
    ch: &'static [Channel; CHANNELS],
    src: Sources<'r>,
    ctx: Ctx,
    /// Light left waiting in media.
    pending: DVec3,
    /// The flux the last level's final light sends on.
    sent_on: DVec3,
    /// Levels copied in a row just before this one (all with the same light).
    copied_in_row: u32,
    /// `w.prev`'s rows hold their wrapped columns in the ring already
    /// ([`Finish::wrap_columns`]; sums with `w.above` keep that).
    prev_columns_wrapped: bool,
}

impl<'r, S: Sink> PassLoop<'r, S> {
    fn new(run: &'r mut Run<'_>, work: Option<Work>, g: Vec<S>) -> Self {
        let (material, options) = (run.material, run.options);
        let desc = *material.desc();
        let fixed = Fixed::of(material, run.boundary, std::mem::take(&mut run.exposed));
        let mut w = Work::reuse(
            work,
            desc.dims().x as usize,
            desc.dims().z as usize,
            desc.point_count(),
        );
        w.prof.begin_sweep();
        let ny = desc.dims().y as i32;
        Self {
            fetch_ahead: std::mem::size_of_val(&g[..]) >= FETCH_AHEAD_BYTES,
            signed_light: options.medium == MediumEmission::Profile,
            defer: options.skip_empty_levels
                && fixed.top_material >= 0
                && fixed.top_material + 1 < ny,
            above: None,
            accel: Accel {
                may: crate::accel::wanted(options) && fixed.level_medium.iter().any(|&m| m),
                dsa: None,
                debt: Debt::new(None),
                mode: Mode::Plain,
                waited: f64::INFINITY,
                grew: 0,
            },
            material,
            boundary: run.boundary,
            options,
            fast: run.fast,
            avg: &mut *run.avg,
            dom: &mut *run.dom,
            g,
            w,
            fixed,
            desc,
            bal: EnergyBalance::default(),
            stats: SweepStats::default(),
            ok: true,
            resolved: false,
            helper: Helper::new(),
        }
    }

    /// Step 4 for the beam's deposit: absorb (1 - a), and the rest waits in both
    /// directions' pending light (each pass emits its half, as for removed light).
    fn book_source(&mut self, src: &CellSource) {
        let (w, bal, desc) = (&mut self.w, &mut self.bal, &self.desc);
        let (cells, exposed) = (self.material.data(), &self.fixed.exposed);
        for (i, (&r, mat)) in src.removed().iter().zip(cells).enumerate() {
            if r == Vec3::ZERO {
                continue;
            }
            bal.source_in += r.as_dvec3();
            let alb = swept_reflectance(mat, exposed[i]);
            bal.absorbed += (r * (Vec3::ONE - alb)).as_dvec3();
            if medium::profiled(self.options.medium, mat.pass) {
                // The beam's first collisions have the height moments the source
                // carries (the beam tracer's), or those of a beam entering the cell
                // through its top (or bottom) face.
                let heights = src.heights().map(|h| h[i]);
                let (j, absorbed) = crate::profile::beam_source(mat, src.dir(), r, heights);
                bal.absorbed += absorbed.as_dvec3();
                w.pend_down[i] = Pending::of_coeffs(j);
                w.pend_up[i] = Pending::of_coeffs(j);
                w.pend_dirty[i / desc.level_len()] = true;
                continue;
            }
            let s = r * alb;
            let p = Pending {
                s,
                m: [s * src.dir().x, s * src.dir().y, s * src.dir().z],
            };
            w.pend_down[i] = p;
            w.pend_up[i] = p;
            w.pend_dirty[i / desc.level_len()] = true;
        }
    }

    /// The passes, accumulating into `g` (whose contents are overwritten: the first pass
    /// sets every point), until they converge or reach the pass limit.
    fn passes(&mut self) {
        let max_passes = self.options.max_passes;
        let mut pass = 0;
        let mut converged = false;
        loop {
            let ends = converged || pass >= max_passes;
            let carry = self.above.is_some() && (ends || (pass + 1 == max_passes && pass % 2 == 0));
            if ends && !carry {
                break;
            }
            let mut p = self.begin_pass(pass, carry);
            self.levels(&mut p);
            // What leaves the last level leaves the grid.
            let leaving = p.sent_on;
            if carry {
                self.bal.top_out += leaving;
                continue;
            }
            self.resolved = p.last;
            if !p.up {
                self.bal.bottom_out += leaving;
            } else if !p.stops {
                self.bal.top_out += leaving;
            }
            let waiting = self.waiting(&p, pass);
            let input = self.bal.input().max_element();
            // A tolerance of 0 runs every pass (as on the GPU): else whether a last
            // rounding residual is exactly 0 would decide how many passes run.
            let tolerance = self.options.tolerance as f64;
            converged = tolerance > 0.0 && waiting.max_element() <= tolerance * input && pass >= 1;
            pass += 1;
        }
    }

    /// Pass `pass`'s choices (`carry`: the run that carries deferred upward light).
    fn begin_pass(&mut self, pass: u32, carry: bool) -> Pass<'r> {
        let (options, boundary) = (self.options, self.boundary);
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
            dims: self.desc.dims(),
            halo: self.fixed.halo,
        };
        let dims = self.desc.dims();
        let mode = self.accel.mode;
        let ctx = Ctx::new(
            dims.x as i32,
            dims.z as i32,
            self.fixed.periodic,
            options,
            ch,
            mode,
        );
        if !carry {
            self.stats.passes += 1;
        }
        // This upward pass stops below the levels above all material (unless light
        // enters them from the sides: the passes' convergence test counts it as it
        // enters).
        let side_light = src.active
            && match &boundary.sides {
                SideBoundary::Periodic => false,
                SideBoundary::Open => boundary.bottom != BinLight::ZERO,
                SideBoundary::Given(_) | SideBoundary::GivenHalves { .. } => true,
            };
        Pass {
            up,
            carry,
            first,
            last: final_pass && mode == Mode::Plain,
            stops: up && self.defer && !carry && !final_pass && !side_light,
            ch,
            src,
            ctx,
            pending: DVec3::ZERO,
            sent_on: DVec3::ZERO,
            copied_in_row: 0,
            prev_columns_wrapped: false,
        }
    }

    /// Whether the halo's partial paths are traced ([`RingPaths`]).
    fn ring_on(&self) -> bool {
        self.options.halo_paths && self.fixed.halo.is_some() && !self.fixed.periodic
    }

    /// The levels of one pass, in its direction.
    fn levels(&mut self, p: &mut Pass<'r>) {
        let ny = self.desc.dims().y as i32;
        let top = self.fixed.top_material;
        let start = if p.carry { top + 1 } else { 0 };
        for li in start..ny {
            let j = if p.up { li } else { ny - 1 - li };
            if p.up && self.defer && j == top + 1 && self.hand_over_above(p) {
                break;
            }
            let from_virtual = li == 0;
            if from_virtual {
                self.w.ring_paths.prev_valid = false;
                self.w.fill_from_boundary(&p.src, &p.ctx);
                p.prev_columns_wrapped = false;
            }
            // Skip: a level above all material, in a downward pass, under a laterally
            // uniform boundary (or with no boundary light at all), receives exactly what
            // it passes on. Copy instead of computing.
            if self.options.skip_empty_levels
                && !p.up
                && j > top
                && (self.fixed.laterally_uniform || !p.src.active)
            {
                self.copy_level(p, j, from_virtual);
            } else {
                self.compute_level(p, li, j, from_virtual);
            }
        }
    }

    /// An upward pass reaching the levels above all material: one that stops leaves
    /// what it sends on in `w.above` (returns `true`); one that goes on first adds
    /// what earlier passes left there.
    fn hand_over_above(&mut self, p: &mut Pass<'r>) -> bool {
        let w = &mut self.w;
        if p.stops {
            match self.above.as_mut() {
                Some(sent) => {
                    w.above.add(&w.prev);
                    *sent += p.sent_on;
                }
                None => {
                    w.above.v.copy_from_slice(&w.prev.v);
                    self.above = Some(p.sent_on);
                }
            }
            return true;
        }
        if let Some(sent) = self.above.take() {
            if p.carry {
                std::mem::swap(&mut w.prev, &mut w.above);
            } else {
                w.prev.add(&w.above);
            }
            p.sent_on += sent;
        }
        false
    }

    /// A level above all material that receives exactly what it passes on: its light
    /// copied, not computed.
    fn copy_level(&mut self, p: &mut Pass<'r>, j: i32, from_virtual: bool) {
        let (ch, range) = (p.ch, self.desc.level_range(j as u32));
        let want_dom = self.options.outputs.dominant;
        let v: Level = std::array::from_fn(|c| p.src.virtual_light(0, 0, &ch[c]));
        // Booked as a computed level books it: of what its points gather, the share
        // from source points beyond open sides enters through the sides, and as much
        // of what the level above sent on left through them.
        let (inside, outside) = p.ctx.uniform_gather(&v);
        if from_virtual {
            self.bal.top_in += inside;
        } else {
            self.bal.side_out += outside;
        }
        self.bal.side_in += outside;
        // Every point of the level receives the same light: one sink value.
        let mut one = S::default();
        for (c, chn) in ch.iter().enumerate() {
            one.add(chn, v[c]);
        }
        let g = &mut self.g[range.clone()];
        if p.first {
            g.par_chunks_mut(MIN_POINTS_PER_TASK)
                .for_each(|gc| gc.fill(one));
        } else if p.src.active {
            g.par_chunks_mut(MIN_POINTS_PER_TASK).for_each(|gc| {
                touch(gc);
                for gp in gc {
                    gp.add_channels(ch, |c| v[c]);
                }
            });
        }
        // From the third copied level on, `cur` is the level two back, which holds `v`
        // already (nothing writes a level's light while it is `prev` of a copied level).
        if p.copied_in_row < 2 {
            self.w.cur.fill(&v);
        }
        p.copied_in_row += 1;
        p.sent_on = (0..CHANNELS)
            .map(|c| v[c].as_dvec3() * ch[c].mu as f64)
            .sum::<DVec3>()
            * self.desc.level_len() as f64;
        self.stats.levels_copied += 1;
        std::mem::swap(&mut self.w.prev, &mut self.w.cur);
        self.w.ring_paths.prev_valid = false;
        p.prev_columns_wrapped = false;
        if p.last && p.first {
            // One pass: the level's points are all `one`.
            let (valid, a, d) = one.resolve(want_dom);
            self.ok &= valid & a.is_finite() & d.is_finite();
            self.avg[range.clone()].fill(AverageLight(a));
            self.dom[range].fill(DominantDir(d));
        } else if p.last {
            self.ok &= resolve(
                &self.g[range.clone()],
                &mut self.avg[range.clone()],
                &mut self.dom[range],
                want_dom,
            );
        }
    }

    /// A level computed: its set-up, phase 1, and where it holds material phases 2
    /// and 3.
    fn compute_level(&mut self, p: &mut Pass<'r>, li: i32, j: i32, from_virtual: bool) {
        self.helper.ensure();
        let (fast, fixed) = (self.fast, &self.fixed);
        let ny = self.desc.dims().y as i32;
        self.stats.levels_computed += 1;
        p.copied_in_row = 0;
        // The next level of this pass has no material: this level's rows wrap their
        // ring columns for it as they end ([`Finish::wrap_columns`]).
        let wrap_in_rows = fast
            && fixed.periodic
            && li + 1 < ny
            && !fixed.level_material[(if p.up { j + 1 } else { j - 1 }) as usize];
        let sent = p.sent_on;
        // A level without material: every point is quiet, and nothing scatters.
        let material_here = fixed.level_material[j as usize] || !fast;
        // Levels with media under the profile rule: their cells' profiles, and the
        // emission planes phase 2 writes.
        let profile_level =
            self.options.medium == MediumEmission::Profile && fixed.level_medium[j as usize];
        self.set_up_level(p, j, material_here, profile_level);
        // Its flux is what the level before it sent on: booked so, not summed.
        let conserved = conserves_flux(
            self.fixed.periodic,
            self.fixed.level_material[j as usize],
            from_virtual,
        );
        let mut f1 = self.phase1(p, j, from_virtual, (material_here, conserved), wrap_in_rows);
        if conserved {
            (f1.inside, f1.sent) = (sent, sent);
        }
        if from_virtual {
            if p.up {
                self.bal.bottom_in += f1.inside;
            } else {
                self.bal.top_in += f1.inside;
            }
        } else {
            // Light that left the previous level but reached no point of this one
            // crossed a side face.
            // (Clamped at 0 against rounding, unless light of either sign flows.)
            let side = sent - f1.inside;
            self.bal.side_out += if self.accel.mode == Mode::Plain {
                side.max(DVec3::ZERO)
            } else {
                side
            };
        }
        self.bal.side_in += f1.outside;
        if material_here {
            p.sent_on = self.media_phases(p, j, (sent, conserved), profile_level, wrap_in_rows);
        } else {
            // Phase 1 finished the level.
            p.sent_on = f1.sent;
            self.ok &= !f1.bad;
        }
        std::mem::swap(&mut self.w.prev, &mut self.w.cur);
        if self.ring_on() {
            let w = &mut self.w;
            w.ring_paths.level_done(&mut w.ring_level);
            w.ring_paths.prev_valid = w.ring_level.traced;
        }
        p.prev_columns_wrapped = wrap_in_rows;
    }

    /// The level's per-cell values and the ring of the light it gathers from: the
    /// transmittances on one thread while the other wraps the ring, finds the quiet
    /// points and the media's profiles (each a short step of one thread that left the
    /// other waiting, a tenth of a 16³ sweep). The transmittances, their planes and the
    /// quiet points are the same in every pass: found at a level's first visit of the
    /// sweep, kept for the others (`Work::set_up`).
    fn set_up_level(&mut self, p: &Pass<'r>, j: i32, material_here: bool, profile_level: bool) {
        let (fast, fixed, options) = (self.fast, &self.fixed, self.options);
        let range = self.desc.level_range(j as u32);
        let lnp = &fixed.lnp[range.clone()];
        let level = &self.material.data()[range.clone()];
        let w = &mut self.w;
        let first_visit = material_here && !w.set_up[j as usize];
        w.set_up[j as usize] |= material_here;
        w.planes.level = j as usize;
        let Work {
            planes,
            prev,
            quiet,
            quiet_rows,
            prof,
            ..
        } = w;
        let quiet = &mut quiet[range];
        let (up, ctx, prev_columns_wrapped) = (p.up, &p.ctx, p.prev_columns_wrapped);
        let mut each_pass = || {
            if fast && fixed.periodic {
                // The level before wrapped its rows' columns as they ended if this
                // level has no material (`Finish::wrap_columns`).
                if prev_columns_wrapped {
                    prev.wrap_ring_rows();
                } else {
                    prev.wrap_ring();
                }
            }
            if profile_level {
                prof.level(up, lnp, |q| medium::profiled(options.medium, level[q].pass));
            }
        };
        if first_visit {
            rayon::join(
                || {
                    planes.fill_pows(ctx, lnp);
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

    /// Phase 1 of level `j`: gathering, on the fast path or the scalar oracle's.
    fn phase1(
        &mut self,
        p: &Pass<'r>,
        j: i32,
        from_virtual: bool,
        (material_here, conserved): (bool, bool),
        wrap_in_rows: bool,
    ) -> RowFlux {
        let range = self.desc.level_range(j as u32);
        let ring_on = self.ring_on();
        let (w, fixed) = (&mut self.w, &self.fixed);
        let src_level = if p.up { j - 1 } else { j + 1 };
        // A level without material changes no path: the halo's light at a point is then
        // the path's light beyond it, as untraced (its gather still reads the paths'
        // light of a level before that traced them).
        let trace = ring_on && fixed.level_material[j as usize];
        w.ring_level.traced = trace;
        if trace {
            w.ring_paths.make_for(&p.ctx, &mut w.ring_level);
        }
        // The halo's partial paths at this level, once its own are gathered.
        let ring_phase1 = |w: &mut Work, f: &mut RowFlux| {
            let from = Gather {
                prev: &w.prev,
                src: &p.src,
                from_virtual,
                src_level,
                ring: Some(&w.ring_paths),
            };
            let (inside, outside) = p.ctx.ring_phase1(
                &from,
                j,
                (w.planes.pows(), &fixed.lnp[range.clone()]),
                (&w.ring_paths, &mut w.ring_level, &mut w.removed[..]),
            );
            f.inside += inside;
            f.outside += outside;
        };
        if !self.fast {
            let mut f = p.ctx.phase1_scalar(
                &Gather {
                    prev: &w.prev,
                    src: &p.src,
                    from_virtual,
                    src_level,
                    ring: ring_on.then_some(&w.ring_paths),
                },
                ((w.planes.pows(), &fixed.lnp[range.clone()]), p.first),
                Removals {
                    removed: &mut w.removed,
                    t_after: &mut w.t_after,
                },
                LevelRows {
                    cur: &mut w.cur,
                    g: &mut self.g[range.clone()],
                    rows: &mut w.rows,
                },
            );
            if trace {
                ring_phase1(w, &mut f);
            }
            return f;
        }
        // Light from outside the sides: the ring of `ghost` (with the halo's paths,
        // their exit light at the source level, in every pass: what the grid's cells
        // emitted into them).
        let exits = ring_on && !from_virtual && w.ring_paths.prev_valid;
        let ghost_on = (p.src.active || exits) && !fixed.periodic;
        if ghost_on {
            w.fill_ghost(&p.src, &p.ctx, from_virtual, src_level);
            if exits {
                w.ghost_ring_exits();
            }
        }
        let quiet = material_here.then_some(&w.quiet[range.clone()]);
        let mut f = p.ctx.phase1_fast(
            Phase1In {
                prev: &w.prev,
                count: !conserved,
                fetch_ahead: self.fetch_ahead,
                ghost: ghost_on.then_some(&w.ghost),
                planes: &w.planes,
                quiet,
                first: p.first,
            },
            Removals {
                removed: &mut w.removed,
                t_after: &mut w.t_after,
            },
            LevelRows {
                cur: &mut w.cur,
                g: &mut self.g[range.clone()],
                rows: &mut w.rows,
            },
            Finish {
                avg: &mut self.avg[range.clone()],
                dom: &mut self.dom[range.clone()],
                last_phase: !material_here,
                resolve: p.last.then_some(self.options.outputs.dominant),
                clamp: self.signed_light,
                from_planes: p.first && !material_here,
                wrap_columns: wrap_in_rows,
            },
        );
        if trace {
            ring_phase1(w, &mut f);
        }
        f
    }

    /// Phases 2 and 3 of level `j` (with material; `sent`: the flux the level before it
    /// sent on): returns the flux the level sends on.
    fn media_phases(
        &mut self,
        p: &mut Pass<'r>,
        j: i32,
        (sent, conserved): (DVec3, bool),
        profile_level: bool,
        wrap_in_rows: bool,
    ) -> DVec3 {
        let (fast, options) = (self.fast, self.options);
        let range = self.desc.level_range(j as u32);
        let nx = self.desc.dims().x as usize;
        let nz = self.desc.dims().z as usize;
        let cells = &self.material.data()[range.clone()];
        let fixed = &self.fixed;
        let ring_on = self.ring_on() && self.w.ring_level.traced;
        let w = &mut self.w;
        let resolve = p.last.then_some(options.outputs.dominant);
        w.pend_dirty[j as usize] = true;
        // Accelerated: a downward pass leaves the upward share of what collides in it
        // in `pend_next` (the next pair's), so the upward pass emits only what the last
        // pair left; its own collisions go to `pend_down` and `pend_up`.
        let (same, other) = match (p.up, self.accel.mode == Mode::Accelerated) {
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
            // Phase 3's emission planes, written (zeroed row by row first) by phase 2 on
            // the fast path; grown once, kept across levels.
            w.planes.ex.resize(
                if fast {
                    SLOTS * 3 * nz * ring_pitch(nx)
                } else {
                    0
                },
                0.0,
            );
        }
        let f2 = p.ctx.phase2(
            Phase2In {
                removed: (
                    &w.removed,
                    ring_on.then_some((&w.ring_paths, &w.ring_level)),
                ),
                scalar: !fast,
                t_after: &w.t_after,
                pows: LevelPows::of(&w.planes.v, w.planes.level, (nx, nz)),
                cells,
                exposed: &fixed.exposed[range.clone()],
            },
            (same.level_mut(j as usize), other.level_mut(j as usize)),
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
            LevelRows {
                cur: &mut w.cur,
                g: &mut self.g[range.clone()],
                rows: &mut w.rows,
            },
            Finish {
                avg: &mut self.avg[range.clone()],
                dom: &mut self.dom[range.clone()],
                last_phase: !phase3,
                resolve,
                clamp: self.signed_light,
                from_planes: false,
                wrap_columns: wrap_in_rows,
            },
        );
        self.bal.absorbed += f2.absorbed;
        p.pending += f2.pending;
        self.ok &= !f2.bad;
        // (The scalar oracle runs phase 2 on levels without material too.)
        if !phase3 {
            return if conserved { sent } else { f2.sent };
        }
        let f3 = p.ctx.phase3(
            Phase3In {
                src: &w.src,
                emits: &w.emits,
                src_hi: &w.src_hi,
                prof: &w.prof,
                lnp: &fixed.lnp[range.clone()],
                cells,
                exposed: &fixed.exposed[range.clone()],
                scalar: !fast,
            },
            &mut w.planes,
            (&mut w.removed, &mut w.pre_rows),
            (same.level_mut(j as usize), other.level_mut(j as usize)),
            LevelRows {
                cur: &mut w.cur,
                g: &mut self.g[range.clone()],
                rows: &mut w.rows,
            },
            Finish {
                avg: &mut self.avg[range.clone()],
                dom: &mut self.dom[range.clone()],
                last_phase: true,
                resolve,
                clamp: self.signed_light,
                from_planes: false,
                wrap_columns: wrap_in_rows,
            },
        );
        if ring_on {
            p.ctx.ring_phase3(
                (&w.src, &w.emits),
                (&w.src_hi, &w.prof),
                (w.planes.pows(), &fixed.lnp[range.clone()]),
                (&w.ring_paths, &mut w.ring_level),
            );
        }
        self.bal.absorbed += f3.absorbed;
        self.bal.side_out += f3.side_out;
        p.pending += f3.pending;
        self.ok &= !f3.bad;
        f3.sent
    }

    /// The light waiting after pass `pass` for the convergence test: with acceleration,
    /// what waits net of the correction not yet taken back, the largest waiting light
    /// of either sign after each pair; and the switch to (or back from) accelerated
    /// passes.
    fn waiting(&mut self, p: &Pass<'r>, pass: u32) -> DVec3 {
        let (options, material) = (self.options, self.material);
        let cells = material.data();
        let (w, fixed, a) = (&mut self.w, &self.fixed, &mut self.accel);
        let up = p.up;
        if let Some(d) = a.dsa.as_ref().filter(|_| a.mode != Mode::Plain) {
            let before = a.debt.waiting(d, w, cells, fixed, options.medium);
            self.bal.pending = before.net;
            if up && a.mode == Mode::Accelerated {
                // Two pairs in a row that left more waiting: the estimate does not suit
                // this medium; back to plain passes (light of either sign now).
                let now = before.abs.max_element();
                a.grew = if now > a.waited { a.grew + 1 } else { 0 };
                a.waited = now;
                if a.grew >= 2 {
                    a.debt.release(d, w, (&fixed.lnp, cells, options.medium));
                    a.mode = Mode::Fallback;
                } else {
                    self.stats.corrections += 1;
                    a.debt.correct(d, w, (&fixed.lnp, cells, options.medium));
                }
            }
            return if up { before.abs } else { DVec3::INFINITY };
        }
        self.bal.pending = p.pending;
        if a.may && up {
            // Plain passes while the light waiting falls fast; accelerated from the
            // first pair after which it fell by less than `crate::accel::SWITCH`.
            let now = p.pending.max_element();
            if now > crate::accel::SWITCH * a.waited
                && now > options.tolerance as f64 * self.bal.input().max_element()
                && pass + 1 < options.max_passes
                && let Some(d) = crate::accel::Diffusion::of(material, fixed.periodic, options)
            {
                let desc = &self.desc;
                if w.pend_next.len() != desc.point_count() {
                    w.pend_next = PendingLevels::new(desc.level_len(), desc.dims().y as usize);
                }
                a.debt = Debt::new(Some(&d));
                a.mode = Mode::Accelerated;
                self.stats.corrections += 1;
                a.debt.correct(&d, w, (&fixed.lnp, cells, options.medium));
                a.dsa = Some(d);
            }
            a.waited = now;
        }
        p.pending
    }

    /// After the passes: light of either sign clamped and resolved where the last pass
    /// did not resolve it as it went; the sink, validity, balance, stats and the work
    /// buffers for the next sweep.
    fn finish(mut self) -> (Vec<S>, bool, EnergyBalance, SweepStats, Work) {
        if !self.resolved && (self.accel.mode != Mode::Plain || self.signed_light) {
            // What the accelerated passes left: light off by up to the tolerance either
            // way, so a point in the dark may hold a little below 0. (A quadratic source
            // in height may dip below 0 within a cell, and a near-transparent cell's
            // mean light round below 0.)
            self.g
                .par_chunks_mut(RESOLVE_CHUNK)
                .for_each(|c| c.iter_mut().for_each(S::clamp));
        }
        if !self.resolved {
            self.ok = resolve(&self.g, self.avg, self.dom, self.options.outputs.dominant);
        }
        (self.g, self.ok, self.bal, self.stats, self.w)
    }
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
    /// `exposed`: the material's [`exposure`] masks (found once, by `run_reusing`).
    pub(crate) fn of(material: &MaterialGrid, boundary: &Boundary, exposed: Vec<u8>) -> Self {
        debug_assert_eq!(exposed.len(), material.data().len());
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
            exposed,
            level_material,
            level_medium,
            laterally_uniform: matches!(boundary.top, TopBoundary::Uniform(_))
                && matches!(boundary.sides, SideBoundary::Open | SideBoundary::Periodic),
            periodic,
            halo: boundary
                .sides
                .halo()
                .map(|_| lightgrid_core::HaloLayout::new(desc.dims())),
        }
    }
}
