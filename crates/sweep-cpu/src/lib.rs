//! # sweep-cpu
//!
//! The reference top-down light-flow sweep: material grid and boundary light in, light
//! grids out, multithreaded on the CPU. Its crate docs will define the sweep semantics
//! that every other sweeper matches, and a Monte Carlo reference measures its error.
//!
//! Status: not built yet (issue "sweep-cpu"); it will implement `grid_core::Sweeper`.
