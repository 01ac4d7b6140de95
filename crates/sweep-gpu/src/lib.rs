//! # sweep-gpu
//!
//! The same sweep as `sweep-cpu`, as wgpu compute shaders (WGSL) with one dispatch per
//! level, so light grids can be rebuilt on the GPU around a moving camera. Its results
//! are property-tested against `sweep-cpu`.
//!
//! Status: not built yet (issue "sweep-gpu"); it will implement `grid_core::Sweeper`.
