//! The work the library skips, each measured with and without the skip, with the
//! difference it makes to the result.

use std::time::Instant;

use anyhow::Result;
use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::light::luminance;
use lightgrid_core::{
    Boundary, GridDesc, LightField, LightGrid, Material, MaterialGrid, Outputs, SideBoundary,
    SweepOptions,
};
use lightgrid_measure::scenes::{Scene, sky_and_sun};
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams, LodSkips};
use lightgrid_viewer::{SceneFile, SweeperChoice, World};
use serde::Serialize;

use super::BenchConfig;

/// One skip.
#[derive(Debug, Clone, Serialize)]
pub struct SkipRow {
    /// What is skipped.
    pub skip: String,
    /// Seconds with the skip (the default).
    pub with_skip: f64,
    /// Seconds without it.
    pub without_skip: f64,
    /// How much the result differs.
    pub difference: f64,
    /// What `difference` measures.
    pub difference_measure: String,
    /// The difference is below the tolerance (see [`super::Report::skip_tolerance`]).
    pub within_tolerance: bool,
}

fn max_rel_diff(a: &LightGrid, b: &LightGrid) -> f64 {
    let max = b.max_value().max(1e-30) as f64;
    a.data()
        .iter()
        .zip(b.data())
        .flat_map(|(x, y)| {
            x.0.iter()
                .zip(y.0.iter())
                .map(|(p, q)| (*p - *q).abs().max_element())
        })
        .fold(0.0f64, |m, d| m.max(d as f64 / max))
}

/// Canopy under `extra` empty levels: most of the grid is air above all material.
fn tall_canopy(n: u32, extra: u32) -> (MaterialGrid, Boundary) {
    let (m, _) = Scene::Canopy.build(n);
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(n, n + extra, n)).expect("valid");
    let cells = (0..desc.point_count())
        .map(|i| {
            let p = desc.coords(i).expect("in range");
            m.get(p).copied().unwrap_or(Material::EMPTY)
        })
        .collect();
    (
        MaterialGrid::new(desc, cells).expect("valid"),
        Boundary {
            sides: SideBoundary::Periodic,
            ..sky_and_sun()
        },
    )
}

/// Probes of a light field around `centre`: irradiance on the ground normal at the
/// ground, and average light 1.5 m above it, on a 64 × 64 lattice 4 m apart (inside and
/// outside the forest).
fn probes(field: &dyn LightField, world: &World, centre: Vec3) -> Result<Vec<f32>> {
    let hm = &world.heightmap;
    let mut out = Vec::new();
    for k in 0..64 {
        for i in 0..64 {
            let (x, z) = (
                centre.x - 128.0 + 4.0 * i as f32,
                centre.z - 128.0 + 4.0 * k as f32,
            );
            let y = hm.height_at(x, z);
            let e = hm.spacing;
            let n = Vec3::new(
                hm.height_at(x - e, z) - hm.height_at(x + e, z),
                2.0 * e,
                hm.height_at(x, z - e) - hm.height_at(x, z + e),
            )
            .normalize();
            out.push(luminance(field.irradiance(Vec3::new(x, y, z), n)?));
            out.push(luminance(field.average(Vec3::new(x, y + 1.5, z))?));
        }
    }
    Ok(out)
}

fn rel_rms(a: &[f32], b: &[f32]) -> f64 {
    let (mut n, mut d) = (0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        n += ((x - y) as f64).powi(2);
        d += (*y as f64).powi(2);
    }
    if d > 0.0 { (n / d).sqrt() } else { 0.0 }
}

/// Builds the demo scene's hierarchy around `eye` with `skip`, frames until ready; the
/// faster of two builds (the first pays for warming caches and allocations).
fn hierarchy(world: &World, eye: Vec3, skip: LodSkips) -> Result<(Hierarchy, f64)> {
    let (_, t0) = hierarchy_once(world, eye, skip)?;
    let (h, t1) = hierarchy_once(world, eye, skip)?;
    Ok((h, t0.min(t1)))
}

fn hierarchy_once(world: &World, eye: Vec3, skip: LodSkips) -> Result<(Hierarchy, f64)> {
    let g = &world.scene.grid;
    let mut params = HierarchyParams {
        world_cell: g.world_cell,
        finest_cell: g.finest_cell,
        node_points: g.node_points,
        apron: g.apron,
        budget_points: u64::MAX / 4,
        skip,
        ..Default::default()
    };
    params.sweep.max_passes = g.passes;
    let top = lightgrid_viewer::world::boundary_light(&world.sky_top, &world.scene)?;
    let t = Instant::now();
    let mut h = Hierarchy::new(
        &world.heightmap,
        Box::new(world.composer.clone()),
        Box::new(lightgrid_sweep_cpu::CpuSweeper::new()),
        top,
        params,
    )?;
    for _ in 0..100 {
        if h.update(eye)?.pending == 0 {
            break;
        }
    }
    Ok((h, t.elapsed().as_secs_f64()))
}

/// Measures every skip.
pub(super) fn measure(cfg: &BenchConfig) -> Result<Vec<SkipRow>> {
    println!("skipped work: measuring each skip with and without it");
    let mut rows = Vec::new();
    let n = cfg.n;

    // Levels above all material: copied, not computed.
    let (m, b) = tall_canopy(n, 3 * n);
    let mut on = SweepOptions::multi_bounce();
    on.max_passes = 4;
    let mut off = on;
    off.skip_empty_levels = false;
    let (a, t_on) = super::fastest(cfg.repeats, || Ok(lightgrid_sweep_cpu::run(&m, &b, &on)?))?;
    let (c, t_off) = super::fastest(cfg.repeats, || Ok(lightgrid_sweep_cpu::run(&m, &b, &off)?))?;
    rows.push(SkipRow {
        skip: format!("levels above all material ({n}x{}x{n}, 3/4 air)", 4 * n),
        with_skip: t_on,
        without_skip: t_off,
        difference: max_rel_diff(
            a.output.bins.as_ref().expect("bins"),
            c.output.bins.as_ref().expect("bins"),
        ),
        difference_measure: "largest bin difference / largest bin".into(),
        within_tolerance: false,
    });

    // Outputs not asked for: average + dominant only, instead of 26 bins (a forest of
    // four times the bench size: the saving is per point).
    let forest = super::scenes::forest(4 * n, &cfg.assets)?;
    let mut avg = on;
    avg.outputs = Outputs::AVERAGE_DOMINANT;
    let (a, t_on) = super::fastest(cfg.repeats, || {
        Ok(lightgrid_sweep_cpu::run(
            &forest.material,
            &forest.boundary,
            &avg,
        )?)
    })?;
    let (c, t_off) = super::fastest(cfg.repeats, || {
        Ok(lightgrid_sweep_cpu::run(
            &forest.material,
            &forest.boundary,
            &on,
        )?)
    })?;
    let (x, y) = (
        a.output.average.expect("average"),
        c.output.average.expect("average"),
    );
    let max = y
        .data()
        .iter()
        .map(|v| v.0.max_element())
        .fold(0.0, f32::max) as f64;
    let diff = x
        .data()
        .iter()
        .zip(y.data())
        .map(|(p, q)| (p.0 - q.0).abs().max_element() as f64 / max)
        .fold(0.0, f64::max);
    rows.push(SkipRow {
        skip: format!("26-bin output not asked for (forest {0}x{0}x{0})", 4 * n),
        with_skip: t_on,
        without_skip: t_off,
        difference: diff,
        difference_measure: "largest average-light difference / largest".into(),
        within_tolerance: false,
    });

    // The hierarchy's skips, on the viewer's demo scene, with the camera at the edge of
    // the forest (bare ground on one side, trees on the other).
    let world = World::build(SceneFile::demo()?, SweeperChoice::Cpu)?;
    let hm = &world.heightmap;
    let size = (hm.width - 1) as f32 * hm.spacing;
    let (x, z) = (0.85 * size, 0.15 * size);
    let eye = Vec3::new(x, hm.height_at(x, z) + 20.0, z);
    let (mut base, t_base) = hierarchy(&world, eye, LodSkips::default())?;
    let p_base = probes(&base, &world, eye)?;
    // Each variant differs from the defaults in one skip; "with" is the skip on.
    for (name, skip, on_by_default) in [
        (
            "no finer grids under bare ground (off by default)",
            LodSkips {
                bare_children: true,
                ..Default::default()
            },
            false,
        ),
        (
            "one downward pass over bare ground (off by default)",
            LodSkips {
                up_pass_over_bare: true,
                ..Default::default()
            },
            false,
        ),
    ] {
        let (h, t) = hierarchy(&world, eye, skip)?;
        let (with_skip, without_skip) = if on_by_default {
            (t_base, t)
        } else {
            (t, t_base)
        };
        rows.push(SkipRow {
            skip: name.into(),
            with_skip,
            without_skip,
            difference: rel_rms(&probes(&h, &world, eye)?, &p_base),
            difference_measure: "relative RMS of ground irradiance and air light".into(),
            within_tolerance: false,
        });
    }
    // Unchanged inputs: a refresh after nothing changed sweeps nothing. (A first
    // refresh settles nodes built before their coarser neighbours existed.)
    base.refresh(eye)?;
    let t = Instant::now();
    base.refresh(eye)?;
    let t_on = t.elapsed().as_secs_f64();
    let (mut forced, _) = hierarchy(
        &world,
        eye,
        LodSkips {
            unchanged: false,
            ..Default::default()
        },
    )?;
    forced.refresh(eye)?;
    let t = Instant::now();
    forced.refresh(eye)?;
    let t_off = t.elapsed().as_secs_f64();
    rows.push(SkipRow {
        skip: "unchanged inputs not swept again (demo, forest edge)".into(),
        with_skip: t_on,
        without_skip: t_off,
        difference: rel_rms(&probes(&forced, &world, eye)?, &probes(&base, &world, eye)?),
        difference_measure: "relative RMS of ground irradiance and air light".into(),
        within_tolerance: false,
    });
    Ok(rows)
}
