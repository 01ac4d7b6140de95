//! # terrain-lod
//!
//! Organises a heightmap terrain as a quadtree and keeps a hierarchy of light grids
//! around the camera: one coarse world grid, finer node grids nearby, each initialised at
//! its edges from the coarser grid and built within a per-frame budget.
//!
//! Status: not built yet (issue "terrain-lod"); it will implement `grid_core::LightField`.
