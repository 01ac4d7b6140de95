//! The Monte Carlo reference for probe irradiance: paths traced through the meshes
//! with Lambertian bounces, the sky seen by escaping rays and the sun by shadow rays at
//! every bounce. Shares nothing with the probes but the ray queries: no surfels, no
//! bricks, no probe-to-probe light.

use lightgrid_core::dirs;
use lightgrid_core::glam::Vec3;
use lightgrid_core::light::{AMBIENT_AXES, AmbientCube};
use lightgrid_material_voxelizer::voxelize::RayScene;
use rayon::prelude::*;

use crate::Lighting;

/// Radiance arriving at a point from direction `d` when the ray leaves the scene.
fn sky_radiance(lighting: &Lighting, d: Vec3) -> Vec3 {
    let b = dirs::nearest_dir(-d);
    lighting.sky.0[b] / dirs::solid_angles()[b]
}

/// A cosine-weighted direction around unit `n`.
fn cosine_sample(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    let (t, b) = n.any_orthonormal_pair();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize()
}

/// Radiance arriving at `o` from direction `d` (path tracing, at most `depth` bounces,
/// Russian roulette after three).
fn radiance(
    scene: &RayScene<'_>,
    lighting: &Lighting,
    mut o: Vec3,
    mut d: Vec3,
    rng: &mut fastrand::Rng,
    max_distance: f32,
    depth: u32,
) -> Vec3 {
    let mut weight = Vec3::ONE;
    let mut sum = Vec3::ZERO;
    for bounce in 0..depth {
        let Some(hit) = scene.closest_hit(o, d, max_distance, 0.5) else {
            sum += weight * sky_radiance(lighting, d);
            break;
        };
        let p = o + d * hit.t + hit.normal * 1e-3;
        let n = hit.normal;
        weight *= hit.colour;
        // Direct sun at the hit: albedo E V max(0, n · s) / π.
        if let Some((s, e)) = lighting.sun {
            let s = s.normalize();
            let c = n.dot(s);
            if c > 0.0 && scene.closest_hit(p, s, max_distance, 0.5).is_none() {
                sum += weight * e * (c / std::f32::consts::PI);
            }
        }
        if bounce >= 3 {
            let survive = weight.max_element().min(0.95);
            if rng.f32() >= survive {
                break;
            }
            weight /= survive;
        }
        // A cosine-weighted bounce: the albedo / π and the cosine / pdf cancel to 1.
        o = p;
        d = cosine_sample(n, rng.f32(), rng.f32());
    }
    sum
}

/// The irradiance at `p` on the six ambient-cube axes, `π × mean L` over `samples`
/// cosine-weighted directions per axis; the direct sun on the probe itself is left
/// out, as in the probes. Deterministic for a seed. Returns the irradiance and its
/// standard error.
pub fn irradiance(
    scene: &RayScene<'_>,
    lighting: &Lighting,
    p: Vec3,
    samples: u32,
    max_distance: f32,
    seed: u64,
) -> (AmbientCube, AmbientCube) {
    let per_axis: Vec<(Vec3, Vec3)> = (0..6)
        .into_par_iter()
        .map(|k| {
            let mut rng = fastrand::Rng::with_seed(seed ^ ((k as u64 + 1) * 0x9E37_79B9));
            let (mut s, mut s2) = (Vec3::ZERO, Vec3::ZERO);
            for _ in 0..samples {
                let d = cosine_sample(AMBIENT_AXES[k], rng.f32(), rng.f32());
                let l = radiance(scene, lighting, p, d, &mut rng, max_distance, 64)
                    * std::f32::consts::PI;
                s += l;
                s2 += l * l;
            }
            let n = samples.max(1) as f32;
            let mean = s / n;
            let var = (s2 / n - mean * mean).max(Vec3::ZERO);
            (mean, (var / n).powf(0.5))
        })
        .collect();
    (
        AmbientCube(std::array::from_fn(|k| per_axis[k].0)),
        AmbientCube(std::array::from_fn(|k| per_axis[k].1)),
    )
}
