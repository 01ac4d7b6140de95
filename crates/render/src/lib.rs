//! # render
//!
//! Reads light from the grid hierarchy for batches of points (light sampling buffers, on
//! CPU and GPU) and shades surfaces with it: irradiance on normals, average plus dominant
//! direction for moving objects, and the seed's ground-blend and normal-bias tweaks.
//!
//! Status: not built yet (issue "render and viewer"); it consumes `grid_core::LightField`.
