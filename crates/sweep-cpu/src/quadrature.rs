//! Gauss–Legendre quadrature on `[0, 1]`: the medium rule's tables ([`crate::profile`])
//! integrate over a cell with it, and the exact problems (`lightgrid-measure`) over
//! angles.

use std::f64::consts::PI;

/// Gauss–Legendre nodes and weights on `[0, 1]` (`n` points, Newton iteration on the
/// Legendre polynomial; exact for polynomials of degree `2n − 1`).
pub fn gauss_legendre_01(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // Initial guess (Tricomi), then Newton on P_n.
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let k = k as f64;
                let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((0.5 * (1.0 - x), 0.5 * w));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        let q = gauss_legendre_01(8);
        assert!((q.iter().map(|p| p.1).sum::<f64>() - 1.0).abs() < 1e-14);
        // ∫₀¹ x^15 dx = 1/16 (degree 2n − 1).
        let v: f64 = q.iter().map(|p| p.1 * p.0.powi(15)).sum();
        assert!((v - 1.0 / 16.0).abs() < 1e-14, "{v}");
    }
}
