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

use super::{Acc3, Errors, Parts, Probe, Reference, SUN_E, sky_bins};

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
    /// The hierarchy against Monte Carlo: the total error of what the renderer reads.
    pub total: Errors,
    /// The single 1 m sweep against Monte Carlo: the sweep's own error.
    pub sweep: Errors,
    /// The hierarchy against the single sweep at the same probes: the nesting error.
    pub nesting: Errors,
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
    let (mut total, mut own, mut nest) = (Acc3::default(), Acc3::default(), Acc3::default());
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
        total.add(hier[i], r);
        own.add(sweep[i], r);
        nest.add(hier[i], sweep[i]);
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
        total: total.errors(),
        sweep: own.errors(),
        nesting: nest.errors(),
    })
}

/// The report's lines.
pub(super) fn lines(m: &MonteCarlo, elevation: f32) -> String {
    let e = |x: &Errors| {
        let f = |a: &super::Error| format!("{:+.1} / {:.1}", a.bias * 100.0, a.rmse * 100.0);
        format!(
            "sky {}, sun {}, both {}, direct sun {}",
            f(&x.sky),
            f(&x.sun),
            f(&x.both),
            f(&x.direct)
        )
    };
    format!(
        "  against Monte Carlo at the last camera, sun {elevation}° ({} probes, {} inside opaque cells left out; {} paths each, {:.0} s; its noise sky / sun / both {:.1} / {:.1} / {:.1} %), bias / RMSE %:\n    total (the hierarchy as read): {}\n    the 1 m sweep's own:           {}\n    nesting (hierarchy vs sweep):  {}\n",
        m.probes,
        m.skipped,
        m.paths,
        m.seconds,
        m.noise[0] * 100.0,
        m.noise[1] * 100.0,
        m.noise[2] * 100.0,
        e(&m.total),
        e(&m.sweep),
        e(&m.nesting),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

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
