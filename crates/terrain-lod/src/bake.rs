//! A whole world baked as a graph of tasks (issue 49): the world grid first, then every
//! node grid of every depth, each from the coarser grids that cover its boundary.
//!
//! The live [`Hierarchy`] builds the nodes a camera wants; a bake builds all of them,
//! and each one in a process of its own if need be. [`WorldBake`] holds what every task
//! shares (the terrain, the material source, the sweeper, sky, sun and parameters) and
//! runs one task at a time:
//!
//! - [`WorldBake::world`]: the world grid, swept under the sky (and its sun responses);
//! - [`WorldBake::node`]: one node grid, given the world grid and the grids it reads
//!   ([`WorldBake::plan`] names them: every node of a coarser depth whose column meets
//!   the node's boundary halo). Its top and side boundaries come from the finest of them
//!   at each place, its sun's beam beyond its box is marched through their materials
//!   (then the world grid's), exactly as [`Hierarchy`] does with the same grids held.
//!
//! A task's result ([`BakedGrid`]: light, material, sun responses) depends only on its
//! inputs, bit for bit, whatever process runs it and in whatever order: a bake split over
//! machines equals one in a single process. [`BakedGrid::to_bytes`] and
//! [`BakedGrid::from_bytes`] carry a result between tasks.

use lightgrid_core::glam::{IVec2, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Grid, GridError, GridFile, HALO_WIDTH, Heightmap, HorizonGrid, LightGrid,
    MaterialGrid, MaterialSource, Sweeper,
};

use crate::{GridSun, Hierarchy, HierarchyParams, LodError, Node, NodeKey, NodeMaterial, SunLight};

/// What every task of a world bake shares; runs one task at a time.
pub struct WorldBake {
    h: Hierarchy,
    /// The world grid's points (the hierarchy's `world` holds a tile while a node runs).
    world_desc: lightgrid_core::GridDesc,
}

/// One node of a bake's plan ([`WorldBake::plan`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedNode {
    /// The node.
    pub key: NodeKey,
    /// The coarser nodes its boundary and sun march read (the world grid besides),
    /// coarse first.
    pub reads: Vec<NodeKey>,
    /// Most points its grid may have (`node_points² × levels` before its empty top is
    /// cut).
    pub max_points: u64,
}

/// A task's result: a grid's light, the material it was swept with, and its sun
/// responses (with the sun kept apart).
#[derive(Debug, Clone, PartialEq)]
pub struct BakedGrid {
    /// The sky's light (26 bins; all light without the sun apart).
    pub light: LightGrid,
    /// The downward halves of `light`'s horizontal bins, where the hierarchy keeps them
    /// (`HierarchyParams::sweep`'s `outputs.horizon`).
    pub horizon: Option<HorizonGrid>,
    /// The material it was swept with.
    pub material: MaterialGrid,
    /// Objects above the ground.
    pub has_objects: bool,
    /// Nothing above the grid in its column.
    pub open_above: bool,
    /// The sun's responses for unit irradiance (with the sun apart).
    pub sun: Option<BakedSun>,
}

/// A grid's sun responses ([`BakedGrid::sun`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BakedSun {
    /// The sun's scattered light (26 bins).
    pub scattered: LightGrid,
    /// The downward halves of `scattered`'s horizontal bins, if kept.
    pub horizon: Option<HorizonGrid>,
    /// The beam's transmittance per point.
    pub transmittance: Grid<f32>,
    /// The direction toward the sun it was computed for.
    pub to_sun: Vec3,
}

/// Bytes a point of a task holds at most: material (16), the swept bins and the sweep's
/// own copy (2 × 312), sun bins and transmittance (316), the horizon halves of both
/// (2 × 96).
pub const BAKE_BYTES_PER_POINT: u64 = 16 + 2 * 312 + 316 + 2 * 96;

/// Bytes a point of a grid read by a task holds (material, light, sun, their halves).
pub const READ_BYTES_PER_POINT: u64 = 16 + 312 + 316 + 2 * 96;

impl WorldBake {
    /// A bake over `heightmap` (nothing is swept yet). `sun`: the sun kept apart (its
    /// responses are baked beside the sky's light), or `None` (`sky_top` then holds all
    /// light).
    pub fn new(
        heightmap: &Heightmap,
        source: Box<dyn MaterialSource + Send + Sync>,
        sweeper: Box<dyn Sweeper + Send + Sync>,
        sky_top: BinLight,
        sun: Option<SunLight>,
        params: HierarchyParams,
    ) -> Result<Self, LodError> {
        if params.sun_with_sky {
            // A baked grid carries the sky and the scattered sun apart (`LGBAKE02`).
            return Err(GridError::invalid(
                "sun_with_sky",
                true,
                "a world bake keeps the sun's scattered light apart: turn it off",
            )
            .into());
        }
        let mut h = Hierarchy::unswept(heightmap, source, sweeper, sky_top, params)?;
        if let Some(mut s) = sun {
            s.to_sun = lightgrid_core::light::check_sun(s.to_sun, s.irradiance)?;
            h.sun = Some(s);
        }
        let world_desc = *h.world.desc();
        Ok(Self { h, world_desc })
    }

    /// The parameters.
    pub fn params(&self) -> &HierarchyParams {
        &self.h.params
    }

    /// The world grid's points.
    pub fn world_points(&self) -> u64 {
        self.world_desc.point_count() as u64
    }

    /// World `(x, z)` rectangle of a node.
    pub fn node_rect(&self, key: NodeKey) -> (Vec2, Vec2) {
        self.h.node_rect(key)
    }

    /// Every node of depths `1..=depths` over the terrain (at most the hierarchy's
    /// depths), coarse first, in lattice order within a depth, with the coarser nodes
    /// each reads.
    pub fn plan(&self, depths: u32) -> Result<Vec<PlannedNode>, LodError> {
        let depths = depths.min(self.h.params.depths());
        let mut out: Vec<PlannedNode> = Vec::new();
        for d in 1..=depths {
            let (lo, hi) = self.node_range(d);
            for iz in lo.y..=hi.y {
                for ix in lo.x..=hi.x {
                    let key = NodeKey {
                        depth: d,
                        index: IVec2::new(ix, iz),
                    };
                    let desc = self.h.node_desc(key)?;
                    out.push(PlannedNode {
                        key,
                        reads: self.reads(key),
                        max_points: desc.point_count() as u64,
                    });
                }
            }
        }
        Ok(out)
    }

    /// The lattice indices of depth `d`'s nodes over the terrain (inclusive).
    fn node_range(&self, d: u32) -> (IVec2, IVec2) {
        let lo = self.h.node_at(d, self.h.heightmap_lo).index;
        // The last node starting before the terrain's far edge.
        let s = self.h.params.node_size(d);
        let hi = ((self.h.heightmap_hi - self.h.heightmap_lo) / s)
            .ceil()
            .as_ivec2()
            - IVec2::ONE;
        (lo, hi.max(lo))
    }

    /// The coarser nodes whose columns meet node `key`'s boundary halo (and its top's
    /// reads), coarse first, then (with
    /// [`HierarchyParams::neighbour_halo`](crate::HierarchyParams::neighbour_halo)) the
    /// nodes of its depth before it: the grids its boundary and sun march may read.
    fn reads(&self, key: NodeKey) -> Vec<NodeKey> {
        let (lo, hi) = self.h.node_rect(key);
        let m = self.halo_cells() * self.h.params.cell(key.depth);
        let (lo, hi) = (lo - Vec2::splat(m), hi + Vec2::splat(m));
        let mut out = Vec::new();
        for d in 1..key.depth {
            let (rlo, rhi) = self.node_range(d);
            let a = self.h.node_at(d, lo).index.max(rlo);
            let b = self.h.node_at(d, hi).index.min(rhi);
            for iz in a.y..=b.y {
                for ix in a.x..=b.x {
                    out.push(NodeKey {
                        depth: d,
                        index: IVec2::new(ix, iz),
                    });
                }
            }
        }
        let (rlo, rhi) = self.node_range(key.depth);
        out.extend(
            self.h
                .before_neighbours(key)
                .filter(|k| k.index.cmpge(rlo).all() && k.index.cmple(rhi).all()),
        );
        out
    }

    /// The world grid's task: swept under the sky, then its sun responses.
    pub fn world(&mut self) -> Result<BakedGrid, LodError> {
        let _span = tracing::info_span!("bake world grid").entered();
        self.h.nodes.clear();
        self.h.sweep_world()?;
        self.h.sweep_world_sun()?;
        let material = self.h.world_material.clone().expect("set by sweep_world");
        Ok(BakedGrid {
            light: self.h.world.clone(),
            horizon: self.h.world_horizon.clone(),
            material,
            has_objects: true,
            open_above: true,
            sun: self.h.world_sun.as_ref().map(baked_sun),
        })
    }

    /// Most points of a world tile ([`WorldBake::world_tiles`]), taking the beam's climb
    /// over the world grid's whole height (the tiles stop where the material does).
    pub fn tile_points_bound(&self) -> u64 {
        let wd = self.world_desc;
        let h = wd.h();
        let mut side = Vec2::splat(
            self.h.params.node_size(1)
                + 2.0 * (self.halo_cells() * self.h.params.cell(1) + 2.0 * h),
        );
        if let Some(sun) = self.h.sun
            && sun.to_sun.y > 0.0
        {
            let climb = wd.dims().y as f32 * h / sun.to_sun.y;
            side += Vec2::new(sun.to_sun.x.abs(), sun.to_sun.z.abs()) * climb;
        }
        let n = (side / h).ceil() + 2.0;
        let n = n.min(Vec2::new(wd.dims().x as f32, wd.dims().z as f32));
        n.x as u64 * n.y as u64 * wd.dims().y as u64
    }

    /// Cells of its own depth that a node's boundary halo reaches beyond its rectangle:
    /// past its apron. A node's reads ([`WorldBake::reads`]) and a depth-1 column's
    /// world tile ([`WorldBake::world_tiles`]) reach that far.
    fn halo_cells(&self) -> f32 {
        HALO_WIDTH as f32 + 1.0 + self.h.params.apron as f32
    }

    /// The world grid cut into tiles, one per depth-1 node (lattice index): the part of
    /// it a node of that column and its descendants read, so that a node task reads a
    /// tile of bounded size however large the world. A tile is the node's rectangle
    /// widened by its apron, its boundary halo and two world cells, and, with the sun
    /// apart, toward the sun by as far as its beam travels before it rises above the
    /// highest cell that holds anything (so the beam's march beyond a node meets the
    /// same material as in the whole grid, up to f32 rounding where a ray grazes a
    /// cell's corner: a tile's coordinates are shifted); it spans the world grid's full
    /// height.
    pub fn world_tiles(&self, world: &BakedGrid) -> Result<Vec<(IVec2, BakedGrid)>, LodError> {
        let wd = self.world_desc;
        if world.light.desc() != &wd {
            return Err(GridError::invalid(
                "world",
                world.light.desc(),
                "must be this world's grid",
            )
            .into());
        }
        let h = wd.h();
        let dlo = wd.point_bounds().0;
        let halo = self.halo_cells() * self.h.params.cell(1) + 2.0 * h;
        let (mut reach_lo, mut reach_hi) = (Vec2::ZERO, Vec2::ZERO);
        if let Some(sun) = self.h.sun
            && sun.to_sun.y > 0.0
        {
            // Above the highest cell holding anything the beam crosses only clear air.
            let top = world
                .material
                .data()
                .iter()
                .enumerate()
                .filter(|(_, m)| m.pass < 1.0)
                .map(|(i, _)| wd.position(wd.coords(i).expect("in range")).y + 0.5 * h)
                .fold(dlo.y - 0.5 * h, f32::max);
            let climb = (top - (dlo.y - 0.5 * h)) / sun.to_sun.y;
            let r = Vec2::new(sun.to_sun.x, sun.to_sun.z) * climb;
            reach_hi = r.max(Vec2::ZERO);
            reach_lo = (-r).max(Vec2::ZERO);
        }
        let (lo1, hi1) = self.node_range(1);
        let mut out = Vec::new();
        for iz in lo1.y..=hi1.y {
            for ix in lo1.x..=hi1.x {
                let index = IVec2::new(ix, iz);
                let (lo, hi) = self.h.node_rect(NodeKey { depth: 1, index });
                let lo = lo - Vec2::splat(halo) - reach_lo;
                let hi = hi + Vec2::splat(halo) + reach_hi;
                // World points from the one at or below `lo` to the one at or above `hi`.
                let o = Vec2::new(wd.origin().x, wd.origin().z);
                let dims = Vec2::new(wd.dims().x as f32, wd.dims().z as f32);
                let a = ((lo - o) / h)
                    .floor()
                    .clamp(Vec2::ZERO, dims - 1.0)
                    .as_uvec2();
                let b = ((hi - o) / h)
                    .ceil()
                    .clamp(Vec2::ZERO, dims - 1.0)
                    .as_uvec2();
                let from = lightgrid_core::glam::UVec3::new(a.x, 0, a.y);
                let size =
                    lightgrid_core::glam::UVec3::new(b.x - a.x + 1, wd.dims().y, b.y - a.y + 1);
                out.push((index, crop_baked(world, from, size)?));
            }
        }
        Ok(out)
    }

    /// Node `key`'s task, given the world grid's result (whole, or its tile for the
    /// node's column: [`WorldBake::world_tiles`]) and those of the nodes it reads (any
    /// others given are ignored; one missing is an error naming it).
    pub fn node(
        &mut self,
        key: NodeKey,
        world: &BakedGrid,
        reads: &[(NodeKey, &BakedGrid)],
    ) -> Result<BakedGrid, LodError> {
        let _span = tracing::info_span!("bake node", ?key).entered();
        self.load(key, world, reads)?;
        let composed = self.h.node_material(key)?;
        let mut sweeper = {
            let lent = crate::Lent(self.h.sweeper.carries_halo_paths());
            std::mem::replace(&mut self.h.sweeper, Box::new(lent))
        };
        let mut times = crate::StageTimes::default();
        let fresh = crate::shadow::Fresh::default();
        let r = self
            .h
            .sky_node(key, &composed, None, (sweeper.as_mut(), &fresh), &mut times)
            .and_then(|node| {
                let sun = self
                    .h
                    .node_sun(key, &composed, sweeper.as_mut(), &fresh, &mut times)?;
                Ok((node, sun))
            });
        self.h.sweeper = sweeper;
        let (node, sun) = r?;
        self.h.nodes.clear();
        Ok(BakedGrid {
            light: node.light,
            horizon: node.horizon,
            material: composed.grid,
            has_objects: composed.has_objects,
            open_above: composed.open_above,
            sun: sun.as_ref().map(baked_sun),
        })
    }

    /// Holds the world grid and `key`'s reads as the hierarchy's grids.
    fn load(
        &mut self,
        key: NodeKey,
        world: &BakedGrid,
        reads: &[(NodeKey, &BakedGrid)],
    ) -> Result<(), LodError> {
        let (lo, hi) = self.node_range(key.depth);
        if key.depth < 1
            || key.depth > self.h.params.depths()
            || key.index.cmplt(lo).any()
            || key.index.cmpgt(hi).any()
        {
            return Err(GridError::invalid(
                "key",
                format!("{key:?}"),
                "must be a node of the plan",
            )
            .into());
        }
        if !within(world.light.desc(), &self.world_desc) {
            return Err(GridError::invalid(
                "world",
                world.light.desc(),
                "must be this world's grid or a tile of it",
            )
            .into());
        }
        let world_sun = self.sun_of(world)?;
        let h = &mut self.h;
        h.nodes.clear();
        h.world = world.light.clone();
        h.world_horizon = world.horizon.clone();
        h.set_world_material(world.material.clone());
        h.world_sun = world_sun;
        let wanted = self.reads(key);
        // The nodes of its depth it reads, as the camera's wanted ones
        // (`HierarchyParams::neighbour_halo`).
        self.h.wanted_now = wanted
            .iter()
            .filter(|k| k.depth == key.depth)
            .copied()
            .collect();
        for k in wanted {
            let Some((_, g)) = reads.iter().find(|(r, _)| *r == k) else {
                return Err(GridError::invalid(
                    "reads",
                    format!("{k:?} missing"),
                    "must hold every node the planned node reads",
                )
                .into());
            };
            let sun = self.sun_of(g)?;
            self.h.nodes.insert(
                k,
                Node {
                    light: g.light.clone(),
                    horizon: g.horizon.clone(),
                    material: NodeMaterial {
                        grid: g.material.clone(),
                        // (Read only: loaded nodes are never swept again.)
                        widened: None,
                        outer: None,
                        has_objects: g.has_objects,
                        open_above: g.open_above,
                    },
                    sun,
                    resident: None,
                    // (A baked grid is read at its own points: no ring.)
                    ring: None,
                    band: None,
                    input_hash: 0,
                    provisional: false,
                },
            );
        }
        Ok(())
    }

    /// A result's sun responses, checked against the bake's sun.
    fn sun_of(&self, g: &BakedGrid) -> Result<Option<GridSun>, LodError> {
        match (self.h.sun, &g.sun) {
            (None, _) => Ok(None),
            (Some(s), Some(b)) if b.to_sun == s.to_sun => Ok(Some(GridSun {
                scattered: Some(b.scattered.clone()),
                horizon: b.horizon.clone(),
                resident: None,
                transmittance: b.transmittance.clone(),
                to_sun: b.to_sun,
                marched_to: b.to_sun,
                with_sky: None,
                march_stale: false,
                ring: None,
            })),
            (Some(s), _) => {
                Err(
                    GridError::invalid("sun", s.to_sun, "a grid read was baked without this sun")
                        .into(),
                )
            }
        }
    }
}

/// Whether `part` is a box of `whole`'s points (same spacing and levels, its points
/// among `whole`'s).
fn within(part: &lightgrid_core::GridDesc, whole: &lightgrid_core::GridDesc) -> bool {
    let off = (part.origin() - whole.origin()) / whole.h();
    part.h() == whole.h()
        && part.origin().y == whole.origin().y
        && part.dims().y == whole.dims().y
        && off.x >= 0.0
        && off.z >= 0.0
        && off.x.fract() == 0.0
        && off.z.fract() == 0.0
        && off.x as u32 + part.dims().x <= whole.dims().x
        && off.z as u32 + part.dims().z <= whole.dims().z
}

/// The points `from .. from + size` of a grid.
fn crop<T: Copy>(
    g: &Grid<T>,
    from: lightgrid_core::glam::UVec3,
    size: lightgrid_core::glam::UVec3,
) -> Result<Grid<T>, GridError> {
    let d = g.desc();
    let desc = lightgrid_core::GridDesc::new(d.position(from), d.h(), size)?;
    let mut data = Vec::with_capacity(desc.point_count());
    for y in 0..size.y {
        for z in 0..size.z {
            let start = d.index_unchecked(lightgrid_core::glam::UVec3::new(
                from.x,
                from.y + y,
                from.z + z,
            ));
            data.extend_from_slice(&g.data()[start..start + size.x as usize]);
        }
    }
    Ok(Grid::from_trusted(desc, data))
}

/// [`crop`] of every grid of a result.
fn crop_baked(
    g: &BakedGrid,
    from: lightgrid_core::glam::UVec3,
    size: lightgrid_core::glam::UVec3,
) -> Result<BakedGrid, GridError> {
    Ok(BakedGrid {
        light: crop(&g.light, from, size)?,
        horizon: g
            .horizon
            .as_ref()
            .map(|h| crop(h, from, size))
            .transpose()?,
        material: crop(&g.material, from, size)?,
        has_objects: g.has_objects,
        open_above: g.open_above,
        sun: match &g.sun {
            None => None,
            Some(s) => Some(BakedSun {
                scattered: crop(&s.scattered, from, size)?,
                horizon: s
                    .horizon
                    .as_ref()
                    .map(|h| crop(h, from, size))
                    .transpose()?,
                transmittance: crop(&s.transmittance, from, size)?,
                to_sun: s.to_sun,
            }),
        },
    })
}

fn baked_sun(g: &GridSun) -> BakedSun {
    BakedSun {
        // (A bake sweeps the scattered sun apart: `WorldBake::new` refuses the sun
        // swept with the sky, whose grids hold none of their own.)
        scattered: g.scattered.clone().unwrap_or_else(|| {
            let desc = *g.transmittance.desc();
            LightGrid::from_trusted(desc, vec![BinLight::ZERO; desc.point_count()])
        }),
        horizon: g.horizon.clone(),
        transmittance: g.transmittance.clone(),
        to_sun: g.to_sun,
    }
}

/// The first bytes of [`BakedGrid::to_bytes`].
const MAGIC: &[u8; 8] = b"LGBAKE02";
/// The first bytes of the earlier format, read as without horizon halves.
const MAGIC_01: &[u8; 8] = b"LGBAKE01";

impl BakedGrid {
    /// The result as bytes: a header, the light and material as grid files, then the
    /// sun's (direction, scattered light, transmittance as little-endian `f32`), then the
    /// horizon halves of the light and of the sun's scattered light as grid files (empty
    /// sections where there are none).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.push(self.has_objects as u8 | (self.open_above as u8) << 1);
        let mut section = |b: &[u8]| {
            out.extend_from_slice(&(b.len() as u64).to_le_bytes());
            out.extend_from_slice(b);
        };
        section(&GridFile::Light(self.light.clone()).to_bytes());
        section(&GridFile::Material(self.material.clone()).to_bytes());
        match &self.sun {
            None => section(&[]),
            Some(s) => {
                let mut b = Vec::new();
                for v in s.to_sun.to_array() {
                    b.extend_from_slice(&v.to_le_bytes());
                }
                for v in s.transmittance.data() {
                    b.extend_from_slice(&v.to_le_bytes());
                }
                section(&b);
                section(&GridFile::Light(s.scattered.clone()).to_bytes());
            }
        }
        let sun_halves = self.sun.as_ref().and_then(|s| s.horizon.as_ref());
        for halves in [self.horizon.as_ref(), sun_halves] {
            match halves {
                Some(h) => section(&GridFile::Horizon(h.clone()).to_bytes()),
                None => section(&[]),
            }
        }
        out
    }

    /// Reads [`BakedGrid::to_bytes`]; errors on anything else.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, GridError> {
        let bad = |why: &'static str| GridError::invalid("baked grid", bytes.len(), why);
        let (rest, halves) = match bytes.strip_prefix(MAGIC) {
            Some(rest) => (rest, true),
            None => (
                bytes
                    .strip_prefix(MAGIC_01)
                    .ok_or_else(|| bad("no LGBAKE02 (or LGBAKE01) header"))?,
                false,
            ),
        };
        let (&flags, mut rest) = rest.split_first().ok_or_else(|| bad("truncated"))?;
        let mut section = || -> Result<&[u8], GridError> {
            let (n, r) = rest.split_at_checked(8).ok_or_else(|| bad("truncated"))?;
            let n = u64::from_le_bytes(n.try_into().expect("8 bytes"));
            let n = usize::try_from(n).map_err(|_| bad("section too long"))?;
            let (s, r) = r.split_at_checked(n).ok_or_else(|| bad("truncated"))?;
            rest = r;
            Ok(s)
        };
        let light = GridFile::from_bytes(section()?)?.into_light()?;
        let material = GridFile::from_bytes(section()?)?.into_material()?;
        if light.desc() != material.desc() {
            return Err(bad("light and material on different grids"));
        }
        let sun_head = section()?;
        let sun = if sun_head.is_empty() {
            None
        } else {
            let f: Vec<f32> = sun_head
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect();
            if sun_head.len() % 4 != 0 || f.len() != 3 + light.desc().point_count() {
                return Err(bad("sun transmittance of the wrong length"));
            }
            let to_sun = Vec3::new(f[0], f[1], f[2]);
            if !to_sun.is_finite() || f[3..].iter().any(|v| !(0.0..=1.0).contains(v)) {
                return Err(bad("sun direction or transmittance out of range"));
            }
            let transmittance = Grid::from_trusted(*light.desc(), f[3..].to_vec());
            let scattered = GridFile::from_bytes(section()?)?.into_light()?;
            if scattered.desc() != light.desc() {
                return Err(bad("sun light on another grid"));
            }
            Some(BakedSun {
                scattered,
                horizon: None,
                transmittance,
                to_sun,
            })
        };
        let mut read_halves = |on: &LightGrid| -> Result<Option<HorizonGrid>, GridError> {
            let s = section()?;
            if s.is_empty() {
                return Ok(None);
            }
            let h = GridFile::from_bytes(s)?.into_horizon()?;
            if h.desc() != on.desc() {
                return Err(bad("horizon halves on another grid"));
            }
            Ok(Some(h))
        };
        let (horizon, mut sun) = (None, sun);
        let horizon = if halves {
            let h = read_halves(&light)?;
            let sun_h = read_halves(sun.as_ref().map_or(&light, |s| &s.scattered))?;
            match (&mut sun, sun_h) {
                (Some(s), h) => s.horizon = h,
                (None, Some(_)) => return Err(bad("sun halves without a sun")),
                (None, None) => {}
            }
            h
        } else {
            horizon
        };
        Ok(Self {
            light,
            horizon,
            material,
            has_objects: flags & 1 != 0,
            open_above: flags & 2 != 0,
            sun,
        })
    }
}
