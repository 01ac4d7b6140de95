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

/// The values above as proptest strategies (feature `proptest`): drawn from the shared
/// values, a crate's own edges and any value at all, so every property test sees the
/// same extremes without copying them.
#[cfg(feature = "proptest")]
pub mod strategies {
    use glam::Vec3;
    use proptest::prelude::*;

    /// Any `f32`, the shared [`F32`](super::F32) and `extra` (a crate's own edges,
    /// possibly none) drawn more often than chance would.
    pub fn f32_with(extra: &'static [f32]) -> BoxedStrategy<f32> {
        let shared = proptest::sample::select(&super::F32[..]);
        if extra.is_empty() {
            prop_oneof![shared, any::<f32>()].boxed()
        } else {
            prop_oneof![shared, proptest::sample::select(extra), any::<f32>()].boxed()
        }
    }

    /// Counts (sizes, passes, points): the given edge `values`, drawn as often as
    /// `small` counts, any of which is a cheap valid case.
    pub fn u32_of(values: &'static [u32], small: std::ops::Range<u32>) -> BoxedStrategy<u32> {
        prop_oneof![proptest::sample::select(values), small].boxed()
    }

    /// Vectors whose three components are drawn from `component`.
    pub fn vec3_of(component: BoxedStrategy<f32>) -> impl Strategy<Value = Vec3> {
        (component.clone(), component.clone(), component).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }
}
