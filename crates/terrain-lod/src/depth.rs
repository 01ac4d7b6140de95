//! The depth of medium a node's composed cells keep: rounded to [`DEPTH_BITS`]
//! significant bits, so that the sweeper's cell profiles, integrated once for each
//! distinct depth and kept across sweeps, are reused from node to node.

use lightgrid_core::Material;

/// Significant bits a medium cell's optical depth keeps in a node's material
/// ([`quantized_pass`]).
pub const DEPTH_BITS: u32 = 11;

/// A medium cell's pass-through with its optical depth `-ln pass` rounded to
/// [`DEPTH_BITS`] significant bits (a change of at most 2⁻¹¹ of the depth, plus the
/// pass-through's own rounding: a few units of 10⁻⁷ in depth for thin cells; clear,
/// opaque and non-finite values as they are). The sweeper integrates a cell profile for each
/// distinct depth and keeps them across sweeps; composed materials have nearly every
/// cell's depth distinct, so without the rounding each node's sweep integrated most of
/// its profiles afresh (a tenth of the 16-point flythrough), with it a process computes
/// each of the few thousand depths once.
pub fn quantized_pass(pass: f32) -> f32 {
    if !(pass > 0.0 && pass < 1.0) {
        return pass;
    }
    const DROP: u32 = 24 - DEPTH_BITS;
    let tau = -pass.ln();
    let q = f32::from_bits((tau.to_bits() + (1 << (DROP - 1))) & !((1u32 << DROP) - 1));
    let p = (-q).exp();
    if p > 0.0 && p < 1.0 { p } else { pass }
}

/// `cells` with every pass-through [`quantized_pass`]ed (on all cores).
pub(crate) fn quantized(mut cells: Vec<Material>) -> Vec<Material> {
    use rayon::prelude::*;
    cells
        .par_iter_mut()
        .for_each(|m| m.pass = quantized_pass(m.pass));
    cells
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depths_change_by_at_most_two_to_the_minus_eleven_and_keep_their_order() {
        let mut last = 1.0f32;
        let mut distinct = std::collections::HashSet::new();
        // Pass-through from 1 - 1e-6 down to e^-60, densely.
        for i in 0..200_000 {
            let tau = 1e-6f64 * (60e6f64).powf(i as f64 / 199_999.0);
            let pass = (-tau).exp() as f32;
            let q = quantized_pass(pass);
            assert!(q > 0.0 && q < 1.0, "{pass} -> {q}");
            let (t, tq) = (-(pass as f64).ln(), -(q as f64).ln());
            // 2^-11 of the depth (half a step of 10 bits after the leading one), and the new pass-through's rounding (an ulp of 1
            // is 1.2e-7 in depth).
            assert!(
                (tq - t).abs() <= t * 2f64.powi(-11) + 2.5e-7,
                "depth {t} -> {tq}"
            );
            // Pass-through falls as the depth grows, and so does the rounded one.
            assert!(q <= last, "{pass} -> {q} after {last}");
            last = q;
            distinct.insert(q.to_bits());
        }
        // Every depth from 1e-6 to 60 in about 26 octaves of 1024 values.
        assert!(distinct.len() < 30_000, "{} distinct", distinct.len());
        for v in [
            0.0,
            1.0,
            -0.5,
            2.0,
            f32::NAN,
            f32::INFINITY,
            f32::MIN_POSITIVE,
        ] {
            let q = quantized_pass(v);
            assert!(
                q.to_bits() == v.to_bits() || (v > 0.0 && v < 1.0),
                "{v} -> {q}"
            );
        }
        // Values already on the grid stay.
        for pass in [0.5f32, 0.9, 0.01] {
            let q = quantized_pass(pass);
            assert_eq!(quantized_pass(q), q);
        }
    }
}
