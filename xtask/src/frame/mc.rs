//! The total error: the light the renderer reads from the hierarchy against a Monte
//! Carlo reference of the same world at the same points (`lightgrid_measure::points`,
//! backward paths from each point through the region's 1 m material, its open sky and
//! the sun), beside the single 1 m sweep's own error and the nesting error at those
//! points.
//!
//! A terrain vertex's true light is taken half a metre above it along its normal (in
//! the voxel world the ground's surface is the top of its opaque cells, which may lie
//! above the heightmap's); probes whose point lies inside an opaque cell (trunks,
//! ground) have no answer and are left out, and counted. The reported noise is the
//! probes' RMS standard error relative to the mean; an RMSE of `r` against a reference
//! of noise `σ` holds about `√(r² − σ²)` of error of its own.

use std::time::Instant;

use anyhow::Result;
use lightgrid_core::light::luminance;
use lightgrid_core::{Boundary, glam::Vec3};
use lightgrid_measure::points::{PointOptions, PointProbe, trace_points};
use lightgrid_measure::reference::CollimatedSun;
use serde::Serialize;

use super::{Acc, Acc3, Error, Errors, Parts, Probe, Reference, SUN_E, sky_bins};

/// The hierarchy, the single sweep and the Monte Carlo reference at a camera's probes.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct MonteCarlo {
    /// Probes with an answer (not inside an opaque cell).
    pub probes: usize,
    /// Probes inside opaque cells, left out.
    pub skipped: usize,
    /// Paths per probe.
    pub paths: u32,
    /// Seconds the Monte Carlo took.
    pub seconds: f64,
    /// The reference's noise: RMS standard error over the mean, sky, sun and both.
    pub noise: [f64; 3],
    /// Over every probe with an answer.
    pub all: Comparison,
    /// Over the terrain vertices.
    pub vertices: Comparison,
    /// Over the volume points.
    pub volume: Comparison,
    /// Over the volume points read facing up, down and sideways.
    pub volume_facing: [Comparison; 3],
}

/// The three comparisons over a set of probes.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Comparison {
    /// The hierarchy against Monte Carlo: the total error of what the renderer reads.
    pub total: Errors,
    /// The single 1 m sweep against Monte Carlo: the sweep's own error.
    pub sweep: Errors,
    /// The hierarchy against the single sweep at the same probes: the nesting error.
    pub nesting: Errors,
    /// The scattered sun alone (sun less direct): total, the sweep's own, nesting.
    pub scattered: [Error; 3],
}

/// Accumulates a [`Comparison`].
#[derive(Default, Clone)]
struct Compare {
    total: Acc3,
    sweep: Acc3,
    nesting: Acc3,
    scattered: [Acc; 3],
}

impl Compare {
    fn add(&mut self, h: Parts, s: Parts, r: Parts) {
        self.total.add(h, r);
        self.sweep.add(s, r);
        self.nesting.add(h, s);
        let sc = |p: Parts| p.sun - p.direct;
        self.scattered[0].add(sc(h), sc(r));
        self.scattered[1].add(sc(s), sc(r));
        self.scattered[2].add(sc(h), sc(s));
    }
    fn finish(&self) -> Comparison {
        Comparison {
            total: self.total.errors(),
            sweep: self.sweep.errors(),
            nesting: self.nesting.errors(),
            scattered: self.scattered.clone().map(|a| a.error()),
        }
    }
}

/// Every `stride`-th probe, `stride` prime to the six axes a volume point is read on
/// (so every axis is drawn), about `count` of them.
pub(super) fn pick(probes: &[Probe], count: usize) -> Vec<usize> {
    let mut stride = (probes.len() / count.max(1)).max(1);
    while stride > 1 && (stride.is_multiple_of(2) || stride.is_multiple_of(3)) {
        stride += 1;
    }
    (0..probes.len()).step_by(stride).collect()
}

/// The three comparisons at probes `which` of `probes`: `hier` and `sweep` are the
/// hierarchy's and the single sweep's reads there (all probes).
pub(super) fn measure(
    reference: &Reference,
    probes: &[Probe],
    which: &[usize],
    (hier, sweep): (&[Parts], &[Parts]),
    to_sun: Vec3,
    paths: u32,
) -> Result<MonteCarlo> {
    let _span = tracing::info_span!("monte carlo", probes = which.len(), paths).entered();
    let t = Instant::now();
    let points: Vec<PointProbe> = which
        .iter()
        .map(|&i| {
            let p = probes[i];
            let n = p.n.normalize();
            PointProbe {
                position: if p.vertex { p.p + 0.5 * n } else { p.p },
                normal: n,
            }
        })
        .collect();
    let sky = sky_bins(to_sun)?;
    let sun = CollimatedSun {
        to_sun,
        irradiance: SUN_E,
    };
    let mc = trace_points(
        &reference.material,
        &Boundary::open_sky(sky),
        Some(&sun),
        &points,
        &PointOptions {
            paths,
            ..Default::default()
        },
    )?;
    let seconds = t.elapsed().as_secs_f64();
    // All, vertices, volume; volume facing up, down, sideways.
    let mut cmp: [Compare; 6] = Default::default();
    let mut noise = [(0.0f64, 0.0f64); 3];
    let mut skipped = 0;
    for (&i, e) in which.iter().zip(&mc) {
        let Some(e) = e else {
            skipped += 1;
            continue;
        };
        let r = Parts {
            sky: luminance(e.sky),
            sun: luminance(e.sun_scattered + e.sun_direct),
            direct: luminance(e.sun_direct),
        };
        cmp[0].add(hier[i], sweep[i], r);
        cmp[if probes[i].vertex { 1 } else { 2 }].add(hier[i], sweep[i], r);
        if !probes[i].vertex {
            let y = probes[i].n.normalize().y;
            let facing = if y > 0.5 {
                3
            } else if y < -0.5 {
                4
            } else {
                5
            };
            cmp[facing].add(hier[i], sweep[i], r);
        }
        for (k, (se, v)) in [
            (e.sky_se, r.sky),
            (e.sun_se, r.sun),
            (e.both_se, r.sky + r.sun),
        ]
        .into_iter()
        .enumerate()
        {
            noise[k].0 += (se as f64).powi(2);
            noise[k].1 += v as f64;
        }
    }
    let n = (which.len() - skipped).max(1) as f64;
    Ok(MonteCarlo {
        probes: which.len() - skipped,
        skipped,
        paths,
        seconds,
        noise: noise.map(|(s2, v)| {
            if v > 0.0 {
                (s2 / n).sqrt() / (v / n)
            } else {
                0.0
            }
        }),
        all: cmp[0].finish(),
        vertices: cmp[1].finish(),
        volume: cmp[2].finish(),
        volume_facing: [cmp[3].finish(), cmp[4].finish(), cmp[5].finish()],
    })
}

/// The report's lines.
pub(super) fn lines(m: &MonteCarlo, elevation: f32) -> String {
    use std::fmt::Write;
    let f = |a: &Error| format!("{:+5.1} / {:4.1}", a.bias * 100.0, a.rmse * 100.0);
    let g = |a: &Error| format!("{:+.1} / {:.1}", a.bias * 100.0, a.rmse * 100.0);
    let mut s = format!(
        "  against Monte Carlo at the last camera, sun {elevation}° ({} probes: {} vertices, {} volume; {} inside opaque cells left out; {} paths each, {:.0} s; its noise sky / sun / both {:.1} / {:.1} / {:.1} %), bias / RMSE %:\n",
        m.probes,
        m.vertices.total.both.n,
        m.volume.total.both.n,
        m.skipped,
        m.paths,
        m.seconds,
        m.noise[0] * 100.0,
        m.noise[1] * 100.0,
        m.noise[2] * 100.0,
    );
    let _ = writeln!(
        s,
        "  total against Monte Carlo at sun {elevation}°: sky {}, sun {}, both {} (bias / RMSE %; the 1 m sweep's own: both {})",
        g(&m.all.total.sky),
        g(&m.all.total.sun),
        g(&m.all.total.both),
        g(&m.all.sweep.both),
    );
    let _ = writeln!(
        s,
        "    {:56} | {:12} | {:12} | {:12} | {:12} | {:12}",
        "", "sky", "sun", "scattered sun", "direct sun", "both"
    );
    for (name, c) in [
        ("all", &m.all),
        ("vertices", &m.vertices),
        ("volume", &m.volume),
        ("volume facing up", &m.volume_facing[0]),
        ("volume facing down", &m.volume_facing[1]),
        ("volume facing sideways", &m.volume_facing[2]),
    ] {
        for (k, (what, e)) in [
            ("total (the hierarchy as read)", &c.total),
            ("the 1 m sweep's own", &c.sweep),
            ("nesting (hierarchy vs sweep)", &c.nesting),
        ]
        .into_iter()
        .enumerate()
        {
            let _ = writeln!(
                s,
                "    {:56} | {} | {} | {} | {} | {}",
                format!("{name}, {what}"),
                f(&e.sky),
                f(&e.sun),
                f(&c.scattered[k]),
                f(&e.direct),
                f(&e.both)
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::glam::UVec3;
    use lightgrid_core::{GridDesc, Material, MaterialGrid};

    /// The single sweep read as the frame reads it, against the Monte Carlo reference
    /// at the same points, on a small world where the sweep is accurate (open sky over
    /// ground, a fog layer): the two agree in bias on sky, the scattered sun and the
    /// direct sun, so a read in other units (the sun's response is per unit
    /// irradiance) cannot pass.
    #[test]
    fn the_sweep_as_read_agrees_with_monte_carlo() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(24, 10, 24)).unwrap();
        let cells = (0..desc.point_count())
            .map(|i| match desc.coords(i).unwrap().y {
                0 | 1 => Material::opaque(Vec3::new(0.5, 0.45, 0.4)),
                4..=6 => Material {
                    reflectance: Vec3::new(0.6, 0.7, 0.5),
                    pass: 0.7,
                },
                _ => Material::EMPTY,
            })
            .collect();
        let mut reference = Reference {
            material: MaterialGrid::new(desc, cells).unwrap(),
            sky: None,
            sun: None,
        };
        let params = lightgrid_terrain_lod::HierarchyParams::default();
        let to_sun = super::super::sun_dir(35.0);
        reference
            .sweep_sky(&params, sky_bins(to_sun).unwrap())
            .unwrap();
        reference.sweep_sun(&params, to_sun).unwrap();
        let mut probes = Vec::new();
        for x in [9.3f32, 12.0, 14.6] {
            for z in [9.5f32, 13.2] {
                probes.push(Probe {
                    p: Vec3::new(x, 1.3, z),
                    n: Vec3::Y,
                    vertex: true,
                });
                for y in [2.5f32, 5.0, 8.0] {
                    for n in lightgrid_core::light::AMBIENT_AXES {
                        probes.push(Probe {
                            p: Vec3::new(x, y, z),
                            n,
                            vertex: false,
                        });
                    }
                }
            }
        }
        let read = reference.sky_and_sun(&probes).unwrap();
        let which: Vec<usize> = (0..probes.len()).collect();
        let m = measure(&reference, &probes, &which, (&read, &read), to_sun, 4096).unwrap();
        assert_eq!(m.skipped, 0);
        let e = &m.all;
        assert!(e.sweep.sky.bias.abs() < 0.05, "sky {:?}", e.sweep.sky);
        assert!(
            e.scattered[1].bias.abs() < 0.15,
            "scattered sun {:?}",
            e.scattered[1]
        );
        // (+2.9 %: trilinear reads of the transmittance across the fog, a convex
        // exponential, overstate it.)
        assert!(
            e.sweep.direct.bias.abs() < 0.05,
            "direct sun {:?}",
            e.sweep.direct
        );
        assert_eq!(e.nesting.both.rmse, 0.0);
    }

    #[test]
    fn picks_every_axis() {
        let probes: Vec<Probe> = (0..6000)
            .map(|i| Probe {
                p: Vec3::ZERO,
                n: Vec3::ONE,
                vertex: i < 600,
            })
            .collect();
        let w = pick(&probes, 500);
        assert!((400..=600).contains(&w.len()), "{}", w.len());
        for axis in 0..6 {
            assert!(w.iter().any(|&i| i % 6 == axis), "axis {axis}");
        }
    }
}
