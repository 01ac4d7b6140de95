//! A material source from a function: each cell takes `f(its centre, its size)` (the
//! tests' made-up scenes).

use lightgrid_core::glam::Vec3;
use lightgrid_core::{GridDesc, GridError, Material, MaterialGrid, MaterialSource};

pub(crate) struct Field<F>(pub(crate) F);

impl<F: Fn(Vec3, f32) -> Material> MaterialSource for Field<F> {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        let cells = (0..desc.point_count())
            .map(|i| (self.0)(desc.position(desc.coords(i).expect("in range")), desc.h()))
            .collect();
        MaterialGrid::new(*desc, cells)
    }
}
