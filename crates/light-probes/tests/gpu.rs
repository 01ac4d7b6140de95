//! Probe relighting on the GPU (`GpuProbeRelight`, feature `gpu`) equals the CPU
//! specification (`ProbeLight`), and its kernel validates with naga with the uniforms'
//! layout the same in Rust and WGSL. Runs on any adapter (lavapipe in CI); fails without
//! one unless LIGHTGRID_ALLOW_NO_GPU=1.

use std::sync::Arc;

use lightgrid_core::BinLight;
use lightgrid_core::glam::{Vec2, Vec3, Vec4};
use lightgrid_gpu::GpuContext;
use lightgrid_light_probes::GpuProbeRelight;
use lightgrid_light_probes::gpu::{RelightParams, kernel_wgsl};

fn context() -> Option<Arc<GpuContext>> {
    GpuContext::shared_for_tests()
}

/// The kernel validates (no GPU needed) and `RelightParams` has the same layout in Rust
/// and in the WGSL generated from it.
#[test]
fn the_kernel_validates_and_its_uniforms_match() {
    let module =
        lightgrid_gpu::check::validate("relight", &kernel_wgsl()).unwrap_or_else(|e| panic!("{e}"));
    lightgrid_gpu::check::layout_in(
        &module,
        "RelightParams",
        &RelightParams::offsets(),
        size_of::<RelightParams>(),
    )
    .unwrap();
}

/// Two triangles of a quad from its corners in order, of material (and part) `m`.
fn quad_triangles(c: [Vec3; 4], m: u32) -> [lightgrid_material_voxelizer::model::Triangle; 2] {
    let t = |a: Vec3, b: Vec3, d: Vec3| lightgrid_material_voxelizer::model::Triangle {
        positions: [a, b, d],
        uvs: [Vec2::ZERO; 3],
        material: m,
        part: m,
    };
    [t(c[0], c[1], c[2]), t(c[0], c[2], c[3])]
}

/// A model of `triangles` with warm grey materials of the given albedos.
fn tinted(
    triangles: Vec<lightgrid_material_voxelizer::model::Triangle>,
    albedos: &[f32],
) -> lightgrid_material_voxelizer::model::Model {
    lightgrid_material_voxelizer::model::Model {
        triangles,
        materials: albedos
            .iter()
            .map(|a| lightgrid_material_voxelizer::model::SurfaceMaterial {
                base_colour: Vec4::new(*a, 0.9 * a, 0.8 * a, 1.0),
                ..Default::default()
            })
            .collect(),
        textures: vec![],
    }
}

/// The GPU's probe light equals the CPU's to 1e-4 of the largest value, and is not dark.
fn probes_match(
    cpu: &[lightgrid_core::AmbientCube],
    gpu: &[lightgrid_core::AmbientCube],
    frame: u32,
) {
    assert_eq!(gpu.len(), cpu.len());
    let scale = cpu
        .iter()
        .flat_map(|a| a.0)
        .map(|v| v.max_element())
        .fold(0.0, f32::max);
    assert!(scale > 0.0);
    for (i, (a, b)) in cpu.iter().zip(gpu).enumerate() {
        for k in 0..6 {
            let d = (a.0[k] - b.0[k]).abs().max_element();
            assert!(
                d <= 1e-4 * scale,
                "frame {frame} probe {i} axis {k}: cpu {} gpu {}",
                a.0[k],
                b.0[k]
            );
        }
    }
}

/// Probe relighting on the GPU (`GpuProbeRelight`) equals `lightgrid_light_probes::ProbeLight`
/// (the CPU specification) frame after frame, to 1e-4 of the largest value (float
/// reassociation and fused multiply-adds are the only differences), on a ground with a
/// wall and a box (bounce light, shadows, several probes per surfel, bricks of 2).
#[test]
fn probe_relight_on_the_gpu_equals_the_cpu() {
    use lightgrid_light_probes::{Lighting, ProbeLight, ProbeParams, ProbeSet, place};
    use lightgrid_material_voxelizer::voxelize::RayScene;
    let Some(ctx) = context() else { return };
    let q = quad_triangles;
    let v = Vec3::new;
    let mut tris = Vec::new();
    tris.extend(q(
        [
            v(-20., 0., -20.),
            v(-20., 0., 20.),
            v(20., 0., 20.),
            v(20., 0., -20.),
        ],
        0,
    ));
    tris.extend(q(
        [v(-8., 0., 4.), v(8., 0., 4.), v(8., 9., 4.), v(-8., 9., 4.)],
        1,
    ));
    tris.extend(q(
        [
            v(2., 3., -6.),
            v(6., 3., -6.),
            v(6., 3., -2.),
            v(2., 3., -2.),
        ],
        2,
    ));
    let model = tinted(tris, &[0.4, 0.7, 0.6]);
    let scene = RayScene::new(&model, obvhs::BvhBuildParams::fast_build());
    let params = ProbeParams {
        spacing: 6.0,
        ..ProbeParams::preview()
    };
    let (lo, hi) = model.bounds().unwrap();
    let set = ProbeSet::bake(&scene, &place(&scene, lo, hi, &params), &params, &|_, _| {}).unwrap();
    assert!(set.probes().len() > 20 && set.brick_count() > 20);
    let to_sun = Vec3::new(0.4, 0.7, -0.5);
    let lighting = Lighting {
        sky: BinLight(std::array::from_fn(|d| {
            Vec3::new(0.2, 0.3, 0.5) * (1 + d % 3) as f32
        })),
        sun: Some((to_sun, Vec3::new(5.0, 4.5, 4.0))),
    };
    let vis = set.sun_visibility(&scene, to_sun);
    let mut cpu = ProbeLight::new(&set);
    let mut gpu = GpuProbeRelight::new(ctx, &set).unwrap();
    for frame in 0..4 {
        cpu.frame(&set, &lighting, &vis).unwrap();
        gpu.frame(&lighting, &vis).unwrap();
        probes_match(cpu.probes(), &gpu.read().unwrap(), frame);
    }
    // Bad input by name.
    let e = gpu.frame(&lighting, &vis[1..]).unwrap_err().to_string();
    assert!(e.contains("sun_visibility"), "{e}");
}

/// An interior probe set (a room with a window beside a street's probes) relit on the
/// GPU (`frame_interior`, the outside surfels reading the exterior set's probes on the
/// device) equals `ProbeLight::frame_interior`, to 1e-4 of the largest value.
#[test]
fn interior_probe_relight_on_the_gpu_equals_the_cpu() {
    use lightgrid_light_probes::{InteriorBox, Lighting, ProbeLight, ProbeParams, ProbeSet, place};
    use lightgrid_material_voxelizer::voxelize::RayScene;
    let Some(ctx) = context() else { return };
    // An axis-aligned rectangle: `axis` fixed at `at`, the other two (in x, y, z order)
    // spanning `u` and `v`.
    let rect = |axis: usize, at: f32, u: [f32; 2], v: [f32; 2], m: u32| {
        let p = |a: f32, b: f32| {
            let mut q = [at; 3];
            let (i, j) = [(1, 2), (0, 2), (0, 1)][axis];
            q[i] = a;
            q[j] = b;
            Vec3::from(q)
        };
        quad_triangles(
            [p(u[0], v[0]), p(u[1], v[0]), p(u[1], v[1]), p(u[0], v[1])],
            m,
        )
    };
    let mut tris = Vec::new();
    tris.extend(rect(1, 0.0, [-30.0, 30.0], [-30.0, 30.0], 0));
    let (xs, ys, zs) = ([0.0, 6.0], [0.02, 3.0], [0.0, 6.0]);
    tris.extend(rect(0, 0.0, ys, zs, 1));
    tris.extend(rect(1, 0.02, xs, zs, 1));
    tris.extend(rect(1, 3.0, xs, zs, 1));
    tris.extend(rect(2, 0.0, xs, ys, 1));
    tris.extend(rect(2, 6.0, xs, ys, 1));
    // The +X wall with a window over y 0.9..2.1, z 2..4.
    tris.extend(rect(0, 6.0, [0.02, 0.9], zs, 1));
    tris.extend(rect(0, 6.0, [2.1, 3.0], zs, 1));
    tris.extend(rect(0, 6.0, [0.9, 2.1], [0.0, 2.0], 1));
    tris.extend(rect(0, 6.0, [0.9, 2.1], [4.0, 6.0], 1));
    let model = tinted(tris, &[0.4, 0.7]);
    let scene = RayScene::new(&model, obvhs::BvhBuildParams::fast_build());
    let params = ProbeParams {
        spacing: 3.0,
        ..ProbeParams::preview()
    };
    let (lo, hi) = (Vec3::new(-9.0, 0.0, -9.0), Vec3::new(15.0, 3.0, 15.0));
    let ext = ProbeSet::bake(&scene, &place(&scene, lo, hi, &params), &params, &|_, _| {}).unwrap();
    let room = InteriorBox {
        lo: Vec3::new(0.05, 0.07, 0.05),
        hi: Vec3::new(5.95, 2.95, 5.95),
        blend: 0.5,
    };
    let pi = ProbeParams {
        spacing: 1.5,
        cell: 0.5,
        ..params
    };
    let int = ProbeSet::bake_interior(
        &scene,
        &room.place(1.5).unwrap(),
        &room,
        &ext,
        &pi,
        &|_, _| {},
    )
    .unwrap();
    let outside = (0..int.surfels().len())
        .filter(|s| int.surfel_outside(*s))
        .count();
    assert!(outside > 0 && outside < int.surfels().len(), "{outside}");
    let e = 25f32.to_radians();
    let to_sun = Vec3::new(e.cos(), e.sin(), -0.15);
    let lighting = Lighting {
        sky: BinLight::uniform(Vec3::new(0.3, 0.35, 0.45)),
        sun: Some((to_sun, Vec3::new(6.0, 5.6, 5.0))),
    };
    let (ev, iv) = (
        ext.sun_visibility(&scene, to_sun),
        int.sun_visibility(&scene, to_sun),
    );
    let (mut ce, mut ci) = (ProbeLight::new(&ext), ProbeLight::new(&int));
    let ge_ctx = ctx.clone();
    let mut ge = GpuProbeRelight::new(ctx.clone(), &ext).unwrap();
    let mut gi = GpuProbeRelight::new(ctx, &int).unwrap();
    // An interior set refuses the exterior's frame, and an exterior of the wrong size.
    assert!(
        gi.frame(&lighting, &iv)
            .unwrap_err()
            .to_string()
            .contains("frame_interior")
    );
    let wrong = GpuProbeRelight::new(ge_ctx.clone(), &int).unwrap();
    assert_ne!(int.probes().len(), ext.probes().len());
    let e = gi
        .frame_interior(&lighting, &iv, &wrong)
        .unwrap_err()
        .to_string();
    assert!(e.contains("exterior"), "{e}");
    for frame in 0..4 {
        ce.frame(&ext, &lighting, &ev).unwrap();
        ci.frame_interior(&int, &lighting, &iv, &ce).unwrap();
        ge.frame(&lighting, &ev).unwrap();
        gi.frame_interior(&lighting, &iv, &ge).unwrap();
        probes_match(ci.probes(), &gi.read().unwrap(), frame);
    }
}
