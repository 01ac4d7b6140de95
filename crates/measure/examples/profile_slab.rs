//! The half-space of `tests/exact.rs` (a thick slab of isotropic scatterers under a
//! zenith beam of irradiance 1) on the sweep's own channel geometry, laterally uniform
//! (every cell of a level alike, as with periodic sides, so each level is one cell),
//! with each cell's source flat or quadratic in height ([`lightgrid_sweep_cpu::profile`]): what
//! the quadratic rule would give in the 3-D sweep before the sweep is changed. Each
//! channel's path crosses its stencil's segments in order; a cell's collisions are the
//! light entering its segments (moments `C_n`) and its own source's (`K_nm`); the
//! beam's first collisions have the moments of a vertical beam entering at the top.
//! Source iteration to convergence. Issue 13.
//!
//! `cargo run --release -p lightgrid-measure --example profile_slab`

use lightgrid_measure::exact::half_space_albedo_beam;
use lightgrid_sweep_cpu::profile::{PassSums, Segment, pass_segments};
use lightgrid_sweep_cpu::sweep::channels;

/// One segment's weight `μ_c ω_b σ_c` and integrals.
struct Seg {
    w: f64,
    decay: f64,
    c: [f64; 3],
    e: [f64; 3],
    k: [[f64; 3]; 3],
}

/// Reflected flux of a slab of total optical depth 40 in cells of depth `tau`, albedo
/// `a`; `order` 0: flat sources, 2: quadratic.
fn albedo(a: f64, tau: f64, order: usize) -> (f64, usize) {
    albedo_with(a, tau, order, false)
}

/// [`albedo`] with each pass's own source (`per_pass`): the pass's half of the
/// collisions' moments, solved with that pass's self-collisions alone
/// ([`lightgrid_sweep_cpu::profile::PassSums::solve`]), as the sweep's passes would emit it.
fn albedo_with(a: f64, tau: f64, order: usize, per_pass: bool) -> (f64, usize) {
    let sums = [PassSums::new(false, tau), PassSums::new(true, tau)];
    let levels = (40.0 / tau).ceil() as usize;
    // Per pass, per channel: its path's segments in travel order.
    let paths: Vec<Vec<Vec<Seg>>> = [false, true]
        .iter()
        .map(|&up| {
            let segs = pass_segments(up, tau);
            let mut it = segs.into_iter();
            channels(up)
                .iter()
                .map(|chn| {
                    (0..chn.stencil.len())
                        .map(|_| {
                            let (w, s) = it.next().expect("one segment a stencil cell");
                            Seg {
                                w,
                                decay: (-s.t).exp(),
                                c: s.collided(),
                                e: s.emitted(),
                                k: s.self_collided(),
                            }
                        })
                        .collect()
                })
                .collect()
        })
        .collect();
    let o_total: f64 = paths
        .iter()
        .flatten()
        .flatten()
        .map(|s| s.w * -s.decay.ln())
        .sum();
    // The beam's first collisions per level (flux) and their height moments.
    let beam = Segment {
        t: tau,
        y0: 1.0,
        y1: -1.0,
    }
    .collided();
    let beam_r: Vec<[f64; 3]> = (0..levels)
        .map(|l| {
            let f = (-tau * l as f64).exp() * beam[0];
            [f, f * beam[1] / beam[0], f * beam[2] / beam[0]]
        })
        .collect();
    // Per pass (both alike unless `per_pass`), per level: the source.
    let mut j = vec![vec![[0.0f64; 3]; levels]; 2];
    let mut refl = 0.0;
    for it in 0..200_000 {
        let mut r = beam_r.clone();
        refl = 0.0;
        for (pass, chans) in paths.iter().enumerate() {
            for path in chans {
                let mut psi = 0.0f64;
                for step in 0..levels {
                    let l = if pass == 0 { step } else { levels - 1 - step };
                    let jl = j[pass][l];
                    for s in path {
                        for n in 0..3 {
                            let own: f64 = (0..3).map(|m| s.k[n][m] * jl[m]).sum();
                            r[l][n] += s.w * (psi * s.c[n] + if per_pass { 0.0 } else { own });
                        }
                        psi = psi * s.decay + (0..3).map(|m| jl[m] * s.e[m]).sum::<f64>();
                    }
                }
                if pass == 1 {
                    refl += path[0].w * psi;
                }
            }
        }
        let mut change = 0.0f64;
        for l in 0..levels {
            for (pass, sum) in sums.iter().enumerate() {
                let mut nj = [0.0; 3];
                if per_pass {
                    let mut e = [0.0; 3];
                    for n in 0..=order {
                        e[n] = 0.5 * a * r[l][n];
                    }
                    nj = sum.solve(a, e).expect("a medium");
                } else {
                    for n in 0..=order {
                        nj[n] = (2 * n + 1) as f64 * a * r[l][n] / o_total;
                    }
                }
                change += (nj[0] - j[pass][l][0]).abs();
                j[pass][l] = nj;
            }
        }
        if change < 1e-13 && it > 2 {
            return (refl, it);
        }
    }
    (refl, 200_000)
}

fn main() {
    println!(
        "{:>10} {:>5} {:>8} {:>10} {:>10} {:>10} {:>8}",
        "cell depth", "w", "exact", "flat", "quadratic", "per pass", "passes"
    );
    for tau in [0.05, 0.69, 1.5, 3.0] {
        for w in [0.1, 0.5, 0.9, 0.99] {
            let exact = half_space_albedo_beam(w, 1.0);
            let (f, _) = albedo(w, tau, 0);
            let (q, it) = albedo(w, tau, 2);
            let (pp, _) = albedo_with(w, tau, 2, true);
            println!(
                "{tau:>10} {w:>5} {exact:>8.4} {:>+9.2} % {:>+9.2} % {:>+9.2} % {it:>8}",
                100.0 * (f / exact - 1.0),
                100.0 * (q / exact - 1.0),
                100.0 * (pp / exact - 1.0)
            );
        }
    }
}
