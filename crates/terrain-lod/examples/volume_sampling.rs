//! Sampling a light volume from the hierarchy: 1.6 M points (the demo's volume size)
//! over a forest around the camera, read bin by bin (`VolumeSample::read`: the sky's and
//! the scattered sun's 26 bins a corner, then average and dominant direction) and
//! through the reduced grids (`LightField::volume_sampler`: 7 numbers a corner), both on
//! all cores; the median of 5 of each, and their largest difference where the two
//! agree by design: lookups whose eight corners lie outside geometry. A lookup with a
//! corner in an opaque cell reads, through the reduced grids, that corner's valid
//! neighbours' light (`lightgrid_core::validity`, so that a surface reads the light
//! above it rather than half of it), and bin by bin the dark inside of the solid: those
//! points (the ground's surface and what lies under it) are counted apart; so are the
//! points between two nodes' outermost points (read across the seam, from both nodes)
//! where a corner of either node's lookup lies inside geometry.
//!
//! `cargo run --release -p lightgrid-terrain-lod --example volume_sampling`

use std::time::Instant;

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, GridDesc, LightField, Material, MaterialGrid, MaterialSource, VolumeSample,
    trilinear_indices, validity,
};
use lightgrid_material_voxelizer::procedural::TreeParams;
use lightgrid_material_voxelizer::voxelize::VoxelizeParams;
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams, SunLight, quantized_pass};
use rayon::prelude::*;

#[path = "../tests/demo/mod.rs"]
mod demo;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let hm = demo::jacksboro(&demo::assets_dir())?;
    let forest = demo::Forest {
        tree: TreeParams::broadleaf(3),
        voxel: VoxelizeParams::standard(0.5),
        count: 2000,
        lo: Vec2::splat(500.0),
        size: 250.0,
        scale: (0.8, 1.3),
        seed: 99,
        ground: Vec3::new(0.25, 0.22, 0.18),
    };
    let composer = forest.composer(&hm)?;
    let (sky, _) = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0)).split_vertical();
    let params = HierarchyParams {
        node_points: 16,
        finest_cell: 1.0,
        max_levels: 48,
        budget_points: u64::MAX / 4,
        ..Default::default()
    };
    let mut h = Hierarchy::new(
        &hm,
        Box::new(composer),
        Box::new(CpuSweeper::new()),
        sky,
        params,
    )?;
    h.set_sun(Some(SunLight {
        to_sun: Vec3::new(0.5, 0.6, 0.3),
        irradiance: Vec3::new(3.0, 2.8, 2.5),
    }))?;
    let cam = Vec3::new(500.0, hm.height_at(500.0, 500.0) + 15.0, 500.0);
    h.update(cam)?;
    // 128 x 96 x 128 = 1.57 M points, 1 m apart, around the camera.
    let dims = UVec3::new(128, 96, 128);
    let origin = Vec3::new(
        cam.x - 64.0,
        hm.height_at(cam.x, cam.z) - 20.0,
        cam.z - 64.0,
    );
    let desc = GridDesc::new(origin, 1.0, dims)?;
    let points: Vec<Vec3> = (0..desc.point_count())
        .map(|i| desc.position(desc.coords(i).expect("in range")))
        .collect();
    println!(
        "{} grids, {} points in the volume, {} threads",
        h.layers().len(),
        points.len(),
        rayon::current_num_threads()
    );
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (mut bins, mut reduced, mut reductions) = (Vec::new(), Vec::new(), Vec::new());
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for _ in 0..5 {
        let t = Instant::now();
        a = points
            .par_iter()
            .map(|p| VolumeSample::read(&h, *p))
            .collect::<Result<Vec<_>, _>>()?;
        bins.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let read = h.volume_sampler().expect("the hierarchy reduces its grids");
        reductions.push(t.elapsed().as_secs_f64());
        b = points
            .par_iter()
            .map(|p| read(*p))
            .collect::<Result<Vec<_>, _>>()?;
        reduced.push(t.elapsed().as_secs_f64());
    }
    // Which grid points lie outside geometry, per layer: the materials composed again by
    // a second composer of the same forest, their depths rounded as the hierarchy
    // rounds them (`quantized_pass`).
    let again = forest.composer(&hm)?;
    let layers = h.layers();
    let valid: Vec<Vec<bool>> = layers
        .par_iter()
        .map(|l| -> Result<Vec<bool>, lightgrid_core::GridError> {
            let m = again.material(l.grid.desc())?;
            let cells = m
                .data()
                .iter()
                .map(|c| Material {
                    pass: quantized_pass(c.pass),
                    ..*c
                })
                .collect();
            Ok(validity::valid_points(&MaterialGrid::new(
                *m.desc(),
                cells,
            )?))
        })
        .collect::<Result<_, _>>()?;
    // The layers a read at `p` takes: the serving grid, and where `p` lies beyond its
    // outermost points (the strip between two nodes, read across the seam) the nodes
    // of its cell size whose points reach `p` (each read clamped to its points).
    let clear = |p: Vec3| {
        let g = h.grid_at(p);
        let (lo, hi) = g.desc().point_bounds();
        let h_cell = g.desc().h();
        let beyond = p.cmplt(lo).any() || p.cmpgt(hi).any();
        layers.iter().zip(&valid).all(|(l, valid)| {
            let d = l.grid.desc();
            let (llo, lhi) = d.point_bounds();
            let read = std::ptr::eq(l.grid, g)
                || (beyond
                    && d.h() == h_cell
                    && (p.cmpge(llo - h_cell).all() && p.cmple(lhi + h_cell).all()));
            if !read {
                return true;
            }
            let (index, weight) = trilinear_indices(d.dims(), d.to_grid(p));
            index.iter().zip(weight).all(|(&k, w)| w == 0.0 || valid[k])
        })
    };
    let (mut da, mut dd, mut ds, mut beside) = (0.0f32, 0.0f32, 0.0f32, 0usize);
    for ((x, y), p) in a.iter().zip(&b).zip(&points) {
        if !clear(*p) {
            beside += 1;
            continue;
        }
        da =
            da.max((x.average - y.average).abs().max_element() / x.average.max_element().max(1e-6));
        dd = dd.max((x.dominant - y.dominant).length());
        ds = ds.max((x.sun - y.sun).abs());
    }
    println!(
        "bin by bin: {:.3} s; reduced grids (reduction included): {:.3} s, of which the reduction {:.3} s; {:.1}x",
        median(bins.clone()),
        median(reduced.clone()),
        median(reductions),
        median(bins) / median(reduced)
    );
    println!(
        "largest difference where a lookup's corners lie outside geometry ({} points): average {da:.2e} (relative), dominant {dd:.2e}, sun {ds:.2e}",
        points.len() - beside
    );
    println!(
        "{beside} points read a corner inside geometry (the ground's surface and below it): the reduced grids give those corners their valid neighbours' light"
    );
    Ok(())
}
