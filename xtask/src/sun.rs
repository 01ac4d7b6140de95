//! `cargo xtask sun`: the sun kept apart (issue 14) against the sun in the bins, on the
//! bench forest and under a single tree, both against the Monte Carlo reference with a
//! collimated sun along its exact direction (`lightgrid_measure::sun_measure`). Writes
//! `target/bench/sun.txt` and `sun.png` (error against sun elevation).

use std::path::Path;

use crate::bench::plot::err;
use anyhow::Result;
use lightgrid_core::glam::{Quat, UVec3, Vec2, Vec3};
use lightgrid_core::{GridDesc, MaterialSource, SweepOptions};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundColour, Heightmap, Instance, Terrain,
};
use lightgrid_material_voxelizer::procedural::{TreeParams, tree};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};
use lightgrid_measure::sun_measure::{
    SunErrors, angle_error, exact_shadow_azimuth, ground_light, shadow_azimuth, sun_errors,
};
use lightgrid_sky::Sun;
use plotters::prelude::*;

/// Sun elevations measured (degrees).
pub const ELEVATIONS: [f32; 5] = [10.0, 25.0, 40.0, 60.0, 80.0];
/// Sun azimuths measured (degrees): between the bins' (multiples of 45).
pub const AZIMUTHS: [f32; 2] = [20.0, 67.0];

fn options() -> SweepOptions {
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 1e-5;
    o.max_passes = 64;
    o
}

/// One procedural broadleaf tree (seed 3, as the demo's oaks), voxelized at 0.25 m.
fn tree_model() -> Result<lightgrid_core::MaterialGrid> {
    let (grid, _) = voxelize(
        &tree(&TreeParams::broadleaf(3))?,
        &VoxelizeParams::standard(0.25),
        &|_, _| {},
    )?;
    Ok(grid)
}

/// Runs the measurement; `n` cells a side for the forest, `paths` reference paths.
pub fn run(root: &Path, assets: &Path, n: u32, paths: u64) -> Result<String> {
    use std::fmt::Write;
    let o = options();
    let mut text = format!(
        "cargo xtask sun --n {n} --paths {paths}\n\
         sun light only, unit irradiance; relative RMSE of average light / irradiance on the six axes\n\
         against the Monte Carlo reference (collimated sun, exact direction); seconds of the sweep\n\n"
    );
    let forest = crate::bench::scenes::forest(n, assets)?;
    let _ = writeln!(text, "forest: {} ({n}^3 cells of 1 m)", forest.about);
    let _ = writeln!(
        text,
        "elev  azim   bins avg  bins irr   split avg  split irr   ref noise   bins s  split s"
    );
    let mut rows: Vec<(f32, f32, SunErrors)> = Vec::new();
    for azim in AZIMUTHS {
        for elev in ELEVATIONS {
            eprintln!("forest, sun at {elev} deg elevation, {azim} deg azimuth...");
            let e = sun_errors(
                &forest.material,
                &forest.boundary.sides,
                elev.to_radians(),
                azim.to_radians(),
                paths,
                &o,
            )
            .map_err(|e| anyhow::anyhow!("{e}"))?;
            let _ = writeln!(
                text,
                "{elev:4.0}  {azim:4.0}   {:8.4}  {:8.4}   {:9.4}  {:9.4}   {:9.4}   {:6.3}  {:7.3}",
                e.bins.0, e.bins.1, e.split.0, e.split.1, e.noise, e.seconds.0, e.seconds.1
            );
            rows.push((elev, azim, e));
        }
    }
    // A single tree's shadow on flat ground.
    let grid = tree_model()?;
    let size = 48u32;
    let heightmap = Heightmap::from_fn(Vec2::ZERO, 1.0, size + 1, size + 1, |_, _| 1.0)?;
    let centre = Vec2::splat(size as f32 / 2.0);
    let terrain = Terrain {
        heightmap: heightmap.clone(),
        colour: GroundColour::Uniform(Vec3::new(0.25, 0.22, 0.15)),
    };
    let compose = |with: bool| -> Result<lightgrid_core::MaterialGrid> {
        let instances = if with {
            vec![Instance {
                model: 0,
                position: Vec3::new(centre.x, 0.9, centre.y),
                rotation: Quat::IDENTITY,
                scale: 1.0,
            }]
        } else {
            Vec::new()
        };
        let c = AreaComposer::new(
            vec![grid.clone()],
            &instances,
            Some(terrain.clone()),
            ComposeParams::default(),
        )?;
        Ok(c.material(&GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(size, 12, size))?)?)
    };
    let (with, without) = (compose(true)?, compose(false)?);
    let _ = writeln!(
        text,
        "\nshadow of a single tree (procedural broadleaf, seed 3) on flat ground, {size} x {size} m periodic:\n\
         azimuth of the centroid of the missing upward irradiance 1 m above the ground (degrees)"
    );
    let _ = writeln!(text, "elev  azim   exact   bins (error)    split (error)");
    let level = 2;
    for azim in AZIMUTHS {
        for elev in [25.0f32, 40.0, 60.0] {
            let sun = Sun::at(elev.to_radians(), azim.to_radians(), Vec3::ONE);
            let (b1, s1) =
                ground_light(&with, &sun, level, &o).map_err(|e| anyhow::anyhow!("{e}"))?;
            let (b0, s0) =
                ground_light(&without, &sun, level, &o).map_err(|e| anyhow::anyhow!("{e}"))?;
            // Cell coordinates of the trunk.
            let axis = Vec3::new(centre.x, 0.0, centre.y);
            let exact = exact_shadow_azimuth(sun.direction);
            let (ab, asp) = (
                shadow_azimuth(&b1, &b0, size, size, axis),
                shadow_azimuth(&s1, &s0, size, size, axis),
            );
            let _ = writeln!(
                text,
                "{elev:4.0}  {azim:4.0}  {exact:6.1}  {ab:6.1} ({:5.1})   {asp:6.1} ({:5.1})",
                angle_error(ab, exact),
                angle_error(asp, exact)
            );
        }
    }
    let out = root.join("target/bench");
    std::fs::create_dir_all(&out)?;
    lightgrid_core::file::write_atomic(&out.join("sun.txt"), text.as_bytes())?;
    plot(&rows, &out.join("sun.png"))?;
    Ok(text)
}

/// A plotted series: name, colour, and the figure it shows.
type Series = (&'static str, RGBColor, fn(&SunErrors) -> f64);

/// Error against elevation, one panel per azimuth: bins and split, average light and
/// irradiance, and the reference's noise.
fn plot(rows: &[(f32, f32, SunErrors)], path: &Path) -> Result<()> {
    let text = crate::bench::plot::register_font();
    let (w, h) = (1100u32, 480u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err).map_err(err)?;
        let panels = root.split_evenly((1, AZIMUTHS.len()));
        for (panel, azim) in panels.iter().zip(AZIMUTHS) {
            let pts: Vec<&(f32, f32, SunErrors)> = rows.iter().filter(|r| r.1 == azim).collect();
            let top = pts
                .iter()
                .map(|r| r.2.bins.1.max(r.2.bins.0))
                .fold(0.0f64, f64::max)
                * 1.1;
            let mut b = ChartBuilder::on(panel);
            b.margin(12);
            if text {
                b.caption(
                    format!("forest, sun azimuth {azim} deg"),
                    ("sans-serif", 18),
                )
                .x_label_area_size(36)
                .y_label_area_size(52);
            }
            let mut chart = b
                .build_cartesian_2d(0f32..90f32, 0f64..top.max(0.05))
                .map_err(err)?;
            if text {
                chart
                    .configure_mesh()
                    .x_desc("sun elevation (deg)")
                    .y_desc("relative RMSE")
                    .draw()
                    .map_err(err)?;
            }
            let series: [Series; 5] = [
                ("bins, average", RED, |e| e.bins.0),
                ("bins, irradiance", MAGENTA, |e| e.bins.1),
                ("split, average", BLUE, |e| e.split.0),
                ("split, irradiance", CYAN, |e| e.split.1),
                ("reference noise", BLACK, |e| e.noise),
            ];
            for (name, colour, f) in series {
                let line: Vec<(f32, f64)> = pts.iter().map(|r| (r.0, f(&r.2))).collect();
                crate::bench::plot::line_with_points(
                    &mut chart,
                    &line,
                    colour.stroke_width(2),
                    text.then(|| name.to_string()),
                )?;
            }
            if text {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .draw()
                    .map_err(err)?;
            }
        }
        root.present().map_err(err)?;
    }
    crate::bench::plot::save_rgb(&buf, (w, h), path)
}
