//! Shading with grid light, on the CPU. These functions are the specification: the WGSL
//! in `shaders/shading.wgsl` implements the same formulas (checked by the known-answer
//! render tests in `tests/render.rs`).
//!
//! Units: a light value is radiance-like (the average light of a uniform sky of radiance
//! `L` is `L`); irradiance is `π L` for that sky; a Lambertian surface of albedo `a`
//! under irradiance `E` sends out radiance `a E / π`.

use std::f32::consts::PI;

use lightgrid_core::glam::Vec3;

/// Irradiance on normal `n` from the average light `average` and the dominant direction
/// `dominant` (the way the light *travels*, length `s` in `[0, 1]`: how directional it
/// is), as for moving objects that read only these two grids.
///
/// The light is modelled as a uniform part `(1 - s)·average` plus the rest concentrated
/// in the one direction `-dominant/s`: `E = π (1 - s) average + 4π s average max(0,
/// n·(-dominant/s))`. Both parts carry the same total light as the bins they came from;
/// a uniform sky (`s = 0`) gives exactly `π L`, light in one narrow beam (`s → 1`) gives
/// the beam's cosine law.
pub fn irradiance_average_dominant(average: Vec3, dominant: Vec3, n: Vec3) -> Vec3 {
    let s = dominant.length().min(1.0);
    let n = n.normalize_or_zero();
    let cos = if s > 0.0 {
        (-n.dot(dominant / s)).max(0.0)
    } else {
        0.0
    };
    average * (PI * (1.0 - s) + 4.0 * PI * s * cos)
}

/// The cheap specular term from the dominant direction (Blinn-Phong on the directional
/// part of the light): `4π s average (n·h)^shininess (shininess + 8) / (8π)` with `h` the
/// half vector of the view direction `to_eye` and the light's arrival direction. Zero for
/// light with no preferred direction.
pub fn specular_dominant(
    average: Vec3,
    dominant: Vec3,
    n: Vec3,
    to_eye: Vec3,
    shininess: f32,
) -> Vec3 {
    let s = dominant.length().min(1.0);
    if s <= 0.0 {
        return Vec3::ZERO;
    }
    let l = -dominant / s;
    let n = n.normalize_or_zero();
    let h = (l + to_eye.normalize_or_zero()).normalize_or_zero();
    if n.dot(l) <= 0.0 {
        return Vec3::ZERO;
    }
    let spec = n.dot(h).max(0.0).powf(shininess) * (shininess + 8.0) / (8.0 * PI);
    average * (4.0 * PI * s * spec)
}

/// The direct sun kept apart from the bins (issue 14) on a surface facing `n`: its
/// irradiance `E T max(0, n · s)` and its Blinn-Phong specular
/// `E T (n·h)^shininess (shininess + 8) / (8π)` (`h` the half vector of `to_eye` and
/// the exact direction toward the sun `to_sun`; zero when the sun is behind the
/// surface). `sun` is the sun's irradiance `E` on a surface facing it, `t` its
/// transmittance at the point. Returns (irradiance, specular radiance per unit albedo).
pub fn direct_sun(
    sun: Vec3,
    t: f32,
    to_sun: Vec3,
    n: Vec3,
    to_eye: Vec3,
    shininess: f32,
) -> (Vec3, Vec3) {
    let (l, n) = (to_sun.normalize_or_zero(), n.normalize_or_zero());
    let cos = n.dot(l);
    if cos <= 0.0 || t.is_nan() || t <= 0.0 {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    let h = (l + to_eye.normalize_or_zero()).normalize_or_zero();
    let spec = n.dot(h).max(0.0).powf(shininess) * (shininess + 8.0) / (8.0 * PI);
    (sun * (t * cos), sun * (t * spec))
}

/// The direct sun on foliage, lit by `π × average` as the seed lights leaves: a beam of
/// irradiance `E T` has average light `E T / 4π`, so it adds `E T / 4`.
pub fn direct_sun_foliage(sun: Vec3, t: f32) -> Vec3 {
    sun * (t.max(0.0) * 0.25)
}

/// The seed's ground blend: an object's lighting becomes the ground's as its vertex gets
/// closer to the ground. Returns the object's share `t = smoothstep(0, blend_height,
/// height_above_ground)`: 0 on the ground (pure ground light), 1 at and above
/// `blend_height`. A non-positive `blend_height` disables the blend (always 1).
pub fn ground_blend_weight(height_above_ground: f32, blend_height: f32) -> f32 {
    if blend_height.is_nan() || blend_height <= 0.0 {
        return 1.0;
    }
    let x = (height_above_ground / blend_height).clamp(0.0, 1.0);
    if x.is_nan() {
        return 1.0;
    }
    x * x * (3.0 - 2.0 * x)
}

/// Underwater attenuation: `exp(-k · depth)` below the water level, 1 above it.
/// `k` is the water's attenuation per metre (>= 0).
pub fn underwater_attenuation(y: f32, water_level: f32, k: f32) -> f32 {
    let depth = water_level - y;
    if depth > 0.0 && k > 0.0 {
        (-k * depth).exp()
    } else {
        1.0
    }
}

/// The ACES filmic curve (Narkowicz's fit), per channel, for HDR to `[0, 1]`.
pub fn tonemap_aces(x: Vec3) -> Vec3 {
    let x = x.max(Vec3::ZERO);
    let (a, b, c, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
    ((x * (a * x + b)) / (x * (c * x + d) + e)).clamp(Vec3::ZERO, Vec3::ONE)
}

pub use lightgrid_core::pack::linear_to_srgb8;

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::BinLight;

    #[test]
    fn uniform_light_gives_pi_l_on_every_normal() {
        let l = Vec3::new(0.5, 1.0, 2.0);
        let b = BinLight::uniform(l);
        for n in [Vec3::Y, Vec3::NEG_Y, Vec3::new(1.0, 2.0, -3.0)] {
            let e = irradiance_average_dominant(b.average(), b.dominant(), n);
            assert!((e - PI * l).abs().max_element() < 1e-4 * PI * 2.0, "{e}");
        }
    }

    #[test]
    fn single_bin_light_follows_the_cosine_of_its_direction() {
        // All light in the straight-down bin: from above, E(up) ≈ total, E(down) = 0, and
        // the model conserves the total (its integral over all normals is the same as the
        // exact bins').
        let b = BinLight::single(lightgrid_core::dirs::DOWN, Vec3::ONE);
        let (avg, dom) = (b.average(), b.dominant());
        let up = irradiance_average_dominant(avg, dom, Vec3::Y);
        let down = irradiance_average_dominant(avg, dom, Vec3::NEG_Y);
        assert!((up.x - 1.0).abs() < 1e-5, "{up}");
        assert_eq!(down, Vec3::ZERO);
        // Exact bins spread over the bin's solid angle: slightly less than the beam.
        let exact = b.irradiance(Vec3::Y).x;
        assert!(exact < up.x && exact > 0.9, "{exact}");
    }

    #[test]
    fn mean_irradiance_over_normals_equals_the_exact_bins() {
        // Averaged over all normals, irradiance is π × average light for any bins (each
        // bin's light lands on half the normals with mean cosine 1/2... over the sphere:
        // ∫ E(n) dn / 4π = π avg). The model keeps that identity.
        let mut b = BinLight::uniform(Vec3::splat(0.3));
        b.0[3] += Vec3::new(5.0, 2.0, 1.0);
        let (avg, dom) = (b.average(), b.dominant());
        let (mut model, mut exact) = (Vec3::ZERO, Vec3::ZERO);
        let n = 20_000;
        for i in 0..n {
            // Fibonacci sphere.
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let phi = i as f32 * 2.399_963;
            let normal = Vec3::new(r * phi.cos(), y, r * phi.sin());
            model += irradiance_average_dominant(avg, dom, normal);
            exact += b.irradiance(normal);
        }
        let (model, exact) = (model / n as f32, exact / n as f32);
        assert!(
            ((model - exact) / exact).abs().max_element() < 2e-3,
            "{model} {exact}"
        );
        assert!(((model - PI * avg) / (PI * avg)).abs().max_element() < 2e-3);
    }

    #[test]
    fn direct_sun_follows_the_cosine_law_and_is_linear() {
        let e = Vec3::new(2.0, 1.0, 0.5);
        let s = Vec3::new(1.0, 1.0, 0.0).normalize();
        let (d, _) = direct_sun(e, 0.5, s, Vec3::Y, Vec3::Y, 16.0);
        assert!((d - e * 0.5 * s.y).abs().max_element() < 1e-6);
        // Linear in E and T.
        let (d2, sp2) = direct_sun(e * 3.0, 0.25, s, Vec3::Y, Vec3::Y, 16.0);
        let (_, sp) = direct_sun(e, 0.5, s, Vec3::Y, Vec3::Y, 16.0);
        assert!((d2 - d * 1.5).abs().max_element() < 1e-6);
        assert!((sp2 - sp * 1.5).abs().max_element() < 1e-6);
        // The specular peaks at the mirror direction.
        let mirror = Vec3::new(-s.x, s.y, 0.0);
        let peak = direct_sun(e, 1.0, s, Vec3::Y, mirror, 32.0).1.x;
        let off = direct_sun(e, 1.0, s, Vec3::Y, Vec3::new(1.0, 0.2, 0.0), 32.0)
            .1
            .x;
        assert!(peak > 10.0 * off, "{peak} {off}");
        // Behind the surface, or no beam: nothing.
        assert_eq!(
            direct_sun(e, 1.0, -s, Vec3::Y, Vec3::Y, 8.0),
            (Vec3::ZERO, Vec3::ZERO)
        );
        assert_eq!(
            direct_sun(e, 0.0, s, Vec3::Y, Vec3::Y, 8.0),
            (Vec3::ZERO, Vec3::ZERO)
        );
        assert_eq!(direct_sun_foliage(e, 0.4), e * 0.1);
    }

    #[test]
    fn specular_is_zero_without_direction_and_peaks_at_the_mirror() {
        let n = Vec3::Y;
        assert_eq!(
            specular_dominant(Vec3::ONE, Vec3::ZERO, n, Vec3::Y, 32.0),
            Vec3::ZERO
        );
        let dom = Vec3::new(1.0, -1.0, 0.0).normalize() * 0.8;
        let mirror = Vec3::new(1.0, 1.0, 0.0).normalize();
        let peak = specular_dominant(Vec3::ONE, dom, n, mirror, 32.0).x;
        let off = specular_dominant(Vec3::ONE, dom, n, Vec3::new(-1.0, 1.0, 0.0), 32.0).x;
        assert!(peak > 10.0 * off && peak > 0.0, "{peak} {off}");
        // Light from below the surface gives no highlight.
        assert_eq!(
            specular_dominant(Vec3::ONE, -dom, n, mirror, 32.0),
            Vec3::ZERO
        );
    }

    #[test]
    fn ground_blend_is_monotone_from_ground_to_object() {
        assert_eq!(ground_blend_weight(0.0, 2.0), 0.0);
        assert_eq!(ground_blend_weight(-1.0, 2.0), 0.0);
        assert_eq!(ground_blend_weight(2.0, 2.0), 1.0);
        assert_eq!(ground_blend_weight(0.3, 0.0), 1.0);
        assert_eq!(ground_blend_weight(f32::NAN, 2.0), 1.0);
        let mut last = 0.0;
        for i in 0..=100 {
            let t = ground_blend_weight(i as f32 * 0.02, 2.0);
            assert!(t >= last);
            last = t;
        }
    }

    #[test]
    fn underwater_light_falls_exponentially_with_depth() {
        assert_eq!(underwater_attenuation(5.0, 3.0, 0.2), 1.0);
        let a1 = underwater_attenuation(2.0, 3.0, 0.2);
        let a2 = underwater_attenuation(1.0, 3.0, 0.2);
        assert!((a1 - (-0.2f32).exp()).abs() < 1e-6);
        assert!((a2 - a1 * a1).abs() < 1e-6);
    }

    #[test]
    fn tonemap_and_srgb_are_monotone_and_bounded() {
        let mut last = -1.0;
        for i in 0..200 {
            let v = tonemap_aces(Vec3::splat(i as f32 * 0.1)).x;
            assert!((0.0..=1.0).contains(&v) && v >= last);
            last = v;
        }
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188);
    }
}
