//! `lightgrid bake` and `lightgrid export`: Bevy irradiance volumes.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::ValueEnum;
use lightgrid_core::{GridFile, LightGrid};
use lightgrid_export::{BevyVolume, Content, TexelFormat, indirect_light_split, write_volumes};

use crate::sweep::{LightArgs, SweepArgs, load_material};

#[derive(Clone, Copy, ValueEnum)]
enum FormatArg {
    /// Shared-exponent RGB (Bevy's `Rgb9e5Ufloat`): the default.
    Rgb9e5,
    /// Small packed floats (Bevy's `Rg11b10Ufloat`).
    Rg11b10,
}

#[derive(clap::Args)]
pub(crate) struct VolumeArgs {
    /// Output folder (created if missing).
    #[arg(short, long)]
    output: PathBuf,
    /// File stem: writes `<name>.dds`, `<name>.ktx2` and `<name>.json`.
    #[arg(long, default_value = "volume")]
    name: String,
    /// Texel format.
    #[arg(long, value_enum, default_value = "rgb9e5")]
    format: FormatArg,
    /// Factor from the grid's light units to Bevy's (cd/m²), folded into the sidecar's
    /// intensity.
    #[arg(long, default_value_t = 1.0)]
    unit_scale: f32,
}

impl VolumeArgs {
    /// The files to write, checked against the inputs and each other.
    fn check_paths(&self, inputs: &[&std::path::Path]) -> Result<()> {
        let files = crate::paths::volume_files(&self.output, &self.name)?;
        let outs: Vec<&std::path::Path> = files.iter().map(|p| p.as_path()).collect();
        crate::paths::check(inputs, &outs)
    }

    fn format(&self) -> TexelFormat {
        match self.format {
            FormatArg::Rgb9e5 => TexelFormat::Rgb9e5,
            FormatArg::Rg11b10 => TexelFormat::Rg11b10,
        }
    }

    fn write(
        &self,
        volume: &BevyVolume,
        content: Content,
        sun: Option<(lightgrid_core::glam::Vec3, lightgrid_core::glam::Vec3)>,
    ) -> Result<()> {
        let paths = write_volumes(
            &self.output,
            &self.name,
            std::slice::from_ref(volume),
            content,
            self.unit_scale,
            sun,
        )
        .with_context(|| format!("writing into {}", self.output.display()))?;
        let d = volume.desc().dims();
        let t = volume.texture_size();
        println!(
            "irradiance volume: {}x{}x{} points -> {}x{}x{} texture of {}, intensity {}, {} light",
            d.x,
            d.y,
            d.z,
            t.x,
            t.y,
            t.z,
            volume.format().wgpu_name(),
            volume.intensity() * self.unit_scale,
            match content {
                Content::Indirect => "indirect",
                Content::All => "all the",
            }
        );
        for p in paths {
            println!("wrote {}", p.display());
        }
        Ok(())
    }
}

#[derive(clap::Args)]
pub(crate) struct BakeArgs {
    /// Material grid file, or a world: a scene file (`.toml`, as the viewer reads), whose
    /// terrain, objects, sky, sun and grid settings it takes (the light and sweep options
    /// below are then not used).
    material: PathBuf,
    /// World only: the store of the tasks' outputs, named by the hash of their inputs
    /// (default `<output>/.lightgrid-store`); a re-bake reuses what is there.
    #[arg(long)]
    store: Option<PathBuf>,
    /// World only: write the task graph as JSON to this file and run nothing.
    #[arg(long, conflicts_with = "task")]
    plan: Option<PathBuf>,
    /// World only: run one task of the plan (its inputs must be in the store).
    #[arg(long)]
    task: Option<String>,
    /// World only: bake the node grids of this many depths (default: all).
    #[arg(long)]
    depths: Option<u32>,
    #[command(flatten)]
    volume: VolumeArgs,
    #[command(flatten)]
    light: LightArgs,
    #[command(flatten)]
    sweep: SweepArgs,
    /// Keep the direct sun in the volume (for engines with no directional light of
    /// their own); by default only sky and scattered sun light are written.
    #[arg(long)]
    with_direct_sun: bool,
}

#[derive(clap::Args)]
pub(crate) struct ExportArgs {
    /// Light grid file (26 bins, packed or not).
    light: PathBuf,
    /// The grid's horizon halves (`lightgrid sweep --horizon`): the faces then read each
    /// horizontal bin in its two halves (exact across the horizon; without them a
    /// surface facing down over a ground of albedo 0.3 under a uniform sky reads 13 %
    /// too much).
    #[arg(long)]
    horizon: Option<PathBuf>,
    #[command(flatten)]
    volume: VolumeArgs,
    /// What the grid holds: `all` (a sweep with sky and sun, the default) or `indirect`
    /// (a grid without the direct sun); recorded in the sidecar.
    #[arg(long, value_enum, default_value = "all")]
    content: ContentArg,
}

#[derive(Clone, Copy, ValueEnum)]
enum ContentArg {
    All,
    Indirect,
}

/// Sweeps the material under sky and sun and writes the indirect light (without
/// `--with-direct-sun`) or all of it.
pub(crate) fn bake(a: BakeArgs) -> Result<()> {
    if a.material.extension().is_some_and(|e| e == "toml") {
        return crate::world::run(crate::world::WorldArgs {
            scene: a.material,
            output: a.volume.output.clone(),
            name: a.volume.name.clone(),
            store: a.store,
            format: a.volume.format(),
            unit_scale: a.volume.unit_scale,
            depths: a.depths,
            plan: a.plan,
            task: a.task,
        });
    }
    if a.store.is_some() || a.plan.is_some() || a.task.is_some() || a.depths.is_some() {
        bail!(
            "--store, --plan, --task and --depths bake a world (a scene file, .toml); {} is a material grid",
            a.material.display()
        );
    }
    a.volume.check_paths(&[&a.material])?;
    let options = a.sweep.options()?;
    let m = load_material(&a.material)?;
    let sky_and_sun = a.light.boundary()?;
    let sun = if a.with_direct_sun {
        None
    } else {
        a.light.sun_boundary()?
    };
    let t = Instant::now();
    let light = indirect_light_split(
        &mut lightgrid_sweep_cpu::CpuSweeper::new(),
        &m,
        &sky_and_sun,
        sun.as_ref(),
        &options,
    )
    .context("sweeping")?;
    println!(
        "swept {} points in {:.2} s{}",
        m.desc().point_count(),
        t.elapsed().as_secs_f64(),
        if sun.is_some() {
            " (sky and sun, then the direct sun alone to remove it)"
        } else {
            ""
        }
    );
    // Points inside geometry take their valid neighbours' light (Bevy reads trilinearly).
    let valid = lightgrid_core::validity::valid_points(&m);
    let volume = BevyVolume::from_field_valid(&light, m.desc(), a.volume.format(), &valid)?;
    let content = if a.with_direct_sun {
        Content::All
    } else {
        Content::Indirect
    };
    a.volume.write(&volume, content, a.light.sun()?)
}

/// Writes a light grid file as it is.
pub(crate) fn export(a: ExportArgs) -> Result<()> {
    let mut inputs = vec![a.light.as_path()];
    inputs.extend(a.horizon.as_deref());
    a.volume.check_paths(&inputs)?;
    let g: LightGrid = match GridFile::load(&a.light)
        .with_context(|| format!("reading light grid {}", a.light.display()))?
    {
        GridFile::Light(g) => g,
        GridFile::PackedLight(p) => p.unpack(),
        other => bail!(
            "{} holds a {} grid; export needs a 26-bin light grid",
            a.light.display(),
            other.kind().name()
        ),
    };
    let volume = match &a.horizon {
        Some(path) => {
            let h = GridFile::load(path)
                .and_then(GridFile::into_horizon)
                .with_context(|| format!("reading horizon halves {}", path.display()))?;
            let split = lightgrid_core::SplitLightGrid::new(g, h).with_context(|| {
                format!(
                    "{} and {} are not grids of the same points",
                    a.light.display(),
                    path.display()
                )
            })?;
            BevyVolume::from_field(&split, split.bins().desc(), a.volume.format())?
        }
        None => BevyVolume::from_field(&g, g.desc(), a.volume.format())?,
    };
    let content = match a.content {
        ContentArg::All => Content::All,
        ContentArg::Indirect => Content::Indirect,
    };
    // (A grid file does not record the sun it was swept under.)
    a.volume.write(&volume, content, None)
}
