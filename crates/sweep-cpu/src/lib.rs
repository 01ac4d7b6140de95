//! # sweep-cpu
//!
//! The reference light-flow sweep of lightgrid, multithreaded with rayon, and
//! ([`mod@reference`]) the Monte Carlo tracer it is measured against. **This page is the
//! specification of the sweep**: `sweep-gpu` implements exactly these formulas.
//!
//! ## Example
//!
//! ```
//! use lightgrid_core::glam::{UVec3, Vec3};
//! use lightgrid_core::{BinLight, Boundary, GridDesc, Material, MaterialGrid, Sweeper, SweepOptions};
//! use lightgrid_sweep_cpu::CpuSweeper;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // A 16 x 12 x 16 grid of 1 m cells: a dense green block on a grey ground layer.
//! let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(16, 12, 16))?;
//! let mut cells = vec![Material::EMPTY; desc.point_count()];
//! for i in 0..desc.point_count() {
//!     let p = desc.coords(i).unwrap();
//!     if p.y == 0 {
//!         cells[i] = Material::opaque(Vec3::splat(0.3));
//!     } else if (5..11).contains(&p.x) && (5..11).contains(&p.z) && p.y < 6 {
//!         cells[i] = Material { reflectance: Vec3::new(0.1, 0.4, 0.1), pass: 0.5 };
//!     }
//! }
//! let material = MaterialGrid::new(desc, cells)?;
//! // A uniform sky of radiance 1 from above.
//! let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
//! let mut options = SweepOptions::multi_bounce();
//! options.smoothing = 0.2;
//! let out = CpuSweeper::new().sweep(&material, &Boundary::open_sky(sky), &options)?;
//! let light = out.bins.unwrap();
//! // Under the block it is darker than in the open.
//! let open = light.get(UVec3::new(1, 1, 1)).unwrap().average();
//! let shaded = light.get(UVec3::new(8, 1, 8)).unwrap().average();
//! assert!(shaded.x < open.x);
//! # Ok(())
//! # }
//! ```
//!
//! ## What is here
//!
//! * [`run`] / [`CpuSweeper`]: the sweep (implements `lightgrid_core::Sweeper`), with its
//!   [`EnergyBalance`].
//! * [`sky`]: uniform and analytic clear skies, EXR environment maps, the sun disc, all
//!   integrated over the bins; [`sweep_responses`] keeps sun and sky apart so their
//!   colours change by a multiply ([`Responses::combine`]).
//! * [`mod@reference`]: the Monte Carlo reference; [`scenes`]: canonical scenes and error
//!   measures.
//! * From the shell, the `lightgrid` command (crate `lightgrid`):
//!   `lightgrid scene canopy -o m.lgrid`,
//!   `lightgrid sweep m.lgrid -o light.lgrid --sky clear --sun 3000 --sun-elevation 40`
//!   (or `--sky-exr sky.exr`), `lightgrid reference m.lgrid -o ref.lgrid --paths 2000000`.
//!
//! ## Speed
//!
//! `cargo bench -p lightgrid-sweep-cpu` (criterion, 10 samples, mean), 64³ canopy scene (a
//! two-level canopy half way up, two levels of ground; in a downward pass under a
//! uniform sky the 30 levels above it are copied, not computed), all outputs, 2-core
//! x86-64 VM (AMD EPYC, 1 MB L2 a core, 32 MB L3; timings vary by ±20 % from run to run,
//! more when the host is busy). Three ways to run the same sweep, in the same run:
//! **recycled** (`CpuSweeper::sweep` after [`CpuSweeper::recycle`]: what a renderer
//! rebuilding light every frame runs), **fresh** ([`run`]: new output memory every
//! time), and the **scalar oracle** ([`sweep::run_scalar`], the steps below written out
//! one by one). The fast path equals the oracle bit for bit in the light, to `f64`
//! rounding in the energy balance (`tests/fast_path.rs`: random sparse and dense grids,
//! every boundary mode, cell sources, any passes).
//!
//! | case | recycled | fresh | scalar oracle | before (issue 15) |
//! |------|---------:|------:|--------------:|------------------:|
//! | 64³, 26 bins, 1 downward pass | 23.6 ms (11.1 M points/s) | 51 ms (5.1 M/s) | 124 ms (2.1 M/s) | 81 ms (3.2 M/s) |
//! | 64³, 26 bins, 4 passes | 104 ms (2.5 M/s) | 130 ms (2.0 M/s) | 696 ms (0.38 M/s) | 265 ms (0.99 M/s) |
//! | 64³, average + dominant only, 1 pass | 17.6 ms (14.9 M/s) | 23 ms (11.4 M/s) | 125 ms (2.1 M/s) | 48 ms (5.5 M/s) |
//! | 64³, average + dominant only, 4 passes | 86 ms (3.0 M/s) | 104 ms (2.5 M/s) | 573 ms (0.46 M/s) | 197 ms (1.33 M/s) |
//! | 16 × 64 × 16, 26 bins, 1 pass | 2.9 ms (5.6 M/s) | 3.0 ms (5.4 M/s) | 9.0 ms (1.8 M/s) | 6.8 ms (2.4 M/s) |
//! | 16 × 64 × 16, 26 bins, 4 passes | 11.3 ms (1.45 M/s) | 10.8 ms (1.5 M/s) | | 29.4 ms (0.56 M/s) |
//!
//! ("Before": the fast path as it stood when issue 15 was filed, same bench and
//! machine.) `cargo run --release -p lightgrid-sweep-cpu --example throughput` is the quick
//! version.
//!
//! **Foliage in many levels.** The canopy has media in two levels; the bench forest
//! (`cargo xtask bench`; Kenney trees on rolling ground, media in most levels) spends
//! its time in phases 2 and 3. `cargo run --release -p xtask --example forest_profile
//! -- N REPEATS` times its headline sweep (4 passes, smoothing 0.25 then); measured in the
//! same minutes against the build before these changes (fastest of 200–300, the VM
//! was about 1.8 times slower than on the day of the table above: the scalar oracle
//! took 226 ms for one 64³ pass, not 124):
//!
//! | case | before | now |
//! |------|-------:|----:|
//! | forest 16³, 4 passes, two threads | 7.7 ms | 3.6–4.4 ms |
//! | forest 16³, 4 passes, one thread | 7.6 ms | 5.0 ms |
//! | forest 48³, 4 passes, one thread | 102 ms | 71–78 ms |
//! | 16 × 64 × 16 canopy, 26 bins, 1 pass (throughput example) | 3.6 M points/s | 7.0 M/s |
//! | 64³ canopy, 26 bins, 1 pass / 4 passes (same) | 7.2–10.3 / 1.9–3.2 M/s | 9.1–11.4 / 2.5–2.8 M/s |
//!
//! The error is unchanged (the light is the same bit for bit): the forest's time to
//! its error against Monte Carlo went from 85× to about 150× (`cargo xtask bench`,
//! forest line). These figures are the flat source's (`MediumEmission::Source`, the
//! default when they were taken). Under the default since issue 13, the quadratic source
//! in height (criterion, same bench, means):
//!
//! | case | default rule | flat source |
//! |------|-------------:|------------:|
//! | 64³, 26 bins, 1 pass, recycled | 25.9 ms (10.1 M/s) | the table above (criterion: +2.7 %, p = 0.65, no change) |
//! | 64³, 26 bins, 4 passes, recycled | 106 ms (2.5 M/s) | the same (+3.3 %, p = 0.61) |
//! | 64³, average + dominant only, 1 / 4 passes, recycled | 22.4 / 84.8 ms | the same |
//! | 16 × 64 × 16, 26 bins, 1 / 4 passes, recycled | 2.6 / 10.3 ms (6.4 / 1.6 M/s) | |
//! | uniform fog, 4 passes, 16³, recycled | 22.4 ms | 11.3 ms |
//! | uniform fog, 4 passes, 48³, recycled (scalar oracle) | 373 ms (829 ms) | 206 ms |
//!
//! The canopy has media in two levels of 64: there the rule costs nothing measurable.
//! Media in every level cost about 1.8 times the flat source (three source coefficients
//! a cell, a 3 × 3 balance per cell and colour); the bench forest takes 5.9–6.0 ms
//! against 3.7–3.8 ms (error 0.0175 against 0.0180; 131–169× Monte Carlo over three
//! runs): see "Against exact answers". What made the difference (perf, one pass, one thread unless said):
//!
//! - **Memory**: a fresh 26-bin output is 82 MB of pages the kernel faults in and zeroes
//!   (some 25 ms at 64³); `CpuSweeper` keeps the output, and its working buffers, for
//!   the next sweep of the same size. Freed 25 MB blocks of pending light came back from
//!   the heap through `calloc` and were zeroed in full each sweep; now only levels that
//!   held pending light are zeroed again.
//! - **Gather** (step 1): level light in row planes with a ring of five
//!   columns (wrapped light on periodic sides, zero otherwise; light from outside in a
//!   second level's ring), so a row's gather is a branch-free loop over slices that the
//!   compiler vectorises; adding the ring's zeros is exact, so the sums equal the
//!   oracle's tap-by-tap ones. It was side logic per tap near the sides (a third of the
//!   gather).
//! - **Empty levels** skip the powers, the quiet mask and phase 2 altogether.
//! - **Phase 2**: a cell's emission rounds over the 17 channels as lanes (structure of
//!   arrays: one loop per colour that vectorises); removals found by index away from the
//!   sides.
//! - **Finishing**: a level's last phase sums the flux each row sends on and, in the last
//!   pass, resolves the row's average and dominant direction in the same task while the
//!   row is in cache (they were sequential passes over the grid: a quarter of the time,
//!   and the second core idled); levels above all material are resolved once.
//! - **Threads**: the passes run on a worker of rayon's pool, so a level's loops start
//!   inside the pool (two cores: 1.8× one core at 64³, from about 1.3×). Tasks take
//!   at least 128 points ([`sweep::MIN_POINTS_PER_TASK`]): a 16 × 16 level runs on
//!   both cores (at 512 it was one task; the forest at 16³ gained 1.5×, though a
//!   fifth of the two threads' time is then the kernel's scheduling); phases 2 and 3,
//!   whose rows differ in cost, in tasks of at most 32 points
//!   ([`sweep::MAX_POINTS_PER_UNEVEN_TASK`], fifth round below).
//! - **Phase 3 as rows**: a cell's collisions with its level-mates' emission read
//!   what each path carries into each segment from the emission loop (`pre`), instead
//!   of walking every path's earlier segments again (quadratic in the five segments of
//!   a horizontal channel). The emission, the transmit step, phase 2's collection of
//!   removed light and phase 3's collisions run channel by channel over blocks of a
//!   row from planes: the level's transmittances and sources with a ring of 4 cells
//!   (`Planes`, wrapped or empty as [`sweep::run`]'s sides say), and what each path
//!   lost or carries per segment as planes per row (slot, colour, column). Each
//!   point's sums keep their order, so the light is the same bit for bit; the scalar
//!   oracle walks each point's paths cell by cell for phase 3 and collects phase 2
//!   point by point, so `tests/fast_path.rs` compares two implementations of every
//!   phase but phase 3's collisions (shared, reading the slot planes both write).
//!
//! **Since (issue 15, third round; default rule; criterion, same bench, means, against
//! the table just above):**
//!
//! | case | now, recycled | change (criterion) |
//! |------|--------------:|-------------------:|
//! | 64³, 26 bins, 1 pass | 24.4 ms (10.7 M/s) | −9.8 % (p = 0.08: within noise) |
//! | 64³, 26 bins, 4 passes | 75.3 ms (3.5 M/s) | −33 % |
//! | 64³, average + dominant only, 1 / 4 passes | 16.7 / 63.8 ms (15.7 / 4.1 M/s) | −24 % / −21 % |
//! | 16 × 64 × 16, 26 bins, 1 / 4 passes | 1.90 / 7.7 ms (8.6 / 2.1 M/s) | −25 % / −31 % |
//! | uniform fog 16³, 4 passes | 17.5 ms | −26 % |
//!
//! (The scalar oracle, which shares the resolve and the clamp, moved −4 to −15 % in the
//! same run; the VM's speed moves by as much.) What changed, found with perf:
//!
//! - **The clamp** every last pass under the default rule (light of either sign) was
//!   `Vec3::max` per bin and did not vectorise: most of `finish_row`. Now flat floats,
//!   `v > 0 ? v : 0`, the same value bit for bit (unit test).
//! - **The validity check** (`valid_bins`, 78 floats a point) was a `fold` over
//!   `Range::contains`, whose `&&` branches: lanes of the least and greatest value and
//!   of "any NaN" now (2× faster). The resolve's sums run four points as lanes.
//! - **Later passes' output adds** waited on the output's cache lines one point at a
//!   time (the 82 MB grid is not in cache after the first pass): each row's lines are
//!   now read ahead in a loop of independent loads (`touch`) before the adds. The
//!   average-only sink's adds went through memory (a store then a load per channel);
//!   they sum in a local now.
//! - **A row that passes its light on unchanged** (all points quiet, no light from
//!   outside) takes the flux it sends on from what it gathered instead of summing its
//!   51 planes again (same terms, same order).
//! - **Profile rule**: the removed light and its height moments are gathered from one
//!   read of the planes; the per-cell profiles are kept across levels (a 64 × 64 level
//!   cleared the set every level: the check counted cells, not distinct values), and
//!   each table node is computed on first use (a process's first sweep paid ~180 ms
//!   for all 1025).
//!
//! Tried and dropped: `-C target-cpu=x86-64-v3` (AVX2) gives no measurable change, and
//! sixteen lanes in the `f64` flux sums none either (they already run at the adder's
//! throughput, 0.2 ns a float): the loops are not bound by vector width.
//!
//! **Fourth round (issue 15).** Criterion's means moved by up to a third between runs
//! of one build this time (the 16 × 64 × 16 grid's four passes read +32 %, its fresh
//! memory run −20 %, in one run), so the figures of record are the fastest of many
//! runs, old and new builds alternating in the same minutes (`throughput`-style loops
//! of `CpuSweeper::sweep` after `recycle`; the old build is `f066d27`):
//!
//! | case | before | now |
//! |------|-------:|----:|
//! | 64³, 26 bins, 1 pass | 19.1–19.3 ms (13.7 M/s) | 16.6 ms (15.8 M/s) |
//! | 64³, 26 bins, 4 passes | 68.9–71.9 ms (3.7 M/s) | 65.0–70.0 ms (3.9 M/s) |
//! | 16 × 64 × 16, 26 bins, 1 pass | 1.66 ms (9.9 M/s) | 1.47 ms (11.1 M/s) |
//! | 16 × 64 × 16, 26 bins, 4 passes | 6.5–6.7 ms | 6.2 ms |
//! | forest 16³, 4 passes (`forest_profile`) | 5.8 ms | 5.3 ms |
//!
//! (Criterion, the same run's means: 64³ one pass 18.6 ms, −17.6 %, p < 0.01; four
//! passes 69.3 ms, −10.9 %, p < 0.01.) The light is the same bit for bit; besides
//! `tests/fast_path.rs`, hashes of every output over the five scenes × periodic and open
//! sides × both medium rules × 1, 2 and 5 passes × both outputs × two smoothings equal
//! the old build's. What changed, found with perf:
//!
//! - **The one-pass resolve from the planes** ([`sweep`]'s `resolve_planes`): where a
//!   point's bins hold exactly the first pass's channel light (levels without material,
//!   whose phase 1 is their last), its average and dominant direction are summed along
//!   the row's planes as lanes, bins in order, the same operations per point as
//!   `BinLight`'s resolve (unit test, bit for bit, bad values included). Point by point
//!   from the bins it was 12 % of a one-pass sweep and did not vectorise.
//! - **Phase 3's collision tally** ran one float at a time (a closure that indexed
//!   `unit[a]`, a bounds check a term): slices now, which vectorise; the media's
//!   profiles are found once a block.
//! - **Blocks of 64 points zeroed in full** for every channel or row (phases 2 and 3,
//!   the gather of removed light), though a 16-wide grid reads 16 of them: zeroed for
//!   the block's points only; phase 2's blocks (13 KiB, and 25 KiB of profile moments)
//!   kept per thread.
//! - **The transmit step** takes a segment's removal factor once, not once a colour,
//!   and updates the light colour by colour along the block (as `Vec3`s point by point
//!   it did not vectorise).
//! - **A sweep's fixed per-cell values** (`ln p` a cell, which faces are exposed, the
//!   levels' scans) on every core: a millisecond of one core at 64³ every sweep.
//! - Copied levels above all material fill the level light only twice in a row (the
//!   third on finds it filled).
//!
//! Tried and dropped (no measurable change): the clamp applied as the first pass adds
//! (instead of a pass over the bins); `wrap` without a division for the side columns'
//! `rem_euclid` (perf put a sixth of the profile rule's gather on it; removing it moved
//! nothing).
//!
//! **Fifth round (issue 15).** Kept: phases 2 and 3 run as tasks of at most 32 points
//! ([`sweep::MAX_POINTS_PER_UNEVEN_TASK`]) that the threads take as they free up; the
//! two tasks of 128 points a 16 × 16 level had before left one thread waiting on the
//! other, as its rows' material differs (timed phase by phase on the forest, phases 2
//! and 3 ran 1.6× faster on two threads than on one; phase 1, which keeps its tasks,
//! 1.5×). The forest (16³, `forest_profile`, fastest of 300–400, old and new builds
//! alternating): two passes 2.63–2.67 → 2.51–2.55 ms, four passes 5.16–5.34 →
//! 4.91–4.99 ms; the canopies no slower (64³, in minutes when the VM was slow: one
//! pass 17.15–17.43 against 17.14–17.54 ms, four passes 66.1–69.4 against 64.3–65.4
//! ms; 16 × 64 × 16, one pass 1.47–1.48 against 1.46–1.48 ms). The light is the same bit for bit (the rows'
//! tallies are summed in row order as before). Kept too: a level's short sequential
//! steps before phase 1 run as two at once (`rayon::join`: the transmittances and
//! their planes on one thread; the ring of periodic light, the quiet mask and the
//! media's profiles on the other), which a 16³ level's timing put at a tenth of the
//! forest's sweep: two passes 2.54 → 2.46–2.48 ms, four 4.88–4.96 → 4.76–4.79 ms.
//! `cargo xtask bench` after both: the forest's four passes reach 0.0175 in 4.8 ms,
//! 175× Monte Carlo (841 ms for that error; 160–168× on the build before this
//! round); two passes reach the same 0.0175 in 2.5 ms, 339×.
//!
//! Tried and dropped in the fifth round (each bit for bit the same light; old and new
//! builds alternating, fastest of 40–400 runs; none moved the time beyond the runs'
//! spread):
//!
//! - A quiet row's adds into the 26-bin output as 4 × 4 transposes (a pass's
//!   channels fill one or two runs of consecutive bins, so four points × four planes
//!   can go through one register transpose): perf still put the same share on the
//!   adds, now on the stores, which wait on the output's memory.
//! - Non-temporal (streaming) stores for the first pass's output: filling 82 MB on two
//!   threads took 2.5–3.2 ms with plain stores and 3.1–3.2 ms streaming on this VM;
//!   the output's first write runs at the memory's speed either way (some 2.7 ms of a
//!   16.3 ms pass).
//! - Each level's transmittance powers once a sweep instead of once a level and pass
//!   (the forest at 16³, four passes: 5.06–5.14 ms before, 5.00–5.05 ms after, for
//!   40 bytes a cell with material kept a sweep), and one tally loop over a block's
//!   wrapped columns in phase 3 (the forest, two passes, one thread: 4.23–4.31 ms
//!   before, 4.15–4.35 ms after).
//! - What two threads still lose on the forest (16³, two passes: 4.2–4.4 ms on one
//!   thread, 2.5 ms on two, 1.7×): perf puts about a fifth of both threads' samples
//!   in the kernel's scheduler and `sched_yield`, the pool's threads waiting between
//!   a level's parallel loops (some 150 of them a sweep); a microbenchmark of rayon
//!   here: 1.3–1.5 µs a loop of two tasks back to back, 8–12 µs once 20 µs of one
//!   thread's work come between loops (the idle thread has gone to sleep). Fewer,
//!   longer loops per level would need phase 3's setup (`near`, the source planes)
//!   inside phase 2's loop.
//! - Sixteen `f64` lanes in the flux sums, again (64³, one pass: 16.2–16.6 ms either
//!   way).
//!
//! **Sixth round (issue 15): work a scene does not need.** Upward passes carry the
//! levels above all material once for all of them ("Skipped work" below): an upward
//! pass that another follows stops below those levels, and the last upward pass
//! carries the sum of their light. Four passes over the 64³ canopy compute 166 levels
//! where they computed 196; over the forest 34 where they computed 44. This one changes
//! the light by rounding (a sum transported instead of two transports summed; within
//! 1e-5 of each value, `tests/skips.rs`), the oracle does the same, and the fast path
//! still equals it bit for bit. Fastest of many, old (`6bc1aa7`) and new builds
//! alternating:
//!
//! | case | before | now |
//! |------|-------:|----:|
//! | 64³, 26 bins, 4 passes | 64.9–65.7 ms (4.0 M/s) | 58.7–60.6 ms (4.5 M/s) |
//! | 64³, 26 bins, 1 pass | 17.1–17.3 ms | 16.6–17.0 ms (no change expected: the VM was slow that hour) |
//! | 16 × 64 × 16, 26 bins, 4 passes | 6.26–6.29 ms | 5.64–5.85 ms |
//! | 16 × 64 × 16, 26 bins, 1 pass | 1.45–1.46 ms | 1.45 ms |
//! | forest 16³, 4 passes (`forest_profile`) | 4.88–4.96 ms | 4.59–4.74 ms |
//! | forest 16³, 2 passes | 2.47–2.54 ms | 2.48–2.52 ms (its one upward pass carries them anyway) |
//!
//! The new test found that the copy skip (levels above all material in a downward
//! pass) booked a copied level's input differently from a computed one under open
//! sides: all of it as entering through the top, where a computed level books what its
//! smoothing taps take from beyond the sides as side input (and as much leaving through
//! them). The passes' convergence test divides by the input, so with a tolerance the
//! sweep could run a different number of passes with the skip than without (5 against
//! 4 in the case it found). A copied level now books its input as a computed one would
//! (counted, `Ctx::uniform_gather`). Also: phase 3 picks its rows from the rows of
//! emitting cells instead of a per-point dilation of 9 × 9 cells that was only read per
//! row (bit for bit the same light).
//!
//! `cargo bench -p lightgrid-sweep-cpu` after this round (criterion means, a noisy hour: its
//! intervals spanned up to ±10 %), each against the scalar oracle in the same run:
//! 64³ one pass 17.2 ms (15.3 M points/s) against 189 ms, 11.0×; four passes 68.9 ms
//! against 778 ms, 11.3×; 16 × 64 × 16 one pass 1.88 ms against 10.8 ms, 5.8×, four
//! passes 7.6 ms against 37.2 ms, 4.9×; the uniform fog (media in every level) 16³
//! four passes 20.7 ms against 25.4 ms, 1.2×, 48³ 328 ms against 784 ms, 2.4×. The
//! fog is where the fast path gains least: phase 3's collisions, which both share,
//! and the profile rule's per-cell work (its 3 × 3 solves alone 9 % on one thread)
//! take most of its time.
//!
//! Tried this round and dropped: `BinLight`'s four-point resolve reading 4 × 4 blocks
//! and transposing them (6 % faster on 4096 points in cache, 0.150 → 0.141 ms; the
//! resolve is 8 % of four passes, so 0.5 %: not worth the code).
//!
//! **Seventh round (issue 15): flux known without summing.** Of the 166 levels four
//! passes over the 64³ canopy compute, 150 hold no material, and each summed its 51
//! planes of gathered light in `f64` for the energy balance. Under periodic sides such a
//! level gathers exactly the flux the level before it sent on, and sends it on: it is
//! now booked as that ([`sweep::conserves_flux`]; "Energy" below), and the sums are
//! not run. The light is the same bit for bit (only the balance changed: it no longer
//! books the sums' rounding as side loss); `tests/skips.rs` checks that the flux booked
//! as leaving through the bottom is what the lowest level's light carries, under
//! periodic and open sides. Also: phase 3 no longer writes what a path carries into
//! its first segment (nothing, and never read); phase 2 writes a medium cell's
//! emission planes for phase 3 slot by slot from whole rows (store by store, each
//! colour looked up and checked, they were a quarter of phase 2 on the forest: perf
//! put phase 2 at 7.6 % of the forest's samples after, 10.2 % before, but the wall
//! time moved within the runs' spread, 4.58–4.79 against 4.65–4.70 ms). This session the VM ran at two speeds,
//! switching every few minutes, one 1.3–1.5 times the other (the forest's four passes:
//! 3.1 ms or 4.7–4.9 ms; Monte Carlo moves less, 620–730 ms), so each figure below is
//! old (`d471002`) and new builds alternating within one of them:
//!
//! | case | slow hours: before → now | fast hours: before → now |
//! |------|-------------------------:|-------------------------:|
//! | 64³, 26 bins, 4 passes | 55.8–56.8 → 49.1–50.8 ms | 41.3–41.9 → 39.6–40.4 ms (6.6 M/s) |
//! | 64³, 26 bins, 1 pass | | 11.5–11.7 → 11.3 ms (23 M/s) |
//! | forest 16³, 4 passes (`forest_profile`) | 4.81–4.87 → 4.64–4.73 ms | 3.08–3.12 → 3.08–3.09 ms |
//!
//! `cargo bench -p lightgrid-sweep-cpu` after it (criterion means, a fast hour), each against the
//! scalar oracle in the same run: 64³ one pass **11.9 ms (22.0 M points/s)** against
//! 114 ms, 9.6×; four passes 52.2 ms (5.0 M/s) against 430 ms, 8.2×; 16 × 64 × 16 one
//! pass 1.60 ms (10.2 M/s), four passes 3.52 ms (4.7 M/s); the uniform fog 16³ four
//! passes 14.0 ms against 23.6 ms, 48³ 226 ms against 476 ms. `cargo xtask bench`: the
//! forest's four passes reach 0.0175 in 3.1 ms, 199× Monte Carlo (623 ms); two passes
//! in 1.6 ms, 387×. In a slow hour the same build gave 4.7 ms, 146–153× (Monte Carlo
//! 687–726 ms), and 2.5 ms, 275–291×.
//!
//! Tried and dropped: the gather summing its row as it writes it (instead of reading
//! it back, in cache): slower, 13.0–13.9 against 11.9–12.2 ms for one pass (it
//! vectorised worse); eight `f64` lanes in those sums (no change, as sixteen before);
//! the one-pass resolve from the planes four points at a time, all bins, its sums in
//! registers (timed only together with the first, and not faster with it).
//!
//! **Eighth round (issue 15): wider vectors, rows fetched ahead, huge pages.** Three
//! changes, the light bit for bit the same:
//!
//! - The workspace's own builds (tests, benches, the demo, CI) target x86-64-v3
//!   (`.cargo/config.toml`: AVX2 and FMA, every x86-64 CPU since 2013–2017), so the
//!   row loops run eight floats wide instead of four. Rust fuses no multiply-add and
//!   reorders no sum by itself, so the results do not change:
//!   `tests/build_flags.rs` holds the hashes of twenty sweeps' outputs from a baseline
//!   build and checks them (`.ci/cpu-target` falls back to the baseline on a CPU
//!   without v3). A crate that depends on this one builds with its own flags: add
//!   `-C target-cpu=x86-64-v3` (or `native`) to get these figures. Monte Carlo gains
//!   too (its ratio to the sweep moves little).
//! - Each row's gather hints the next row's bins into cache, a share per channel
//!   ([`sweep::FETCH_AHEAD_BYTES`]: sinks of 16 MiB or more, which stay in no cache
//!   between passes). Before, the sweep's `touch` read a row's lines while nothing else
//!   ran: 12 % of four passes at 64³. All hinted at once at the row's start they
//!   stalled the gather (5 % slower); a share a channel overlaps them with it. Hints
//!   for the previous level's rows gained nothing; on grids whose sink fits the cache
//!   (16 × 64 × 16, 5 MB) they cost 3 %, so they are left out there. This is the
//!   workspace's first `unsafe` (`_mm_prefetch`, which cannot fault).
//! - A sweep's fresh buffers (its output, where the caller gives none back with
//!   `recycle`) are advised to be backed by 2 MB pages on Linux (`madvise`; the kernel
//!   here backs only advised ranges with them). The 82 MB of a 64³ grid's bins took
//!   20 000 page faults, about 23 ms of a 33 ms one-pass sweep; now 41. Criterion, one
//!   run: one pass without `recycle` 33.3 → **19.3 ms**, four 63.4 → 55.3 ms (the
//!   oracle, which allocates the same way, 104 → 94 ms); with `recycle` unchanged
//!   (10.4, 36.0 ms). Loops, builds alternating: one pass 27.6–32.4 → 15.6–17.9 ms,
//!   four 52.5–70.8 → 40.3–55.3 ms. The workspace's second `unsafe`.
//!
//! Same spell, fastest runs of a loop of `CpuSweeper::sweep` after `recycle` (64³
//! canopy, 26 bins), builds alternating: one pass 11.5–11.8 ms (the seventh round's
//! build) → 10.5–10.6 ms (x86-64-v3) → 9.8–10.2 ms (and fetched ahead), **26 M
//! points/s**; four passes 38.7–40.4 → 36.5–37.4 → 33.8–35.2 ms, **7.5–7.8 M/s**. The
//! 16 × 64 × 16 canopy: 0.865 → 0.82 ms one pass (20 M/s), 3.24 → 3.19 ms four. The
//! forest (16³, `forest_profile`, all three builds alternating): four passes
//! 3.03–3.11 → 3.00–3.02 → 3.00–3.05 ms, two passes 1.62–1.64 → 1.57–1.62 →
//! 1.59–1.62 ms (1–3 %: its levels are small, its time per-cell work and scheduling;
//! its sink is not fetched ahead).
//! In the VM's slow spells (it switches speed every few minutes, the slow one
//! 1.3–1.4× slower) the new build took 12.1–12.4 ms for one pass (21 M/s) and
//! 47.2–47.3 ms for four (5.5 M/s), against 12.9–13.1 and 49.1–50.0 ms with
//! x86-64-v3 alone.
//! `cargo bench -p lightgrid-sweep-cpu` (criterion means, one run), each against the scalar
//! oracle in the same run: 64³ one pass (recycled) **10.1 ms, 25.9 M points/s**,
//! against 104 ms (10.3×); four passes (recycled) **34.7 ms, 7.6 M/s**, against 405 ms
//! (11.7×); 16 × 64 × 16 one pass 0.84 ms (19.5 M/s), four 3.26 ms (5.0 M/s); uniform
//! fog four passes 16³ 8.5 ms against 17.5 ms, 48³ 183 ms against 465 ms. Without
//! `recycle`: 19.3 ms for one pass, 55.3 ms for four (above). `cargo xtask bench`: the forest's four passes reach 0.0175 in
//! 3.0 ms, 216× Monte Carlo (651 ms), two passes in 1.6 ms, 409×.
//!
//! Tried and dropped (measured): the 26 bins kept as planes along each row while the
//! passes run (a `RowBins` sink: the adds vectorise and read 17 of 26 bins; transposed
//! once, as the last pass resolves a row): the transpose cost what the adds saved
//! (four passes 47.5–48.2 → 48.2–50.3 ms) and one pass, which has no adds to save,
//! lost 20 % to it; the transmit step's adds as 8 × 8 blocks transposed in registers
//! (no change: the stores wait, not the loads); the resolve's validity check from the
//! least value alone (no change).
//!
//! **Ninth round (issue 15): constant row widths, the ring wrapped as rows end.** Two
//! changes, the light bit for bit the same:
//!
//! - The row loops over a block of `b` points (the transmit step, phase 3, the
//!   collisions, the planes' resolve) run with `b` a constant for blocks of 64, 32 and
//!   16 points (`sweep::with_width`, each arm inlining the block), so they compile
//!   without remainder loops. The forest's rows are 16 points: its four passes
//!   3.03–3.10 → 2.76–2.80 ms (`forest_profile`, fast spell, builds alternating); the
//!   64³ canopy's four passes 34.9 → 33.7 ms. `tests/fast_path.rs::block_widths` checks
//!   rows of 16, 32, 80, 96 and 21 points against the oracle (it fails if an arm runs
//!   the wrong width).
//! - Each level began by wrapping the ring of the light it gathers from (periodic
//!   sides: 51 planes × 10 columns a row, and 10 ring rows) on one thread, beside the
//!   transmittances on the other; a level without material has none, so the other
//!   thread waited. A level whose next level has no material now wraps each row's
//!   ring columns as the row ends, in cache, on the row's thread
//!   (`Finish::wrap_columns`); the next level copies only the ring rows. Canopy four
//!   passes 33.1–33.9 → **32.2–32.4 ms, 8.1 M points/s** (fast spell), and
//!   45.6–47.1 → 40.1–42.1 ms in slow spells, where the waiting cost most. The forest
//!   is unchanged: its levels have material, whose transmittances hide the wrap.
//!
//! Also: a sweep's pending scattered light is kept per level and allocated when a
//! level first holds some (`PendingLevels`): fresh work (`lightgrid_sweep_cpu::run`, or the
//! first sweep of a `CpuSweeper`) no longer reserves 25–38 MB at 64³ that the
//! allocator, serving a freed block of that size from its heap, zeroed in full.
//! Repeated fresh four-pass sweeps: peak memory 134.5 → 126.3 MB; their time moves
//! within the kernel's noise (fresh sweeps vary by 2× from run to run with how fast the
//! kernel finds huge pages).
//!
//! Where the time goes, per pass of four over the 64³ canopy (before these changes):
//! the first (downward: 34 levels computed, 30 copied) 7.7 ms, the second and third
//! (34 levels each) 6.9 and 6.6 ms, the last (upward: 64 levels and the resolve of all
//! 262 144 points) 12.8 ms. `cargo bench -p lightgrid-sweep-cpu` (criterion means, a fast
//! spell), each against the scalar oracle in the same run: 64³ one pass (recycled)
//! **9.75 ms, 26.9 M points/s**, against 94.8 ms (9.7×); four passes (recycled)
//! **32.3 ms, 8.1 M/s**, against 411 ms (12.7×); without `recycle` 18.3 ms (14.3 M/s)
//! and 47.7 ms (5.5 M/s); 16 × 64 × 16 one pass 0.87 ms (18.9 M/s), four 3.08 ms
//! (5.3 M/s). A whole run of the bench in mixed spells gave 11.7 ms and 34.0 ms, and
//! the small grid's four passes 6.1 ms in a slow spell: on this VM a figure means
//! little without its spell. `cargo xtask bench`: the forest's four passes reach
//! 0.0175 in 2.8 ms, 250× Monte Carlo (704.5 ms), two passes in 1.5 ms, 479×.
//!
//! Tried and dropped (measured, builds alternating): phase 2 writing phase 3's
//! emission planes slot by slot after the row instead of cell by cell (0.9 ms slower
//! on four passes: the per-cell weights are gathered instead of read in a run); the
//! quiet rows' adds channel by channel along the row (no change); constant widths for
//! the gather and for phase 2's gathers, whose loops run over tap ranges (no change, or
//! 1–2 % slower); the gather reading rows beyond the sides as the wrapped rows instead
//! of the ring's copies (canopy 2 %, forest 3 % slower); no `rayon::join` for levels
//! without material (forest 5 % slower, likely the pool's second thread sleeping
//! between levels).
//!
//! **Roofline** (per point and pass, quiet point, 26 bins). Compute: gather 17 channels
//! × 3 colours × 9 flops ≈ 460 flops (~60 eight-lane operations), flux tallies and
//! output adds ≈ 150, the last pass's resolve ≈ 390 (26 bins × 15): some 650
//! scalar-equivalent operations, which two cores at ~3 GHz issuing two a cycle would
//! run at ~18 M points/s with four-lane vectors, more with eight. Memory
//! (`cargo run --release -p lightgrid-sweep-cpu --example memory_floor`, two threads, eighth
//! round): writing the 82 MB output takes 0.9–2.2 ms, a read-modify-write of it
//! 1.1–2.1 ms (the seventh round measured 4–5 ms in a slow spell); four passes move
//! about one write and three partial read-modify-writes of it, ≤ 7 ms of their
//! 34 ms. So neither pass count is bound by bandwidth: what costs is the latency of
//! bringing each row's bins in (now fetched ahead) and compute. Where four passes go
//! (perf, two threads, ninth round): the transmit step 19 % (on quiet rows, adding the
//! 17 channels' planes into each point's bins, a transpose), the gather 15 %, phase 2
//! 10 %, the resolve 9 %, phase 3, the collisions and the profile rule's moments,
//! solves and sources 18 %, reading a row's bins 5 %, copies (the ring's rows, phase
//! 3's emission rows) 4.5 %, the ring's columns 1.4 %. The issue's targets: one pass 20 M points/s,
//! **met** by a per-frame rebuild that recycles its output (26.9 M/s, criterion; 21
//! M/s in the VM's slow spells), not by a sweep into fresh memory (criterion's plain
//! bench, 18.3 ms, 14.3 M/s: the kernel zeroing 82 MB); four passes 8 M/s, **met in
//! fast spells** by a recycling rebuild (criterion 32.3 ms, 8.1 M/s; slow spells
//! 40–42 ms, 6.3 M/s; fresh memory 47.7 ms); small grids 5 M/s, met (18.9 M/s one
//! pass, 5.3 M/s four).
//!
//! **The forest** (`cargo xtask bench`): its headline (4 passes, the presets' smoothing,
//! 0.5 since the thirteenth round: **Smoothing** under "Accuracy") reaches error 0.0160
//! in 1.9–2.0 ms, 389–417× Monte Carlo's 767–799 ms to that error in seven runs (the
//! same runs' 0.25: 0.0175, about 350×; the cheapest setting, 2 passes at 0.5, 0.0161 in
//! 1.1 ms, 712–750×; slow spells 3.3–3.4 ms, 230–245×). At smoothing 0.25 it reached error 0.0175 in 1.9 ms, 310–365× Monte
//! Carlo's 579–698 ms to that error on earlier days (twelfth round, below; eleventh: 2.4 ms, 279×; ninth: 2.8 ms, 250×; eighth: 3.0 ms,
//! 216×); the bench also names the cheapest setting for its error: 2 passes reach the
//! same 0.0175 in 1.0–1.1 ms, 560–660× (eleventh: 1.3 ms, 515×; ninth: 1.5 ms, 479×;
//! eighth: 1.6 ms, 409×). The VM's slow spells give
//! 4.7 ms and 146–153× (seventh round). Earlier rounds: 5.3–5.6 ms, 160–168× (fifth);
//! 6.0–6.5 ms (fourth); Monte Carlo's time moves more than the sweep's between runs
//! (620–1206 ms). Where the forest's two passes go (perf, two threads, eighth round):
//! phase 3's emission 10 % and collisions 9 %, the transmit step 10 %, phase 2 8 %,
//! the profile rule's moments, 3 × 3 solves and sources 12 %, threads sleeping and
//! waking 8 % (its levels have 256 points: four parallel loops a level, each a few
//! microseconds of work a thread; two threads give 1.6× one).
//!
//! **Tenth round (issue 15): the profile set, and where the forest's time goes.** The
//! per-cell profiles of the default rule ([`profile`]) were kept in a set of at most 4096
//! that cleared itself whenever a level brought more than fitted. A 32³ forest holds
//! about 6000 distinct (depth, direction) pairs, so every level of every pass cleared the
//! set and computed its own again (some 700 at 1.2 µs each). Once full, the set now
//! keeps what it holds and computes a level's other profiles for that level alone. A
//! sweep that begins with a full set of which the last sweep read less than half (a
//! renderer sweeping one area after another) starts it afresh
//! (`profile::tests::profiles_of_another_scene_replace_a_full_set`). The set
//! also holds up to 65 536 profiles, 77.5 MiB at most. A scene uses only as many as it
//! has distinct depths of medium times two directions, and [`sweep::sweep_bytes`] now
//! counts them. Forests under `forest_profile`, four passes, three builds alternating,
//! fastest of 100, 30 and 20 sweeps:
//!
//! | forest | before | cap 16 384 | now |
//! |--------|-------:|-----------:|----:|
//! | 32³ | 13.4–13.9 ms | 10.9–11.1 ms (another spell: old 14.1–14.5) | **9.7–10.5 ms** |
//! | 48³ | 33.5–33.8 ms | 29.4–29.7 ms (another spell: old 37.0–37.7) | **28.1–28.5 ms** |
//! | 64³ (more profiles than 16 384) | 70.1–73.4 ms | 62.2–63.2 ms | **56.7–57.8 ms** |
//!
//! The 16³ and 24³ forests are unchanged, since their profiles fit either way. The
//! light is the same bit for bit
//! (`profile::tests::profiles_beyond_keep_computed_again_alone`). Two more changes
//! followed for large levels. The set's map hashes its keys with splitmix64's
//! finaliser instead of SipHash, so its lookups fell from 3.3 % to 1.9 % of a 64³
//! forest's samples. And levels of more than [`sweep::FETCH_PROFILES_ABOVE`] points
//! fetch each block's profiles before the slot-major loops read them one value a point
//! at a time: 64³ 51.2–52.6 → **45.8–46.0 ms** (phase 2 18.6 → 11.9 % of the samples),
//! 32³ 9.9 → 9.7 ms, the 16³ forest unchanged. So the 64³ forest's four passes went
//! from 70–73 ms to 46 ms in this round.
//!
//! Where the bench forest's 2.8 ms go. The forest has material in its six lowest levels
//! only (levels 0–5: 256, 256, 232, 181, 121 and 12 cells of 256). The ten above are
//! copied in downward passes and carried once upward ("Skipped work"), so the time is
//! the six levels' 24 runs. Timed per level and phase in one upward pass (fast spell;
//! the timers are not kept in the code), levels 0–4 take 115–137 µs each and level 5
//! 63 µs. Of that time the set-up (transmittances, quiet points, profiles; a
//! `rayon::join`) is 7 %, phase 1 (gather and transmit) 15 %, phase 2 (removed light,
//! the profile rule's moments and 3 × 3 solves, the emission planes) 34 % and phase 3
//! (emission, collisions) 44 %. In slow spells phase 1 slows most (2.2×, the others
//! 1.3×). Level 5, with 12 cells of medium, costs half a full level: phase 3's row loops
//! run over every point of a row within 4 rows of an emitting cell, whatever the number
//! of emitters. **Rows of 16 points are the limit:**
//! `TILE=4 forest_profile` lays four copies of the forest side by side. Under periodic
//! sides each copy gets the same light, and the work per point is the same, but rows
//! are 64 points long. A copy then takes 1.77 ms against 2.78 ms (`TILE=2`: 2.06 ms).
//! Per phase, in one upward pass: phase 1 −42 %, phase 2 −29 %, phase 3 −40 %, the
//! set-up −10 %. Each channel, stencil slot and colour sets up a loop over a block of
//! the row (slices, bounds, offsets), and at 16 points that set-up costs about as
//! much as the arithmetic. The forest's four-pass target (380× Monte Carlo, ≤ 1.85
//! ms) therefore needs blocks of several rows. The transmittance and source planes
//! are already padded 2-D arrays ([`sweep`]'s `Planes`), where a tap is a fixed offset
//! for every point of a level. The level's light, the removed light and the emission
//! planes are still per row, and they would have to follow. That is the next round,
//! not this one.
//!
//! Tried and dropped: the periodic tails of the taps (the columns beyond the row, up
//! to 4 of a 16-point row's) read as one run of wrapped columns a side instead of
//! point by point with a remainder: no change where only the collisions did it, 4 %
//! slower everywhere (the short runs' loops cost more than the division they saved).
//!
//! **Eleventh round (issue 15): rings on the slot planes.** A level's slot planes (the
//! light each cell removed from each path, what each path carries into each segment,
//! and the profile rule's emission per segment) are kept per row, slot and colour. Each
//! row of them now carries a ring of [`sweep`]'s two columns a side (the stencil's
//! reach along a row), filled as the row is written: the wrapped columns on periodic
//! sides, zeros on open ones, and only for the slots whose tap lies beside the column.
//! So every tap of phase 2's gathers and of phase 3's emission and collisions reads one
//! slice of the block's points. Before, on a row of 16 points, a tap beside the column
//! ran as a vector loop over 14 or 15 points, then its scalar remainder and one or two
//! wrapped points (a division each), and the emission first copied each tap's row out
//! of the emission planes. Three smaller changes went with it. Phase 3 stores what a
//! path carries into its next segment as the segment's loop computes it (a copy
//! afterwards was a `memcpy` call per slot and colour, 2.3 % of the forest). The
//! emission runs on the rows within two of an emitting cell (a path's reach), not
//! four. The transmittance planes' ring is two columns, not four, and the row loops
//! index the slot planes by row and column instead of dividing a point index by `nx`.
//! The light is the same bit for bit (`tests/fast_path.rs`; its oracle tests fail if
//! the emission's reach is cut to one row). Four passes, fastest of 100 (10 at 64³),
//! builds alternating in one spell:
//!
//! | scene | before | now |
//! |-------|-------:|----:|
//! | forest 16³ | 2.91–2.92 ms | **2.40–2.46 ms** |
//! | forest 32³ | 10.1–10.3 ms | **8.9–9.0 ms** |
//! | forest 64³ | 48.3–49.5 ms | **46.4–46.5 ms** |
//! | canopy 64³, four passes (one pass) | 32.9–33.3 (9.46) ms | **32.0–32.2 (9.2–9.3) ms** |
//!
//! `cargo xtask bench`: the forest's four passes reach 0.0175 in 2.4 ms, **279×**
//! Monte Carlo (668 ms); two passes 1.3 ms, 515×. The 380× target is not met: it needs
//! about 1.76 ms at that Monte Carlo time. Timed per level and phase (the timers are not
//! kept), a sweep now spends 6 % in the levels' set-up, 18 % in phase 1, 33 % in phase 2
//! and 39 % in phase 3. What remains per row is still the cost of setting up each short
//! loop (`TILE=4` copies of the forest take 27 % less per copy, down from 35 %).
//!
//! Tried and dropped: the block's width as a constant for rows of 16 (the block body
//! written out twice by a macro, since the optimiser compiled the large closures of
//! `with_width` once for any width). With the width known, each loop compiles to two
//! eight-lane operations, where with it unknown the loops take 32 points per iteration
//! and a 16-point row runs their four-lane remainder. It was still 1–3 % slower, before
//! and after the rings: the unrolled bodies hold their arrays in registers and shuffle
//! them. What the four-lane remainders cost shows with LLVM told not to interleave its
//! vector loops (`RUSTFLAGS="-C target-cpu=x86-64-v3 -C
//! llvm-args=-force-vector-interleave=1"`, so that a loop takes eight points at a time):
//! canopy 16³ four passes 1.62–1.64 → 1.53–1.55 ms, the forest 16³ 3–4 % faster (a slow
//! spell), canopy 64³ unchanged, the light the same. A flag for every crate of the
//! build does not reach a crate that depends on ours; loops written as eight-lane
//! chunks would, and are left for the next round with the multi-row blocks. (The
//! twelfth round, below, took the flag all the same, as the CPU target was.) (A first
//! try, phase 3's segment loops run through a helper calling `f(i)` for `i` in `j..j +
//! 8`, made the forest 8 % slower: chunks of fixed-size arrays remain to try.)
//!
//! **Twelfth round (issue 15): fewer calls, the colours of a solve together, set-up
//! kept.** Six changes, the light the same bit for bit (`tests/build_flags.rs`'
//! hashes did not move, `tests/fast_path.rs`):
//!
//! - The workspace's builds tell LLVM not to interleave its vector loops
//!   (`.cargo/config.toml`, beside x86-64-v3; above, "Tried and dropped"): a loop of
//!   unknown length took four vectors (32 floats) an iteration, so a 16-point row ran
//!   its four-lane remainder. Like the CPU target it does not reach a crate that
//!   depends on ours.
//! - The profile rule's 3 × 3 source balance ([`profile`]) is solved with its
//!   cofactors shared (`J = adj(M) e / det M`: Cramer's four determinants expanded
//!   along the replaced column), a cell's three colours as lanes of one loop that
//!   compiles to four-wide `f64` vectors, the emission and absorbed flux in the same
//!   loop (the wrappers around the solve, `f64` conversions and the flux sums, had
//!   cost more than the solve): the solve's share of a forest sweep 8.3 → 5.4 %.
//! - Three row loops no longer zero their sums first: `gather_moments`' first tap,
//!   phase 3's first segment and a point's own cell set them (`0 + v` is `v`, but for
//!   the sign of a zero; every stencil holds its own cell, which the stencil test
//!   checks). Each `fill(0.0)` over a block of unknown width was a call to `memset`,
//!   once per array, channel and colour: 4.4 → 1.1 % of the samples.
//! - A level's transmittances (ten exponentials a cell), their padded planes and its
//!   quiet points depend on its material alone: found at the level's first visit of a
//!   sweep and kept for the later passes (`Work::set_up`; 41 bytes a point and the
//!   planes, [`sweep::sweep_bytes`]), so later passes drop a `rayon::join` a level.
//!
//! The forest 16³, four passes (`forest_profile`, fastest of 300–500, builds
//! alternating within one spell):
//!
//! | step | one thread | two threads (fast spell) |
//! |------|-----------:|-------------------------:|
//! | eleventh round | 4.27–4.35 ms | 2.34–2.41 ms |
//! | the solve's cofactors, colours as lanes | 3.92–3.95 ms | 2.27–2.29 ms |
//! | loops not interleaved | 3.75–3.76 ms | 2.13–2.16 ms |
//! | the solve's wrappers in the lane loop | 3.79–3.86 ms (a slower spell; ~1 %) | 2.08–2.10 ms |
//! | no zeroing (moments, emission, collisions) | 3.42–3.51 ms | |
//! | set-up kept across passes | **3.30–3.43 ms** | **1.92–1.98 ms** |
//!
//! Against the eleventh round's build (a worktree, alternating): forest 16³ one thread
//! 4.20–4.21 → 3.45–3.49 ms, two 2.34–2.42 → 1.97–2.02 ms; 32³ 8.44–8.53 → 7.55–7.58
//! ms; 64³ 44.1–44.3 → 39.7–41.0 ms; the canopy (`throughput`, recycled) 64³ one pass
//! 26.2 → 27.3 M points/s, four passes 8.25 → 8.74 M/s. `cargo xtask bench --scene
//! forest`: the four passes reach 0.0175 in **1.9 ms, 365×** Monte Carlo (698 ms; the
//! next run 1.9 ms against 579 ms, 310×; earlier in the round 2.0 ms, 325×); two
//! passes 1.1 ms, 560–660×. The 380× target is met in no run: 1.9 ms needs 720 ms of
//! Monte Carlo, whose time moved 579–698 ms between these runs.
//!
//! **The VM's spells are its cores' distance.** A ping-pong of one cache line between
//! two threads takes 80 ns a round trip in the fast spells and 380–500 ns in the slow
//! ones (the hypervisor places the two virtual cores near or far; the spell changes
//! every few minutes). One thread runs at the same speed in both, and two independent
//! processes do not slow each other: what slows is the threads' talk. At 16³ two
//! threads take 1.95 ms in a fast spell and 3.4 ms in a slow one, no faster than one
//! thread (3.4 ms); bench runs in slow spells reported 3.4 ms, 193× and 218×. Each level
//! runs three or four parallel loops of a few microseconds, each a fork and a join
//! across the cores, and the rows a core wrote move to the other when the next step
//! reads them. Tried and dropped: phase 1 in small tasks like phases 2 and 3 (worse
//! in both spells); the ring's rows read wrapped instead of copied (80 KB a level no
//! longer copied; no change); the profiles found beside phase 1 on the other thread
//! (no change); the emission planes' 147 stores a cell with one bounds check, and the
//! collisions' tallies without a range (no change); phase 3's segments with the three
//! colours in one loop (5 % slower); whole arrays zeroed in one call instead of
//! per-width fills (no change). Fewer joins a level (one parallel loop over a level's
//! phases with the threads' rows fixed and a spin barrier between phases) or blocks of
//! several rows (longer loops, fewer of them) are what remains.
//!
//! ## Semantics of the sweep
//!
//! Notation: grid of `nx × ny × nz` points, cell size `h`; `p_c` the pass-through and
//! `a_c` the reflectance (RGB) of cell `c`; bins and their solid angles `ω_b` as in
//! `lightgrid_core::dirs`; `u_b` the unit vector of bin `b`.
//!
//! **Slabs and channels.** Level `j` is a slab of cells of thickness `h`. Light moves
//! between slabs along 17 *channels* per pass. The downward pass has the 17 sweep
//! directions of `lightgrid_core::dirs::sweep_dirs`: channel `c` has step `s_c` = `(dx, -1, dz)`
//! for the 9 downward bins and `(4dx, -1, 4dz)` for the 8 horizontal bins, path length
//! `ℓ_c = 1/μ_c` (in `h`) per slab, where `μ_c` is the bin's mean `|cos|` to the vertical
//! (over the downward half of a horizontal bin; [`sweep::channel_length`]: 0.953, 0.679,
//! 0.555, 0.184, 0.148 for the vertical, edge, corner and the two horizontal kinds; the
//! step vectors' own cosines overstated them, by 30 % on the horizontal bins, and a
//! thin-celled half-space reflected 5.5 % too much). The upward pass mirrors it
//! (`y = +1`, upward bins, the same horizontal bins). A horizontal bin is split in two
//! halves about the horizon: the downward pass carries one, the upward pass the other
//! (share `σ_c` = 1/2 for horizontal channels, 1 otherwise).
//!
//! **Light and flux.** A channel value is light as a bin holds it (radiance integrated
//! over the bin). The flux it carries through a horizontal plane, per point (per `h²`), is
//! `value × μ_c`. Energy is accounted in flux.
//!
//! **Path of a point.** In slab `j`, the path of channel `c` at point `x` runs from
//! `x - s_c/2` (entry face) to `x + s_c/2` (exit face), so it is centred on `x`. It crosses
//! only cells of level `j`: for vertical and diagonal channels the cell of `x` (the whole
//! path); for horizontal channels the five cells `x + k·(dx, dz)`, `k = -2..2`, with path
//! fractions `1/8, 1/4, 1/4, 1/4, 1/8`. A path fraction `f` through cell `c` transmits
//! `τ = p_c^(f ℓ_c)`.
//!
//! For each pass and each level, in order (downward: `j = ny-1 .. 0`; upward: `0 .. ny-1`):
//!
//! 1. **Gather.** `I(x, c) = (1 - w) O'(x - s_c, c) + (w/4) Σ O'(x - s_c ± e, c)` over
//!    the four horizontal neighbours `e` of the source point, where `w` is the smoothing
//!    weight and `O'` the outgoing light of the previous level. For the first level the
//!    previous level is the virtual level outside the grid: the top boundary (downward)
//!    or the bottom boundary (upward). Source points beyond the sides take: open — the
//!    top (downward) or bottom (upward) boundary light, as if the world around were empty;
//!    periodic — the wrapped point; given — the halo value of that point and level (the
//!    level clamped into the grid), its horizontal bins halved. Boundary light enters only
//!    in the first downward and the first upward pass.
//! 2. **Transmit.** Along the path, cell by cell: cell `k` removes `I · T_k (1 - τ_k)`
//!    (`T_k` the product of the `τ` before it); the path leaves with `I · T`. Path cells
//!    outside the grid are empty (periodic: wrapped). `T_after` is the transmittance of
//!    the path cells after the point's own cell (1 for vertical and diagonal channels).
//! 3. **Collect.** Each cell sums, in flux, what it removed from every path crossing it:
//!    `R = Σ_c μ_c Σ removed`, and the first moment `M = Σ_c μ_c u_c Σ removed`.
//! 4. **Absorb.** `(1 - a) R` is absorbed; `S = a R` and `a M` are scattered. This
//!    pass emits its own channels' share of it (half, for a medium: the downward bins
//!    and the downward halves of the horizontal bins hold half the sphere); the rest
//!    waits for the next pass in the other direction. To `(S, M)` the cell adds what
//!    earlier passes left for this direction.
//! 5. **Emit.** A cell with `0 < p < 1` (a medium) holds its scattered light as an
//!    isotropic *source* `J` (light per unit solid angle). Under the flat rule
//!    ([`medium`], the option [`MediumEmission::Source`](lightgrid_core::MediumEmission);
//!    the default, `MediumEmission::Profile`, makes the source quadratic in height,
//!    below) the source is the same throughout the cell: this pass's share of
//!    it is `E = ½ (S ± β M_y)` (`+` downward, `−` upward; `β` = [`medium::split`] of the
//!    cell's optical depth, 0 for thin cells: light that collided on its way down, near
//!    the top of a thick cell, leaves upward more), and `J = E / (G + (1 − a) K)`, with `G
//!    = Σ μ_c ω_b σ_c (1 − τ_k)` over the cell's path segments of the pass (what a unit
//!    source sends out) and `K = τ Σ_c ω_b σ_c − G` (what the cell's own material stops
//!    of it, scattered again `a` of it: `(1 − a) K J` is absorbed). Then, once every
//!    cell of the level has its source (**phase 3**), every path segment `k` (a cell of
//!    each channel's path, step 2) emits `J ω_b σ_c (1 − τ_k)` into its path, which the
//!    later segments attenuate: the path's outgoing light gains `Σ_k J_k ω_b σ_c (1 −
//!    τ_k) T_{>k}`, the point's light the same sum up to its own cell's segment and that
//!    segment's mean (`L_in m + J (1 − m)`, step 7), and what a later segment's cell stops of it that cell
//!    has removed, as in step 3 (absorbed `1 − a`, the rest waits for the next passes of
//!    both directions). Segments of paths of points beyond an open or given side are not
//!    traced: what a cell emits into them leaves through the side. The sums telescope:
//!    a path that enters with its cells' source leaves with it, so a white furnace is
//!    exact in any medium. (The older rule, `MediumEmission::Escape`: the cell sends
//!    into channel `c` the flux `F_c = σ_c ω_b / 4π · (A S - B u_b · M) · T_after` with
//!    `(A, B)` = [`sweep::medium_emission`], and steps 6–7 as for surfaces; it fails the
//!    furnace, measured in [`exact`], and is closer on thick dark cells. The seed's
//!    `(A, B) = ((1 + p)/2, (1 − p)/2)` was removed: worse everywhere measured.) A
//!    cell with `p = 0`
//!    is opaque: its faces that border non-opaque cells or the outside through a side are
//!    diffuse surfaces (below the bottom level is ground, never a surface), and it
//!    sends `F_c = W_c S · T_after` with fixed weights `W_c`, the mean over those faces
//!    of the exact Lambertian share of the channel's bin, `∫_b max(0, u · n) dω / π`; a
//!    horizontal bin's share goes to the channel on the face's side of the horizon
//!    (both halves for a side face) ([`sweep::surface_weights`]); the downward pass
//!    emits its channels' share, the upward pass the rest. No rule depends on the
//!    light (the weights and `β` depend on the cell alone), so the sweep is linear.
//!    The outgoing light gains `F_c / μ_c`.
//!    **The default, [`MediumEmission::Profile`](lightgrid_core::MediumEmission)**,
//!    replaces the medium's flat source by one quadratic in height, `j(y) = Σ_m J_m
//!    P_m(y)` ([`profile`], where the rule is written out): steps 3 and phase 3's
//!    collisions also tally the height moments of where each segment's light collides;
//!    each batch of collisions becomes an isotropic source solving the cell's 3 × 3
//!    balance over both passes' segments (no `β` split); this pass's segments emit `Σ_m
//!    J_m E_m` along their paths, the point's own segment adds `Σ_m J_m M_m` to its
//!    light (step 7), and the same coefficients wait for the other direction's pass.
//!    Linear up to the output, which clamps at 0 light the quadratic sent below 0.
//! 6. **Re-absorb** (surfaces and the older medium rules). What the weights and
//!    `T_after` stopped, `σ_c ω_b/4π S - F_c`
//!    summed over the channels, was removed by the cell from light travelling along
//!    `u_c`: it is absorbed and scattered again as in steps 3–5, up to
//!    [`sweep::LOCAL_ROUNDS`] times within the pass; what is left waits for the next
//!    passes of both directions.
//! 7. **Outgoing and final light.** `O(x, c) = I T + Σ F_c / μ_c`. The light grid gets
//!    `I T_mid + F_c / (2 μ_c)` (before `T_after`) in bin `b_c`, summed over all passes
//!    (horizontal bins sum both halves), where `T_mid` is the transmittance to the
//!    point's own cell times `m = (1 − τ_own) / d_own` (`d_own` its optical depth, [`sweep::seg_mean`]), the
//!    mean transmittance over the path's segment through that cell: **a point's light is
//!    the mean of its paths' light over its own cell**, as the Monte Carlo reference
//!    tallies it (the cell's mean over its volume). In empty cells that is the light at
//!    the centre; in a medium cell of optical depth 3 lit from above the centre sees 0.22
//!    of the light entering, the cell 0.32 on average. (Until issue 13's measurement of
//!    the bench forest the point took the light at the cell's centre, `τ_own^½`: its
//!    points in media came out 1.5 % dark on average, 5.7 % RMS against the reference,
//!    now +1.0 % and 4.2 %; the forest's error under the sky alone fell from 0.0204 to
//!    0.0176, `cargo run --release -p xtask --example forest_error_parts -- 16 4000000
//!    "sky only"`.)
//!
//! The outgoing light of the last level leaves the grid (bottom, or top for upward
//! passes); light whose receiving point lies beyond a side leaves through the side.
//! Passes alternate downward, upward, downward, ... and stop after `max_passes`, or
//! (after at least one pass each way) when the scattered flux still waiting is at most
//! `tolerance` times the input flux. With diffusion acceleration ([`accel`]) the passes
//! may run differently from the first slow pair on (media emit one generation per
//! pair, a diffusion estimate of the later ones is added and taken back), converging to
//! the same light.
//!
//! **Energy.** Steps 1–7 conserve flux exactly: input (top, bottom, sides) = absorbed +
//! escaped (top, bottom, sides) + pending. [`Sweep::balance`] reports every term; the
//! tests hold it to 1e-4. The flux a level gathers and sends on is summed from its
//! light, except where it is known exactly ([`sweep::conserves_flux`]): a level without
//! material under periodic sides gathers what the level before it sent on (the
//! smoothing's weights sum to 1 and every source point is a grid point) and sends it
//! on unchanged, so both are booked as that flux (summed, they differed from it by the
//! `f32` values' rounding, which the balance booked as side loss; the sums took 5–12 %
//! of four passes over the 64³ canopy, whose computed levels are mostly empty).
//!
//! **Skipped work.** In a downward pass, levels above all material under a laterally
//! uniform boundary (uniform top, open or periodic sides) pass the top light on unchanged:
//! they are filled, not computed (`SweepStats::levels_copied`; the energy balance books
//! them as computed levels, what their gather takes from beyond open sides as side
//! input). In later downward passes they carry nothing. In upward passes those levels
//! only carry light up, and the sweep is linear: an upward pass that another follows
//! stops below them and leaves the light it sends on waiting; the next upward pass to
//! run to the top carries the sum through them once (or, where the sweep ends first or a
//! last downward pass follows, a run of its own). Not where boundary light enters them
//! from the sides in that pass (given sides, open sides under bottom light: the first
//! upward pass), so that the convergence test sees the same input. Four passes over a
//! 64³ canopy compute 166 levels (196 with the downward skip alone, 256 with neither;
//! 57–60 ms against 62–64 ms). Both skips change the light by
//! rounding only (`tests/skips.rs`: within 1e-5 of each value, the same passes and
//! balance, against `skip_empty_levels` off). Outputs not asked for are not computed:
//! with `outputs.bins` off the sweep keeps 7 floats per point instead of 78.
//!
//! ## Accuracy against the Monte Carlo reference
//!
//! The five canonical scenes of [`scenes`] on 12³ cells, multi-bounce defaults with
//! tolerance 1e-4, against 600 000 reference paths (seed 1); relative RMSE (see
//! [`scenes::Errors`]). The reference's own relative standard error is listed: the
//! empty scene's error is that noise alone (the sweep is exact there). The test
//! `sweep_against_reference_on_canonical_scenes` holds each figure within 10 %.
//!
//! | scene | average light | irradiance (6 axes) | reference noise | flat source | escape rule | seed's rule (removed) |
//! |-------|--------------:|--------------------:|----------------:|------------:|------------:|------------:|
//! | empty | 0.0114 | 0.0126 | 0.0117 | same | same | same |
//! | uniform fog | 0.0169 | 0.0202 | 0.0165 | 0.0167 / 0.0198 | 0.0430 / 0.0408 | 0.0392 / 0.0376 |
//! | dense block | 0.0306 | 0.0374 | 0.0117 | 0.0365 / 0.0451 | 0.0420 / 0.0491 | 0.0490 / 0.0583 |
//! | canopy | 0.0112 | 0.0144 | 0.0133 | 0.0128 / 0.0151 | 0.0256 / 0.0238 | 0.0184 / 0.0212 |
//! | canopy, 1-level ground | 0.0112 | 0.0146 | 0.0136 | 0.0130 / 0.0153 | 0.0256 / 0.0241 | 0.0183 / 0.0213 |
//!
//! (The dense block at the presets' smoothing 0.5, **Smoothing** below; 0.0374 / 0.0454
//! at 0.25, where the other rules' columns were measured.) With the default rule for
//! media (a quadratic source in height, [`profile`], issue
//! 13) and the channels' cosines the bins' mean cosines, the sweep's error on the fog
//! and the canopies is the reference's own noise (it was 0.0472 / 0.0469 on the fog
//! and 0.0269 / 0.0275 on the canopy with the escape rule and the step vectors'
//! cosines); the canopies are 12 % closer than with the flat source. The dense block
//! (cells of optical depth 3) is the one scene clearly above the noise, under both
//! source rules: its error is not the vertical profile within a cell (the profile rule
//! moved it by +0.0009). Points hold the mean of their cell (step 7): the dense block
//! was 0.0394 / 0.0490 with the centre's light. The older rules
//! (`SweepOptions::medium = MediumEmission::Escape`; the seed's, measured before it was
//! removed with the centre's light) are worse on every scene. Time (fastest of three,
//! 2-core VM, `examples/canonical.rs`, before phase 3's profile emission had its row
//! kernel): the fog 43 ms against 20 ms with the flat source and 21 ms with the escape
//! rule, the canopies 5.5 against 3.6 ms, the dense block 3.9 against 4.0 ms (fewer
//! passes); the source rules' third phase costs time on levels with media, and the
//! profile rule carries three coefficients a cell (fog 38 ms with the row kernel).
//!
//! **Smoothing.** The presets' smoothing weight (step 1's `w`,
//! [`lightgrid_core::SweepOptions::smoothing`]) is 0.5 since issue 15's thirteenth round
//! (0.25 before, a guess). Relative RMSE of the average light, 4 passes, against a
//! Monte Carlo reference (16³: 4 M paths, 24³: 8 M; `cargo run --release -p xtask
//! --example smoothing -- 16 4000000`, about a minute), at smoothing 0 / 0.25 / 0.35 /
//! 0.5 / 0.6:
//!
//! | scene | 16³ | 24³ |
//! |-------|-----|-----|
//! | forest (Kenney trees, sky and sun) | 0.0224 / 0.0179 / 0.0170 / **0.0165** / 0.0167 | 0.0174 / 0.0140 / 0.0134 / **0.0129** / 0.0130 |
//! | dense block | 0.0516 / 0.0350 / 0.0313 / 0.0278 / 0.0266 | 0.0581 / 0.0395 / 0.0358 / 0.0320 / 0.0305 |
//! | line source through a slit | 0.224 / 0.162 / 0.147 / 0.133 / 0.129 | 0.243 / 0.188 / 0.173 / 0.160 / 0.156 |
//! | checkerboard lattice | 0.702 / 0.532 / 0.491 / 0.450 / 0.434 | 0.456 / 0.355 / 0.331 / 0.305 / 0.294 |
//!
//! The forest's least error is at 0.5 at both sizes (against `cargo xtask bench`'s
//! cached reference: 0.0175 at 0.25, 0.0160 at 0.5); the other scenes it changes gain
//! up to 0.6 and beyond (the fog, the canopies and the empty scene are laterally
//! uniform: no change). One pass (16³): the lattice 0.393 → 0.315, the slit 0.474 →
//! 0.458, the dense block and the forest within 0.0004. Exact answers do not move (the
//! white furnace is exact at any smoothing; the Lambertian ground and the half-space
//! are laterally uniform). More smoothing blurs a shadow's edge by about `√(n w / 2)`
//! cells after `n` levels, which shrinks in metres as cells do. The bench's relMSE
//! (a per-point relative error, ε 1e-4: dim points count as much as bright ones, where
//! the RMSEs weigh by brightness) moves the other way on the dense
//! block (0.025 → 0.057) and the forest (0.0033 → 0.0043): more smoothing carries more
//! light into deep shadow; SMAPE falls with the RMSEs (dense block 0.0365 → 0.0322,
//! forest 0.0211 → 0.0198, the slit 0.250 → 0.184). Shadows of the sun (`cargo xtask
//! sun`, 24³, 1 M reference paths): the sun kept apart has the same error at 0.25 and
//! 0.5 (within 0.0002 at every elevation and azimuth), a single tree's shadow the same
//! azimuth (to 0.1°); the sun in the bins moves by −0.002 to +0.0013.
//!
//! Opaque surfaces emit with the exact Lambertian share of each bin (step 5) since the
//! exact-answer tests (`tests/exact.rs`: an infinite Lambertian ground reflects its
//! albedo to 1e-3, at any number of ground levels, sun angle or sky).
//!
//! `cargo run --release -p lightgrid-sweep-cpu --example canonical -- 16 1000000` prints the same
//! comparison with timings.
//!
//! ## Against exact answers
//!
//! [`exact`] holds problems whose answers share none of the sweep's assumptions, and
//! `cargo xtask exact` measures them (2-core VM, release):
//!
//! | problem | exact | sweep | escape rule, step cosines (before) |
//! |---------|------:|------:|------:|
//! | one-level Lambertian ground, albedo 0.3, zenith sun | 0.3000 | 0.3000 | 0.3000 |
//! | white furnace, random white blobs (pass-through 0.02–1), 12³, smoothing 0 / 0.25: largest deviation of the average light, of irradiance | 0 | 0.0 % / 0.0 % | 36 % / 81 %, 22 % / 45 % |
//! | white furnace, uniform white medium of pass-through 0.9 / 0.5 / 0.1: largest bin deviation | 0 | 0.0 / 0.0 / 0.0 % | 1.6 / 44 / 119 % |
//! | half-space albedo, w 0.1, cells of optical depth 0.05 / 0.69 / 3 | 0.0164 | +1.7 / +1.7 / +0.8 % | +8.0 / +10.1 / −3.1 % |
//! | half-space albedo, w 0.5, same cells | 0.1152 | +1.1 / +1.1 / +1.1 % | +6.3 / +8.7 / −4.0 % |
//! | half-space albedo, w 0.9, same cells | 0.4149 | +0.2 / +0.2 / +0.5 % | +3.1 / +5.1 / −1.5 % |
//! | half-space albedo, w 0.99, same cells | 0.7527 | −0.1 / −0.1 / −0.0 % | +1.0 / +1.9 / +0.2 % |
//! | the same four albedos with the flat source ([`MediumEmission::Source`](lightgrid_core::MediumEmission)), same cells | | +1.6 / −1.4 / −23 %, +1.1 / −0.4 / −15 %, +0.2 / +0.3 / +0.4 %, −0.1 / +0.1 / +2.5 % | |
//! | half-space under a uniform sky (diffuse albedo), w 0.1 / 0.5 / 0.9 / 0.99, cells of depth 3 (`examples/hs_diffuse.rs`) | 0.0087–0.73 | −0.1 / +1.4 / +1.6 / +0.6 %; flat source −47 / −39 / −18 / −5.4 % | |
//! | the same, cells of depth 0.05 (the channels' angular error under diffuse light) | | +4.5 / +3.5 / +1.7 / +0.6 %; flat source +4.4 / +3.5 / +1.7 / +0.6 % | |
//! | passes to tolerance 1e-4, slab of optical depth 100, w 0.5 / 0.9 / 0.99 / 0.999 | | 8 / 34 / 275 / over 1024 (flat source: 8 / 33 / 264 / over 1024) | 8 / 38 / 326 / over 400 |
//! | the same, accelerated ([`accel`]) | | 8 / 30 / 30 / 30 (flat source: 8 / 30 / 26 / 24) | |
//!
//! Surfaces are exact, and so is the white furnace in any medium: the source rules
//! ([`profile`], the default, and [`medium`]) emit from every path segment what the
//! cell's source sends along it, and the later segments of the path attenuate and collect it, so a path that
//! enters with its cells' source radiance leaves with it (the escape rule, which sent a
//! cell's light into its own points' paths alone, put too much into the long horizontal
//! channels and could not balance a horizontal path through several cells). The
//! half-space's remaining error in thin cells is the angular discretisation (26 bins:
//! `examples/do1d.rs` solves the same slab with a fine mesh and the channels as
//! ordinates: +1.65 / +1.07 / +0.20 / −0.06 % with the bins' mean cosines, +6.9 / +5.5 /
//! +2.7 / +0.9 % with the step vectors' cosines, which is where the old thin-cell error
//! came from). Where the rules stand:
//!
//! - **Thick dark cells: solved by the default rule, a quadratic source in height**
//!   ([`MediumEmission::Profile`](lightgrid_core::MediumEmission), [`profile`]: the
//!   collisions' height moments, each batch of scattered light an isotropic source
//!   solving the cell's 3 × 3 balance with its own re-collisions). The half-space is
//!   within 1.7 % at every albedo and every cell depth from 0.05 to 3: the channels' own
//!   angular error (`cargo run --release -p lightgrid-sweep-cpu --example hs_depths`; the 1-D model
//!   `examples/profile_slab.rs` predicts the same figures to 0.01 %). The white furnace
//!   stays exact and flux is conserved; the light is linear except where the quadratic
//!   dips below 0 and the output is clamped (26 of 319 488 values of the bench forest,
//!   none on the canonical scenes), and it is not a positive scheme: darkening one cell
//!   can brighten another value by about 1e-6 of the grid's brightest light
//!   (`tests/sweep.rs`, monotonicity; the flat rule is exactly monotone). Measured
//!   against the flat source: canonical scenes (table above) canopy 0.0112 / 0.0144
//!   against 0.0128 / 0.0151, dense block 0.0374 / 0.0454 against 0.0365 / 0.0451 (its
//!   error is not the vertical profile), fog the same; the bench forest at 4 passes
//!   (`cargo xtask bench`) 0.0175 against 0.0180 under sky and sun, but 0.0195 against
//!   0.0176 under the sky alone (`cargo run --release -p xtask --example
//!   forest_error_parts`; the same at 40 passes): under a uniform sky the flat rule's
//!   thick cells reflect far too little (−47 % at depth 3, albedo 0.1, table above)
//!   against the channels' angular error of +4.4 %, and in the forest the two errors
//!   partly cancel; the profile rule leaves the angular one (its air far from media
//!   +0.5 % bright, the flat rule's +0.0 %). That is the flat rule's one measured win
//!   besides speed, and why it stays an option. Cost on the CPU (2-core VM): the bench
//!   forest 16³, 4 passes, 5.9–6.0 ms against 3.7–3.8 ms (`cargo run --release -p xtask
//!   --example forest_profile -- 16 300 [profile|source]`), uniform fog 12³ 38 against
//!   19–20 ms, a 64³ canopy (two levels of media) at the same speed; its row kernels
//!   carry three source coefficients per cell instead of one and solve a 3 × 3 balance
//!   per cell and colour; the first sweep of a process computes the table nodes its
//!   media's depths read, about 0.3 ms each (a 8³ canopy's first sweep: 5.5 ms against
//!   2 ms after; all 1025 nodes, as the GPU's copy needs, take some 180 ms). Plain passes
//!   converge a little slower in thick white media (uniform furnace of pass-through
//!   0.02: 868 passes to 1e-7 against 524); [`accel`] runs it (slabs of cells of optical
//!   depth 1, depth 10 to 1000, albedo 0.5 to 0.999: at most 30 passes to 1e-4; cells
//!   of optical depth 3, albedo 0.999: 102 passes to 1e-5 against 794 plain, where the
//!   estimate's walk through thick cells models the flat rule). `sweep-gpu` runs it too.
//! - **Thick dark cells, the flat rule (the option).** A flat source in a cell of optical depth 3 lit from above
//!   sends too much of its light through the cell: `medium::split` moves the share of
//!   light that collided on its way down to the upward pass, which fixes albedos ≥ 0.9,
//!   but the emission within each pass is still spread flat over the cell's height, and
//!   the horizontal channels' lower segments lose it (−23 % at albedo 0.1). Tried and
//!   measured, not kept: an exponential profile fitted to the collisions' height (furnace
//!   +4 % / +10 %: the fit depends on the light, so the passes no longer add up), a
//!   linear profile (negative light in thick cells, or clamped: not linear), the first
//!   generation's escape by profile with later generations flat (−17 / −20 / −15 /
//!   −5 % at depth 3). The forest of `cargo xtask bench` has such cells: its error is
//!   0.0211 with this rule (0.0180 since points hold their cell's mean), 0.0175 with
//!   the escape rule (the centre's light). Where the light goes missing
//!   (`examples/do1d.rs`, second table, a 1D slab): at depth 3 a flat source is −48 /
//!   −41 / −23 / −7.5 % (w 0.1 / 0.5 / 0.9 / 0.99); with the *beam's* first collisions
//!   emitted from their exact profile, −0.5 / −8.2 / −8.8 / −3.0 %. Tried in this
//!   sweep, not kept yet: the cell source's first collisions emitted from their
//!   profile, and what the cell stops of them split by their own profile's height,
//!   give +1.0 / −0.5 / +3.3 / +2.7 % at depth 3 and within 1.7 % at depth 1.6 and
//!   below; the high albedos' excess is the later generations' split (+2.5 % at
//!   w 0.99 with this rule already).
//! - **Convergence.** The plain passes are source iteration; they slow down as the
//!   albedo nears 1 in thick media. [`Acceleration::Diffusion`](lightgrid_core::Acceleration)
//!   ([`accel`]) keeps the passes to 1e-4 between 8 and 30 for slabs of optical depth
//!   10 to 1000 and albedo 0.5 to 0.999 (`cargo xtask exact`: table and
//!   `target/bench/convergence.png`; albedo 0.999, depth 1000: 30 passes, 2.9 s,
//!   against over 1024 passes, 53 s; with the flat source 24 passes, 0.78 s, against
//!   over 1024, 34 s). It helps least where its diffusion estimate
//!   knows least: cells of optical depth 3 at albedo 0.99 (52 passes to 1e-5 against
//!   169), speckled random bright media with surfaces (0.64 to 1.16 times
//!   the plain passes, 0.88 on average, where it switches on), scenes whose
//!   light bounces mostly between surfaces (not accelerated).
//!
//! **Edge approximation.** The paths of points outside the grid are not traced, so light
//! leaving through a side skips the (at most two) edge cells its path would still cross.
//! Periodic boundaries have no edge.

pub mod accel;
pub mod exact;
pub mod isa;
pub mod medium;
pub mod profile;
pub mod reference;
pub mod scenes;
pub mod sky;
pub mod sun;
pub mod sun_measure;
pub mod sweep;

pub use lightgrid_core::CellSource;
pub use sky::{ClearSky, EnvMap, SkyBins, SkyError, Sun};
pub use sun::SunTransmittance;
pub use sweep::{EnergyBalance, Sweep, run, run_with_source};

use lightgrid_core::glam::Vec3;
use lightgrid_core::light::luminance;
use lightgrid_core::{
    AverageLight, BinLight, Boundary, DominantDir, Grid, MaterialGrid, SideBoundary, SweepError,
    SweepOptions, SweepOutput, Sweeper, TopBoundary,
};

/// The light of a grid under the sky and under the sun, swept separately with white
/// light: since the sweep is linear, any sky and sun colour and intensity is a multiply
/// away ([`Responses::combine`]), with no new sweep.
#[derive(Debug, Clone)]
pub struct Responses {
    /// Response to the sky (`SkyBins` as given).
    pub sky: Sweep,
    /// Response to the sun (`Sun::bins` as given).
    pub sun: Sweep,
}

/// Sweeps `material` once under `sky` and once under `sun` (both usually white).
pub fn sweep_responses(
    material: &MaterialGrid,
    sky: &SkyBins,
    sun: &BinLight,
    sides: SideBoundary,
    options: &SweepOptions,
) -> Result<Responses, SweepError> {
    let (sky_b, sun_b) = response_boundaries(sky, sun, sides);
    Ok(Responses {
        sky: run(material, &sky_b, options)?,
        sun: run(material, &sun_b, options)?,
    })
}

/// The boundaries of the sky response and of the sun response.
fn response_boundaries(sky: &SkyBins, sun: &BinLight, sides: SideBoundary) -> (Boundary, Boundary) {
    let sky_b = Boundary {
        top: TopBoundary::Uniform(Box::new(sky.top)),
        bottom: sky.bottom,
        sides: sides.clone(),
    };
    let sun_b = Boundary {
        top: TopBoundary::Uniform(Box::new(*sun)),
        bottom: BinLight::ZERO,
        sides,
    };
    (sky_b, sun_b)
}

impl Responses {
    /// The light under a sky of colour `sky` and a sun of colour `sun` (per-channel
    /// multipliers of the white responses). Bins and averages are exact. The dominant
    /// direction is exact from the bins when they were computed; without bins it is the
    /// luminance-weighted blend of the two responses' directions, exact for grey
    /// materials.
    pub fn combine(&self, sky: Vec3, sun: Vec3) -> SweepOutput {
        combine_outputs(&self.sky.output, &self.sun.output, sky, sun)
    }
}

/// The sky and sun responses of any sweeper (CPU or GPU): `(sky, sun)` outputs, to be
/// combined by [`combine_outputs`].
pub fn responses_with(
    sweeper: &mut dyn Sweeper,
    material: &MaterialGrid,
    sky: &SkyBins,
    sun: &BinLight,
    sides: SideBoundary,
    options: &SweepOptions,
) -> Result<(SweepOutput, SweepOutput), SweepError> {
    let (sky_b, sun_b) = response_boundaries(sky, sun, sides);
    Ok((
        sweeper.sweep(material, &sky_b, options)?,
        sweeper.sweep(material, &sun_b, options)?,
    ))
}

/// Combines a sky response `a` and a sun response `b` under colours `sky` and `sun`
/// (see [`Responses::combine`]).
pub fn combine_outputs(a: &SweepOutput, b: &SweepOutput, sky: Vec3, sun: Vec3) -> SweepOutput {
    let bins = a.bins.as_ref().zip(b.bins.as_ref()).map(|(x, y)| {
        Grid::from_trusted(
            *x.desc(),
            x.data()
                .iter()
                .zip(y.data())
                .map(|(p, q)| *p * sky + *q * sun)
                .collect(),
        )
    });
    let average = a.average.as_ref().zip(b.average.as_ref()).map(|(x, y)| {
        Grid::from_trusted(
            *x.desc(),
            x.data()
                .iter()
                .zip(y.data())
                .map(|(p, q)| AverageLight(p.0 * sky + q.0 * sun))
                .collect(),
        )
    });
    let dominant = match (&bins, &average) {
        (Some(g), _) if a.dominant.is_some() => Some(g.dominant_grid()),
        (_, Some(_)) => a
            .dominant
            .as_ref()
            .zip(b.dominant.as_ref())
            .zip(a.average.as_ref().zip(b.average.as_ref()))
            .map(|((dx, dy), (ax, ay))| {
                Grid::from_trusted(
                    *dx.desc(),
                    (0..dx.data().len())
                        .map(|i| {
                            let wx = luminance(ax.data()[i].0 * sky);
                            let wy = luminance(ay.data()[i].0 * sun);
                            let w = wx + wy;
                            DominantDir(if w > 0.0 {
                                ((dx.data()[i].0 * wx + dy.data()[i].0 * wy) / w)
                                    .clamp_length_max(1.0)
                            } else {
                                Vec3::ZERO
                            })
                        })
                        .collect(),
                )
            }),
        _ => None,
    };
    SweepOutput {
        bins,
        average,
        dominant,
        stats: a.stats,
        resident: None,
    }
}

/// The reference sweeper (multithreaded through rayon's global pool).
///
/// A sweeper rebuilding light every frame should hand each output it is done with back
/// through [`CpuSweeper::recycle`]: the next sweep of the same grid size writes into that
/// memory instead of fresh pages (at 64³ with 26 bins, 82 MB the kernel would otherwise
/// fault in and zero: some 13 ms on the 2-core VM).
///
/// ```
/// use lightgrid_core::{BinLight, Boundary, Sweeper, SweepOptions};
/// use lightgrid_core::glam::Vec3;
/// use lightgrid_sweep_cpu::{CpuSweeper, scenes::Scene};
///
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let (material, boundary) = Scene::Canopy.build(16);
/// let mut sweeper = CpuSweeper::new();
/// let options = SweepOptions::multi_bounce();
/// let first = sweeper.sweep(&material, &boundary, &options)?;
/// let total = first.bins.as_ref().unwrap().data()[0].total();
/// sweeper.recycle(first); // its memory holds the next frame's light
/// let second = sweeper.sweep(&material, &boundary, &options)?;
/// assert_eq!(second.bins.as_ref().unwrap().data()[0].total(), total);
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Clone, Default)]
pub struct CpuSweeper {
    last_balance: Option<EnergyBalance>,
    spare: sweep::Spare,
}

impl CpuSweeper {
    /// A new sweeper.
    pub fn new() -> Self {
        Self::default()
    }
    /// The energy balance of the last successful sweep.
    pub fn last_balance(&self) -> Option<&EnergyBalance> {
        self.last_balance.as_ref()
    }
    /// Takes back an output this sweeper (or another) returned, for its memory: the
    /// next sweep of a grid with as many points writes into it (its values are all
    /// overwritten). Outputs of another size are kept until one of their size comes.
    pub fn recycle(&mut self, output: SweepOutput) {
        if let Some(b) = output.bins {
            self.spare.bins = b.into_data();
        }
        if let Some(a) = output.average {
            self.spare.average = a.into_data();
        }
        if let Some(d) = output.dominant {
            self.spare.dominant = d.into_data();
        }
    }
}

/// The `tracing` span of one sweep (debug level: a hierarchy runs hundreds a second).
fn sweep_span(material: &MaterialGrid, options: &SweepOptions) -> tracing::Span {
    tracing::debug_span!(
        "cpu sweep",
        points = material.desc().point_count(),
        passes = options.max_passes
    )
}

impl Sweeper for CpuSweeper {
    fn name(&self) -> &'static str {
        "cpu"
    }
    fn sweep(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        let _span = sweep_span(material, options).entered();
        let s = sweep::run_reusing(material, boundary, None, options, true, &mut self.spare)?;
        self.last_balance = Some(s.balance);
        Ok(s.output)
    }
    fn sweep_with_source(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        source: &CellSource,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        let _span = sweep_span(material, options).entered();
        let s = sweep::run_reusing(
            material,
            boundary,
            Some(source),
            options,
            true,
            &mut self.spare,
        )?;
        self.last_balance = Some(s.balance);
        Ok(s.output)
    }
    fn sweep_sun(
        &mut self,
        material: &MaterialGrid,
        sun: &lightgrid_core::SunBoundary<'_>,
        options: &SweepOptions,
    ) -> Result<lightgrid_core::SunResponse, SweepError> {
        sun::sweep_sun(self, material, sun, options)
    }
}
