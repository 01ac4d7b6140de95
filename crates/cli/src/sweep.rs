//! `lightgrid scene | sweep | reference`: canonical material grids, the sweep of a
//! material grid file under a sky, and the Monte Carlo reference.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Subcommand, ValueEnum};
use lightgrid_core::glam::Vec3;
use lightgrid_core::{
    BinLight, Boundary, GridFile, Outputs, SideBoundary, SweepOptions, TopBoundary,
};
use lightgrid_measure::reference::{ReferenceOptions, trace};
use lightgrid_measure::scenes::Scene;
use lightgrid_sky::{self as sky, Sun};

#[derive(Subcommand)]
pub(crate) enum Command {
    /// Write the material grid of a canonical test scene.
    Scene {
        /// Which scene.
        scene: SceneArg,
        /// Cells along each axis.
        #[arg(long, default_value_t = 16)]
        size: u32,
        /// Output material grid file.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Sweep a material grid and write the light grid.
    Sweep {
        /// Material grid file.
        material: PathBuf,
        /// Output light grid file.
        #[arg(short, long)]
        output: PathBuf,
        #[command(flatten)]
        light: LightArgs,
        #[command(flatten)]
        sweep: SweepArgs,
        /// Write the light packed as R11G11B10 (104 bytes a point instead of 312).
        #[arg(long)]
        packed: bool,
        /// Also write the horizon halves (the downward-travelling halves of the 8
        /// horizontal bins, 96 bytes a point) to this grid file: `lightgrid export
        /// --horizon` reads them for faces exact across the horizon.
        #[arg(long)]
        horizon: Option<PathBuf>,
        /// Also write a PNG preview: the average light on the grid's middle vertical slice.
        #[arg(long)]
        preview: Option<PathBuf>,
    },
    /// Trace the Monte Carlo reference and write its light grid.
    Reference {
        /// Material grid file.
        material: PathBuf,
        /// Output light grid file.
        #[arg(short, long)]
        output: PathBuf,
        #[command(flatten)]
        light: LightArgs,
        /// Paths to trace.
        #[arg(long, default_value_t = 1_000_000)]
        paths: u64,
        /// Stop after this many seconds (between batches).
        #[arg(long)]
        seconds: Option<f64>,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Also write a PNG preview: the average light on the grid's middle vertical slice.
        #[arg(long)]
        preview: Option<PathBuf>,
    },
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum SceneArg {
    Empty,
    Fog,
    Block,
    Canopy,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum SkyArg {
    /// No sky light (sun only).
    None,
    /// Uniform radiance above the horizon (`--sky-radiance`).
    Uniform,
    /// The analytic clear sky, glowing around the sun.
    Clear,
    /// A clear daylight sky in cd/m² (Preetham's shape, measured clear-sky level:
    /// `lightgrid_sky::Daylight`); `--sun-from-sky` gives the matching sun in lux.
    Daylight,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum SidesArg {
    Open,
    Periodic,
}

#[derive(clap::Args)]
pub(crate) struct SweepArgs {
    /// Most passes (alternating down and up).
    #[arg(long, default_value_t = SweepOptions::multi_bounce().max_passes)]
    passes: u32,
    /// Smoothing weight in [0, 1).
    #[arg(long, default_value_t = SweepOptions::multi_bounce().smoothing)]
    smoothing: f32,
    /// Stop when the light still to transport is below this fraction of the input.
    #[arg(long, default_value_t = SweepOptions::multi_bounce().tolerance)]
    tolerance: f32,
    /// Diffusion acceleration of the passes (`Acceleration::Diffusion`): for thick,
    /// bright media (snow, cloud, fog banks) that take many passes.
    #[arg(long)]
    accelerate: bool,
}

impl SweepArgs {
    /// Multiple-bounce options with these settings, 26-bin output only.
    pub(crate) fn options(&self) -> Result<SweepOptions> {
        if !(1..=lightgrid_core::MAX_PASSES).contains(&self.passes) {
            bail!(
                "--passes must be in 1..={}, got {}",
                lightgrid_core::MAX_PASSES,
                self.passes
            );
        }
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = self.passes;
        o.smoothing = self.smoothing;
        o.tolerance = self.tolerance;
        if self.accelerate {
            o.acceleration = lightgrid_core::Acceleration::Diffusion;
        }
        o.outputs = Outputs {
            bins: true,
            average: false,
            dominant: false,
            horizon: false,
        };
        Ok(o)
    }
}

#[derive(clap::Args)]
pub(crate) struct LightArgs {
    /// Sky model (ignored with --sky-exr).
    #[arg(long, value_enum, default_value = "clear")]
    sky: SkyArg,
    /// Radiance of the uniform sky, `R,G,B`.
    #[arg(long, value_parser = parse_rgb, default_value = "1,1,1")]
    sky_radiance: Vec3,
    /// Equirectangular HDR environment map (EXR) as the sky.
    #[arg(long)]
    sky_exr: Option<PathBuf>,
    /// Sun illuminance `R,G,B` (irradiance facing the sun); `0,0,0` for no sun.
    #[arg(long, value_parser = parse_rgb, default_value = "0,0,0")]
    sun: Vec3,
    /// With `--sky daylight`: the sun's illuminance from the same clear-sky measurements
    /// (lux, white; about 92,000 at 40° elevation), instead of `--sun`.
    #[arg(long, conflicts_with = "sun")]
    sun_from_sky: bool,
    /// Haze of `--sky daylight`: 2 very clear, 3 clear, 6 hazy (1.7 to 10).
    #[arg(long, default_value_t = lightgrid_sky::DEFAULT_TURBIDITY)]
    turbidity: f32,
    /// Sun elevation above the horizon, degrees.
    #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
    sun_elevation: f32,
    /// Sun azimuth from -Z towards +X, degrees.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    sun_azimuth: f32,
    /// Side boundaries.
    #[arg(long, value_enum, default_value = "open")]
    sides: SidesArg,
}

fn parse_rgb(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|p| p.trim().parse::<f32>().map_err(|e| format!("`{p}`: {e}")))
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [r, g, b] if v.iter().all(|x| x.is_finite() && *x >= 0.0) => Ok(Vec3::new(*r, *g, *b)),
        [x] if x.is_finite() && *x >= 0.0 => Ok(Vec3::splat(*x)),
        _ => Err(format!("expected R,G,B (three numbers >= 0), got `{s}`")),
    }
}

impl LightArgs {
    /// The sun's illuminance: `--sun`, or with `--sun-from-sky` the daylight model's.
    fn sun_rgb(&self) -> Result<Vec3> {
        if !self.sun_from_sky {
            return Ok(self.sun);
        }
        if !matches!(self.sky, SkyArg::Daylight) || self.sky_exr.is_some() {
            bail!("--sun-from-sky needs --sky daylight");
        }
        Ok(Vec3::splat(lightgrid_sky::ies_sun_illuminance(
            self.sun_elevation.to_radians(),
        )))
    }

    /// The sky (top and bottom bins) and the sun's bins (zero without a sun).
    fn sky_and_sun(&self) -> Result<(sky::SkyBins, BinLight)> {
        let rgb = self.sun_rgb()?;
        let sun = Sun::at(
            self.sun_elevation.to_radians(),
            self.sun_azimuth.to_radians(),
            rgb,
        );
        let spec = match (&self.sky_exr, self.sky) {
            (Some(path), _) => sky::SkySpec::exr(path)?,
            (None, SkyArg::None) => sky::SkySpec::None,
            (None, SkyArg::Uniform) => sky::SkySpec::Uniform(self.sky_radiance),
            (None, SkyArg::Clear) => sky::SkySpec::Clear,
            (None, SkyArg::Daylight) => sky::SkySpec::Daylight(self.turbidity),
        };
        let sky = spec.bins(sun.direction)?;
        let sun_bins = if rgb == Vec3::ZERO {
            BinLight::ZERO
        } else {
            sun.bins()?
        };
        Ok((sky, sun_bins))
    }

    fn sides(&self) -> SideBoundary {
        match self.sides {
            SidesArg::Open => SideBoundary::Open,
            SidesArg::Periodic => SideBoundary::Periodic,
        }
    }

    /// Sky and sun together.
    pub(crate) fn boundary(&self) -> Result<Boundary> {
        let (sky, sun) = self.sky_and_sun()?;
        Ok(Boundary {
            top: TopBoundary::Uniform(Box::new(sky.top + sun)),
            bottom: sky.bottom,
            sides: self.sides(),
        })
    }

    /// The sun as a direction towards it and its irradiance facing it (`None`
    /// without a sun).
    pub(crate) fn sun(&self) -> Result<Option<(Vec3, Vec3)>> {
        let rgb = self.sun_rgb()?;
        let sun = Sun::at(
            self.sun_elevation.to_radians(),
            self.sun_azimuth.to_radians(),
            rgb,
        );
        Ok((rgb != Vec3::ZERO).then_some((sun.direction, rgb)))
    }

    /// The sun alone (`None` without a sun).
    pub(crate) fn sun_boundary(&self) -> Result<Option<Boundary>> {
        let (_, sun) = self.sky_and_sun()?;
        Ok((sun != BinLight::ZERO).then(|| Boundary {
            top: TopBoundary::Uniform(Box::new(sun)),
            bottom: BinLight::ZERO,
            sides: self.sides(),
        }))
    }
}

/// The average light of the middle x-y slice (z = nz / 2), scaled so the brightest
/// point is white, gamma 2.2, each point a 4 × 4 block, top level at the top.
fn write_preview(g: &lightgrid_core::LightGrid, path: &std::path::Path) -> Result<()> {
    let d = g.desc();
    let (nx, ny, nz) = (d.dims().x, d.dims().y, d.dims().z);
    let k = nz / 2;
    let at = |i: u32, j: u32| {
        g.get(lightgrid_core::glam::UVec3::new(i, j, k))
            .map(|b| b.average())
            .unwrap_or_default()
    };
    let max = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| (i, j)))
        .map(|(i, j)| at(i, j).max_element())
        .fold(1e-30f32, f32::max);
    let s = 4;
    let img = image::RgbImage::from_fn(nx * s, ny * s, |x, y| {
        let c = at(x / s, ny - 1 - y / s) / max;
        let t = |v: f32| (v.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0 + 0.5) as u8;
        image::Rgb([t(c.x), t(c.y), t(c.z)])
    });
    // Encoded in memory, then written atomically like the grids.
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .context("encoding the preview")?;
    lightgrid_core::file::write_atomic(path, &png)
        .with_context(|| format!("writing {}", path.display()))?;
    println!(
        "wrote {} (average light, slice z = {k}, white = {max:.3})",
        path.display()
    );
    Ok(())
}

pub(crate) fn load_material(path: &std::path::Path) -> Result<lightgrid_core::MaterialGrid> {
    GridFile::load(path)
        .and_then(GridFile::into_material)
        .with_context(|| format!("reading material grid {}", path.display()))
}

/// Runs `scene`, `sweep` or `reference`.
pub(crate) fn run(command: Command) -> Result<()> {
    match command {
        Command::Scene {
            scene,
            size,
            output,
        } => {
            if size == 0 || size > 512 {
                bail!("--size must be in 1..=512, got {size}");
            }
            crate::paths::check(&[], &[&output])?;
            let s = match scene {
                SceneArg::Empty => Scene::Empty,
                SceneArg::Fog => Scene::UniformFog,
                SceneArg::Block => Scene::DenseBlock,
                SceneArg::Canopy => Scene::Canopy,
            };
            let (m, _) = s.build(size);
            GridFile::Material(m)
                .save(&output)
                .with_context(|| format!("writing {}", output.display()))?;
            println!(
                "wrote {} ({size}³ cells, scene {})",
                output.display(),
                s.name()
            );
        }
        Command::Sweep {
            material,
            output,
            light,
            sweep,
            packed,
            horizon,
            preview,
        } => {
            let mut outs = vec![output.as_path()];
            outs.extend(horizon.as_deref());
            outs.extend(preview.as_deref());
            crate::paths::check(&[&material], &outs)?;
            let mut o = sweep.options()?;
            if horizon.is_some() {
                o.outputs = o.outputs.with_horizon();
            }
            let m = load_material(&material)?;
            let b = light.boundary()?;
            let t = Instant::now();
            let s = lightgrid_sweep_cpu::run(&m, &b, &o).context("sweeping")?;
            let secs = t.elapsed().as_secs_f64();
            let g = s.output.bins.expect("bins were asked for");
            // The grid first: a bad preview path must not throw the sweep away.
            let file = if packed {
                GridFile::PackedLight(g.pack())
            } else {
                GridFile::Light(g.clone())
            };
            file.save(&output)
                .with_context(|| format!("writing {}", output.display()))?;
            if let (Some(path), Some(h)) = (&horizon, s.output.horizon) {
                GridFile::Horizon(h)
                    .save(path)
                    .with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            if let Some(p) = &preview {
                write_preview(&g, p)?;
            }
            let st = s.output.stats;
            println!(
                "swept {} points in {:.1} ms: {} passes ({} diffusion corrections), {} levels computed, {} copied; energy balance error {:.2e}",
                m.desc().point_count(),
                secs * 1e3,
                st.passes,
                st.corrections,
                st.levels_computed,
                st.levels_copied,
                s.balance.relative_error()
            );
            println!("wrote {}", output.display());
        }
        Command::Reference {
            material,
            output,
            light,
            paths,
            seconds,
            seed,
            preview,
        } => {
            let mut outs = vec![output.as_path()];
            outs.extend(preview.as_deref());
            crate::paths::check(&[&material], &outs)?;
            let m = load_material(&material)?;
            let b = light.boundary()?;
            let time_budget = match seconds {
                None => None,
                Some(s) => match std::time::Duration::try_from_secs_f64(s) {
                    Ok(d) if s > 0.0 => Some(d),
                    _ => bail!("--seconds must be a positive number of seconds, got {s}"),
                },
            };
            if !(1..=lightgrid_measure::reference::MAX_PATHS).contains(&paths) {
                bail!("--paths must be in 1..=2^40 (1099511627776), got {paths}");
            }
            let bar = indicatif::ProgressBar::new(paths);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:40}] {pos}/{len} paths ({eta} left)",
                )
                .expect("valid template"),
            );
            let opts = ReferenceOptions {
                paths,
                time_budget,
                seed,
                ..Default::default()
            };
            let t = Instant::now();
            let r = trace(&m, &b, &opts, &|done, _| bar.set_position(done))
                .context("tracing the reference")?;
            bar.finish_and_clear();
            GridFile::Light(r.light.clone())
                .save(&output)
                .with_context(|| format!("writing {}", output.display()))?;
            if let Some(p) = &preview {
                write_preview(&r.light, p)?;
            }
            println!(
                "traced {} paths in {:.2} s; relative standard error of the average light {:.4}",
                r.paths,
                t.elapsed().as_secs_f64(),
                r.relative_std_error(0.0)
            );
            println!("wrote {}", output.display());
        }
    }
    Ok(())
}
