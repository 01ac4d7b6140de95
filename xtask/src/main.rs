//! `cargo xtask <task>`: project chores.
//!
//! * `bench [--full] [--scene NAME]... [--no-gpu] [--out DIR]`: run time against error
//!   for the sweep (CPU, GPU) and Monte Carlo on every bench scene, against a cached long
//!   Monte Carlo reference, and the work the library skips; writes a table, JSON and a
//!   log-log plot (see `bench` module docs). The quick default takes a few minutes on two
//!   cores; `--full` uses larger grids and a longer reference.
//! * `exact [--max-passes N]`: the sweep against problems with exact answers (white
//!   furnace, Lambertian ground, Chandrasekhar's half-space albedo) and passes to
//!   tolerance against optical depth and albedo (`lightgrid_measure::exact`); writes
//!   `target/bench/exact.txt`.
//! * `frame [--node-points N] [--frames N] [--elevation DEG]... [--gpu] [--bare-skip] [--no-casters] [--skip-finest-sun] [--sun-with-sky] [--even] [--budget-ms MS] [--budget-points N] [--neighbour-halo] [--halo-paths] [--passes N] [--tolerance T] [--flat-source] [--path forest|edge] [--mc-probes N] [--mc-paths N]`:
//!   the hierarchy along a camera path, timed by stage and measured against one
//!   full-resolution sweep (see `xtask::frame`); writes `target/bench/frame.{txt,json,png}`.
//! * `figures [--assemble]`: the README's figures measured in one go (bench forest,
//!   exact, sun, frame, throughput, first sweep, the demo), each alone; writes
//!   `docs/figures.md` and the README's table (see `xtask::figures`).
//! * `fuzz [--inputs N] [--target NAME]... [--seed S]`: every reader of user files (grid,
//!   scene, volume, gltf, exr, png) over N generated inputs (default one million per
//!   target): panics, slow inputs, peak memory (see `xtask::fuzz`). Writes
//!   `target/fuzz/fuzz.{txt,json}`; exits non-zero if any panic escaped or any input was
//!   slow.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};

use xtask::{bench, convergence, sun};

#[derive(Debug, Parser)]
#[command(about = "lightgrid project chores")]
struct Args {
    #[command(subcommand)]
    task: Task,
}

#[derive(Debug, Subcommand)]
enum Task {
    /// Run time against error, and the skipped work.
    Bench {
        /// Larger grids, a longer reference and more Monte Carlo path counts.
        #[arg(long)]
        full: bool,
        /// Only this scene (repeatable): empty, uniform-fog, dense-block, canopy,
        /// line-source, lattice, forest.
        #[arg(long = "scene")]
        scenes: Vec<String>,
        /// Leave the GPU sweeper out.
        #[arg(long)]
        no_gpu: bool,
        /// Output folder (default target/bench).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// The sweep against exact answers (white furnace, Lambertian ground, Chandrasekhar's
    /// half-space albedo) and its passes to tolerance against optical depth and albedo.
    Exact {
        /// Most passes per case.
        #[arg(long, default_value_t = 1024,
              value_parser = clap::value_parser!(u32).range(1..=lightgrid_core::MAX_PASSES as i64))]
        max_passes: u32,
    },
    /// The sun kept apart against the sun in the bins, against the Monte Carlo
    /// reference: the bench forest at several sun elevations and azimuths, and a single
    /// tree's shadow direction (target/bench/sun.txt, sun.png).
    Sun {
        /// Cells a side of the forest.
        #[arg(long, default_value_t = 24)]
        n: u32,
        /// Reference paths per case.
        #[arg(long, default_value_t = 1_000_000)]
        paths: u64,
    },
    /// The hierarchy frame by frame along a camera path: stage times, points swept, and
    /// the error of the light the renderer samples against one full-resolution sweep of
    /// the region, for sky, sun and both at several sun elevations
    /// (target/bench/frame.{txt,json,png}).
    Frame {
        /// Points across a node grid.
        #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(2..=1024))]
        node_points: u32,
        /// Frames along the path.
        #[arg(long, default_value_t = 24, value_parser = clap::value_parser!(u32).range(1..=10_000))]
        frames: u32,
        /// Sun elevations in degrees (repeatable; default 10, 30 and 60).
        #[arg(long = "elevation")]
        elevations: Vec<f32>,
        /// Sweep with the GPU sweeper (the reference stays on the CPU).
        #[arg(long)]
        gpu: bool,
        /// No finer grids over bare ground (the bare-ground skip, off by default).
        #[arg(long)]
        bare_skip: bool,
        /// No sun's casters (LodSkips::sun_casters): a node's direct sun is marched past
        /// the built nodes through coarser material, for comparison.
        #[arg(long)]
        no_casters: bool,
        /// The finest depth's scattered sun read from the coarser grids, not swept
        /// (LodSkips::finest_scattered_sun, off by default), for comparison.
        #[arg(long)]
        skip_finest_sun: bool,
        /// Every grid sweeps the sun's first collisions with its sky
        /// (HierarchyParams::sun_with_sky, off by default; what the viewer runs on the
        /// CPU): only "both" and the direct sun are then measured apart.
        #[arg(long)]
        sun_with_sky: bool,
        /// Keep no horizon halves: every grid's horizontal bins read as even across the
        /// horizon (in the hierarchy and the reference sweep), for comparison.
        #[arg(long)]
        even: bool,
        /// A frame's time budget in milliseconds (HierarchyParams::budget_ms; default:
        /// none, the points budget alone).
        #[arg(long)]
        budget_ms: Option<f32>,
        /// Points a frame may sweep (HierarchyParams::budget_points; default: the node's
        /// points across with its apron squared times 96, two 48-level nodes)
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
        budget_points: Option<u64>,
        /// Side halos read the nodes of their depth before them where built
        /// (HierarchyParams::neighbour_halo, off by default), for comparison
        #[arg(long)]
        neighbour_halo: bool,
        /// The halo's paths traced through the nodes' edge cells
        /// (SweepOptions::halo_paths, off by default), for comparison
        #[arg(long)]
        halo_paths: bool,
        /// Halo points near bare ground read the coarser grid where they are
        /// (HierarchyParams::halo_ground_lift off; on by default), for comparison
        #[arg(long)]
        no_ground_lift: bool,
        /// Where the nodes' sweeps take their halo's cells from
        /// (HierarchyParams::halo_cells: off, coarser (the default) or composed)
        #[arg(long, default_value = "coarser", value_parser = ["off", "coarser", "composed"])]
        halo_cells: String,
        /// Under a time budget, a new node whose sun's casters wait marches its direct
        /// sun at once through those held (HierarchyParams::march_before_casters, off
        /// by default)
        #[arg(long)]
        march_before_casters: bool,
        /// The ground's partly covered cells take its colour as their albedo
        /// (ComposeParams::band_albedo = GroundBand::Colour, the composition before
        /// GroundBand::Reflecting, the default), in the hierarchy and every reference
        #[arg(long)]
        colour_band: bool,
        /// Most passes a sweep runs, in the hierarchy and the reference sweep (default:
        /// the hierarchy's, 4).
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4096))]
        passes: Option<u32>,
        /// The sweeps' convergence tolerance, in the hierarchy and the reference sweep
        /// (default: the hierarchy's, 0.01).
        #[arg(long)]
        tolerance: Option<f32>,
        /// The flat source rule (MediumEmission::Source) instead of the default profile
        /// rule, in the hierarchy and the reference sweep, for comparison.
        #[arg(long)]
        flat_source: bool,
        /// The sun's first two scatterings gathered by rays (SweepOptions::gather =
        /// Gather::LOW_SUN, a bake's setting), in the hierarchy and the reference sweep,
        /// for comparison.
        #[arg(long)]
        gather: bool,
        /// The camera path: forest (inside the forest) or edge (out of it over bare
        /// ground).
        #[arg(long, default_value = "forest")]
        path: xtask::frame::CameraPath,
        /// Probes of the last camera measured against Monte Carlo (about; 0: none).
        #[arg(long, default_value_t = 1000)]
        mc_probes: usize,
        /// Monte Carlo paths per probe.
        #[arg(long, default_value_t = 16384, value_parser = clap::value_parser!(u32).range(2..=(1 << 24)))]
        mc_paths: u32,
        /// Metres of world around the sampled region in the reference sweeps (a low
        /// sun's rays leave a narrow one early: beyond it nothing shades them).
        #[arg(long, default_value_t = 40.0)]
        margin: f32,
        /// Cells a node's sky sweep reaches beyond the node (HierarchyParams::apron;
        /// default: the hierarchy's, 6, for nodes of 32 points or more; 0 for smaller
        /// ones)
        #[arg(long)]
        apron: Option<u32>,
        /// Cells of that apron the nodes' sun responses are swept over too
        /// (HierarchyParams::sun_apron, at most the apron; default: the hierarchy's, 3)
        #[arg(long)]
        sun_apron: Option<u32>,
        /// Output folder (default target/bench).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Measure the README's figures (bench forest, exact, sun, frame, throughput, first
    /// sweep, demo), each alone, and write docs/figures.md and the README's table.
    Figures {
        /// Do not run the measurements: rebuild both files from the reports in
        /// target/bench.
        #[arg(long)]
        assemble: bool,
    },
    /// Feed every file reader generated bad inputs: panics, slow inputs, peak memory.
    Fuzz {
        /// Inputs per target.
        #[arg(long, default_value_t = 1_000_000)]
        inputs: u64,
        /// Only this target (repeatable): grid, scene, volume, gltf, exr, png.
        #[arg(long = "target")]
        targets: Vec<String>,
        /// Seed of the input generator.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

fn main() -> ExitCode {
    let args = Args::parse();
    lightgrid_viewer::init_logs();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    match args.task {
        Task::Bench {
            full,
            scenes,
            no_gpu,
            out,
        } => {
            let mut cfg = if full {
                bench::BenchConfig::full(&root)
            } else {
                bench::BenchConfig::quick(&root)
            };
            cfg.only = scenes;
            cfg.gpu = !no_gpu;
            if let Some(o) = out {
                cfg.out = o;
            }
            match bench::run(&cfg) {
                Ok(_) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("xtask bench: {e:#}");
                    ExitCode::FAILURE
                }
            }
        }
        Task::Exact { max_passes } => exact(&root, max_passes),
        Task::Sun { n, paths } => match sun::run(&root, &root.join("assets"), n, paths) {
            Ok(text) => {
                print!("{text}");
                println!("wrote target/bench/sun.txt and sun.png");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("xtask sun: {e:#}");
                ExitCode::FAILURE
            }
        },
        Task::Frame {
            node_points,
            frames,
            elevations,
            gpu,
            bare_skip,
            no_casters,
            skip_finest_sun,
            sun_with_sky,
            even,
            budget_ms,
            budget_points,
            neighbour_halo,
            halo_paths,
            no_ground_lift,
            halo_cells,
            march_before_casters,
            colour_band,
            passes,
            tolerance,
            flat_source,
            gather,
            path,
            mc_probes,
            mc_paths,
            margin,
            apron,
            sun_apron,
            out,
        } => {
            let mut cfg = xtask::frame::FrameConfig::new(&root);
            cfg.mc_probes = mc_probes;
            cfg.mc_paths = mc_paths;
            cfg.margin = margin;
            cfg.apron = apron;
            cfg.sun_apron = sun_apron;
            cfg.node_points = node_points;
            cfg.frames = frames;
            cfg.gpu = gpu;
            cfg.bare_skip = bare_skip;
            cfg.no_casters = no_casters;
            cfg.skip_finest_sun = skip_finest_sun;
            cfg.sun_with_sky = sun_with_sky;
            cfg.even = even;
            cfg.budget_ms = budget_ms;
            cfg.budget_points = budget_points;
            cfg.neighbour_halo = neighbour_halo;
            cfg.halo_paths = halo_paths;
            cfg.no_ground_lift = no_ground_lift;
            cfg.halo_cells = match halo_cells.as_str() {
                "off" => lightgrid_terrain_lod::HaloCells::Off,
                "coarser" => lightgrid_terrain_lod::HaloCells::Coarser,
                "composed" => lightgrid_terrain_lod::HaloCells::Composed,
                // (clap takes no other value.)
                _ => lightgrid_terrain_lod::HaloCells::Coarser,
            };
            cfg.march_before_casters = march_before_casters;
            cfg.colour_band = colour_band;
            cfg.passes = passes;
            cfg.tolerance = tolerance;
            cfg.flat_source = flat_source;
            cfg.gather = gather;
            cfg.path = path;
            if !elevations.is_empty() {
                cfg.elevations = elevations;
            }
            if let Some(o) = out {
                cfg.out = o;
            }
            match xtask::frame::run(&cfg) {
                Ok(r) => {
                    print!("{}", xtask::frame::text(&r));
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("xtask frame: {e:#}");
                    ExitCode::FAILURE
                }
            }
        }
        Task::Figures { assemble } => match xtask::figures::run(&root, assemble) {
            Ok(written) => {
                for p in written {
                    println!("wrote {}", p.display());
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("xtask figures: {e:#}");
                ExitCode::FAILURE
            }
        },
        Task::Fuzz {
            inputs,
            targets,
            seed,
        } => fuzz(&root, inputs, &targets, seed),
    }
}

fn exact(root: &std::path::Path, max_passes: u32) -> ExitCode {
    use lightgrid_measure::exact;
    let measured = exact::measure(max_passes)
        .map_err(anyhow::Error::from)
        .and_then(|c| {
            Ok((
                c,
                convergence::measure(max_passes)?,
                convergence::half_spaces(max_passes)?,
            ))
        });
    let (cases, rows, halves) = match measured {
        Ok(m) => m,
        Err(e) => {
            eprintln!("xtask exact: {e:#}");
            return ExitCode::FAILURE;
        }
    };
    let text = format!(
        "cargo xtask exact --max-passes {max_passes}\n{}\nPasses and time to tolerance 1e-4, slabs of cells of optical depth 1 under a zenith beam (plain | accelerated):\n{}\nHalf-spaces to tolerance 1e-5 (plain | accelerated):\n{}",
        exact::table(&cases),
        convergence::table(&rows),
        convergence::half_space_table(&halves)
    );
    print!("{text}");
    let out = root.join("target/bench");
    let _ = std::fs::create_dir_all(&out);
    let written = lightgrid_core::file::write_atomic(&out.join("exact.txt"), text.as_bytes())
        .with_context(|| format!("writing {}", out.join("exact.txt").display()))
        .and_then(|()| convergence::plot(&rows, &out.join("convergence.png")));
    match written {
        Ok(()) => {
            println!(
                "wrote {} and {}",
                out.join("exact.txt").display(),
                out.join("convergence.png").display()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("xtask exact: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn fuzz(root: &std::path::Path, inputs: u64, only: &[String], seed: u64) -> ExitCode {
    let out = root.join("target/fuzz");
    let all = xtask::fuzz::targets();
    if let Some(bad) = only
        .iter()
        .find(|o| !all.iter().any(|t| t.name == o.as_str()))
    {
        let names: Vec<&str> = all.iter().map(|t| t.name).collect();
        eprintln!("xtask fuzz: no target {bad:?} (targets: {names:?})");
        return ExitCode::FAILURE;
    }
    let mut reports = Vec::new();
    println!("{}", xtask::fuzz::Report::header());
    for t in all
        .iter()
        .filter(|t| only.is_empty() || only.iter().any(|o| o == t.name))
    {
        eprintln!("fuzzing {} ({inputs} inputs)...", t.name);
        let r = xtask::fuzz::run_target(t, inputs, seed, Some(&out));
        println!("{}", r.line());
        reports.push(r);
    }
    let mut text = format!(
        "cargo xtask fuzz --inputs {inputs} --seed {seed}\n{}\n",
        xtask::fuzz::Report::header()
    );
    for r in &reports {
        text.push_str(&r.line());
        text.push('\n');
    }
    let _ = std::fs::create_dir_all(&out);
    // A report is a by-product: a failure to write it is said, not fatal.
    let written = serde_json::to_string_pretty(&reports)
        .map_err(|e| e.to_string())
        .and_then(|json| {
            lightgrid_core::file::write_all_atomic(&[
                (out.join("fuzz.txt"), text.as_bytes()),
                (out.join("fuzz.json"), json.as_bytes()),
            ])
            .map_err(|e| e.to_string())
        });
    match written {
        Ok(()) => println!("wrote {}", out.join("fuzz.txt").display()),
        Err(e) => eprintln!("xtask fuzz: the report was not written: {e}"),
    }
    if reports.iter().all(|r| r.clean()) {
        ExitCode::SUCCESS
    } else {
        eprintln!(
            "xtask fuzz: panics escaped or inputs were slow (crash inputs in {})",
            out.display()
        );
        ExitCode::FAILURE
    }
}
