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
//! times the points (15° and 40°: 2.9 / 2.6 / 2.2 / 3.0 % without, 1.0 / 1.0 / 1.8 /
//! 1.9 % with three when first measured; now 1.2 / 1.2 / 1.8 / 2.1 % at 15°, the
//! finest depth over issue 43's 2 %): the default. The
//! neighbours of the node's own depth, where built, gave little as a halo instead (4.3
//! → 4.0 % at depth 4): the apron's light is swept with the node's own levels, ground
//! and passes.

use lightgrid_core::glam::{IVec2, UVec3, Vec3};
use lightgrid_core::{
    Grid, GridDesc, GridError, HorizonGrid, LightGrid, MaterialGrid, Resident, SunBeam,
    SunResponse, SweepError, SweepOptions, SweepOutput, Sweeper,
};

use crate::{Hierarchy, LodError, NodeKey, NodeMaterial, StageTimes, shadow, timed};

/// A node's composed material: its grid, widened by the apron, and widened by the apron
/// and the halo ([`Hierarchy::compose_node`]).
pub(crate) type Composed = (MaterialGrid, Option<MaterialGrid>, Option<MaterialGrid>);

/// What a node's sky sweep reads besides its material: the boundary of its grid, or of
/// the grid widened by the apron, and the hash of those inputs ([`Hierarchy::refresh`]).
pub(crate) struct SkyInputs {
    pub(crate) boundary: lightgrid_core::Boundary,
    pub(crate) hash: u64,
    /// The node (the sun's march beyond its box reads its depth's materials and
    /// coarser ones, [`HierarchyParams::sun_with_sky`](crate::HierarchyParams::sun_with_sky);
    /// its apron's [`Band`] is kept while a wanted node beside it is missing).
    key: NodeKey,
}

impl Hierarchy {
    /// The source's material over `desc` and, with an apron, over `desc` widened by it:
    /// composed once over the widened grid, `desc`'s its inner points (every cell is
    /// composed from its own box: the same bit for bit).
    ///
    /// With [`HierarchyParams::halo_cells`](crate::HierarchyParams::halo_cells), composed
    /// [`HALO_WIDTH`](lightgrid_core::HALO_WIDTH) cells wider still, and that grid (whose
    /// ring holds the cells of the sweeps' halos) returned third.
    pub(crate) fn compose_node(&self, desc: &GridDesc) -> Result<Composed, GridError> {
        let apron = self.params.apron;
        if self.params.halo_cells == crate::HaloCells::Composed {
            let ring = lightgrid_core::HALO_WIDTH as u32;
            let outer_desc = widened(desc, apron + ring)?;
            let outer = self.compose(&outer_desc)?;
            let wide = (apron > 0).then(|| {
                let big = widened(desc, apron).expect("narrower than the composed grid");
                crop(&outer, &outer_desc, &big, ring)
            });
            return Ok((
                crop(&outer, &outer_desc, desc, apron + ring),
                wide,
                Some(outer),
            ));
        }
        if apron == 0 {
            return Ok((self.compose(desc)?, None, None));
        }
        let big = widened(desc, apron)?;
        let wide = self.compose(&big)?;
        Ok((crop(&wide, &big, desc, apron), Some(wide), None))
    }

    /// The inputs of node `key`'s sky sweep, its material `material`: the boundary from
    /// the coarser grids (and the nodes of its depth before it, where it reads those)
    /// around the grid it is swept on (its widened one where it has one).
    pub(crate) fn sky_inputs(
        &self,
        key: crate::NodeKey,
        material: &NodeMaterial,
        options: &SweepOptions,
        times: &mut StageTimes,
    ) -> SkyInputs {
        let mut inputs = self.sky_boundary(key, material, times);
        let m = (&material.grid, material.widened.as_ref());
        timed(&mut times.boundary, || {
            inputs.hash = self.sky_hash(m, &inputs.boundary, options);
        });
        inputs
    }

    /// [`Hierarchy::sky_inputs`] without their hash (0): the caller takes it with
    /// [`Hierarchy::sky_hash`] (beside the sweep: [`Hierarchy::sky_node`]).
    pub(crate) fn sky_boundary(
        &self,
        key: crate::NodeKey,
        material: &NodeMaterial,
        times: &mut StageTimes,
    ) -> SkyInputs {
        let m = material.widened.as_ref().unwrap_or(&material.grid);
        let boundary = timed(&mut times.boundary, || {
            let cells = crate::boundary::HaloMaterial {
                swept: Some(m),
                outer: material.outer.as_ref(),
            };
            let mut b = self.node_boundary(m.desc(), key, cells);
            // Carried here, in place: the sweep then copies nothing.
            lightgrid_core::halo_carry::carry_halo(&mut b, m.desc().dims());
            b
        });
        SkyInputs {
            boundary,
            hash: 0,
            key,
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
    ) -> Result<(SweepOutput, Option<Ring>, Option<Band>), LodError> {
        let m = material.widened.as_ref().unwrap_or(&material.grid);
        let out = timed(&mut times.sky_sweep, || match self.sky_sun() {
            // The beam marched on beyond the node's box as its transmittance is.
            Some(sun) => {
                let sky = shadow::SkyMarch::new(self, inputs.key.depth, fresh);
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
            None => (out, None, None),
            Some(w) => {
                let (big, desc, apron) = (w.desc(), material.grid.desc(), self.params.apron);
                let widened = |bins| Widened {
                    bins,
                    halves: out.horizon.as_ref(),
                    big,
                    desc,
                    apron,
                };
                // Where the light stays on the CPU (a device copy is read by the GPU's
                // layers, which have no ring: their reads clamp).
                let ring = out
                    .bins
                    .as_ref()
                    .filter(|_| out.resident.is_none())
                    .map(|b| Ring::of(widened(b)));
                // Read by finer nodes' boundaries (on the CPU whatever the sweeper):
                // only at a depth with finer ones, beside a wanted node not built.
                let band = out
                    .bins
                    .as_ref()
                    .filter(|_| inputs.key.depth < self.params.depths())
                    .filter(|_| self.band_read(inputs.key))
                    .map(|b| Band::of(widened(b)));
                (cropped(out, big, desc, apron, sweeper), ring, band)
            }
        })
    }

    /// The material node `m`'s sun responses are swept and marched over: its grid
    /// widened by [`HierarchyParams::sun_apron_cells`](crate::HierarchyParams::sun_apron_cells)
    /// cells (the sky's widened grid's inner part), and those cells; `None`: its own.
    pub(crate) fn sun_material<'a>(
        &self,
        m: &'a NodeMaterial,
    ) -> Option<(std::borrow::Cow<'a, MaterialGrid>, u32)> {
        let (a, k) = (self.params.apron, self.params.sun_apron_cells());
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
        let wide = self.sun_material(material);
        let m = wide.as_ref().map_or(&material.grid, |w| &*w.0);
        let t = self
            .march_grids(sweeper, (key, fresh), to_sun, &[m])?
            .remove(0);
        Ok(match &wide {
            None => t,
            Some((w, k)) => crop(&t, w.desc(), material.grid.desc(), *k),
        })
    }

    /// Each of `grids` (node `key`'s, or beside it) marched toward `to_sun`: every
    /// point's ray through its grid, then on through the materials the hierarchy holds
    /// down to `key`'s depth (`fresh`: those composed this frame).
    fn march_grids(
        &self,
        sweeper: &mut dyn Sweeper,
        (key, fresh): (NodeKey, &shadow::Fresh<'_>),
        to_sun: Vec3,
        grids: &[&MaterialGrid],
    ) -> Result<Vec<Grid<f32>>, SweepError> {
        let sky = shadow::SkyMarch::new(self, key.depth, fresh);
        let outside = |p: Vec3| sky.to_sky(p, to_sun);
        grids
            .iter()
            .map(|m| crate::sun_move::march(sweeper, m, to_sun, &outside))
            .collect()
    }
}

/// A node's sun transmittance one cell beyond its points ([`Ring`]'s tiles, each
/// marched toward the sun through the apron's cells there and on through the
/// materials the hierarchy holds): what its missing neighbours' outermost points would
/// hold (within the march's steps past each box's faces: `shadow::SkyMarch`), read in
/// the strip beside them instead of the node's outermost points clamped (a read half a
/// cell out took their transmittance, shadow edges and all, half a cell too far). A
/// tile's grid lies on its [`Ring`] tile's layout. Marched with every march of the
/// node's transmittance that has its material (its sun responses, `set_sun`'s; read
/// only where the node keeps a sky [`Ring`], its light on the CPU); 13 % more points
/// marched at 32 across. Measured (`cargo xtask frame --node-points 32
/// --elevation 15 --elevation 40 --mc-probes 0`, the nesting alone): the direct sun's
/// RMSE at depth 2 went from 2.0 to 0.0 % at 15° and at depth 4 from 0.9 to 0.2 %, the
/// sun's at depth 2 5.1 / 3.5 → 4.8 / 3.3 % at 15 / 40° and at depth 4 1.3 / 1.5 → 0.9
/// / 1.3 %, the finest depth's largest error of sky and sun over the local brightest
/// 14.4 → 10.5 % at 15°, depth 2's 5.1 / 8.9 → 3.6 / 4.9 %; its strips' sun RMSE 7.1 →
/// 1.1 % at 15°. The sky is unchanged. Cost, mostly the sun's casters found one cell
/// wider for the ring's rays ([`Hierarchy::marched_extent`]): 166 casters over that
/// path at 15° instead of 99, its frame 6 % longer.
pub(crate) struct SunRing {
    /// The direction marched toward.
    pub(crate) to_sun: Vec3,
    tiles: Vec<Grid<f32>>,
}

impl SunRing {
    /// The tile at `offset` from the node (x, z), if one of the eight.
    pub(crate) fn tile(&self, offset: IVec2) -> Option<&Grid<f32>> {
        self.tiles.get(Ring::index(offset)?)
    }
}

impl Hierarchy {
    /// The grid node material `m`'s transmittance is marched from (its rays start in
    /// all of it; the sun's casters are found for it): with the sun swept with the sky,
    /// the sky sweep's (widened by the apron), else the sun responses' (widened by
    /// `sun_apron`), and at least one cell past the node where it has an apron (its
    /// [`SunRing`]).
    pub(crate) fn marched_extent(&self, m: &NodeMaterial) -> GridDesc {
        if self.params.sun_with_sky {
            return *m.widened.as_ref().unwrap_or(&m.grid).desc();
        }
        let desc = *m.grid.desc();
        match &m.widened {
            Some(_) => widened(&desc, self.params.sun_apron_cells().max(1)).unwrap_or(desc),
            None => desc,
        }
    }

    /// Node `key`'s [`SunRing`] for `to_sun`: `None` without an apron (no material
    /// beyond the node's points).
    pub(crate) fn march_ring(
        &self,
        sweeper: &mut dyn Sweeper,
        (key, fresh): (NodeKey, &shadow::Fresh<'_>),
        material: &NodeMaterial,
        to_sun: Vec3,
    ) -> Result<Option<SunRing>, SweepError> {
        let apron = self.params.apron;
        let Some(wide) = material.widened.as_ref().filter(|_| apron > 0) else {
            return Ok(None);
        };
        let (desc, big) = (material.grid.desc(), wide.desc());
        let cells: Vec<MaterialGrid> = Ring::OFFSETS
            .into_iter()
            .map(|o| {
                let (lo, n) = tile_box(desc, apron, o);
                crop_box(wide, big, lo, n)
            })
            .collect();
        let cells: Vec<&MaterialGrid> = cells.iter().collect();
        let tiles = self.march_grids(sweeper, (key, fresh), to_sun, &cells)?;
        Ok(Some(SunRing { to_sun, tiles }))
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

/// A node's light one cell beyond its grid, as its sky sweep over the apron left it:
/// the tiles its eight neighbours of its depth would hold next to it (a side's column
/// of points, or a corner's one), read in their place where a neighbour is not built.
/// A read in the half cell between the node's outermost points and its rectangle's
/// side takes, by [`lightgrid_core::seam`]'s rule, each tile's own clamped read; a
/// missing neighbour's is its outermost points, which the ring's points estimate with
/// the node's own fine material around them (the node's clamped read without one).
/// Measured (`cargo xtask frame --node-points 32 --elevation 15 --mc-probes 0`, the
/// nesting alone): depth 2's largest sky error over the local brightest 10.0 → 5.3 %,
/// the finest depth's 13.8 → 11.7 %, the finest depth's strips' sky RMSE 2.8 → 2.3 %;
/// nothing else read changes. `((n + 2)² − n²) / n²` of the node's points more (13 % at
/// 32 points across).
pub(crate) struct Ring {
    /// The tiles at [`Ring::OFFSETS`] from the node.
    tiles: Vec<LightGrid>,
    halves: Option<Vec<HorizonGrid>>,
}

impl Ring {
    /// The tiles' offsets from the node (x, z), in the ring's order.
    const OFFSETS: [IVec2; 8] = [
        IVec2::new(-1, -1),
        IVec2::new(0, -1),
        IVec2::new(1, -1),
        IVec2::new(-1, 0),
        IVec2::new(1, 0),
        IVec2::new(-1, 1),
        IVec2::new(0, 1),
        IVec2::new(1, 1),
    ];

    /// The ring of a node's widened light.
    fn of(light: Widened<'_>) -> Self {
        let (tiles, halves) =
            light.crop(&Self::OFFSETS.map(|o| tile_box(light.desc, light.apron, o)));
        Self { tiles, halves }
    }

    /// Where the tile at `offset` from the node (x, z) is in the ring's order, if one
    /// of the eight.
    pub(crate) fn index(offset: IVec2) -> Option<usize> {
        Self::OFFSETS.iter().position(|&o| o == offset)
    }

    /// The tile at `offset` from the node (x, z), if one of the eight.
    pub(crate) fn tile(&self, offset: IVec2) -> Option<(&LightGrid, Option<&HorizonGrid>)> {
        let k = Self::index(offset)?;
        Some((&self.tiles[k], self.halves.as_ref().map(|h| &h[k])))
    }

    /// The tiles with their offsets, in the ring's order.
    pub(crate) fn tiles(&self) -> impl Iterator<Item = (IVec2, &LightGrid)> {
        Self::OFFSETS.into_iter().zip(&self.tiles)
    }

    /// Points held (the eight tiles).
    pub(crate) fn points(&self) -> u64 {
        self.tiles
            .iter()
            .map(|t| t.desc().point_count() as u64)
            .sum()
    }
}

/// A node's light over its apron beyond each side, as its sky sweep over the apron left
/// it: four slabs of the widened grid (beyond −z and +z its whole width, beyond −x and +x
/// the node's own extent in z), each `apron` points deep and the node's outermost points
/// beside them, so that every read of the widened grid beyond the node's points falls
/// on one slab's points. While a wanted node of its depth beside it is not built, a
/// finer node's boundary reads its points there from the slab instead of a coarser grid
/// ([`Hierarchy::coarse_grid`](crate::Hierarchy)): light swept over the node's own fine
/// material. Such a reader is provisional (`order.rs`) and swept again once that node is
/// built, so a settled hierarchy never reads a band, and one without a budget, or a
/// bake, is the same as before; what the band changes is the light a node shows while
/// it waits. Kept by the depths with finer ones below them, and dropped once no wanted
/// node of its depth beside it is missing ([`Hierarchy::drop_unread_bands`]). Measured
/// (`cargo xtask frame --node-points 32 --elevation 15 --elevation 40 --mc-probes 0`,
/// the nesting alone along the cold-start path): the finest depth's sky RMSE 2.3 / 2.0
/// → 2.1 / 1.9 % at 15 / 40°, depth 3's 2.0 / 1.7 → 1.8 / 1.6 %; at most 54,320 points
/// held in bands at a frame's end there.
///
/// [`Hierarchy::drop_unread_bands`]: crate::Hierarchy
pub(crate) struct Band {
    /// The slabs beyond −z, +z, −x and +x.
    slabs: Vec<LightGrid>,
    halves: Option<Vec<HorizonGrid>>,
}

impl Band {
    /// The band of a node's widened light.
    fn of(light: Widened<'_>) -> Self {
        let (slabs, halves) = light.crop(&slab_boxes(light.desc, light.apron));
        Self { slabs, halves }
    }

    /// The slab whose points hold the trilinear read at `p` (all eight corners), with
    /// its halves; `None` where none does.
    pub(crate) fn at(&self, p: Vec3) -> Option<(&LightGrid, Option<&HorizonGrid>)> {
        let k = self.slabs.iter().position(|s| {
            let g = s.desc().to_grid(p);
            g.cmpge(Vec3::ZERO).all() && g.cmple((s.desc().dims() - 1).as_vec3()).all()
        })?;
        Some((&self.slabs[k], self.halves.as_ref().map(|h| &h[k])))
    }

    /// Points held (the four slabs).
    pub(crate) fn points(&self) -> u64 {
        self.slabs
            .iter()
            .map(|t| t.desc().point_count() as u64)
            .sum()
    }
}

/// The eight nodes of `key`'s depth beside it (edge or corner), in row order.
pub(crate) fn around(key: NodeKey) -> impl Iterator<Item = NodeKey> {
    Ring::OFFSETS.into_iter().map(move |o| NodeKey {
        depth: key.depth,
        index: key.index + o,
    })
}

/// The boxes of [`Band`]'s slabs on the grid widened by `apron` (≥ 1): lowest point and
/// points across (x, levels, z), beyond −z, +z, −x and +x.
fn slab_boxes(desc: &GridDesc, apron: u32) -> [(UVec3, UVec3); 4] {
    let d = desc.dims();
    let (a, wide) = (apron, d.x + 2 * apron);
    [
        (UVec3::ZERO, UVec3::new(wide, d.y, a + 1)),
        (UVec3::new(0, 0, a + d.z - 1), UVec3::new(wide, d.y, a + 1)),
        (UVec3::new(0, 0, a), UVec3::new(a + 1, d.y, d.z)),
        (UVec3::new(a + d.x - 1, 0, a), UVec3::new(a + 1, d.y, d.z)),
    ]
}

/// The box of the tile at `offset` on the grid widened by `apron` (≥ 1): its lowest
/// point and its points across (x, levels, z).
fn tile_box(desc: &GridDesc, apron: u32, offset: IVec2) -> (UVec3, UVec3) {
    let d = desc.dims();
    let along = |o: i32, n: u32| match o {
        -1 => (apron - 1, 1),
        0 => (apron, n),
        _ => (apron + n, 1),
    };
    let (x0, nx) = along(offset.x, d.x);
    let (z0, nz) = along(offset.y, d.z);
    (UVec3::new(x0, 0, z0), UVec3::new(nx, d.y, nz))
}

/// The points of `g` (a node's grid) beside its ring's tile at `offset`, laid out as
/// the tile's (`tile`): what the node's clamped read gives over the tile.
pub(crate) fn edge_of<T: Copy>(g: &Grid<T>, offset: IVec2, tile: &GridDesc) -> Grid<T> {
    let d = g.desc().dims();
    let at = |o: i32, n: u32| if o > 0 { n - 1 } else { 0 };
    let lo = UVec3::new(at(offset.x, d.x), 0, at(offset.y, d.z));
    points_from(g, g.desc(), lo, *tile)
}

/// A node's light as its sky sweep over its apron left it: `bins` (and `halves`) on
/// `big`, the node's grid `desc` widened by `apron` (≥ 1) cells a side.
#[derive(Clone, Copy)]
struct Widened<'a> {
    bins: &'a LightGrid,
    halves: Option<&'a HorizonGrid>,
    big: &'a GridDesc,
    desc: &'a GridDesc,
    apron: u32,
}

impl Widened<'_> {
    /// The light cropped to each box (lowest point, points across).
    fn crop(&self, boxes: &[(UVec3, UVec3)]) -> (Vec<LightGrid>, Option<Vec<HorizonGrid>>) {
        fn of<T: Copy>(g: &Grid<T>, big: &GridDesc, boxes: &[(UVec3, UVec3)]) -> Vec<Grid<T>> {
            boxes
                .iter()
                .map(|&(lo, n)| crop_box(g, big, lo, n))
                .collect()
        }
        (
            of(self.bins, self.big, boxes),
            self.halves.map(|h| of(h, self.big, boxes)),
        )
    }
}

/// `g` (on `big`) at the `n` points from `lo` (in `big`'s points).
fn crop_box<T: Copy>(g: &Grid<T>, big: &GridDesc, lo: UVec3, n: UVec3) -> Grid<T> {
    let desc = GridDesc::new(big.origin() + lo.as_vec3() * big.h(), big.h(), n)
        .expect("a box of a valid grid");
    points_from(g, big, lo, desc)
}

/// `g` (on `big`, `desc` widened by `apron`) at `desc`'s points.
fn crop<T: Copy>(g: &Grid<T>, big: &GridDesc, desc: &GridDesc, apron: u32) -> Grid<T> {
    points_from(g, big, UVec3::new(apron, 0, apron), *desc)
}

/// `onto`'s points taken from `g` (laid out on `from`) from its point `lo` on: a row
/// (x) at a time, in `onto`'s order (level, z, x).
fn points_from<T: Copy>(g: &Grid<T>, from: &GridDesc, lo: UVec3, onto: GridDesc) -> Grid<T> {
    let (data, n) = (g.data(), onto.dims());
    let mut kept = Vec::with_capacity(onto.point_count());
    for y in 0..n.y {
        for z in 0..n.z {
            let start = from.index_unchecked(lo + UVec3::new(0, y, z));
            kept.extend_from_slice(&data[start..start + n.x as usize]);
        }
    }
    Grid::from_trusted(onto, kept)
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

    /// The ring's tile at each offset holds the widened grid's points one cell beyond
    /// the node on that side (a column for a side, a corner's column for a corner), at
    /// their own positions, and the node's points beside it are those its clamped read
    /// gives there.
    #[test]
    fn the_ring_holds_the_points_one_cell_beyond_each_side() {
        let desc = GridDesc::new(Vec3::new(3.5, -2.0, 7.5), 1.0, UVec3::new(4, 3, 5)).unwrap();
        for apron in [1, 3] {
            let big = widened(&desc, apron).unwrap();
            let index = |p: Vec3| {
                let c = big.to_grid(p).round().as_uvec3();
                big.index_unchecked(c) as f32
            };
            let values = (0..big.point_count())
                .map(|i| lightgrid_core::BinLight([Vec3::splat(i as f32); 26]))
                .collect();
            let bins = LightGrid::new(big, values).unwrap();
            let ring = Ring::of(Widened {
                bins: &bins,
                halves: None,
                big: &big,
                desc: &desc,
                apron,
            });
            assert_eq!(ring.points(), (6 * 7 - 4 * 5) * 3);
            let (lo, hi) = desc.point_bounds();
            for (offset, tile) in ring.tiles() {
                assert!(ring.tile(offset).unwrap().1.is_none());
                for (i, v) in tile.data().iter().enumerate() {
                    let p = tile.desc().position(tile.desc().coords(i).unwrap());
                    // One cell beyond the node's points on the offset's sides, within
                    // them on the others.
                    let beyond = |x: f32, o: i32, lo: f32, hi: f32| match o {
                        -1 => x == lo - 1.0,
                        1 => x == hi + 1.0,
                        _ => x >= lo && x <= hi,
                    };
                    assert!(
                        beyond(p.x, offset.x, lo.x, hi.x) && beyond(p.z, offset.y, lo.z, hi.z),
                        "{offset} {p}"
                    );
                    assert_eq!(v.0[0].x, index(p), "{offset} {p}");
                }
                // The node's points beside the tile: its clamped read at the tile's.
                let own = Grid::from_trusted(desc, (0..desc.point_count()).collect::<Vec<_>>());
                let edge = edge_of(&own, offset, tile.desc());
                for (i, &j) in edge.data().iter().enumerate() {
                    let p = tile.desc().position(tile.desc().coords(i).unwrap());
                    let q = desc.position(desc.coords(j).unwrap());
                    assert_eq!(q, p.clamp(lo, hi), "{offset} {p}");
                }
            }
            assert!(ring.tile(IVec2::ZERO).is_none() && ring.tile(IVec2::new(2, 0)).is_none());
        }
    }

    /// Every read of the widened grid beyond the node's points (all eight corners on
    /// the widened grid, at least one of them off the node's points) lies on one of
    /// the band's slabs, which reads there what the widened grid reads; a read on the
    /// node's points or off the widened grid finds none.
    #[test]
    fn the_band_holds_every_read_beyond_the_node() {
        let desc = GridDesc::new(Vec3::new(3.5, -2.0, 7.5), 1.0, UVec3::new(4, 3, 5)).unwrap();
        for apron in [1, 3] {
            let big = widened(&desc, apron).unwrap();
            let values = (0..big.point_count())
                .map(|i| lightgrid_core::BinLight([Vec3::splat(i as f32); 26]))
                .collect();
            let bins = LightGrid::new(big, values).unwrap();
            let band = Band::of(Widened {
                bins: &bins,
                halves: None,
                big: &big,
                desc: &desc,
                apron,
            });
            let (nx, nz) = (desc.dims().x, desc.dims().z);
            assert_eq!(
                band.points(),
                (2 * (nx + 2 * apron) * (apron + 1) + 2 * (apron + 1) * nz) as u64 * 3
            );
            let (lo, hi) = desc.point_bounds();
            let (blo, bhi) = big.point_bounds();
            let mut rng = fastrand::Rng::with_seed(7);
            let (mut beyond, mut inside) = (0, 0);
            for _ in 0..4000 {
                let p = Vec3::new(
                    blo.x - 0.5 + rng.f32() * (bhi.x - blo.x + 1.0),
                    blo.y + rng.f32() * (bhi.y - blo.y),
                    blo.z - 0.5 + rng.f32() * (bhi.z - blo.z + 1.0),
                );
                let on_big = p.cmpge(blo).all() && p.cmple(bhi).all();
                let on_node = p.cmpge(lo).all() && p.cmple(hi).all();
                match band.at(p) {
                    Some((slab, halves)) => {
                        assert!(on_big && !on_node, "{apron}: {p} on a slab");
                        assert!(halves.is_none());
                        // (The same corners and weights, to the rounding of each
                        // grid's own origin.)
                        let (a, b) = (
                            slab.sample(p).unwrap().0[0].x,
                            bins.sample(p).unwrap().0[0].x,
                        );
                        assert!(
                            (a - b).abs() <= 1e-4 * b.abs().max(1.0),
                            "{p}: {a} against {b}"
                        );
                        beyond += 1;
                    }
                    None => {
                        assert!(
                            !on_big || on_node,
                            "{apron}: {p} beyond the node, on no slab"
                        );
                        inside += on_node as u32;
                    }
                }
            }
            assert!(
                beyond > 1000 && inside > 100,
                "{beyond} beyond, {inside} inside"
            );
        }
    }

    /// A node's sun ring holds, one cell beyond each side and corner, the
    /// transmittance its neighbour there holds at its outermost points (the same rays
    /// through the same cells), not the node's own outermost points' (columns of many
    /// heights under a sun 30° up: shadows cross the nodes' sides); without an apron a
    /// node keeps none.
    #[test]
    fn the_suns_ring_is_what_the_neighbour_holds_beside_it() {
        use crate::testing::{Columns, built_over};
        let h = built_over(Box::new(Columns), 0, false);
        assert!(
            h.nodes
                .values()
                .all(|n| n.sun.as_ref().is_some_and(|g| g.ring.is_none()))
        );
        let h = built_over(Box::new(Columns), 1, false);
        let (mut compared, mut moved) = (0u32, 0.0f32);
        // The ring's rays leave its tile at once and go on through the materials held
        // (`shadow::SkyMarch`), which steps a two-thousandth of the finest cell past
        // each box's face it leaves: through the columns' medium (pass-through 0.4 a
        // cell) up to three such steps let `0.4^(-0.006)` more through than the
        // neighbour's march inside its own grid, never less.
        let skipped = 0.4f32.powf(-0.006);
        for (key, node) in &h.nodes {
            let g = node.sun.as_ref().expect("a sun apart: every node has one");
            for offset in Ring::OFFSETS {
                let tile = g.ring_tile(offset).expect("an apron: a ring");
                let at = NodeKey {
                    depth: key.depth,
                    index: key.index + offset,
                };
                let own = edge_of(&g.transmittance, offset, tile.desc());
                let theirs = h.nodes.get(&at).and_then(|n| n.sun.as_ref());
                for (i, (&t, &o)) in tile.data().iter().zip(own.data()).enumerate() {
                    assert!((0.0..=1.0).contains(&t), "{key:?} {offset}: {t}");
                    moved = moved.max((t - o).abs());
                    let Some(s) = theirs else { continue };
                    let p = tile.desc().position(tile.desc().coords(i).unwrap());
                    let d = s.transmittance.desc();
                    let (lo, hi) = d.point_bounds();
                    // (Its own levels: the nodes end above their highest column.)
                    if p.cmpge(lo).all() && p.cmple(hi).all() {
                        let q = d.to_grid(p);
                        assert!(
                            (q - q.round()).abs().max_element() < 1e-3,
                            "{p} on its points"
                        );
                        let b = s.transmittance.sample(p).unwrap();
                        assert!(
                            t >= b - 1e-6 && t <= b * skipped + 1e-6,
                            "{key:?} {p}: {t} {b}"
                        );
                        compared += 1;
                    }
                }
            }
        }
        assert!(compared > 1000, "{compared} points compared");
        assert!(moved > 0.1, "the ring is not the node's edge: {moved}");
    }
}
