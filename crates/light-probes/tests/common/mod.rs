//! Scene builders shared by the integration tests: triangles, quads, a ground square
//! and a room (a box of six faces, with an optional window).

#![allow(dead_code)]

use lightgrid_core::glam::{Vec2, Vec3, Vec4};
use lightgrid_material_voxelizer::model::{Model, SurfaceMaterial, Triangle};

pub(crate) fn tri(a: Vec3, b: Vec3, c: Vec3, material: u32) -> Triangle {
    Triangle {
        positions: [a, b, c],
        uvs: [Vec2::ZERO; 3],
        material,
        part: material,
    }
}

/// A quad from its four corners (counter-clockwise seen from its front).
pub(crate) fn quad(c: [Vec3; 4], material: u32) -> [Triangle; 2] {
    [
        tri(c[0], c[1], c[2], material),
        tri(c[0], c[2], c[3], material),
    ]
}

/// A model of `triangles` with grey materials of the given albedos.
pub(crate) fn model(triangles: Vec<Triangle>, albedos: &[f32]) -> Model {
    Model {
        triangles,
        materials: albedos
            .iter()
            .map(|a| SurfaceMaterial {
                base_colour: Vec4::new(*a, *a, *a, 1.0),
                ..Default::default()
            })
            .collect(),
        textures: vec![],
    }
}

/// A ground square of side `2 s` at height 0.
pub(crate) fn ground_triangles(s: f32, material: u32) -> Vec<Triangle> {
    quad(
        [
            Vec3::new(-s, 0.0, -s),
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
        ],
        material,
    )
    .to_vec()
}

/// An axis-aligned rectangle on the plane `axis = at`, spanning `u` and `v` on the
/// other two axes (in x, y, z order).
fn rect(axis: usize, at: f32, u: [f32; 2], v: [f32; 2], material: u32) -> [Triangle; 2] {
    let p = |a: f32, b: f32| {
        let mut q = [0.0; 3];
        q[axis] = at;
        let (i, j) = match axis {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        q[i] = a;
        q[j] = b;
        Vec3::from(q)
    };
    quad(
        [p(u[0], v[0]), p(u[1], v[0]), p(u[1], v[1]), p(u[0], v[1])],
        material,
    )
}

/// The six faces of the box `lo..hi`. With `window = Some((y, z))`, the `+X` face has a
/// hole over `y[0]..y[1]` and `z[0]..z[1]`.
pub(crate) fn room(
    lo: Vec3,
    hi: Vec3,
    window: Option<([f32; 2], [f32; 2])>,
    material: u32,
) -> Vec<Triangle> {
    let mut t = Vec::new();
    let (xs, ys, zs) = ([lo.x, hi.x], [lo.y, hi.y], [lo.z, hi.z]);
    t.extend(rect(0, lo.x, ys, zs, material));
    t.extend(rect(1, lo.y, xs, zs, material));
    t.extend(rect(1, hi.y, xs, zs, material));
    t.extend(rect(2, lo.z, xs, ys, material));
    t.extend(rect(2, hi.z, xs, ys, material));
    match window {
        None => t.extend(rect(0, hi.x, ys, zs, material)),
        Some((y, z)) => {
            t.extend(rect(0, hi.x, [lo.y, y[0]], zs, material));
            t.extend(rect(0, hi.x, [y[1], hi.y], zs, material));
            t.extend(rect(0, hi.x, y, [lo.z, z[0]], material));
            t.extend(rect(0, hi.x, y, [z[1], hi.z], material));
        }
    }
    t
}
