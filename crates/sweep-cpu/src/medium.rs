//! The medium emission rule of step 5 ([`MediumEmission::Source`], issue 13): how a
//! medium cell sends on the light it scatters.
//!
//! A medium cell's scattered light is an isotropic, uniform *source* `J` inside the cell
//! (light per unit of a bin's solid angle, as radiance), and every **path segment**
//! through the cell (each channel's path at each of its points crosses one cell for
//! vertical and diagonal channels, five for horizontal ones, step 2) gains what such a
//! source sends along it: a segment of pass-through `τ_k` emits
//!
//! ```text
//! J ω_b σ_c (1 − τ_k)      at its exit,
//! ```
//!
//! which the later segments of the same path attenuate, *removing* what they stop: their
//! cells collide with it as with any light (phase 3 of the sweep). Along a path
//! `Σ_k (1 − τ_k) Π_{m>k} τ_m = 1 − Π τ` telescopes, so a path that enters with the
//! radiance of its cells' sources leaves with it, whatever cells it crossed: **the white
//! furnace is exact in any medium** (every source 1, every path 1), not only in uniform
//! ones. The light at a point is likewise the mean of its path's light over the segment
//! through its own cell (`L_in m + J (1 − m)`, `m` the segment's mean transmittance,
//! [`crate::sweep::seg_mean`]; 1 in a white furnace).
//!
//! The source a cell holds follows from the flux it emits in a pass, `S` (its share of
//! the scattered light, below; the rest goes to the other pass): its segments send out `G J`
//! with `G = Σ μ_c ω_b σ_c (1 − τ_k)` over the cell's segments of the pass, and it emits
//! `O J` in all, `O = Σ μ_c ω_b σ_c t_k` (`t_k = −ln τ_k`, so `O = τ Σ_c ω_b σ_c` with
//! `τ = −ln p`); the rest, `K = O − G`, its own material stops again, and of that it
//! scatters `a` once more (albedo `a`), and so on: `J = S / (G + (1 − a) K)`, of which
//! `(1 − a) K J` is absorbed. (This is the step-characteristics scheme of discrete-
//! ordinates transport: a flat source in each cell, exact attenuation along each
//! ordinate.)
//!
//! Thick cells lit from one side: light that enters a cell of optical depth `τ` ≳ 1
//! through one face collides near it, and a source there leaves back through that face
//! more than on through the cell. The share of the scattered light each direction's
//! pass emits is therefore `½ (S ∓ β M_y)` rather than `½ S` ([`split`]: `β` from exact
//! integrals of a beam's first-collision profile along every segment, 0 for thin
//! cells; `M_y` the vertical moment of the light's incoming directions). Linear in the
//! light, and `M_y = 0` in a white furnace, so it stays exact there.
//!
//! What it leaves out: within each pass the source is still flat over the cell's
//! height. In thick dark cells (optical depth 3, albedo ≤ 0.5) Chandrasekhar's
//! half-space albedo comes out 15–23 % low (the crate docs' table; `lightgrid_measure::exact`).
//! The option [`MediumEmission::Profile`] ([`crate::profile`]) makes the source of each
//! cell of optical depth at least [`PROFILE_MIN_DEPTH`] a quadratic in height instead,
//! and is within 2 % there ([`profiled`]: thinner cells keep the flat source).

use std::sync::OnceLock;

use lightgrid_core::MediumEmission;
use lightgrid_core::dirs;

use crate::sweep::{CHANNELS, MAX_EXPONENTS, channels, path_exponents};

/// A pass's weights for the source rule ([`weights`]).
#[derive(Debug)]
pub struct Weights {
    /// Per path exponent `e` ([`path_exponents`]): `Σ μ_c ω_b σ_c` over the pass's
    /// segments (stencil slots) of that exponent: a unit source sends `w_e (1 − p^e)` of
    /// flux out through them.
    pub w: [f32; MAX_EXPONENTS],
    /// Per channel: `ω_b σ_c`, the light a unit source sends along a segment per unit
    /// `1 − τ`.
    pub omega: [f32; CHANNELS],
    /// `Σ_e w_e e`: `O = τ ×` this (`Σ_c ω_b σ_c`, half the sphere: `2π` to rounding).
    pub o: f32,
}

/// The source rule's weights of the downward (`up = false`) or upward pass.
pub fn weights(up: bool) -> &'static Weights {
    static W: OnceLock<[Weights; 2]> = OnceLock::new();
    &W.get_or_init(|| [make(false), make(true)])[up as usize]
}

fn make(up: bool) -> Weights {
    let omega = dirs::solid_angles();
    let exps = path_exponents();
    let mut w = [0f32; MAX_EXPONENTS];
    let mut om = [0f32; CHANNELS];
    for (c, chn) in channels(up).iter().enumerate() {
        om[c] = omega[chn.bin] * chn.share;
        for &e in &chn.pow {
            w[e] += chn.mu * om[c];
        }
    }
    Weights {
        w,
        omega: om,
        o: (0..exps.len()).map(|e| w[e] * exps[e]).sum(),
    }
}

/// The source `J` of a medium cell of `ln(pass)` `lnp` and transmittance `pows` (per
/// path exponent) that emits scattered flux `s` this pass (one colour, albedo `a`), and
/// the flux its own material absorbs of that emission: `J = s / (G + (1 − a) K)`,
/// absorbed `(1 − a) K J` (module docs). Zero for `s ≤ 0`; finite always.
#[inline]
pub fn source(w: &Weights, lnp: f32, pows: &[f32; MAX_EXPONENTS], s: f32, a: f32) -> (f32, f32) {
    let (g, k) = cell_sums(w, lnp, pows);
    source_of(g, k, s, a)
}

/// A medium cell's `(G, K)` for a pass ([`source`]): what a unit source sends out of
/// the cell's segments, and what the cell's own material stops of it.
#[inline]
pub fn cell_sums(w: &Weights, lnp: f32, pows: &[f32; MAX_EXPONENTS]) -> (f32, f32) {
    let g: f32 = (0..MAX_EXPONENTS).map(|e| w.w[e] * (1.0 - pows[e])).sum();
    (g, (-lnp * w.o - g).max(0.0))
}

/// [`source`] from the cell's [`cell_sums`] (the same for every colour).
#[inline]
pub fn source_of(g: f32, k: f32, s: f32, a: f32) -> (f32, f32) {
    if s.is_nan() || s <= 0.0 {
        return (0.0, 0.0);
    }
    let d = g + (1.0 - a) * k;
    if !(d > 0.0 && d.is_finite()) {
        return (0.0, 0.0);
    }
    let j = s / d;
    if !j.is_finite() {
        return (0.0, 0.0);
    }
    (j, (1.0 - a) * k * j)
}

/// [`source_of`] for light of either sign (the accelerated sweep's `signed` mode,
/// [`crate::accel`]): linear in `s`, 0 only where the cell emits nothing.
#[inline]
pub fn source_signed(g: f32, k: f32, s: f32, a: f32) -> (f32, f32) {
    let d = g + (1.0 - a) * k;
    let j = s / d;
    if !(d > 0.0 && j.is_finite()) {
        return (0.0, 0.0);
    }
    (j, (1.0 - a) * k * j)
}

/// How a medium cell of optical depth `tau` (per level) shares its scattered light
/// between the two directions' passes: the downward pass emits `½ (S + β M_y)`, the
/// upward `½ (S − β M_y)` (`M_y` the vertical moment of the incoming directions of the
/// light it scattered, `|M_y| ≤ S`), so light that collided travelling down (`M_y < 0`)
/// goes up more: a beam entering a thick cell collides near the face it entered by, and
/// a source there escapes back through that face more than on through the cell.
///
/// `β = (ρ − 1) / (ρ + 1)`, with `ρ` the ratio of what escapes upward to what escapes
/// downward from a source spread as a vertical beam's first collisions, `∝ e^{τ z}`
/// over the cell's height `z ∈ [−½, ½]`, through every path segment of the two passes
/// (exact integrals along each segment): `β = 0` for a thin cell, `β → 1` for an opaque
/// one. Light from every direction alike (`M_y = 0`, a white furnace) is shared evenly.
/// Linear in the light (a fixed weight per cell on `M_y`), as the sweep must be, and
/// both shares stay ≥ 0. Read from a table ([`split`]).
pub fn split_exact(tau: f64) -> f64 {
    if tau.is_nan() || tau <= 0.0 {
        return 0.0;
    }
    let exps = path_exponents();
    let esc = |up: bool| -> f64 {
        let mut g = 0.0;
        for chn in channels(up).iter() {
            let om = (dirs::solid_angles()[chn.bin] * chn.share * chn.mu) as f64;
            let mut along = 0.0f64;
            for (k, &(_, _, f)) in chn.stencil.iter().enumerate() {
                let h = |a: f64| if up { a - 0.5 } else { 0.5 - a };
                let (za, zb) = (h(along), h(along + f as f64));
                along += f as f64;
                let t = exps[chn.pow[k]] as f64 * tau;
                // ∫₀ᵗ e^{τ z(s)} e^{−(t − s)} ds, z from za to zb.
                let x = tau * (zb - za) + t;
                let v = if x.abs() < 1e-9 {
                    (tau * za - t).exp() * t
                } else {
                    t * ((tau * zb).exp() - (tau * za - t).exp()) / x
                };
                g += om * v;
            }
        }
        g
    };
    let rho = esc(true) / esc(false);
    ((rho - 1.0) / (rho + 1.0)).clamp(0.0, 1.0)
}

/// Table of [`split_exact`] at `τ = SPLIT_TAU_MAX · (i / (SPLIT_TABLE − 1))²`.
pub const SPLIT_TABLE: usize = 257;
/// Largest optical depth in the table (beyond it, its last value, within 1e-3 of the
/// limit 1).
pub const SPLIT_TAU_MAX: f32 = 64.0;

/// The table behind [`split`] (generated into the GPU sweep's shaders too).
pub fn split_table() -> &'static [f32; SPLIT_TABLE] {
    static T: OnceLock<[f32; SPLIT_TABLE]> = OnceLock::new();
    T.get_or_init(|| {
        std::array::from_fn(|i| {
            let u = i as f64 / (SPLIT_TABLE - 1) as f64;
            split_exact(SPLIT_TAU_MAX as f64 * u * u) as f32
        })
    })
}

/// [`split_exact`] for a cell of `ln(pass)` `lnp`, interpolated linearly in `√τ` from
/// [`split_table`].
#[inline]
pub fn split(lnp: f32) -> f32 {
    let t = split_table();
    let u = ((-lnp / SPLIT_TAU_MAX).max(0.0)).sqrt() * (SPLIT_TABLE - 1) as f32;
    if u.is_nan() || u >= (SPLIT_TABLE - 1) as f32 {
        return t[SPLIT_TABLE - 1];
    }
    let i = u as usize;
    let f = u - i as f32;
    t[i] + (t[i + 1] - t[i]) * f
}

/// The least optical depth `−ln p` of a medium cell whose source the profile rule
/// ([`MediumEmission::Profile`], [`crate::profile`]) makes a quadratic in height;
/// thinner cells emit this module's flat source under that rule too. Where the
/// collisions in a cell fall nearly evenly over its height the flat source is as good.
/// Chandrasekhar's half-space albedo with the flat source, albedos 0.1 / 0.5 / 0.9 /
/// 0.99: under a beam +1.6 / +1.1 / +0.2 / −0.1 % at cell depth 0.05 and −1.4 / −0.4 /
/// +0.3 / +0.1 % at 0.69 (`cargo xtask exact`); under a uniform sky (the measure
/// crate's `hs_diffuse` example) +4.4 / +3.5 / +1.7 / +0.6 % at 0.05 (the channels'
/// angular error, the profile's too), +1.3 / +1.3 / +0.9 / +0.4 % at 0.3, −0.7 / −0.1 /
/// +0.4 / +0.2 % at 0.4 and −7.5 / −5.1 / −1.7 / −0.4 % at 0.69, −47 % at 3, which the
/// profile keeps within 2 %. A composed terrain's partly covered cells, whose
/// collisions lie at the ground, not evenly (`lightgrid_terrain_lod`'s `ground_band`
/// example), read as before at 0.3 and 5 % darker under the sky at 0.4. The flat source
/// costs a cell less (no height moments, profile or emission planes): the fly-through's
/// frames took 14 % less time at 0.3, most of the forest's medium cells being thinner
/// (17 % at 0.4).
pub const PROFILE_MIN_DEPTH: f32 = 0.3;

/// The largest pass-through of a cell the profile rule gives a quadratic source:
/// `exp(−PROFILE_MIN_DEPTH)` (held by a test).
pub const PROFILE_MAX_PASS: f32 = 0.740_818_2;

/// Whether a cell of pass-through `p` is a medium whose source is a quadratic in height
/// under `rule` (the profile rule, and optical depth at least [`PROFILE_MIN_DEPTH`]);
/// other media under that rule emit the flat source.
#[inline]
pub fn profiled(rule: MediumEmission, p: f32) -> bool {
    rule == MediumEmission::Profile && p > 0.0 && p <= PROFILE_MAX_PASS
}

/// Whether a cell of pass-through `p` is a medium that emits by this module's rule
/// under `rule`.
#[inline]
pub fn applies(rule: MediumEmission, p: f32) -> bool {
    matches!(rule, MediumEmission::Source | MediumEmission::Profile) && p > 0.0 && p < 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_profile_rule_takes_cells_of_its_least_depth_and_thicker() {
        assert_eq!(PROFILE_MAX_PASS, (-PROFILE_MIN_DEPTH).exp());
        let p = MediumEmission::Profile;
        assert!(profiled(p, PROFILE_MAX_PASS));
        assert!(profiled(p, 0.01));
        assert!(!profiled(p, f32::from_bits(PROFILE_MAX_PASS.to_bits() + 1)));
        assert!(!profiled(p, 0.9));
        assert!(profiled(p, (-0.69f32).exp()));
        for p in [0.0, 1.0, 1.5, -0.1, f32::NAN] {
            assert!(!profiled(MediumEmission::Profile, p), "{p}");
        }
        for rule in [MediumEmission::Source, MediumEmission::Escape] {
            assert!(!profiled(rule, 0.1));
        }
    }

    #[test]
    fn split_known_answers_and_table() {
        // Thin: even; thick: nearly all back; monotonic in between.
        assert!(split_exact(1e-4) < 1e-3);
        assert!(split_exact(40.0) > 0.95);
        let mut last = 0.0;
        for i in 1..100 {
            let b = split_exact(i as f64 * 0.1);
            assert!(b > last && b < 1.0, "{i}: {b}");
            last = b;
        }
        // The table interpolates the exact values closely between its nodes.
        for tau in [0.01f32, 0.1, 0.69, 1.0, 3.0, 10.0, 50.0] {
            let want = split_exact(tau as f64) as f32;
            let got = split(-tau);
            assert!((got - want).abs() < 2e-3, "tau {tau}: {got} vs {want}");
        }
        assert_eq!(split(0.0), 0.0);
        assert!(split(f32::NEG_INFINITY) > 0.95);
    }

    fn pows(p: f32) -> [f32; MAX_EXPONENTS] {
        let e = path_exponents();
        std::array::from_fn(|i| if i < e.len() { p.powf(e[i]) } else { 1.0 })
    }

    #[test]
    fn weights_cover_half_the_sphere() {
        for up in [false, true] {
            let w = weights(up);
            let half: f32 = w.omega.iter().sum();
            assert!((half - 2.0 * std::f32::consts::PI).abs() < 1e-4, "{half}");
            // μ_c ℓ_c = 1 and each channel's fractions sum to 1: O = τ Σ ω σ.
            assert!((w.o - half).abs() < 1e-4, "{}", w.o);
        }
        // The passes mirror each other: the same weights.
        assert_eq!(weights(false).w, weights(true).w);
    }

    /// A white cell emits all it scatters; otherwise escaped + absorbed = scattered; a
    /// thin cell's escape is its optical depth's share (`G → O`), a thick one's less.
    #[test]
    fn source_accounts_for_every_flux() {
        let w = weights(false);
        for p in [0.999f32, 0.9, 0.5, 0.05, 1e-6] {
            let pw = pows(p);
            let g: f32 = (0..MAX_EXPONENTS).map(|e| w.w[e] * (1.0 - pw[e])).sum();
            for a in [0.0f32, 0.3, 1.0] {
                let (j, absorbed) = source(w, p.ln(), &pw, 2.0, a);
                assert!(j > 0.0 && j.is_finite());
                let escaped = g * j;
                assert!(
                    (escaped + absorbed - 2.0).abs() < 1e-4 * 2.0,
                    "p {p} a {a}: {escaped} + {absorbed}"
                );
                if a == 1.0 {
                    assert_eq!(absorbed, 0.0);
                }
            }
            let ratio = g / (-p.ln() * w.o);
            assert!(
                ratio <= 1.0 + 1e-5 && (p < 0.99 || ratio > 0.99),
                "p {p}: {ratio}"
            );
        }
        assert_eq!(source(w, 0.5f32.ln(), &pows(0.5), 0.0, 0.5), (0.0, 0.0));
        assert_eq!(
            source(w, 0.5f32.ln(), &pows(0.5), f32::NAN, 0.5),
            (0.0, 0.0)
        );
    }
}
