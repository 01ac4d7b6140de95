//! Deterministic procedural demo assets: trees (trunk, branches, alpha-masked leaf
//! cards), bushes and rocks, as in-memory [`Model`]s that can be written as glTF
//! ([`write_glb`]), so the demo scene and the tests need no downloads.

use lightgrid_core::glam::{Quat, Vec2, Vec3, Vec4};
use lightgrid_core::{GridError, SeededRng as Rng};

use crate::model::{AlphaMode, Model, SurfaceMaterial, Texture, Triangle, UvTransform};

/// Parameters of a procedural tree. Start from a preset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TreeParams {
    /// Total height, metres.
    pub height: f32,
    /// Trunk radius at the ground, metres.
    pub trunk_radius: f32,
    /// Radius of the crown, metres.
    pub crown_radius: f32,
    /// Branches off the trunk.
    pub branches: u32,
    /// Leaf cards per branch.
    pub leaves_per_branch: u32,
    /// Side of a leaf card, metres.
    pub leaf_size: f32,
    /// Random seed: the same seed gives the same tree.
    pub seed: u64,
}

impl TreeParams {
    /// An 8 m broadleaf tree.
    pub const fn broadleaf(seed: u64) -> Self {
        Self {
            height: 8.0,
            trunk_radius: 0.25,
            crown_radius: 3.0,
            branches: 10,
            leaves_per_branch: 40,
            leaf_size: 0.6,
            seed,
        }
    }
    /// A 4 m young tree.
    pub const fn young(seed: u64) -> Self {
        Self {
            height: 4.0,
            trunk_radius: 0.12,
            crown_radius: 1.5,
            branches: 6,
            leaves_per_branch: 25,
            leaf_size: 0.4,
            seed,
        }
    }

    fn validate(&self) -> Result<(), GridError> {
        for (name, v) in [
            ("height", self.height),
            ("trunk_radius", self.trunk_radius),
            ("crown_radius", self.crown_radius),
            ("leaf_size", self.leaf_size),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GridError::invalid(name, v, "must be finite and > 0"));
            }
        }
        Ok(())
    }
}

const BARK: u32 = 0;
const LEAVES: u32 = 1;

fn tree_materials() -> (Vec<SurfaceMaterial>, Vec<Texture>) {
    (
        vec![
            SurfaceMaterial {
                base_colour: Vec4::new(0.20, 0.12, 0.06, 1.0),
                ..Default::default()
            },
            SurfaceMaterial {
                base_colour: Vec4::ONE,
                texture: Some(0),
                uv_transform: UvTransform::IDENTITY,
                alpha: AlphaMode::Mask(0.5),
            },
        ],
        vec![leaf_texture(64)],
    )
}

/// A leaf-shaped alpha mask (a pointed ellipse along the texture's diagonal) in shades of
/// green, linear RGBA, `size × size` texels.
pub fn leaf_texture(size: u32) -> Texture {
    let n = size.max(4);
    let texels = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32 + 0.5, (i / n) as f32 + 0.5);
            let p = Vec2::new(x, y) / n as f32 * 2.0 - Vec2::ONE;
            // Leaf axis along the diagonal: u along it, v across.
            let u = (p.x + p.y) * std::f32::consts::FRAC_1_SQRT_2;
            let v = (p.x - p.y) * std::f32::consts::FRAC_1_SQRT_2;
            let width = 0.45 * (1.0 - u * u).max(0.0).powf(0.8);
            let inside = u.abs() < 0.95 && v.abs() < width;
            let shade = 0.6 + 0.4 * (1.0 - v.abs() / width.max(1e-3)).clamp(0.0, 1.0);
            Vec4::new(
                0.05 * shade,
                0.30 * shade,
                0.04 * shade,
                if inside { 1.0 } else { 0.0 },
            )
        })
        .collect();
    Texture {
        width: n,
        height: n,
        texels,
    }
}

/// Appends a closed tapered cylinder (8 sides, capped) from `a` to `b`.
fn cylinder(out: &mut Vec<Triangle>, a: Vec3, b: Vec3, r0: f32, r1: f32, material: u32, part: u32) {
    let axis = (b - a).normalize_or(Vec3::Y);
    let t1 = axis.any_orthonormal_vector();
    let t2 = axis.cross(t1);
    let sides = 8;
    let ring = |c: Vec3, r: f32| -> Vec<Vec3> {
        (0..sides)
            .map(|k| {
                let phi = std::f32::consts::TAU * k as f32 / sides as f32;
                c + (t1 * phi.cos() + t2 * phi.sin()) * r
            })
            .collect()
    };
    let (ra, rb) = (ring(a, r0), ring(b, r1));
    let mut push = |p: [Vec3; 3]| {
        out.push(Triangle {
            positions: p,
            uvs: [Vec2::ZERO; 3],
            material,
            part,
        })
    };
    for k in 0..sides {
        let k1 = (k + 1) % sides;
        push([ra[k], ra[k1], rb[k1]]);
        push([ra[k], rb[k1], rb[k]]);
        push([a, ra[k1], ra[k]]);
        push([b, rb[k], rb[k1]]);
    }
}

/// Appends one leaf card: a square of side `size` centred at `c`, facing `normal`.
fn leaf_card(out: &mut Vec<Triangle>, c: Vec3, normal: Vec3, spin: f32, size: f32, part: u32) {
    let n = normal.normalize_or(Vec3::Y);
    let q = Quat::from_axis_angle(n, spin);
    let u = q * n.any_orthonormal_vector() * (size * 0.5);
    let v = n.cross(u);
    let p = [c - u - v, c + u - v, c + u + v, c - u + v];
    let uv = [
        Vec2::new(0.0, 1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(0.0, 0.0),
    ];
    out.push(Triangle {
        positions: [p[0], p[1], p[2]],
        uvs: [uv[0], uv[1], uv[2]],
        material: LEAVES,
        part,
    });
    out.push(Triangle {
        positions: [p[0], p[2], p[3]],
        uvs: [uv[0], uv[2], uv[3]],
        material: LEAVES,
        part,
    });
}

/// A procedural tree standing at the origin (Y up): a closed trunk, closed branches and
/// alpha-masked leaf cards clustered around the branch ends.
pub fn tree(params: &TreeParams) -> Result<Model, GridError> {
    params.validate()?;
    let mut rng = Rng::new(params.seed);
    let mut tris = Vec::new();
    let trunk_top = params.height * 0.65;
    cylinder(
        &mut tris,
        Vec3::ZERO,
        Vec3::Y * trunk_top,
        params.trunk_radius,
        params.trunk_radius * 0.6,
        BARK,
        0,
    );
    let crown_centre = Vec3::Y * (params.height - params.crown_radius);
    for b in 0..params.branches {
        let start = Vec3::Y * rng.range(0.45, 0.62) * params.height;
        let azimuth = std::f32::consts::TAU * (b as f32 + rng.f32()) / params.branches as f32;
        let dir = Vec3::new(azimuth.cos(), rng.range(0.5, 1.2), azimuth.sin()).normalize();
        let end = start + dir * params.crown_radius * rng.range(0.7, 1.0);
        let r = params.trunk_radius * 0.35;
        cylinder(&mut tris, start, end, r, r * 0.5, BARK, 1 + b);
        for _ in 0..params.leaves_per_branch {
            // Around the branch's outer half, pulled towards the crown's surface.
            let along = start + (end - start) * rng.range(0.4, 1.1);
            let mut c = along + rng.unit() * params.crown_radius * 0.35;
            let from_centre = c - crown_centre;
            if from_centre.length() > params.crown_radius {
                c = crown_centre + from_centre.normalize() * params.crown_radius;
            }
            leaf_card(
                &mut tris,
                c,
                rng.unit(),
                rng.range(0.0, std::f32::consts::TAU),
                params.leaf_size,
                1000 + b,
            );
        }
    }
    let (materials, textures) = tree_materials();
    Ok(Model {
        triangles: tris,
        materials,
        textures,
    })
}

/// A procedural bush of `radius` metres: a short stem and a dome of leaf cards.
pub fn bush(seed: u64, radius: f32) -> Result<Model, GridError> {
    if !(radius.is_finite() && radius > 0.0) {
        return Err(GridError::invalid(
            "radius",
            radius,
            "must be finite and > 0",
        ));
    }
    let mut rng = Rng::new(seed ^ 0xB05);
    let mut tris = Vec::new();
    cylinder(
        &mut tris,
        Vec3::ZERO,
        Vec3::Y * radius * 0.6,
        radius * 0.06,
        radius * 0.04,
        BARK,
        0,
    );
    let cards = (120.0 * radius * radius).clamp(20.0, 400.0) as u32;
    for _ in 0..cards {
        let mut d = rng.unit();
        d.y = d.y.abs();
        let c = Vec3::Y * radius * 0.5 + d * radius * rng.range(0.3, 1.0).sqrt();
        leaf_card(
            &mut tris,
            c,
            rng.unit(),
            rng.range(0.0, std::f32::consts::TAU),
            radius * 0.35,
            1,
        );
    }
    let (materials, textures) = tree_materials();
    Ok(Model {
        triangles: tris,
        materials,
        textures,
    })
}

/// A unit icosphere: the icosahedron with each triangle split in four `subdivisions`
/// times (20 · 4^n triangles), vertices on the unit sphere, faces counter-clockwise seen
/// from outside.
pub fn icosphere(subdivisions: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut verts: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: std::collections::HashMap<(usize, usize), usize> =
            std::collections::HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        for f in &faces {
            let mut m = [0usize; 3];
            for e in 0..3 {
                let (a, b) = (f[e], f[(e + 1) % 3]);
                let key = (a.min(b), a.max(b));
                m[e] = *mid.entry(key).or_insert_with(|| {
                    verts.push(((verts[a] + verts[b]) * 0.5).normalize());
                    verts.len() - 1
                });
            }
            next.extend([
                [f[0], m[0], m[2]],
                [f[1], m[1], m[0]],
                [f[2], m[2], m[1]],
                [m[0], m[1], m[2]],
            ]);
        }
        faces = next;
    }
    (
        verts,
        faces.into_iter().map(|f| f.map(|i| i as u32)).collect(),
    )
}

/// A procedural rock: a closed, bumpy icosphere of about `radius` metres, grey.
pub fn rock(seed: u64, radius: f32) -> Result<Model, GridError> {
    if !(radius.is_finite() && radius > 0.0) {
        return Err(GridError::invalid(
            "radius",
            radius,
            "must be finite and > 0",
        ));
    }
    let (verts, faces) = icosphere(2);
    let faces: Vec<[usize; 3]> = faces.iter().map(|f| f.map(|i| i as usize)).collect();
    let mut rng = Rng::new(seed ^ 0x50C);
    let bumps: Vec<(Vec3, f32)> = (0..6)
        .map(|_| (rng.unit(), rng.range(-0.15, 0.2)))
        .collect();
    let squash = Vec3::new(
        rng.range(0.9, 1.2),
        rng.range(0.5, 0.8),
        rng.range(0.9, 1.2),
    );
    let shaped: Vec<Vec3> = verts
        .iter()
        .map(|v| {
            let r = 1.0
                + bumps
                    .iter()
                    .map(|(d, a)| a * v.dot(*d).max(0.0).powi(3))
                    .sum::<f32>();
            *v * r * squash * radius + Vec3::Y * radius * squash.y * 0.6
        })
        .collect();
    let triangles = faces
        .iter()
        .map(|f| Triangle {
            positions: [shaped[f[0]], shaped[f[1]], shaped[f[2]]],
            uvs: [Vec2::ZERO; 3],
            material: 0,
            part: 0,
        })
        .collect();
    Ok(Model {
        triangles,
        materials: vec![SurfaceMaterial {
            base_colour: Vec4::new(0.32, 0.31, 0.29, 1.0),
            ..Default::default()
        }],
        textures: vec![],
    })
}

pub use crate::glb::write_glb;
