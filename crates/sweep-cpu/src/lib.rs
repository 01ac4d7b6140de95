//! # sweep-cpu
//!
//! The reference light-flow sweep of lightgrid, multithreaded with rayon, and the sun's
//! exact transmittance. **This page is the specification of the sweep**: `sweep-gpu` implements
//! exactly these formulas. What measures it (the Monte Carlo reference, the canonical
//! scenes, the exact problems, the sun's measures) is the crate `lightgrid-measure`,
//! whose tests, examples and benchmark hold the figures below.
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
//! Light facing down over the ground is read exactly across the horizon with the
//! horizon halves (`Outputs::horizon`, a `SplitLightGrid`): over an infinite ground of
//! albedo 0.3 under that sky, `0.3 π`; the 26 bins alone read 13 % more.
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use lightgrid_core::glam::{UVec3, Vec3};
//! use lightgrid_core::{
//!     BinLight, Boundary, GridDesc, LightField, Material, MaterialGrid, SideBoundary,
//!     SplitLightGrid, SweepOptions,
//! };
//! let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 6, 4))?;
//! let cells = (0..desc.point_count())
//!     .map(|i| if i < desc.level_len() { Material::opaque(Vec3::splat(0.3)) } else { Material::EMPTY })
//!     .collect();
//! let material = MaterialGrid::new(desc, cells)?;
//! let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
//! let boundary = Boundary { sides: SideBoundary::Periodic, ..Boundary::open_sky(sky) };
//! let mut options = SweepOptions::multi_bounce();
//! options.outputs = options.outputs.with_horizon();
//! let out = lightgrid_sweep_cpu::run(&material, &boundary, &options)?.output;
//! let field = SplitLightGrid::new(out.bins.unwrap(), out.horizon.unwrap())?;
//! let p = Vec3::new(2.0, 2.0, 2.0);
//! let down = field.irradiance(p, Vec3::NEG_Y)?.x;
//! assert!((down / (0.3 * std::f32::consts::PI) - 1.0).abs() < 1e-3);
//! let even = field.bins().irradiance(p, Vec3::NEG_Y)?.x;
//! assert!(even > 1.1 * down);
//! # Ok(())
//! # }
//! ```
//!
//! ## What is here
//!
//! * [`run`] / [`CpuSweeper`]: the sweep (implements `lightgrid_core::Sweeper`), with its
//!   [`EnergyBalance`].
//! * Skies and the sun's disc are the crate `lightgrid-sky` (uniform and analytic clear
//!   skies, EXR environment maps, all integrated over the bins); [`sweep_responses`]
//!   keeps sun and sky apart so their
//!   colours change by a multiply ([`Responses::combine`]).
//! * [`gather`]: a cell source's first scatterings gathered by rays instead of swept
//!   (`SweepOptions::gather`): a low sun's light in a patchy canopy right cell by cell,
//!   at a bake's cost.
//! * [`quadrature`]: Gauss–Legendre nodes for the medium rule's tables.
//! * In `lightgrid-measure`: `reference` (the Monte Carlo reference), `scenes` (canonical
//!   scenes and error measures), `exact` (problems with exact answers), `sun_measure`.
//! * From the shell, the `lightgrid` command (crate `lightgrid`):
//!   `lightgrid scene canopy -o m.lgrid`,
//!   `lightgrid sweep m.lgrid -o light.lgrid --sky clear --sun 3000 --sun-elevation 40`
//!   (or `--sky-exr sky.exr`), `lightgrid reference m.lgrid -o ref.lgrid --paths 2000000`.
//!
//! ## Speed
//!
//! Three ways to run the same sweep: **recycled** (`CpuSweeper::sweep` after
//! [`CpuSweeper::recycle`]: what a renderer rebuilding light every frame runs),
//! **fresh** ([`run`]: new output memory each time) and the **scalar oracle**
//! ([`sweep::run_scalar`], the steps below written out one by one). The fast path equals
//! the oracle bit for bit in the light, to `f64` rounding in the energy balance
//! (`tests/fast_path.rs`: random sparse and dense grids, every boundary mode, cell
//! sources, any passes).
//!
//! Figures of record, 2-core x86-64 VM (AMD EPYC; a figure moves ±20 % with the VM's
//! spells, so each comes with its command):
//!
//! | case | recycled | fresh | scalar oracle |
//! |------|---------:|------:|--------------:|
//! | 64³ canopy, 26 bins, 1 downward pass | 9.75 ms (26.9 M points/s) | 18.3 ms (14.3 M/s) | 94.8 ms |
//! | 64³ canopy, 26 bins, 4 passes | 32.3 ms (8.1 M/s) | 47.7 ms (5.5 M/s) | 411 ms |
//! | 16 × 64 × 16, 26 bins, 1 / 4 passes | 0.87 / 3.08 ms (18.9 / 5.3 M/s) | | |
//! | bench forest 16³, 4 passes (two threads / one) | 1.9–2.0 / 3.3–3.5 ms | | |
//!
//! Commands: `cargo bench -p lightgrid-measure` (criterion: the canopy rows),
//! `cargo run --release -p lightgrid-measure --example throughput` (quick),
//! `cargo run --release -p xtask --example forest_profile -- 16 300` (the forest;
//! `RAYON_NUM_THREADS=1` for one thread), and `cargo xtask bench` for time against
//! error (the forest's headline reaches 0.0160 in about 2 ms, some 400× faster than
//! Monte Carlo to the same error). A process's first sweep also builds the nodes of the
//! profile rule's tables that its media read ([`profile`], about 0.2 ms a node).
//!
//! **Vector instructions.** The row kernels are compiled for the baseline and for
//! x86-64-v3 and pick the widest the CPU has at run time ([`isa`];
//! `LIGHTGRID_SIMD=baseline` keeps them on SSE2), with the same results bit for bit
//! (`measure/tests/dispatch.rs`). Against a whole build for x86-64-v3 of the code before the
//! dispatch (the old `-C target-cpu=x86-64-v3`), the forest 16³ runs in the same time
//! within the machine's noise: 0.98–1.03× on one thread and 0.99–1.00× on two (fastest
//! and median of 300 sweeps, medians of per-round ratios over 8–16 alternating rounds,
//! three runs in both orders, `forest_profile 16 300`, 2026-11-27). The build just
//! before the phases took argument structs still took 1.04–1.05× on one thread (1.00×
//! on two), on the same day (it runs 0.3 % fewer instructions: callgrind, 20 sweeps,
//! 2.437 G against 2.444 G; the difference is the code's layout, not its work). The
//! per-level set-up (emission lanes and
//! budgets, the rows' flux sums) and the profile tables (a fifth fewer instructions for
//! a process's first sweep) run on the vector path too. The baseline path takes about
//! 1.2× on the forest. A crate that depends on this one gets the
//! same dispatch with no flags.
//!
//! **Memory.** [`sweep::sweep_bytes`] gives a sweep's working memory beside its output
//! (14.3 MB for a 16³ grid, most of it room for the cell profiles of as many distinct
//! depths as it could hold; 112 MB at 32³, 319 MB at 64³).
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
//!    or the bottom boundary (upward), beyond the sides too (a `PerPoint` top at the
//!    column, or the nearest it holds). Source points beyond the sides take: open — the
//!    top (downward) or bottom (upward) boundary light, as if the world around were empty;
//!    periodic — the wrapped point; given — the halo value of that point and level
//!    (for a level inside the grid; above the top or below the bottom the virtual
//!    level's, as above: the halo's top level holds light that crossed that level's
//!    cells, which a path from above has not; `tests/handover.rs`), its horizontal bins split across the horizon as given
//!    (`SideBoundary::GivenHalves`: the downward pass takes the given downward half,
//!    clamped to the bin; [`sweep::channel_value_halves`]), else by their neighbours
//!    (`BinLight::horizon_share`: the downward pass takes
//!    `h · B(x,−1,z) / (B(x,−1,z) + B(x,1,z))`, the upward pass the rest; exact where the
//!    radiance is constant over each hemisphere; [`sweep::channel_value`]). Boundary light enters only
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
//!    furnace, measured in `lightgrid_measure::exact`, and is closer on thick dark cells. The seed's
//!    `(A, B) = ((1 + p)/2, (1 − p)/2)` was removed: worse everywhere measured.) A
//!    cell with `p = 0`
//!    is opaque: its faces that border non-opaque cells, the sky above the top or the
//!    outside through an open side are diffuse surfaces (below the bottom level is
//!    ground, never a surface; beyond a given side the world goes on as it is at the
//!    side, [`sweep::exposure`]; periodic sides wrap), and it
//!    sends `F_c = W_c S · T_after` with fixed weights `W_c`, the mean over those faces
//!    of the exact Lambertian share of the channel's bin, `∫_b max(0, u · n) dω / π`; a
//!    horizontal bin's share goes to the channel on the face's side of the horizon
//!    (both halves for a side face) ([`sweep::surface_weights`]); the downward pass
//!    emits its channels' share, the upward pass the rest. An opaque cell with no
//!    such face lies inside a solid: what reaches it (light a path's long step carried
//!    past the solid's surface cell) is absorbed there, its reflectance taken as 0
//!    ([`sweep::swept_reflectance`]), not scattered on through the solid. No rule
//!    depends on the light (the weights and `β` depend on the cell alone), so the sweep
//!    is linear.
//!    The outgoing light gains `F_c / μ_c`.
//!    **The default, [`MediumEmission::Profile`](lightgrid_core::MediumEmission)**,
//!    replaces the flat source of a medium cell of optical depth at least
//!    [`medium::PROFILE_MIN_DEPTH`] (0.3; thinner cells keep the flat source, as close
//!    to the exact answers there, [`medium::profiled`]) by one quadratic in height, `j(y) = Σ_m J_m
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
//! with `outputs.bins` off the sweep keeps 7 floats per point instead of 78; with
//! `outputs.horizon` on it keeps 102, the downward passes' horizontal channels apart
//! (`tests/horizon.rs`; 59 → 70 ms on the 64³ canopy, four passes, recycled).
//!
//! ## Accuracy against the Monte Carlo reference
//!
//! The five canonical scenes of `lightgrid_measure::scenes` on 12³ cells, multi-bounce defaults with
//! tolerance 1e-4, against 600 000 reference paths (seed 1); relative RMSE (see
//! `lightgrid_measure::scenes::Errors`). The reference's own relative standard error is listed: the
//! empty scene's error is that noise alone (the sweep is exact there). The test
//! `sweep_against_reference_on_canonical_scenes` (in `lightgrid-measure`) measures the
//! noise the same way (a second reference against the first) and holds the sweep's own
//! error, `√(e² − n²)`, to fixed targets: 0.5 % where the sweep is exact, 1.5 % in
//! smooth media, 4 % in the dense block (measured: 0.0 / 0.0 %, fog 1.3 / 1.3 %,
//! canopies 0.0 / 0.5 %, dense block 2.9 / 3.5 %).
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
//! 13) and the channels' cosines the bins' mean cosines, the sweep's error on the
//! canopies is the reference's own noise, on the fog about 1.3 % beyond it (it was 0.0472 / 0.0469 on the fog
//! and 0.0269 / 0.0275 on the canopy with the escape rule and the step vectors'
//! cosines); the canopies are 12 % closer than with the flat source. The dense block
//! (cells of optical depth 3) is the one scene clearly above the noise, under both
//! source rules: its error is not the vertical profile within a cell (the profile rule
//! moved it by +0.0009). Points hold the mean of their cell (step 7): the dense block
//! was 0.0394 / 0.0490 with the centre's light. The older rules
//! (`SweepOptions::medium = MediumEmission::Escape`; the seed's, measured before it was
//! removed with the centre's light) are worse on every scene. Time (fastest of three,
//! 2-core VM, `measure/examples/canonical.rs`, before phase 3's profile emission had its row
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
//! exact-answer tests (`measure/tests/exact.rs`: an infinite Lambertian ground reflects its
//! albedo to 1e-3, at any number of ground levels, sun angle or sky).
//!
//! `cargo run --release -p lightgrid-measure --example canonical -- 16 1000000` prints the same
//! comparison with timings.
//!
//! ## Against exact answers
//!
//! `lightgrid_measure::exact` holds problems whose answers share none of the sweep's assumptions, and
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
//! | half-space under a uniform sky (diffuse albedo), w 0.1 / 0.5 / 0.9 / 0.99, cells of depth 3 (`measure/examples/hs_diffuse.rs`) | 0.0087–0.73 | −0.1 / +1.4 / +1.6 / +0.6 %; flat source −47 / −39 / −18 / −5.4 % | |
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
//! `measure/examples/do1d.rs` solves the same slab with a fine mesh and the channels as
//! ordinates: +1.65 / +1.07 / +0.20 / −0.06 % with the bins' mean cosines, +6.9 / +5.5 /
//! +2.7 / +0.9 % with the step vectors' cosines, which is where the old thin-cell error
//! came from). Where the rules stand:
//!
//! - **Thick dark cells: solved by the default rule, a quadratic source in height**
//!   ([`MediumEmission::Profile`](lightgrid_core::MediumEmission), [`profile`]: the
//!   collisions' height moments, each batch of scattered light an isotropic source
//!   solving the cell's 3 × 3 balance with its own re-collisions). The half-space is
//!   within 1.7 % at every albedo and every cell depth from 0.05 to 3: the channels' own
//!   angular error (`cargo run --release -p lightgrid-measure --example hs_depths`; the 1-D model
//!   `measure/examples/profile_slab.rs` predicts the same figures to 0.01 %). The white furnace
//!   stays exact and flux is conserved; the light is linear except where the quadratic
//!   dips below 0 and the output is clamped (26 of 319 488 values of the bench forest,
//!   none on the canonical scenes), and it is not a positive scheme: darkening one cell
//!   can brighten another value by about 1e-6 of the grid's brightest light
//!   (`measure/tests/sweep.rs`, monotonicity; the flat rule is exactly monotone). Measured
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
//!   per cell and colour; its tables' nodes ship with the crate (computing one took
//!   about 0.15 ms; all 1025, as the GPU's copy needs, 60 ms on two threads, read in 4).
//!   Plain passes
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
//!   (`measure/examples/do1d.rs`, second table, a 1D slab): at depth 3 a flat source is −48 /
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
//! Periodic boundaries have no edge. With given sides and
//! [`SweepOptions::halo_paths`](lightgrid_core::SweepOptions::halo_paths) they are,
//! where they cross the grid's cells (the horizontal channels of the halo's points
//! within two cells of a side; `sweep::ring_paths`): a path entering the grid starts
//! from the halo's light at its point (the mean of the point's cell, taken as the light
//! at its centre: exact where the halo's cells are empty) and crosses the grid's media
//! after the centre (steps 2, 3 and the medium's emission of step 5; opaque cells do
//! not stop it, as the exposure rule has the world beyond the side go on as it is there,
//! a surface whose light leaves over its level-mates), and the next level gathers its
//! outgoing light in place of the halo value; a path leaving the grid gathers as the
//! grid's points do and crosses the grid's cells before its point (steps 2 and 3), what
//! they emit into it leaving. Not traced: what a later cell of such a path stops of
//! what an earlier one emitted into it (step 5's collection), which waits for the next
//! passes (`tests/handover.rs`: a crop of fog handed its sweep's own light, exact in one
//! pass, within 2e-4 of the brightest bin in two, 7 % off untraced). A halo value is
//! its cell's mean; where the caller gives the halo's cells
//! ([`SideBoundary::GivenHalves`]'s `cells`) it is carried through them before the
//! sweep, from the mean to where its bin's path leaves the cell and through the halo's
//! cells after it ([`lightgrid_core::halo_carry`]); the grid's own points' paths still
//! cross the halo's cells before the grid's as empty space.

pub mod accel;
pub mod beam;
pub mod gather;
pub mod isa;
pub mod medium;
pub mod profile;
pub mod quadrature;
pub mod sun;
pub mod sweep;

pub use lightgrid_core::CellSource;
pub use sun::SunTransmittance;
pub use sweep::{EnergyBalance, Sweep, run, run_with_source};

use lightgrid_core::glam::Vec3;
use lightgrid_core::light::luminance;
use lightgrid_core::{
    AverageLight, BinLight, Boundary, DominantDir, Grid, MaterialGrid, SideBoundary, SweepError,
    SweepOptions, SweepOutput, Sweeper, TopBoundary,
};
use lightgrid_sky::SkyBins;

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
    let bins = mix(a.bins.as_ref(), b.bins.as_ref(), sky, sun);
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
    let horizon = mix(a.horizon.as_ref(), b.horizon.as_ref(), sky, sun);
    SweepOutput {
        bins,
        horizon,
        average,
        dominant,
        stats: a.stats,
        resident: None,
    }
}

/// `x * sky + y * sun` point by point, where both grids are there.
fn mix<T>(x: Option<&Grid<T>>, y: Option<&Grid<T>>, sky: Vec3, sun: Vec3) -> Option<Grid<T>>
where
    T: Copy + std::ops::Mul<Vec3, Output = T> + std::ops::Add<Output = T>,
{
    x.zip(y).map(|(x, y)| {
        Grid::from_trusted(
            *x.desc(),
            x.data()
                .iter()
                .zip(y.data())
                .map(|(p, q)| *p * sky + *q * sun)
                .collect(),
        )
    })
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
/// use lightgrid_core::glam::UVec3;
/// use lightgrid_core::{GridDesc, Material, MaterialGrid};
/// use lightgrid_sweep_cpu::CpuSweeper;
///
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// // Foliage over a ground level, under a uniform sky.
/// let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(16))?;
/// let leaf = Material { reflectance: Vec3::new(0.1, 0.4, 0.1), pass: 0.6 };
/// let cells = (0..desc.point_count())
///     .map(|i| match desc.coords(i).unwrap().y {
///         0 => Material::opaque(Vec3::splat(0.3)),
///         6..=9 => leaf,
///         _ => Material::EMPTY,
///     })
///     .collect();
/// let material = MaterialGrid::new(desc, cells)?;
/// let boundary = Boundary::open_sky(BinLight::uniform(Vec3::ONE).split_vertical().0);
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
        if let Some(h) = output.horizon {
            self.spare.horizon = h.into_data();
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
    /// A new CPU sweeper with memory of its own (sweeps are deterministic: the same
    /// results bit for bit on any thread).
    fn carries_halo_paths(&self) -> bool {
        true
    }
    fn fork(&self) -> Option<Box<dyn Sweeper + Send + Sync>> {
        Some(Box::new(CpuSweeper::new()))
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
        gather::sweep_gathered(material, boundary, source, options, |src, o| {
            let s = sweep::run_reusing(material, boundary, Some(src), o, true, &mut self.spare)?;
            self.last_balance = Some(s.balance);
            Ok(s.output)
        })
    }
    fn sweep_sun(
        &mut self,
        material: &MaterialGrid,
        sun: &lightgrid_core::SunBoundary<'_>,
        options: &SweepOptions,
    ) -> Result<lightgrid_core::SunResponse, SweepError> {
        sun::sweep_sun(self, material, sun, options)
    }
    fn sweep_with_sun(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        sun: &lightgrid_core::SunBeam<'_>,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        sun::sweep_with_sun(self, material, boundary, sun, options)
    }
    fn sun_transmittance(
        &mut self,
        material: &MaterialGrid,
        sun: &lightgrid_core::SunBoundary<'_>,
    ) -> Result<lightgrid_core::Grid<f32>, SweepError> {
        Ok(sun::transmittance(material, sun)?)
    }
}
