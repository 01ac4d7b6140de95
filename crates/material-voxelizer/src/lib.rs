//! # material-voxelizer
//!
//! Turns glTF models into model material grids (reflectance and pass-through per cell)
//! by ray queries against an obvhs BVH, offline, and composes the material grid of an
//! area from a terrain heightmap and model instances at run time.
//!
//! Status: not built yet (issue "material-voxelizer"); the types it produces and the
//! `MaterialSource` trait it will implement live in `grid-core`.
