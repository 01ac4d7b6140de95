//! Project chores for lightgrid, as a library so that tests can run them too; the
//! `cargo xtask` command (`src/main.rs`) is the front end.

pub mod bench;
pub mod convergence;
pub mod figures;
pub mod frame;
pub mod fuzz;
pub mod fuzz_api;
pub mod sun;
pub mod tree;
