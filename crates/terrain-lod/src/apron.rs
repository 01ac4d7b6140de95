//! A node's sky sweep over its grid widened by an apron of cells on every side
//! ([`HierarchyParams::apron`](crate::HierarchyParams::apron)), kept only inside.
//!
//! A node takes the light entering its sides from a coarser grid's points, which blur
//! the canopy and the ground at twice the node's cell or more; horizontal light crosses
//! the whole node with what it brought. Swept over a wider grid, composed from the
//! scene at the node's own cell, the light reaching the node's own points has crossed
//! the apron's fine material first, and the coarser light's error fades over it. On the
//! frame bench's forest at 30° (16-point nodes; `cargo xtask frame --apron N`, the
//! nesting alone: each depth against one sweep of the region at its own cell), the
//! sky's RMSE at depths 1–4 went from 2.7 / 2.5 / 4.0 / 4.3 % without an apron to
//! 1.6 / 1.8 / 3.2 / 3.3 % with one cell and 1.4 / 1.5 / 2.5 / 2.9 % with two, for
//! `((n + 2a) / n)²` the points of each sky sweep (`n` points across, `a` the apron),
//! which the point budget counts. With the default 32-point nodes three cells cost 1.41
//! times the points, and the sky nests within 2 % RMSE at every depth (15° and 40°: 2.9
//! / 2.6 / 2.2 / 3.0 % without, 1.0 / 1.0 / 1.8 / 1.9 % with three): the default. The
//! neighbours of the node's own depth, where built, gave little as a halo instead (4.3
//! → 4.0 % at depth 4): the apron's light is swept with the node's own levels, ground
//! and passes.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    Grid, GridDesc, GridError, MaterialGrid, Resident, SunBeam, SunResponse, SweepError,
    SweepOptions, SweepOutput, Sweeper,
};

use crate::{Hierarchy, LodError, NodeKey, NodeMaterial, StageTimes, shadow, timed};

/// What a node's sky sweep reads besides its material: the boundary of its grid, or of
/// the grid widened by the apron, and the hash of those inputs ([`Hierarchy::refresh`]).
pub(crate) struct SkyInputs {
    pub(crate) boundary: lightgrid_core::Boundary,
    pub(crate) hash: u64,
    /// The node's depth: the sun's march beyond its box reads this depth's materials
    /// and coarser ones ([`HierarchyParams::sun_with_sky`](crate::HierarchyParams::sun_with_sky)).
    depth: u32,
}

impl Hierarchy {
    /// The source's material over `desc` and, with an apron, over `desc` widened by it:
    /// composed once over the widened grid, `desc`'s its inner points (every cell is
    /// composed from its own box: the same bit for bit).
    pub(crate) fn compose_node(
        &self,
        desc: &GridDesc,
    ) -> Result<(MaterialGrid, Option<MaterialGrid>), GridError> {
        let apron = self.params.apron;
        if apron == 0 {
            return Ok((self.compose(desc)?, None));
        }
        let big = widened(desc, apron)?;
        let wide = self.compose(&big)?;
        Ok((crop(&wide, &big, desc, apron), Some(wide)))
    }

    /// The inputs of node `key`'s sky sweep, its material `material`: the boundary from
    /// the coarser grids (and the nodes of its depth before it, where it reads those)
    /// around the grid it is swept on (its widened one where it has one).
    pub(crate) fn sky_inputs(
        &self,
        key: crate::NodeKey,
        material: (&MaterialGrid, Option<&MaterialGrid>),
        options: &SweepOptions,
        times: &mut StageTimes,
    ) -> SkyInputs {
        let mut inputs = self.sky_boundary(key, material, times);
        timed(&mut times.boundary, || {
            inputs.hash = self.sky_hash(material, &inputs.boundary, options);
        });
        inputs
    }

    /// [`Hierarchy::sky_inputs`] without their hash (0): the caller takes it with
    /// [`Hierarchy::sky_hash`] (beside the sweep: [`Hierarchy::sky_node`]).
    pub(crate) fn sky_boundary(
        &self,
        key: crate::NodeKey,
        material: (&MaterialGrid, Option<&MaterialGrid>),
        times: &mut StageTimes,
    ) -> SkyInputs {
        let m = material.1.unwrap_or(material.0);
        let boundary = timed(&mut times.boundary, || self.node_boundary(m.desc(), key));
        SkyInputs {
            boundary,
            hash: 0,
            depth: key.depth,
        }
    }

    /// The hash of a node's sky inputs (its material as swept, `boundary`, `options`,
    /// and the sun where its sky sweep holds it) that [`Hierarchy::refresh`] compares.
    pub(crate) fn sky_hash(
        &self,
        material: (&MaterialGrid, Option<&MaterialGrid>),
        boundary: &lightgrid_core::Boundary,
        options: &SweepOptions,
    ) -> u64 {
        let m = material.1.unwrap_or(material.0);
        let hash = crate::hash_grid(m, boundary, options);
        match self.sky_sun() {
            Some(sun) => crate::sun::hash_sun(hash, sun),
            None => hash,
        }
    }

    /// The sky sweep of `inputs` (made for `material` by [`Hierarchy::sky_inputs`]),
    /// its outputs on the node's own grid. Points swept: [`sky_points`].
    pub(crate) fn sweep_sky(
        &self,
        inputs: &SkyInputs,
        material: &NodeMaterial,
        options: &SweepOptions,
        (sweeper, fresh): (&mut dyn Sweeper, &shadow::Fresh<'_>),
        times: &mut StageTimes,
    ) -> Result<SweepOutput, LodError> {
        let m = material.widened.as_ref().unwrap_or(&material.grid);
        let out = timed(&mut times.sky_sweep, || match self.sky_sun() {
            // The beam marched on beyond the node's box as its transmittance is.
            Some(sun) => {
                let sky = shadow::SkyMarch::new(self, inputs.depth, fresh);
                let outside = |p: Vec3| sky.to_sky(p, sun.to_sun);
                let beam = SunBeam {
                    to_sun: sun.to_sun,
                    irradiance: sun.irradiance,
                    outside: &outside,
                };
                sweeper.sweep_with_sun(m, &inputs.boundary, &beam, options)
            }
            None => sweeper.sweep(m, &inputs.boundary, options),
        })?;
        Ok(match &material.widened {
            None => out,
            Some(w) => cropped(
                out,
                w.desc(),
                material.grid.desc(),
                self.params.apron,
                sweeper,
            ),
        })
    }

    /// The material node `m`'s sun responses are swept and marched over: its grid
    /// widened by [`HierarchyParams::sun_apron`](crate::HierarchyParams::sun_apron)
    /// cells (the sky's widened grid's inner part), and those cells; `None`: its own.
    pub(crate) fn sun_material<'a>(
        &self,
        m: &'a NodeMaterial,
    ) -> Option<(std::borrow::Cow<'a, MaterialGrid>, u32)> {
        let (a, k) = (self.params.apron, self.params.sun_apron);
        let w = m.widened.as_ref().filter(|_| k > 0)?;
        if k >= a {
            return Some((std::borrow::Cow::Borrowed(w), a));
        }
        let small = widened(m.grid.desc(), k).ok()?;
        Some((std::borrow::Cow::Owned(crop(w, w.desc(), &small, a - k)), k))
    }

    /// Node `key`'s sun transmittance for `to_sun`, marched over its sun's material
    /// ([`Hierarchy::sun_material`]: widened where the sun has an apron, as its sun
    /// sweep's), kept on its own points.
    pub(crate) fn march_node(
        &self,
        sweeper: &mut dyn Sweeper,
        key: NodeKey,
        material: &NodeMaterial,
        to_sun: Vec3,
        fresh: &shadow::Fresh<'_>,
    ) -> Result<Grid<f32>, SweepError> {
        let sky = shadow::SkyMarch::new(self, key.depth, fresh);
        let outside = |p: Vec3| sky.to_sky(p, to_sun);
        let wide = self.sun_material(material);
        let m = wide.as_ref().map_or(&material.grid, |w| &*w.0);
        let t = crate::sun_move::march(sweeper, m, to_sun, &outside)?;
        Ok(match &wide {
            None => t,
            Some((w, k)) => crop(&t, w.desc(), material.grid.desc(), *k),
        })
    }
}

/// `g`'s lowest `levels` levels (all of them where it has no more).
pub(crate) fn lowest_levels<T: Copy>(g: Grid<T>, levels: u32) -> Result<Grid<T>, GridError> {
    let d = *g.desc();
    if levels >= d.dims().y {
        return Ok(g);
    }
    let desc = GridDesc::new(
        d.origin(),
        d.h(),
        UVec3::new(d.dims().x, levels, d.dims().z),
    )?;
    let mut data = g.into_data();
    data.truncate(desc.point_count());
    Ok(Grid::from_trusted(desc, data))
}

/// The points a node grid's sky sweep sweeps with an apron of `apron` cells.
pub(crate) fn sky_points(desc: &GridDesc, apron: u32) -> u64 {
    let d = desc.dims();
    (d.x + 2 * apron) as u64 * d.y as u64 * (d.z + 2 * apron) as u64
}

/// `desc` widened by `apron` cells on every side (the same levels and lattice).
pub(crate) fn widened(desc: &GridDesc, apron: u32) -> Result<GridDesc, GridError> {
    let h = desc.h();
    let a = apron as f32 * h;
    GridDesc::new(
        desc.origin() - Vec3::new(a, 0.0, a),
        h,
        desc.dims() + UVec3::new(2 * apron, 0, 2 * apron),
    )
}

/// `out`, swept by `sweeper` on `big` (`desc` widened by `apron`), kept on `desc`'s
/// points: its device copy too, where the sweeper keeps one
/// ([`Sweeper::crop_resident`]).
fn cropped(
    out: SweepOutput,
    big: &GridDesc,
    desc: &GridDesc,
    apron: u32,
    sweeper: &dyn Sweeper,
) -> SweepOutput {
    SweepOutput {
        bins: out.bins.map(|g| crop(&g, big, desc, apron)),
        horizon: out.horizon.map(|g| crop(&g, big, desc, apron)),
        average: out.average.map(|g| crop(&g, big, desc, apron)),
        dominant: out.dominant.map(|g| crop(&g, big, desc, apron)),
        stats: out.stats,
        resident: crop_resident(out.resident.as_ref(), desc, apron, sweeper),
    }
}

/// The sun's responses swept by `sweeper` on `big` (`desc` widened by `apron`), kept
/// on `desc`'s points, as [`cropped`]'s.
pub(crate) fn cropped_sun(
    r: SunResponse,
    big: &GridDesc,
    desc: &GridDesc,
    apron: u32,
    sweeper: &dyn Sweeper,
) -> SunResponse {
    SunResponse {
        scattered: crop(&r.scattered, big, desc, apron),
        horizon: r.horizon.map(|g| crop(&g, big, desc, apron)),
        transmittance: crop(&r.transmittance, big, desc, apron),
        stats: r.stats,
        resident: crop_resident(r.resident.as_ref(), desc, apron, sweeper),
    }
}

/// A device copy of a grid widened by `apron`, cropped to `desc`'s points on the
/// device by the sweeper that made it (`None` where it keeps none).
fn crop_resident(
    resident: Option<&Resident>,
    desc: &GridDesc,
    apron: u32,
    sweeper: &dyn Sweeper,
) -> Option<Resident> {
    sweeper.crop_resident(resident?, desc, UVec3::new(apron, 0, apron))
}

/// `g` (on `big`, `desc` widened by `apron`) at `desc`'s points.
fn crop<T: Copy>(g: &Grid<T>, big: &GridDesc, desc: &GridDesc, apron: u32) -> Grid<T> {
    let shift = UVec3::new(apron, 0, apron);
    let data = g.data();
    let kept = (0..desc.point_count())
        .map(|i| {
            let c = desc.coords(i).expect("an index of the grid");
            data[big.index_unchecked(c + shift)]
        })
        .collect();
    Grid::from_trusted(*desc, kept)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The widened grid has the node's levels and lattice, `apron` more points on every
    /// side; the kept points are its inner ones, each at the node's point's position.
    #[test]
    fn cropping_keeps_the_inner_points() {
        let desc = GridDesc::new(Vec3::new(3.5, -2.0, 7.5), 1.0, UVec3::new(4, 3, 5)).unwrap();
        let big = widened(&desc, 2).unwrap();
        assert_eq!(big.dims(), UVec3::new(8, 3, 9));
        assert_eq!(big.h(), desc.h());
        assert_eq!(sky_points(&desc, 2), big.point_count() as u64);
        let g = Grid::from_trusted(big, (0..big.point_count()).collect::<Vec<usize>>());
        let kept = crop(&g, &big, &desc, 2);
        assert_eq!(*kept.desc(), desc);
        for (i, &j) in kept.data().iter().enumerate() {
            let p = desc.position(desc.coords(i).unwrap());
            let q = big.position(big.coords(j).unwrap());
            assert_eq!(p, q, "point {i}");
        }
    }
}
