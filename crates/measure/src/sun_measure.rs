//! Measuring the sun split against the sun in the bins (issue 14), both against the
//! Monte Carlo reference with a collimated sun along its exact direction
//! ([`crate::reference::trace_with_sun`], its uncollided light kept apart). Shared by
//! `examples/sun_split.rs` (canonical scenes, a dense block's shadow) and
//! `cargo xtask sun` (the bench forest, a single tree's shadow).
//!
//! - **Bins**: the sun's disc split over the bins of the top boundary, swept; its light
//!   moves along the nearest bin and lands with the bin's mean cosine.
//! - **Split**: the exact transmittance ([`SunTransmittance::march`]) for the direct
//!   beam, its first collisions ([`first_collision`]) swept as a cell source for the
//!   scattered light.
//!
//! Errors are relative RMSE over the points that are not solid and not dark (average
//! above 1e-3 of the largest), of the luminance of the average light and of the
//! irradiance on the six axes, sun light only.

use std::time::Instant;

use lightgrid_core::glam::Vec3;
use lightgrid_core::light::{AMBIENT_AXES, luminance};
use lightgrid_core::{BinLight, Boundary, MaterialGrid, SideBoundary, SweepOptions};

use crate::reference::{CollimatedSun, ReferenceOptions, trace_with_sun};
use lightgrid_sky::Sun;
use lightgrid_sweep_cpu::run;
use lightgrid_sweep_cpu::sun::{SunTransmittance, first_collision};

/// Average light and the six axis irradiances (luminance) of every point.
pub type Field = Vec<(f32, [f32; 6])>;

/// The field of `bins`, plus a direct beam `(transmittance per point, irradiance E,
/// direction s toward the sun)` where one is kept apart: it adds `E T / 4π` to the
/// average and `E T max(0, n · s)` to the irradiance on `n`.
pub fn field(bins: &[BinLight], direct: Option<(&[f32], Vec3, Vec3)>) -> Field {
    bins.iter()
        .enumerate()
        .map(|(i, b)| {
            let (mut avg, mut irr) = (b.average(), AMBIENT_AXES.map(|n| b.irradiance(n)));
            if let Some((t, e, s)) = direct {
                avg += e * t[i] / (4.0 * std::f32::consts::PI);
                for (k, n) in AMBIENT_AXES.iter().enumerate() {
                    irr[k] += e * t[i] * n.dot(s).max(0.0);
                }
            }
            (luminance(avg), irr.map(luminance))
        })
        .collect()
}

/// Relative RMSE of average light and of irradiance of `a` against the reference `r`,
/// over the points not `solid` and not dark.
pub fn errors(a: &Field, r: &Field, solid: &[bool]) -> (f64, f64) {
    let max = r.iter().map(|x| x.0).fold(0.0, f32::max);
    let (mut na, mut da, mut ni, mut di) = (0.0, 0.0, 0.0, 0.0);
    for ((x, y), &s) in a.iter().zip(r).zip(solid) {
        if s || y.0 <= 1e-3 * max {
            continue;
        }
        na += ((x.0 - y.0) as f64).powi(2);
        da += (y.0 as f64).powi(2);
        for k in 0..6 {
            ni += ((x.1[k] - y.1[k]) as f64).powi(2);
            di += (y.1[k] as f64).powi(2);
        }
    }
    ((na / da.max(1e-300)).sqrt(), (ni / di.max(1e-300)).sqrt())
}

/// The Monte Carlo reference of a collimated sun of unit irradiance toward `to_sun`
/// in `material` with `boundary` (its light besides the sun's), `paths` paths from
/// `seed`.
pub fn sun_reference(
    material: &MaterialGrid,
    boundary: &Boundary,
    to_sun: Vec3,
    paths: u64,
    seed: u64,
) -> Result<crate::reference::Reference, lightgrid_core::SweepError> {
    trace_with_sun(
        material,
        boundary,
        Some(&CollimatedSun {
            to_sun,
            irradiance: Vec3::ONE,
        }),
        &ReferenceOptions {
            paths,
            time_budget: None,
            seed,
            max_events: 256,
            max_track: 8.0,
        },
        &|_, _| {},
    )
}

/// One case's figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunErrors {
    /// Relative RMSE of average light / irradiance with the sun in the bins.
    pub bins: (f64, f64),
    /// The same with the split.
    pub split: (f64, f64),
    /// The reference's own relative standard error of the average light.
    pub noise: f64,
    /// Seconds: the binned sweep, and the split (march, first collisions, sweep).
    pub seconds: (f64, f64),
}

/// The sun's first collisions `source` (the sun toward `to_sun`) swept into the bins by
/// the CPU sweeper, their first scatterings gathered where `options.gather` asks for a
/// sun this high, as `Sweeper::sweep_sun` does (`multi_bounce`'s `Gather::AUTO` at or
/// below 30°).
fn scattered_sun(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: &lightgrid_core::CellSource,
    to_sun: Vec3,
    options: &SweepOptions,
) -> Result<lightgrid_core::LightGrid, lightgrid_core::SweepError> {
    let mut o = *options;
    o.gather = options.gather.for_sun(to_sun);
    o.outputs.bins = true;
    let out = lightgrid_core::Sweeper::sweep_with_source(
        &mut lightgrid_sweep_cpu::CpuSweeper::new(),
        material,
        boundary,
        source,
        &o,
    )?;
    Ok(out.bins.expect("bins asked for"))
}

/// Sun light only (unit irradiance) at `elevation`/`azimuth` (radians) in `material`
/// with `sides`: the bins and the split against a reference of `paths` paths.
pub fn sun_errors(
    material: &MaterialGrid,
    sides: &SideBoundary,
    elevation: f32,
    azimuth: f32,
    paths: u64,
    options: &SweepOptions,
) -> Result<SunErrors, Box<dyn std::error::Error>> {
    let e = Vec3::ONE;
    let sun = Sun::at(elevation, azimuth, e);
    let s = sun.direction;
    let dark = Boundary {
        sides: sides.clone(),
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let periodic = matches!(sides, SideBoundary::Periodic);
    let solid: Vec<bool> = material.data().iter().map(|c| c.pass <= 0.0).collect();
    let reference = sun_reference(material, &dark, s, paths, 7)?;
    let ref_t: Vec<f32> = reference.direct.iter().map(|d| d.x / e.x).collect();
    let r = field(reference.light.data(), Some((&ref_t, e, s)));
    let t0 = Instant::now();
    let in_bins = Boundary {
        sides: sides.clone(),
        ..Boundary::open_sky(sun.bins()?)
    };
    let binned = run(material, &in_bins, options)?.output.bins.expect("bins");
    let t_bins = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let open = |_: Vec3| 1.0;
    let t = SunTransmittance::march(material, s, periodic, &open)?;
    let src = first_collision(material, s, e, periodic, &open)?;
    let scattered = scattered_sun(material, &dark, &src, s, options)?;
    let t_split = t0.elapsed().as_secs_f64();
    let fb = field(binned.data(), None);
    let fs = field(scattered.data(), Some((t.values(), e, s)));
    Ok(SunErrors {
        bins: errors(&fb, &r, &solid),
        split: errors(&fs, &r, &solid),
        noise: reference.relative_std_error(0.0),
        seconds: (t_bins, t_split),
    })
}

/// Upward irradiance (luminance) at the points of `level`, with the sun in the bins and
/// with the split, periodic sides.
pub fn ground_light(
    m: &MaterialGrid,
    sun: &Sun,
    level: u32,
    o: &SweepOptions,
) -> Result<(Vec<f32>, Vec<f32>), Box<dyn std::error::Error>> {
    let periodic = SideBoundary::Periodic;
    let range = m.desc().level_range(level);
    let binned = run(
        m,
        &Boundary {
            sides: periodic.clone(),
            ..Boundary::open_sky(sun.bins()?)
        },
        o,
    )?
    .output
    .bins
    .expect("bins");
    let s = sun.direction;
    let open = |_: Vec3| 1.0;
    let t = SunTransmittance::march(m, s, true, &open)?;
    let src = first_collision(m, s, sun.illuminance, true, &open)?;
    let dark = Boundary {
        sides: periodic,
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let scattered = scattered_sun(m, &dark, &src, s, o)?;
    let b: Vec<f32> = binned.data()[range.clone()]
        .iter()
        .map(|l| luminance(l.irradiance(Vec3::Y)))
        .collect();
    let sp: Vec<f32> = scattered.data()[range.clone()]
        .iter()
        .zip(&t.values()[range])
        .map(|(l, t)| luminance(l.irradiance(Vec3::Y) + sun.illuminance * (t * s.y)))
        .collect();
    Ok((b, sp))
}

/// A patchy canopy over opaque ground (issue 44's scene, unlike the canonical ones):
/// `n × n` columns, `n * 5 / 8` levels, periodic-friendly; the ground's top level
/// (albedo 0.2), then two clear levels, then clumps of 2 × 2 columns, each present
/// with probability one half, of three medium levels (pass-through 0.35–0.75 a cell,
/// albedo 0.7), clear air above.
pub fn patchy_canopy(n: u32, seed: u64) -> MaterialGrid {
    use lightgrid_core::{GridDesc, Material};
    let ny = (n * 5 / 8).max(8);
    let desc = GridDesc::new(Vec3::ZERO, 1.0, lightgrid_core::glam::UVec3::new(n, ny, n))
        .expect("valid dims");
    let mut rng = fastrand::Rng::with_seed(seed);
    let clumps = n.div_ceil(2) as usize;
    let present: Vec<bool> = (0..clumps * clumps).map(|_| rng.bool()).collect();
    let passes: Vec<f32> = (0..desc.point_count())
        .map(|_| 0.35 + 0.4 * rng.f32())
        .collect();
    let cells = (0..desc.point_count())
        .map(|i| {
            let c = desc.coords(i).expect("in range");
            if c.y == 0 {
                return Material {
                    reflectance: Vec3::splat(0.2),
                    pass: 0.0,
                };
            }
            let clump = (c.x / 2) as usize + clumps * (c.z / 2) as usize;
            if (3..6).contains(&c.y) && present[clump] {
                Material {
                    reflectance: Vec3::splat(0.7),
                    pass: passes[i],
                }
            } else {
                Material::EMPTY
            }
        })
        .collect();
    MaterialGrid::new(desc, cells).expect("valid cells")
}

/// The sweep's sun light (first collisions swept, plus the direct beam) in the medium
/// cells against the Monte Carlo reference's, sun only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MediumErrors {
    /// The medium cells' summed average light over the reference's, minus 1.
    pub bias: f64,
    /// Relative RMS of the cells' average light.
    pub rms: f64,
    /// The largest relative error of a cell whose reference noise is below 1 %.
    pub max: f64,
    /// The reference's relative standard error (RMS over the medium cells).
    pub noise: f64,
    /// The beam's first collisions over what entered.
    pub collided: f64,
    /// Relative RMS of the cells' direct light alone (the beam's cell-mean
    /// transmittance against the reference's uncollided tally).
    pub direct_rms: f64,
    /// The medium cells' summed scattered light over the reference's, minus 1.
    pub scattered_bias: f64,
    /// The cells whose reference noise is below 1 %.
    pub quiet: usize,
    /// How many of those are over 5 % off.
    pub over_5: usize,
    /// The sweep's and the reference's light (luminance) at the worst of those cells.
    pub worst: [f64; 2],
}

/// [`MediumErrors`] for a sun at `elevation`/`azimuth` (radians), unit irradiance, in
/// `material` with periodic or open sides.
pub fn medium_errors(
    material: &MaterialGrid,
    periodic: bool,
    elevation: f32,
    azimuth: f32,
    paths: u64,
    options: &SweepOptions,
) -> Result<MediumErrors, Box<dyn std::error::Error>> {
    let e = Vec3::ONE;
    let s = Sun::at(elevation, azimuth, e).direction;
    let sides = if periodic {
        SideBoundary::Periodic
    } else {
        SideBoundary::Open
    };
    let dark = Boundary {
        sides,
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let reference = sun_reference(material, &dark, s, paths, 11)?;
    let open = |_: Vec3| 1.0;
    let fc = lightgrid_sweep_cpu::sun::first_collisions(
        material,
        s,
        e,
        periodic,
        &open,
        &lightgrid_sweep_cpu::sun::BeamOptions::DEFAULT.with_mean_transmittance(),
    )?;
    let mean_t = fc.mean_transmittance.as_deref().expect("asked for");
    let scattered = scattered_sun(material, &dark, &fc.source, s, options)?;
    let four_pi = 4.0 * std::f32::consts::PI;
    let (mut sa, mut sr, mut se, mut sw, mut max, mut noise, mut n) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64, 0usize);
    // Direct alone: squared error and weight; scattered alone: sums.
    let (mut de, mut dw, mut ss, mut sref) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (mut quiet, mut over_5, mut worst) = (0usize, 0usize, [0.0f64; 2]);
    for (i, cell) in material.data().iter().enumerate() {
        if cell.pass <= 0.0 || cell.pass >= 1.0 {
            continue;
        }
        let a = luminance(scattered.data()[i].average() + e * mean_t[i] / four_pi) as f64;
        let r =
            luminance(reference.light.data()[i].average() + reference.direct[i] / four_pi) as f64;
        let rel_noise = luminance(reference.std_error[i]) as f64 / r.max(1e-30);
        let (d, dr) = (
            luminance(e * mean_t[i]) as f64,
            luminance(reference.direct[i]) as f64,
        );
        de += (d - dr).powi(2);
        dw += dr * dr;
        ss += luminance(scattered.data()[i].average()) as f64;
        sref += luminance(reference.light.data()[i].average()) as f64;
        sa += a;
        sr += r;
        se += (a - r).powi(2);
        sw += r * r;
        noise += rel_noise * rel_noise;
        n += 1;
        if rel_noise < 0.01 {
            let off = (a / r - 1.0).abs();
            quiet += 1;
            over_5 += (off > 0.05) as usize;
            if off > max {
                max = off;
                worst = [a, r];
            }
        }
    }
    Ok(MediumErrors {
        bias: sa / sr.max(1e-300) - 1.0,
        rms: (se / sw.max(1e-300)).sqrt(),
        max,
        noise: (noise / n.max(1) as f64).sqrt(),
        collided: fc.budget.collided / fc.budget.entered.max(1e-300),
        direct_rms: (de / dw.max(1e-300)).sqrt(),
        scattered_bias: ss / sref.max(1e-300) - 1.0,
        quiet,
        over_5,
        worst,
    })
}

/// The azimuth (degrees, from -Z toward +X as [`Sun::at`]) of the centroid of the light
/// an object takes away from a periodic `nx × nz` level (`lit` with it, `open` without),
/// seen from `centre` (the object's axis, in cell coordinates): the direction of its
/// shadow.
pub fn shadow_azimuth(lit: &[f32], open: &[f32], nx: u32, nz: u32, centre: Vec3) -> f32 {
    let (mut sum, mut acc) = (0.0f32, Vec3::ZERO);
    for (i, (a, b)) in lit.iter().zip(open).enumerate() {
        let deficit = (b - a).max(0.0);
        let p = Vec3::new((i as u32 % nx) as f32, 0.0, (i as u32 / nx) as f32);
        // Periodic ground: the nearest image of the point.
        let mut off = p - centre;
        off.x -= nx as f32 * (off.x / nx as f32).round();
        off.z -= nz as f32 * (off.z / nz as f32).round();
        acc += off * deficit;
        sum += deficit;
    }
    let v = acc / sum.max(1e-12);
    v.x.atan2(-v.z).to_degrees()
}

/// The exact azimuth of a shadow (away from the sun) for a sun toward `to_sun`
/// ([`Sun::direction`]).
pub fn exact_shadow_azimuth(to_sun: Vec3) -> f32 {
    (-to_sun.x).atan2(to_sun.z).to_degrees()
}

/// `|a - b|` in degrees, wrapped into `[0, 180]`.
pub fn angle_error(a: f32, b: f32) -> f32 {
    ((a - b + 540.0).rem_euclid(360.0) - 180.0).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shadow_azimuth_of_a_known_deficit() {
        // A shadow three cells toward +X of the centre: azimuth 90 degrees.
        let (nx, nz) = (8u32, 8u32);
        let open = vec![1.0; 64];
        let mut lit = open.clone();
        lit[(4 * nx + 7) as usize] = 0.0;
        let a = shadow_azimuth(&lit, &open, nx, nz, Vec3::new(4.0, 0.0, 4.0));
        assert!((a - 90.0).abs() < 1e-4, "{a}");
        assert!((angle_error(179.0, -179.0) - 2.0).abs() < 1e-4);
        // A sun in the -X sky casts its shadow toward +X.
        let to_sun = Vec3::new(-1.0, 1.0, 0.0).normalize();
        assert!((exact_shadow_azimuth(to_sun) - 90.0).abs() < 1e-4);
    }
}
