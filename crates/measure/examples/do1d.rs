//! The angular error of the sweep's channels alone: Chandrasekhar's half-space albedo
//! (zenith beam) of a discrete-ordinates slab whose ordinates are the channels, with a
//! fine spatial mesh (so only the choice of each channel's cosine `μ_c` matters), for the
//! step vectors' own cosines and for the bins' mean cosines
//! (`lightgrid_sweep_cpu::sweep::channel_length`). Issue 13.
//!
//! Then where thick dark cells lose their light: the same slab in cells of optical
//! depth 0.69 to 3 with a flat source in each cell (the sweep's source rule without its
//! up/down split), against the beam's first collisions emitted from their exact
//! exponential profile inside each cell, later generations flat. Measured at depth 3:
//! flat −48 / −41 / −23 / −7.5 % (w 0.1 / 0.5 / 0.9 / 0.99), first collisions exact
//! −0.5 / −8.2 / −8.8 / −3.0 %: the first generation is what a dark thick cell gets
//! wrong; later generations need the split (the 3D sweep's: +0.4 % at w 0.9).
//!
//! Then which source *within* a cell would pass the 2 % at every depth: the
//! cell's source (the beam's first collisions and all later ones alike) as its Legendre
//! expansion in height up to order 0 (flat), 1 (linear) or 2 (quadratic), each order's
//! coefficient the cell's moment of its collisions, so the scheme stays linear in the
//! light and exact in a white furnace (the moments above 0 vanish in uniform light).
//! Measured at depth 3, w 0.1 / 0.5 / 0.9 / 0.99: flat −48 / −41 / −23 / −7.5 %, linear
//! −7.5 / −3.5 / +0.9 / +0.3 %, quadratic +0.7 / +1.1 / +0.4 / −0.0 %, which is the
//! channels' own angular error (+1.7 / +1.1 / +0.2 / −0.1 % on a fine mesh, first
//! table): a quadratic source in height, two more moments a cell and colour, leaves no
//! spatial error at depths 0.69 to 3; that is the plan for the sweep's thick cells
//! (issue 13).
//!
//! `cargo run --release -p lightgrid-measure --example do1d`

use lightgrid_core::dirs;
use lightgrid_core::glam::DVec3;

/// Reflected flux of a half-space (optical depth 50, cells of `dz`) under a unit zenith
/// beam; `exact_first`: the beam's first collisions emitted from their exponential
/// profile (exact integrals along each ordinate), else spread flat over each cell.
fn albedo(q: &[(f64, f64)], w: f64, dz: f64, exact_first: bool) -> f64 {
    let n = (50.0 / dz).ceil() as usize;
    let mut phi = vec![0.0f64; n];
    let mut refl = 0.0;
    let c = w / (4.0 * std::f64::consts::PI);
    for _ in 0..40000 {
        let za = |i: usize| i as f64 * dz;
        let beam_avg = |i: usize| ((-za(i)).exp() - (-(za(i) + dz)).exp()) / dz;
        let jf: Vec<f64> = (0..n)
            .map(|i| c * (phi[i] + if exact_first { 0.0 } else { beam_avg(i) }))
            .collect();
        let mut next = vec![0.0f64; n];
        refl = 0.0;
        for &(mu, wt) in q {
            let t = (-dz / mu).exp();
            for down in [true, false] {
                let mut psi = 0.0;
                for k in 0..n {
                    let i = if down { k } else { n - 1 - k };
                    let (mut out, mut avg) = (psi * t + jf[i] * (1.0 - t), jf[i]);
                    if exact_first {
                        let e = (-za(i)).exp() * c;
                        let b = if down {
                            if (mu - 1.0).abs() < 1e-9 {
                                e * (-dz).exp() * dz / mu
                            } else {
                                e * (-dz / mu).exp() * (1.0 - (-dz * (1.0 - 1.0 / mu)).exp())
                                    / (mu - 1.0)
                            }
                        } else {
                            e * (1.0 - (-dz * (1.0 + 1.0 / mu)).exp()) / (mu + 1.0)
                        };
                        out += b;
                        avg += c * beam_avg(i);
                    }
                    next[i] += wt * (avg + (psi - out) * mu / dz);
                    psi = out;
                }
                if !down {
                    refl += wt * mu * psi;
                }
            }
        }
        let change: f64 = next.iter().zip(&phi).map(|(a, b)| (a - b).abs()).sum();
        phi = next;
        if change < 1e-12 {
            break;
        }
    }
    refl
}

/// Sub-intervals of a cell in [`albedo_order`]: the source is the mean of its
/// polynomial at each sub-interval's middle, light crosses each exactly.
const SUB: usize = 64;

/// Legendre polynomials `P_0..P_2` at `x` in `[-1, 1]`.
fn legendre(x: f64) -> [f64; 3] {
    [1.0, x, 0.5 * (3.0 * x * x - 1.0)]
}

/// As [`albedo`] with the cell's whole source (the beam's first collisions included) as
/// its Legendre expansion in height up to `order` (0 flat, 1 linear, 2 quadratic), each
/// coefficient from the cell's moment of its collisions.
fn albedo_order(q: &[(f64, f64)], w: f64, dz: f64, order: usize) -> f64 {
    let n = (50.0 / dz).ceil() as usize;
    let c = w / (4.0 * std::f64::consts::PI);
    let h = dz / SUB as f64;
    let pk: Vec<[f64; 3]> = (0..SUB)
        .map(|k| legendre(2.0 * (k as f64 + 0.5) / SUB as f64 - 1.0))
        .collect();
    // The beam's collided light (4π × its scalar flux) per cell: its Legendre moments.
    let beam: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let mut m = [0.0; 3];
            for (k, p) in pk.iter().enumerate() {
                let z = i as f64 * dz + k as f64 * h;
                let v = ((-z).exp() - (-(z + h)).exp()) / h / SUB as f64;
                for o in 0..3 {
                    m[o] += (2 * o + 1) as f64 * p[o] * v;
                }
            }
            m
        })
        .collect();
    let mut phi = vec![[0.0f64; 3]; n];
    let mut refl = 0.0;
    for _ in 0..40000 {
        let src: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                pk.iter()
                    .map(|p| {
                        (0..=order)
                            .map(|o| c * (phi[i][o] + beam[i][o]) * p[o])
                            .sum()
                    })
                    .collect()
            })
            .collect();
        let mut next = vec![[0.0f64; 3]; n];
        refl = 0.0;
        for &(mu, wt) in q {
            let t = (-h / mu).exp();
            for down in [true, false] {
                let mut psi = 0.0;
                for k in 0..n {
                    let i = if down { k } else { n - 1 - k };
                    for s in 0..SUB {
                        let sub = if down { s } else { SUB - 1 - s };
                        let j = src[i][sub];
                        let out = psi * t + j * (1.0 - t);
                        let avg = j + (psi - out) * mu / h;
                        for o in 0..3 {
                            next[i][o] += wt * (2 * o + 1) as f64 * pk[sub][o] * avg / SUB as f64;
                        }
                        psi = out;
                    }
                }
                if !down {
                    refl += wt * mu * psi;
                }
            }
        }
        let change: f64 = next
            .iter()
            .zip(&phi)
            .map(|(a, b)| (a[0] - b[0]).abs())
            .sum();
        phi = next;
        if change < 1e-12 {
            break;
        }
    }
    refl
}

fn main() {
    let g = dirs::bins();
    let (mut steps, mut means) = (Vec::new(), Vec::new());
    for b in 0..17 {
        // Downward bins whole, horizontal bins their downward half.
        let om = if b < 9 { g.omega[b] } else { 0.5 * g.omega[b] };
        let step = 1.0 / dirs::sweep_dirs()[b].length as f64;
        let mean = dirs::clipped_cosine(b, -DVec3::Y) / om;
        steps.push((step, om));
        means.push((mean, om));
    }
    println!(
        "{:>6} {:>8} {:>22} {:>22}",
        "w", "exact", "step vectors' cosines", "bins' mean cosines"
    );
    for w in [0.1, 0.5, 0.9, 0.99] {
        let exact = lightgrid_measure::exact::half_space_albedo_beam(w, 1.0);
        let (a, b) = (
            albedo(&steps, w, 0.02, false),
            albedo(&means, w, 0.02, false),
        );
        println!(
            "{w:>6} {exact:>8.4} {a:>13.4} ({:+.2} %) {b:>13.4} ({:+.2} %)",
            100.0 * (a / exact - 1.0),
            100.0 * (b / exact - 1.0)
        );
    }
    // Thick cells: the same slab in cells of optical depth up to 3, the bins' mean
    // cosines, a flat source per cell against the beam's first collisions from their
    // exact profile (later generations flat).
    println!(
        "\n{:>10} {:>5} {:>10} {:>24}",
        "cell depth", "w", "flat", "first collisions exact"
    );
    for dz in [0.69, 1.5, 3.0] {
        for w in [0.1, 0.5, 0.9, 0.99] {
            let exact = lightgrid_measure::exact::half_space_albedo_beam(w, 1.0);
            let (a, b) = (albedo(&means, w, dz, false), albedo(&means, w, dz, true));
            println!(
                "{dz:>10} {w:>5} {:>+9.2} % {:>+23.2} %",
                100.0 * (a / exact - 1.0),
                100.0 * (b / exact - 1.0)
            );
        }
    }
    // Thick cells: the whole source as a Legendre expansion in height.
    println!(
        "\n{:>10} {:>5} {:>10} {:>10} {:>10}",
        "cell depth", "w", "flat", "linear", "quadratic"
    );
    for dz in [0.69, 1.5, 3.0] {
        for w in [0.1, 0.5, 0.9, 0.99] {
            let exact = lightgrid_measure::exact::half_space_albedo_beam(w, 1.0);
            let e: Vec<f64> = (0..3)
                .map(|o| 100.0 * (albedo_order(&means, w, dz, o) / exact - 1.0))
                .collect();
            println!(
                "{dz:>10} {w:>5} {:>+9.2} % {:>+9.2} % {:>+9.2} %",
                e[0], e[1], e[2]
            );
        }
    }
}
