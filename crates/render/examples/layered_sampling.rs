//! Time of sampling a grid hierarchy for drawing, on the device (grids where the GPU
//! sweeper leaves them: `GpuLightSampler::sample_layers`) and on the CPU (`sample_points`
//! with the same layer rule), with the largest difference between the two.
//!
//! `cargo run --release -p lightgrid-render --example layered_sampling`
//! (a world grid of 65 x 17 x 65 points under 16 finer nodes of 33 x 17 x 33, a light
//! volume of 1.6 M lattice points and 66 k terrain-like points with normals).

use std::sync::Arc;
use std::time::Instant;

use lightgrid_core::glam::{IVec2, UVec3, Vec2, Vec3};
use lightgrid_core::{BinLight, Grid, GridDesc, LightGrid};
use lightgrid_gpu::GpuContext;
use lightgrid_render::{
    GpuLightGrid, GpuLightSampler, GpuPoints, GpuSampleLayer, LayerOwner, SamplePoints,
    SampledLight, sample_points,
};

fn grid(desc: GridDesc, seed: usize) -> LightGrid {
    let data = (0..desc.point_count())
        .map(|i| {
            BinLight(std::array::from_fn(|d| {
                let x = ((i * 31 + d * 17 + seed * 7) % 23) as f32;
                Vec3::new(0.1 + x, 0.5 + ((d + seed) % 5) as f32, 0.2 + (i % 7) as f32) * 0.1
            }))
        })
        .collect();
    Grid::from_trusted(desc, data)
}

fn main() -> anyhow::Result<()> {
    let ctx = Arc::new(GpuContext::new()?);
    println!("adapter: {} ({:?})", ctx.info.name, ctx.info.device_type);
    let mut cpu_layers: Vec<(LightGrid, Option<LayerOwner>)> = vec![(
        grid(GridDesc::new(Vec3::ZERO, 8.0, UVec3::new(65, 17, 65))?, 0),
        None,
    )];
    // 4 x 4 nodes of 128 m over the middle, cells of 4 m, each with a one-cell halo.
    for k in 0..16 {
        let index = IVec2::new(1 + k % 4, 1 + k / 4);
        let lo = index.as_vec2() * 128.0 - Vec2::splat(4.0);
        let desc = GridDesc::new(Vec3::new(lo.x, 0.0, lo.y), 4.0, UVec3::new(35, 17, 35))?;
        let owner = LayerOwner {
            origin: Vec2::ZERO,
            size: 128.0,
            index,
        };
        cpu_layers.push((grid(desc, k as usize + 1), Some(owner)));
    }
    let dev: Vec<GpuLightGrid> = cpu_layers
        .iter()
        .map(|(g, _)| GpuLightGrid::new(ctx.clone(), g))
        .collect::<Result<_, _>>()?;
    let layers: Vec<GpuSampleLayer> = dev
        .iter()
        .zip(&cpu_layers)
        .map(|(g, (_, o))| GpuSampleLayer::bins(g, *o))
        .collect();
    let sampler = GpuLightSampler::new(ctx.clone());
    let owning = |p: Vec3| -> usize {
        cpu_layers
            .iter()
            .rposition(|(g, o)| {
                o.is_none_or(|o| {
                    ((Vec2::new(p.x, p.z) - o.origin) / o.size)
                        .floor()
                        .as_ivec2()
                        == o.index
                        && g.desc().contains(p)
                })
            })
            .expect("the world layer owns every point")
    };
    // CPU: group points by their layer, one sample_points call (rayon) per layer.
    let cpu = |pts: &[Vec3], ns: Option<&[Vec3]>| -> anyhow::Result<Vec<SampledLight>> {
        let mut out = vec![SampledLight::default(); pts.len()];
        let owner: Vec<usize> = pts.iter().map(|p| owning(*p)).collect();
        for (l, (g, _)) in cpu_layers.iter().enumerate() {
            let idx: Vec<usize> = (0..pts.len()).filter(|&i| owner[i] == l).collect();
            let p: Vec<Vec3> = idx.iter().map(|&i| pts[i]).collect();
            let n: Option<Vec<Vec3>> = ns.map(|n| idx.iter().map(|&i| n[i]).collect());
            let s = sample_points(
                g,
                SamplePoints {
                    positions: &p,
                    normals: n.as_deref(),
                },
            )?;
            for (k, &i) in idx.iter().enumerate() {
                out[i] = s[k];
            }
        }
        Ok(out)
    };
    let volume = GridDesc::new(Vec3::new(0.0, 0.0, 0.0), 2.0, UVec3::new(257, 24, 257))?;
    let lattice: Vec<Vec3> = (0..volume.point_count())
        .map(|i| volume.position(volume.coords(i).expect("in range")))
        .collect();
    let terrain: Vec<Vec3> = (0..257 * 257)
        .map(|i| {
            Vec3::new(
                (i % 257) as f32 * 2.0,
                5.0 + (i % 13) as f32,
                (i / 257) as f32 * 2.0,
            )
        })
        .collect();
    let normals: Vec<Vec3> = (0..terrain.len())
        .map(|i| {
            Vec3::new(
                (i as f32 * 0.1).sin() * 0.3,
                1.0,
                (i as f32 * 0.07).cos() * 0.3,
            )
        })
        .collect();
    for (what, pts, ns, gpu_points) in [
        ("light volume", &lattice, None, GpuPoints::Lattice(volume)),
        (
            "terrain vertices",
            &terrain,
            Some(&normals[..]),
            GpuPoints::List(SamplePoints {
                positions: &terrain,
                normals: Some(&normals),
            }),
        ),
    ] {
        let t = Instant::now();
        let c = cpu(pts, ns)?;
        let cpu_s = t.elapsed().as_secs_f64();
        // The first call compiles nothing (the pipeline exists); time three and keep the best.
        let mut best = f64::INFINITY;
        let mut g = Vec::new();
        for _ in 0..3 {
            let t = Instant::now();
            let s = sampler.sample_layers(&layers, gpu_points)?;
            ctx.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            best = best.min(t.elapsed().as_secs_f64());
            g = s.read()?;
        }
        let err = c
            .iter()
            .zip(&g)
            .map(|(a, b)| {
                (a.light - b.light).abs().max_element() / a.light.abs().max_element().max(1e-6)
            })
            .fold(0.0f32, f32::max);
        println!(
            "{what}: {} points, {} layers: device {:.3} s (sampled in place, nothing read back), cpu {:.3} s; largest relative difference {err:.2e}",
            pts.len(),
            layers.len(),
            best,
            cpu_s
        );
    }
    Ok(())
}
