//! How the 26 bins read irradiance across the horizon (issue 44): a horizontal bin holds
//! light travelling slightly down and slightly up, and `BinLight::irradiance` reads it
//! as even across the horizon. Against exact answers (an infinite Lambertian ground
//! under a uniform sky) and against the Monte Carlo reference's irradiance tally, which
//! uses the paths' exact directions (`Reference::irradiance`), on canopies.
//!
//! On canopies, sky alone, a 30° sun alone (its first collisions swept, its direct beam
//! by the cells' mean transmittance) and both.
//!
//! `cargo run --release -p lightgrid-measure --example horizon -- [paths]` (2 000 000)

use lightgrid_core::BinLight;
use lightgrid_core::glam::Vec3;
use lightgrid_core::light::{AMBIENT_AXES, luminance};
use lightgrid_core::{Boundary, MaterialGrid, SideBoundary, SweepOptions};
use lightgrid_measure::reference::{Reference, ReferenceOptions, trace};
use lightgrid_measure::scenes::Scene;
use lightgrid_measure::sun_measure;
use lightgrid_sky::Sun;
use lightgrid_sweep_cpu::sun::{BeamOptions, first_collisions};

fn converged() -> SweepOptions {
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 64;
    o.tolerance = 1e-6;
    o.outputs = o.outputs.with_horizon();
    o
}

/// Six axes' irradiance (luminance) per cell: the sweep's bins read even across the
/// horizon, read in halves, and the reference's tally.
struct Axes {
    even: Vec<[f64; 6]>,
    halves: Vec<[f64; 6]>,
    reference: Vec<[f64; 6]>,
}

impl Axes {
    /// From the sweep's bins and halves and the reference's tally, plus a direct beam
    /// `E T max(0, n·s)` of each (the sweep's transmittance `t`, the reference's cell
    /// mean `direct`) where there is one.
    fn new(out: &lightgrid_core::SweepOutput, r: &Reference, beam: Option<(&[f32], Vec3)>) -> Self {
        let (g, h) = (out.bins.as_ref().unwrap(), out.horizon.as_ref().unwrap());
        let direct = |n: Vec3, t: f32| match beam {
            Some((_, s)) => t * n.dot(s).max(0.0),
            None => 0.0,
        };
        let sweep_t = |i: usize| beam.map_or(0.0, |(t, _)| t[i]);
        let axes = |f: &dyn Fn(usize, Vec3) -> f32| -> Vec<[f64; 6]> {
            (0..g.data().len())
                .map(|i| AMBIENT_AXES.map(|n| f(i, n) as f64))
                .collect()
        };
        Self {
            even: axes(&|i, n| luminance(g.data()[i].irradiance(n)) + direct(n, sweep_t(i))),
            halves: axes(&|i, n| {
                luminance(g.data()[i].irradiance_split(n, &h.data()[i])) + direct(n, sweep_t(i))
            }),
            reference: axes(&|i, n| {
                let k = AMBIENT_AXES.iter().position(|a| *a == n).unwrap();
                luminance(r.irradiance[i][k]) + direct(n, luminance(r.direct[i]))
            }),
        }
    }

    /// The light times `k`.
    fn scaled(&self, k: f64) -> Self {
        let mul =
            |a: &[[f64; 6]]| -> Vec<[f64; 6]> { a.iter().map(|x| x.map(|v| v * k)).collect() };
        Self {
            even: mul(&self.even),
            halves: mul(&self.halves),
            reference: mul(&self.reference),
        }
    }

    /// The light of both.
    fn plus(&self, o: &Self) -> Self {
        let add = |a: &[[f64; 6]], b: &[[f64; 6]]| -> Vec<[f64; 6]> {
            a.iter()
                .zip(b)
                .map(|(x, y)| std::array::from_fn(|k| x[k] + y[k]))
                .collect()
        };
        Self {
            even: add(&self.even, &o.even),
            halves: add(&self.halves, &o.halves),
            reference: add(&self.reference, &o.reference),
        }
    }

    /// Bias and relative RMS of the six axes, then the bias facing up and facing down,
    /// over the cells that are not opaque: bins read even, then in halves.
    fn errors(&self, m: &MaterialGrid) -> [[f64; 4]; 2] {
        [&self.even, &self.halves].map(|a| {
            let (mut s, mut sr, mut se, mut sw) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            let mut per = [(0.0f64, 0.0f64); 6];
            for (i, c) in m.data().iter().enumerate() {
                if c.pass <= 0.0 {
                    continue;
                }
                for k in 0..6 {
                    let (x, want) = (a[i][k], self.reference[i][k]);
                    s += x;
                    sr += want;
                    per[k].0 += x;
                    per[k].1 += want;
                    se += (x - want).powi(2);
                    sw += want * want;
                }
            }
            let bias = |k: usize| per[k].0 / per[k].1 - 1.0;
            let (up, down) = (
                AMBIENT_AXES.iter().position(|n| n.y > 0.0).unwrap(),
                AMBIENT_AXES.iter().position(|n| n.y < 0.0).unwrap(),
            );
            [s / sr - 1.0, (se / sw).sqrt(), bias(up), bias(down)]
        })
    }
}

/// The sky alone: the sweep and the reference (the paths' exact directions).
fn sky_axes(m: &MaterialGrid, b: &Boundary, paths: u64) -> Axes {
    let out = lightgrid_sweep_cpu::run(m, b, &converged()).unwrap().output;
    let options = ReferenceOptions {
        paths,
        seed: 21,
        max_track: 64.0,
        ..Default::default()
    };
    let r = trace(m, b, &options, &|_, _| {}).unwrap();
    Axes::new(&out, &r, None)
}

/// A sun of unit irradiance at `elevation` degrees alone (periodic sides, dark sky):
/// its first collisions swept as a cell source, the direct beam by each cell's mean
/// transmittance (the reference tallies cell means; the march's point values are not
/// one inside a medium, where the beam decays across the cell).
fn sun_axes(m: &MaterialGrid, elevation: f32, paths: u64) -> Axes {
    let sun = Sun::at(elevation.to_radians(), 0.7, Vec3::ONE);
    let s = sun.direction;
    let dark = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let open = |_: Vec3| 1.0;
    let beam = BeamOptions::DEFAULT.with_mean_transmittance();
    let f = first_collisions(m, s, Vec3::ONE, true, &open, &beam).unwrap();
    let out = lightgrid_sweep_cpu::run_with_source(m, &dark, Some(&f.source), &converged())
        .unwrap()
        .output;
    let r = sun_measure::sun_reference(m, &dark, s, paths, 5).unwrap();
    let t = f.mean_transmittance.unwrap();
    Axes::new(&out, &r, Some((&t, s)))
}

fn main() {
    let paths: u64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("paths: a number"))
        .unwrap_or(2_000_000);
    let sky = lightgrid_sky::uniform_sky(Vec3::ONE).unwrap().top;
    println!("Lambertian ground under a uniform sky of radiance 1: the bins' irradiance just");
    println!("above the ground against the exact one (up pi, down a pi, sideways (1 + a) pi / 2)");
    println!("levels  albedo   up (err)          down (err)        sideways (err)");
    for levels in [1u32, 3] {
        for albedo in [0.3f32, 0.8] {
            let m = lightgrid_measure::exact::ground_material(levels, albedo).unwrap();
            let b = Boundary {
                sides: SideBoundary::Periodic,
                ..Boundary::open_sky(sky)
            };
            let out = lightgrid_sweep_cpu::run(&m, &b, &converged())
                .unwrap()
                .output;
            let i = m.desc().level_len() * levels as usize;
            let (l, h) = (out.bins.unwrap().data()[i], out.horizon.unwrap().data()[i]);
            let pi = std::f32::consts::PI;
            for split in [false, true] {
                let e = |n: Vec3| {
                    if split {
                        l.irradiance_split(n, &h).x
                    } else {
                        l.irradiance(n).x
                    }
                };
                let row = [
                    (e(Vec3::Y), pi),
                    (e(Vec3::NEG_Y), albedo * pi),
                    (e(Vec3::X), (1.0 + albedo) * pi / 2.0),
                ]
                .map(|(got, want)| format!("{got:.4} ({:+5.1} %)", 100.0 * (got / want - 1.0)));
                println!(
                    "{levels:6}  {albedo:6}   {}   {}   {}   {}",
                    row[0],
                    row[1],
                    row[2],
                    if split { "halves" } else { "even" }
                );
            }
        }
    }
    println!();
    println!(
        "six axes' irradiance per cell, sweep against the reference's tally ({paths} paths; sun \
         of irradiance pi at {SUN_ELEVATION} deg, its direct beam included)"
    );
    println!(
        "scene                          bias      relative RMS   bias facing up   facing down"
    );
    let periodic = |m: MaterialGrid| {
        let b = Boundary {
            sides: SideBoundary::Periodic,
            ..Boundary::open_sky(sky)
        };
        (m, b)
    };
    let scenes = [
        (Scene::Canopy.name(), Scene::Canopy.build(16)),
        (Scene::UniformFog.name(), Scene::UniformFog.build(16)),
        (
            "patchy canopy",
            periodic(lightgrid_measure::sun_measure::patchy_canopy(16, 3)),
        ),
    ];
    for (name, (m, b)) in scenes {
        let sky_only = sky_axes(&m, &b, paths);
        print_errors(&format!("{name}, sky"), sky_only.errors(&m));
        let sun_only = sun_axes(&m, SUN_ELEVATION, paths);
        print_errors(&format!("{name}, sun"), sun_only.errors(&m));
        let both = sky_only.plus(&sun_only.scaled(std::f64::consts::PI));
        print_errors(&format!("{name}, sky and sun"), both.errors(&m));
    }
}

/// The sun's elevation in the canopies' rows (degrees).
const SUN_ELEVATION: f32 = 30.0;

/// The rows of one scene: the bins read even across the horizon, then in halves.
fn print_errors(name: &str, e: [[f64; 4]; 2]) {
    for (e, how) in e.iter().zip(["even", "halves"]) {
        println!(
            "{:29}  {:+.4}   {:.4}         {:+.4}          {:+.4}   {how}",
            name, e[0], e[1], e[2], e[3]
        );
    }
}
