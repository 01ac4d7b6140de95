//! Values that break arithmetic, shared by the workspace's property tests of public
//! entry points over extreme inputs (`crates/*/tests/extremes.rs`): every public
//! constructor and entry point must return a typed error or a finite result for them,
//! never panic or return a NaN.
//!
//! ```
//! use lightgrid_core::extremes::F32;
//! assert!(F32.iter().any(|x| x.is_nan()) && F32.contains(&f32::MAX));
//! ```

/// Zeros, ones, the edges of `f32`'s range, a subnormal, NaN and the infinities.
pub const F32: [f32; 13] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    1e30,
    f32::MAX,
    -f32::MAX,
    f32::MIN_POSITIVE,
    1e-45,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
];

/// Counts and sizes: zero, one, small ones, powers of two and the edge of `u32`
/// (products of three of them overflow `u32` and `u64`).
pub const U32: [u32; 8] = [0, 1, 2, 3, 4096, 1 << 16, 1 << 31, u32::MAX];
