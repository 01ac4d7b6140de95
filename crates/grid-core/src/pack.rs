//! Packed HDR colour: R11G11B10 (the light grid's storage format) and RGB9E5 beside it.
//!
//! Written here because no tested crate packs these exactly as Vulkan specifies them
//! (round to nearest even, saturation, denormals); the tests below check every code.
//!
//! # R11G11B10 (Vulkan `B10G11R11_UFLOAT_PACK32`)
//!
//! | bits   | channel | format |
//! |--------|---------|--------|
//! | 0–10   | R       | unsigned float: 5-bit exponent (bias 15), 6-bit mantissa |
//! | 11–21  | G       | same |
//! | 22–31  | B       | unsigned float: 5-bit exponent (bias 15), 5-bit mantissa |
//!
//! Encoding rounds to nearest, ties to even. Negative values, `-0` and NaN encode as 0.
//! Values at or past the largest finite value, and `+inf`, saturate to the largest finite
//! value ([`MAX_UF11`] = 65024 for R and G, [`MAX_UF10`] = 64512 for B): a light grid never
//! holds infinity. Values below the smallest normal (2^-14) use the denormal codes.
//! Relative error of a normal value is at most 2^-7 (R, G) and 2^-6 (B).
//!
//! # RGB9E5 (Vulkan `E5B9G9R9_UFLOAT_PACK32`)
//!
//! Three 9-bit mantissas (R bits 0–8, G 9–17, B 18–26) sharing a 5-bit exponent (bits
//! 27–31, bias 15), encoded per `EXT_texture_shared_exponent` with round to nearest;
//! largest value [`MAX_RGB9E5`] = 65408. Better for bright saturated colours, worse for
//! dark channels next to a bright one (they share its exponent).

use glam::Vec3;

/// Largest finite 11-bit unsigned float.
pub const MAX_UF11: f32 = 65024.0;
/// Largest finite 10-bit unsigned float.
pub const MAX_UF10: f32 = 64512.0;
/// Largest RGB9E5 channel value.
pub const MAX_RGB9E5: f32 = 65408.0;

/// Encodes `x` as an unsigned float with 5 exponent bits and `mant` mantissa bits.
fn encode_ufloat(x: f32, mant: u32) -> u32 {
    let max_code = (30 << mant) | ((1 << mant) - 1);
    if x.is_nan() || x <= 0.0 {
        return 0;
    }
    let bits = x.to_bits();
    let exp = ((bits >> 23) & 0xff) as i32;
    if exp == 0xff {
        return max_code; // +inf
    }
    if exp == 0 {
        return 0; // f32 denormals are far below the smallest 2^-14 * 2^-6 code.
    }
    let sig = (bits & 0x7f_ffff) | 0x80_0000; // 24-bit significand, value = sig * 2^(exp-150)
    let e = exp - 127 + 15; // target biased exponent
    // Number of significand bits to drop: normal keeps `mant` fraction bits;
    // denormal (e <= 0) shifts further right by 1 - e.
    let shift = if e >= 1 {
        23 - mant as i32
    } else {
        23 - mant as i32 + 1 - e
    };
    if shift > 25 {
        return 0;
    }
    let shift = shift as u32;
    let kept = sig >> shift;
    let rem = sig & ((1 << shift) - 1);
    let half = 1 << (shift - 1);
    let mut code = if e >= 1 {
        ((e as u32) << mant) | (kept & ((1 << mant) - 1))
    } else {
        kept
    };
    if rem > half || (rem == half && code & 1 == 1) {
        code += 1; // may carry into the exponent: that is the correctly rounded result
    }
    code.min(max_code)
}

/// Decodes an unsigned float with 5 exponent bits and `mant` mantissa bits.
fn decode_ufloat(code: u32, mant: u32) -> f32 {
    let e = (code >> mant) & 0x1f;
    let m = code & ((1 << mant) - 1);
    let scale = (1u32 << mant) as f32;
    match e {
        0 => m as f32 / scale * 2f32.powi(-14),
        31 => {
            if m == 0 {
                f32::INFINITY
            } else {
                f32::NAN
            }
        }
        _ => (1.0 + m as f32 / scale) * 2f32.powi(e as i32 - 15),
    }
}

/// Encodes one value as an 11-bit unsigned float code.
pub fn f32_to_uf11(x: f32) -> u32 {
    encode_ufloat(x, 6)
}
/// Encodes one value as a 10-bit unsigned float code.
pub fn f32_to_uf10(x: f32) -> u32 {
    encode_ufloat(x, 5)
}
/// Decodes an 11-bit unsigned float code (the low 11 bits of `code`).
pub fn uf11_to_f32(code: u32) -> f32 {
    decode_ufloat(code & 0x7ff, 6)
}
/// Decodes a 10-bit unsigned float code (the low 10 bits of `code`).
pub fn uf10_to_f32(code: u32) -> f32 {
    decode_ufloat(code & 0x3ff, 5)
}

/// Packs linear RGB into R11G11B10 (see the module docs for rounding and saturation).
pub fn pack_r11g11b10(c: Vec3) -> u32 {
    f32_to_uf11(c.x) | (f32_to_uf11(c.y) << 11) | (f32_to_uf10(c.z) << 22)
}

/// Unpacks R11G11B10. Codes written by [`pack_r11g11b10`] are always finite; foreign
/// words with exponent 31 (infinity or NaN) decode to the largest finite value or 0, so
/// no NaN or infinity leaves this function.
pub fn unpack_r11g11b10(w: u32) -> Vec3 {
    let fix = |v: f32, max: f32| {
        if v.is_nan() { 0.0 } else { v.min(max) }
    };
    Vec3::new(
        fix(uf11_to_f32(w), MAX_UF11),
        fix(uf11_to_f32(w >> 11), MAX_UF11),
        fix(uf10_to_f32(w >> 22), MAX_UF10),
    )
}

/// Packs linear RGB into RGB9E5 (negative and NaN to 0, saturating at [`MAX_RGB9E5`]).
pub fn pack_rgb9e5(c: Vec3) -> u32 {
    const N: i32 = 9;
    const B: i32 = 15;
    let clamp = |v: f32| {
        if v.is_nan() || v <= 0.0 {
            0.0
        } else {
            v.min(MAX_RGB9E5) as f64
        }
    };
    let (r, g, b) = (clamp(c.x), clamp(c.y), clamp(c.z));
    let maxc = r.max(g).max(b);
    if maxc == 0.0 {
        return 0;
    }
    let mut exp = (maxc.log2().floor() as i32).max(-B - 1) + 1 + B;
    let mut denom = 2f64.powi(exp - B - N);
    let maxm = (maxc / denom + 0.5).floor() as i32;
    if maxm == 1 << N {
        denom *= 2.0;
        exp += 1;
    }
    let q = |v: f64| ((v / denom + 0.5).floor() as u32).min((1 << N) - 1);
    q(r) | (q(g) << 9) | (q(b) << 18) | ((exp as u32) << 27)
}

/// Unpacks RGB9E5.
pub fn unpack_rgb9e5(w: u32) -> Vec3 {
    let exp = (w >> 27) as i32;
    let scale = 2f32.powi(exp - 15 - 9);
    Vec3::new(
        (w & 0x1ff) as f32 * scale,
        ((w >> 9) & 0x1ff) as f32 * scale,
        ((w >> 18) & 0x1ff) as f32 * scale,
    )
}

/// A per-grid exposure scale for packing: the power of two that maps `max_value` as close
/// to (but not over) [`MAX_UF10`] as possible, so bright sun light does not saturate and
/// dim light keeps its precision. Powers of two keep the relative error of packing
/// unchanged. `max_value` 0, negative or non-finite gives 1.
pub fn exposure_for(max_value: f32) -> f32 {
    if !(max_value.is_finite() && max_value > 0.0) {
        return 1.0;
    }
    // At least 2^-111: the largest code divided by the exposure stays finite (a smaller
    // exposure would unpack to infinity; light that large saturates instead).
    let e = (MAX_UF10 / max_value).log2().floor().clamp(-111.0, 126.0);
    2f32.powi(e as i32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn every_finite_code_round_trips_bit_exactly() {
        for mant in [5u32, 6] {
            let count = 31 << mant; // exponents 0..=30
            for code in 0..count {
                let v = decode_ufloat(code, mant);
                assert!(v.is_finite());
                assert_eq!(
                    encode_ufloat(v, mant),
                    code,
                    "mant {mant} code {code:#x} value {v}"
                );
            }
        }
        // Exponent 31 holds infinity and NaN; they decode as such, and re-encode saturated.
        assert_eq!(uf11_to_f32(0x7c0), f32::INFINITY);
        assert!(uf11_to_f32(0x7c1).is_nan());
        assert_eq!(f32_to_uf11(uf11_to_f32(0x7c0)), f32_to_uf11(MAX_UF11));
    }

    #[test]
    fn known_values() {
        assert_eq!(uf11_to_f32(0x7bf), MAX_UF11);
        assert_eq!(uf10_to_f32(0x3df), MAX_UF10);
        assert_eq!(f32_to_uf11(1.0), 15 << 6);
        assert_eq!(f32_to_uf10(1.0), 15 << 5);
        // Smallest denormal, and halfway cases.
        let tiny11 = 2f32.powi(-20);
        assert_eq!(f32_to_uf11(tiny11), 1);
        assert_eq!(f32_to_uf11(tiny11 * 0.5), 0); // tie to even (0)
        assert_eq!(f32_to_uf11(tiny11 * 1.5), 2); // tie to even (2)
        assert_eq!(f32_to_uf11(tiny11 * 0.5000001), 1);
        // 1 + 1/128 is halfway between 1 and 1 + 1/64: ties to even keeps 1.
        assert_eq!(f32_to_uf11(1.0 + 1.0 / 128.0), 15 << 6);
        assert_eq!(f32_to_uf11(1.0 + 3.0 / 128.0), (15 << 6) + 2);
        // Largest denormal rounds up into the smallest normal.
        assert_eq!(f32_to_uf11(2f32.powi(-14) * (1.0 - 1.0 / 256.0)), 1 << 6);
    }

    #[test]
    fn special_inputs() {
        for bad in [f32::NAN, -f32::NAN, -1.0, -0.0, f32::NEG_INFINITY, -1e-40] {
            assert_eq!(pack_r11g11b10(Vec3::splat(bad)), 0, "{bad}");
            assert_eq!(pack_rgb9e5(Vec3::splat(bad)), 0, "{bad}");
        }
        for big in [65024.0, 65025.0, 65535.0, 1e9, f32::MAX, f32::INFINITY] {
            let v = unpack_r11g11b10(pack_r11g11b10(Vec3::splat(big)));
            assert_eq!(v, Vec3::new(MAX_UF11, MAX_UF11, MAX_UF10), "{big}");
        }
        for big in [65408.0, 65409.0, 1e9, f32::MAX, f32::INFINITY] {
            let v = unpack_rgb9e5(pack_rgb9e5(Vec3::splat(big)));
            assert_eq!(v, Vec3::splat(MAX_RGB9E5), "{big}");
        }
        // f32 denormals encode to 0 (they are below half the smallest code).
        assert_eq!(pack_r11g11b10(Vec3::splat(1e-40)), 0);
        // Foreign infinity/NaN codes never come out as such.
        let v = unpack_r11g11b10(u32::MAX);
        assert!(v.is_finite());
    }

    #[test]
    fn exposure_is_a_power_of_two_that_fits() {
        for m in [1e-30f32, 1e-3, 1.0, 65024.0, 1e6, 3e9] {
            let e = exposure_for(m);
            assert!(m * e <= MAX_UF10 && m * e > MAX_UF10 / 2.0, "{m}: {e}");
            assert_eq!(e.to_bits() & 0x7f_ffff, 0);
        }
        assert_eq!(exposure_for(0.0), 1.0);
        assert_eq!(exposure_for(f32::NAN), 1.0);
    }

    #[test]
    fn rgb9e5_known_values() {
        assert_eq!(unpack_rgb9e5(pack_rgb9e5(Vec3::ONE)), Vec3::ONE);
        let c = Vec3::new(1000.0, 0.5, 3.25);
        let d = unpack_rgb9e5(pack_rgb9e5(c));
        // The shared exponent of 1000 gives steps of 2 on every channel.
        assert_eq!(d.x, 1000.0);
        assert_eq!(d.y, 0.0);
        assert_eq!(d.z, 4.0);
    }

    proptest! {
        #[test]
        fn r11g11b10_relative_error_is_bounded(r in 0f32..70000.0, g in 0f32..1e-3, b in 2f32.powi(-14)..64000.0) {
            let c = Vec3::new(r, g, b);
            let d = unpack_r11g11b10(pack_r11g11b10(c));
            let tol = |x: f32, rel: f32, step: f32| (x.min(MAX_UF11) * rel).max(step * 0.5);
            prop_assert!((d.x - r.min(MAX_UF11)).abs() <= tol(r, 2f32.powi(-7), 2f32.powi(-20)));
            prop_assert!((d.y - g).abs() <= tol(g, 2f32.powi(-7), 2f32.powi(-20)));
            prop_assert!((d.z - b).abs() <= b * 2f32.powi(-6));
        }

        #[test]
        fn packing_is_monotonic(a in 0f32..1e5, b in 0f32..1e5) {
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            prop_assert!(f32_to_uf11(lo) <= f32_to_uf11(hi));
            prop_assert!(f32_to_uf10(lo) <= f32_to_uf10(hi));
        }

        #[test]
        fn rgb9e5_error_is_bounded_by_the_shared_step(r in 0f32..60000.0, g in 0f32..60000.0, b in 0f32..60000.0) {
            let c = Vec3::new(r, g, b);
            let d = unpack_rgb9e5(pack_rgb9e5(c));
            // Step of the shared exponent: max / 2^8 at most (9-bit mantissa, round to nearest).
            let step = c.max_element() * 2f32.powi(-8);
            prop_assert!((d - c).abs().max_element() <= step.max(2f32.powi(-24)));
        }

        #[test]
        fn any_word_unpacks_finite(w in any::<u32>()) {
            prop_assert!(unpack_r11g11b10(w).is_finite());
            prop_assert!(unpack_rgb9e5(w).is_finite());
        }
    }
}

/// Linear `[0, 1]` to an 8-bit sRGB code (the IEC 61966-2-1 curve; clamped).
pub fn linear_to_srgb8(c: f32) -> u8 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    let s = if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// An 8-bit sRGB code to linear `[0, 1]`.
pub fn srgb8_to_linear(code: u8) -> f32 {
    let c = code as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod srgb_tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_code() {
        for code in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(code)), code);
        }
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(2.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188);
    }
}
