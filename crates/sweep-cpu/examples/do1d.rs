//! The angular error of the sweep's channels alone: Chandrasekhar's half-space albedo
//! (zenith beam) of a discrete-ordinates slab whose ordinates are the channels, with a
//! fine spatial mesh (so only the choice of each channel's cosine `μ_c` matters), for the
//! step vectors' own cosines and for the bins' mean cosines
//! (`sweep_cpu::sweep::channel_length`). Issue 13.
//!
//! `cargo run --release -p sweep-cpu --example do1d`

use lightgrid_core::dirs;
use lightgrid_core::glam::DVec3;

/// Reflected flux of a half-space (optical depth 50, cells of `dz`) under a unit zenith
/// beam, ordinates `(μ, weight)` over one hemisphere (weights summing to 2π), single
/// scattering albedo `w`: source iteration with exact attenuation in each cell.
fn albedo(q: &[(f64, f64)], w: f64, dz: f64) -> f64 {
    let n = (50.0 / dz) as usize;
    let mut phi = vec![0.0f64; n];
    let mut refl = 0.0;
    for _ in 0..40000 {
        let j: Vec<f64> = (0..n)
            .map(|i| {
                let z = (i as f64 + 0.5) * dz;
                let beam = ((-(z - 0.5 * dz)).exp() - (-(z + 0.5 * dz)).exp()) / dz;
                w * (phi[i] + beam) / (4.0 * std::f64::consts::PI)
            })
            .collect();
        let mut next = vec![0.0f64; n];
        refl = 0.0;
        for &(mu, wt) in q {
            let t = (-dz / mu).exp();
            for down in [true, false] {
                let mut psi = 0.0;
                for k in 0..n {
                    let i = if down { k } else { n - 1 - k };
                    let out = psi * t + j[i] * (1.0 - t);
                    next[i] += wt * (j[i] + (psi - out) * mu / dz);
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
        let exact = sweep_cpu::exact::half_space_albedo_beam(w, 1.0);
        let (a, b) = (albedo(&steps, w, 0.02), albedo(&means, w, 0.02));
        println!(
            "{w:>6} {exact:>8.4} {a:>13.4} ({:+.2} %) {b:>13.4} ({:+.2} %)",
            100.0 * (a / exact - 1.0),
            100.0 * (b / exact - 1.0)
        );
    }
}
