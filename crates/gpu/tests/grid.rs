//! `GpuLightGrid` on the device: upload and read back bit for bit, wrapping a kernel's
//! buffer is checked, a box of points cropped on the device, and `kernel::Kernel` runs a known-answer kernel over a sentinel.
//! Needs an adapter (lavapipe in CI); fails without one unless LIGHTGRID_ALLOW_NO_GPU=1.

use std::sync::Arc;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, Grid, GridDesc};
use lightgrid_gpu::kernel::{Binding, Kernel, buffer};
use lightgrid_gpu::{GpuContext, GpuLightGrid};

/// The process's one device, shared by the tests (with a device each, this binary hung
/// in its first runs on a freshly started NVIDIA H200 machine; cause not established).
fn context() -> Option<Arc<GpuContext>> {
    GpuContext::shared_for_tests()
}

#[test]
fn grid_round_trip_and_checked_wrapping() {
    let Some(ctx) = context() else { return };
    let desc = GridDesc::new(Vec3::new(1.0, -2.0, 0.5), 0.5, UVec3::new(3, 4, 5)).unwrap();
    let grid = Grid::from_trusted(
        desc,
        (0..desc.point_count())
            .map(|i| BinLight(std::array::from_fn(|d| Vec3::new(i as f32, d as f32, 0.25))))
            .collect(),
    );
    let g = GpuLightGrid::new(ctx.clone(), &grid).unwrap();
    assert_eq!(g.read().unwrap(), grid);
    assert_eq!(g.desc(), &desc);
    // Too small, or without the usages: refused, naming the field.
    let small = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: GpuLightGrid::USAGE,
        mapped_at_creation: false,
    });
    let e = GpuLightGrid::from_buffer(ctx.clone(), small, desc).unwrap_err();
    assert!(e.to_string().contains("buffer.size()"), "{e}");
    let read_only = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: desc.point_count() as u64 * 312,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let e = GpuLightGrid::from_buffer(ctx.clone(), read_only, desc).unwrap_err();
    assert!(e.to_string().contains("buffer.usage()"), "{e}");
}

/// A box of a grid's points cropped on the device is those points, bit for bit, in a
/// grid of their own; a box beyond the grid or another cell size is refused, naming
/// the field.
#[test]
fn a_grid_cropped_on_the_device_is_its_inner_points() {
    let Some(ctx) = context() else { return };
    let big = GridDesc::new(Vec3::new(-1.0, 0.0, 2.0), 0.5, UVec3::new(7, 4, 6)).unwrap();
    let grid = Grid::from_trusted(
        big,
        (0..big.point_count())
            .map(|i| BinLight(std::array::from_fn(|d| Vec3::new(i as f32, d as f32, 0.5))))
            .collect(),
    );
    let g = GpuLightGrid::new(ctx.clone(), &grid).unwrap();
    let offset = UVec3::new(2, 1, 1);
    let inner = GridDesc::new(
        big.origin() + offset.as_vec3() * big.h(),
        big.h(),
        UVec3::new(3, 3, 4),
    )
    .unwrap();
    let cropped = g.crop(inner, offset).unwrap();
    assert_eq!(cropped.desc(), &inner);
    let expected = Grid::from_trusted(
        inner,
        (0..inner.point_count())
            .map(|i| grid.data()[big.index_unchecked(inner.coords(i).unwrap() + offset)])
            .collect(),
    );
    assert_eq!(cropped.read().unwrap(), expected);
    let e = g.crop(inner, UVec3::new(5, 0, 0)).unwrap_err();
    assert!(e.to_string().contains("offset"), "{e}");
    let coarse = GridDesc::new(inner.origin(), 1.0, inner.dims()).unwrap();
    let e = g.crop(coarse, offset).unwrap_err();
    assert!(e.to_string().contains("inner.h()"), "{e}");
}

#[test]
fn kernel_known_answer_over_a_sentinel() {
    let Some(ctx) = context() else { return };
    let k = Kernel::new(
        &ctx.device,
        "double",
        "@group(0) @binding(0) var<uniform> n: vec4<u32>;
         @group(0) @binding(1) var<storage, read> a: array<f32>;
         @group(0) @binding(2) var<storage, read_write> b: array<f32>;
         @compute @workgroup_size(64)
         fn main(@builtin(global_invocation_id) g: vec3<u32>) {
             if (g.x < n.x) { b[g.x] = 2.0 * a[g.x]; }
         }",
        &[Binding::Uniform, Binding::Read, Binding::ReadWrite],
    );
    let n = 100u32;
    let a: Vec<f32> = (0..130).map(|i| i as f32).collect();
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
    let params = buffer(
        &ctx,
        "n",
        bytemuck::cast_slice(&[n, 0, 0, 0]),
        wgpu::BufferUsages::UNIFORM,
    );
    let input = buffer(
        &ctx,
        "a",
        bytemuck::cast_slice(&a),
        wgpu::BufferUsages::STORAGE,
    );
    let out = buffer(&ctx, "b", bytemuck::cast_slice(&vec![-7.0f32; 130]), usage);
    let bind = k.bind(&ctx.device, &[&params, &input, &out]);
    k.dispatch(&ctx, &bind, n);
    let b: Vec<f32> = bytemuck::pod_collect_to_vec(&ctx.read_back(&out).unwrap());
    for (i, v) in b.iter().enumerate() {
        // Written below n, the sentinel beyond.
        let want = if (i as u32) < n { 2.0 * i as f32 } else { -7.0 };
        assert_eq!(*v, want, "element {i}");
    }
}
