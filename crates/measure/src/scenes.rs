//! Canonical test scenes and the error measures used to compare a sweep with the
//! Monte Carlo reference.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::light::{AMBIENT_AXES, luminance};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, LightGrid, Material, MaterialGrid, SideBoundary,
};

/// The five canonical scenes (periodic sides, lit by a uniform sky of radiance 1 from
/// above and a sun).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scene {
    /// No material at all.
    Empty,
    /// Fog everywhere: pass-through 0.8, reflectance 0.7.
    UniformFog,
    /// A dense block (pass-through 0.05, reflectance 0.5) standing on opaque ground.
    DenseBlock,
    /// A layer of foliage (pass-through 0.6, green) over opaque ground (two levels).
    Canopy,
    /// The canopy over ground one level thick (issue 13: a bottom level of ground
    /// once emitted half its bounce light downward into nothing).
    CanopyOneLevelGround,
}

impl Scene {
    /// All five, in order.
    pub const ALL: [Scene; 5] = [
        Scene::Empty,
        Scene::UniformFog,
        Scene::DenseBlock,
        Scene::Canopy,
        Scene::CanopyOneLevelGround,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Scene::Empty => "empty",
            Scene::UniformFog => "uniform fog",
            Scene::DenseBlock => "dense block",
            Scene::Canopy => "canopy",
            Scene::CanopyOneLevelGround => "canopy, 1-level ground",
        }
    }

    /// The scene's material on an `n × n × n` grid of 1 m cells, and its boundary.
    pub fn build(self, n: u32) -> (MaterialGrid, Boundary) {
        let n = n.max(4);
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(n)).expect("valid scene grid");
        let ground = Material::opaque(Vec3::splat(0.3));
        let cells = (0..desc.point_count())
            .map(|i| {
                let p = desc.coords(i).expect("index in range");
                let third = n / 3;
                match self {
                    Scene::Empty => Material::EMPTY,
                    Scene::UniformFog => Material {
                        reflectance: Vec3::splat(0.7),
                        pass: 0.8,
                    },
                    Scene::DenseBlock if p.y < 2 => ground,
                    Scene::DenseBlock => {
                        let inside = (third..2 * third).contains(&p.x)
                            && (third..2 * third).contains(&p.z)
                            && p.y < 2 + third;
                        if inside {
                            Material {
                                reflectance: Vec3::splat(0.5),
                                pass: 0.05,
                            }
                        } else {
                            Material::EMPTY
                        }
                    }
                    Scene::Canopy if p.y < 2 => ground,
                    Scene::CanopyOneLevelGround if p.y < 1 => ground,
                    Scene::Canopy | Scene::CanopyOneLevelGround => {
                        if (n / 2..n / 2 + 2).contains(&p.y) {
                            Material {
                                reflectance: Vec3::new(0.1, 0.4, 0.1),
                                pass: 0.6,
                            }
                        } else {
                            Material::EMPTY
                        }
                    }
                }
            })
            .collect();
        let material = MaterialGrid::new(desc, cells).expect("valid scene material");
        (
            material,
            Boundary {
                sides: SideBoundary::Periodic,
                ..sky_and_sun()
            },
        )
    }
}

/// A uniform sky of radiance 1 from above plus a sun of 20 in the bin `(1, -1, 0)`,
/// nothing from below.
pub fn sky_and_sun() -> Boundary {
    let (mut top, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    let sun_bin =
        lightgrid_core::dirs::dir_index(lightgrid_core::glam::IVec3::new(1, -1, 0)).expect("bin");
    top.0[sun_bin] += Vec3::splat(20.0);
    Boundary::open_sky(top)
}

/// Errors of a light grid against a reference, over the points outside opaque cells
/// whose reference average light exceeds 1e-3 of the largest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Errors {
    /// `sqrt(Σ (a - r)² / Σ r²)` of the average light's luminance.
    pub average: f64,
    /// The same over irradiance on the six axis normals together.
    pub irradiance: f64,
    /// Points compared.
    pub points: usize,
}

/// Compares `light` with `reference` (same descriptor).
pub fn compare(light: &LightGrid, reference: &LightGrid, material: &MaterialGrid) -> Errors {
    let max = reference
        .data()
        .iter()
        .map(|b| luminance(b.average()))
        .fold(0.0, f32::max);
    let (mut na, mut da, mut ni, mut di, mut points) = (0.0, 0.0, 0.0, 0.0, 0);
    for ((a, r), m) in light
        .data()
        .iter()
        .zip(reference.data())
        .zip(material.data())
    {
        let ra = luminance(r.average());
        if m.pass <= 0.0 || ra <= 1e-3 * max {
            continue;
        }
        points += 1;
        let la = luminance(a.average());
        na += ((la - ra) as f64).powi(2);
        da += (ra as f64).powi(2);
        for n in AMBIENT_AXES {
            let (x, y) = (
                luminance(a.irradiance(n)) as f64,
                luminance(r.irradiance(n)) as f64,
            );
            ni += (x - y).powi(2);
            di += y * y;
        }
    }
    let ratio = |n: f64, d: f64| if d > 0.0 { (n / d).sqrt() } else { 0.0 };
    Errors {
        average: ratio(na, da),
        irradiance: ratio(ni, di),
        points,
    }
}
