//! A node's boundary from the coarser grids: the top from the downward light just above
//! it, the sides from the full light in its halo, with the horizon halves where the
//! coarser grid keeps them.

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Blend, Boundary, GridDesc, HALO_WIDTH, HaloLayout, HorizonGrid, HorizonLight,
    LightGrid, MaterialGrid, SideBoundary, TopBoundary,
};

use lightgrid_core::{trilinear_frame, trilinear_indices};

/// A halo column's reads of a coarser grid at one of its levels: the four corners
/// around the column blended in x and z (weights `(1 − f.x)(1 − f.z)`… in the
/// trilinear lookup's corner order), tagged with the grid (its address, stable while
/// the hierarchy is borrowed) and the level. The fine levels between two coarse ones
/// blend those two reads in y: two blends a halo point where the trilinear read took
/// eight, and none at a fine level that lies on a coarse one (there the read is the
/// trilinear one bit for bit: its weights along y are 1 and 0).
type LevelRead = (usize, u32, BinLight, Option<HorizonLight>);

/// The two coarse levels a halo column read last ([`Hierarchy::column_light_split`]),
/// the terrain's height under the column once found, whether the grid (its
/// address) it read near the ground was clear above its band
/// ([`Hierarchy::ground_lifted`]), and the sky's coarser grids over the column once
/// found ([`Coarser`]).
#[derive(Clone, Default)]
pub(crate) struct ColumnReads<'a>(
    [Option<LevelRead>; 2],
    Option<f32>,
    Option<(usize, bool)>,
    Option<Vec<Coarser<'a>>>,
);

/// A depth's node over a halo column, coarser than the node whose halo it is, as
/// [`Hierarchy::coarse_grid`] goes through them for the sky (finest first): the one
/// built there, with the heights of its levels, or the key of the one not built (a
/// read there may take a neighbour's band: [`Hierarchy::band_light`]). Found once a
/// column: a halo point's hash-map lookups were about a quarter of its read.
#[derive(Clone)]
pub(crate) enum Coarser<'a> {
    Built {
        light: &'a LightGrid,
        horizon: Option<&'a HorizonGrid>,
        levels: (f32, f32),
    },
    Missing(NodeKey),
}

use crate::{GROUND_LIFT, Hierarchy, NodeKey, Response};

/// Where a halo column's cells near the ground are taken from
/// ([`Hierarchy::halo_cells_of`]): the terrain's height at the column's centre, the
/// index within a level of the node's nearest column, and the levels from a halo cell
/// to the cell of that column at the same height above the terrain.
#[derive(Clone, Copy)]
struct StandIn {
    ground: f32,
    column: u32,
    shift: i32,
}

/// The node's own materials its halo's cells may be taken from
/// ([`Hierarchy::halo_cells_of`]).
#[derive(Clone, Copy, Default)]
pub(crate) struct HaloMaterial<'a> {
    /// The material the node is swept on (`desc`'s): near the ground, its nearest cells
    /// stand in for the halo's.
    pub swept: Option<&'a MaterialGrid>,
    /// A grid of the same cells and levels around it (the node composed wider: with
    /// [`HaloCells::Composed`](crate::HaloCells::Composed), or the sky's widened grid
    /// around the sun's): it holds the halo's cells themselves.
    pub outer: Option<&'a MaterialGrid>,
}

impl Hierarchy {
    /// Light (full bins) at `p` from the finest ready grid coarser than `depth` (the
    /// sky's, or all light without the sun apart, or the sun's scattered response), and
    /// that grid's horizon halves at `p`, if it keeps them.
    pub(crate) fn coarse_light_split(
        &self,
        p: Vec3,
        depth: u32,
        which: Response,
    ) -> (BinLight, Option<HorizonLight>) {
        if !p.is_finite() {
            return Default::default();
        }
        // One lookup for the bins and the halves (on the same points): the halo's
        // reads were half a node's boundary time.
        self.coarse_grid(p, depth, which)
            .map(|(g, h)| {
                let p = if self.params.halo_ground_lift {
                    self.ground_lifted(p, g, depth, self.heights.height_at(p.x, p.z))
                } else {
                    p
                };
                let lookup = trilinear_indices(g.desc().dims(), g.desc().to_grid(p));
                (
                    g.blend(lookup),
                    h.map(|h| {
                        if h.desc() == g.desc() {
                            h.blend(lookup)
                        } else {
                            h.sample(p).unwrap_or_default()
                        }
                    }),
                )
            })
            .unwrap_or_default()
    }

    /// [`Hierarchy::coarse_light_split`] at `p`, a point of node `key`'s halo column
    /// whose earlier reads `reads` keeps: each coarse level's x–z blend is made once
    /// for the column ([`ColumnReads`]), and `p` blends the two around it in y. Equal to
    /// `coarse_light_split` bit for bit where `p` lies on a coarse level, to rounding
    /// between (the same weights, added in another order). Where a built node of the
    /// same depth before `key` holds `p` among its points
    /// ([`HierarchyParams::neighbour_halo`](crate::HierarchyParams::neighbour_halo)),
    /// that node's light there, read the same way (on its points: its own values).
    /// The bins are blended into `light` (zero when called, a halo's own slot), the
    /// halves returned.
    pub(crate) fn column_light_split<'a>(
        &'a self,
        p: Vec3,
        key: NodeKey,
        which: Response,
        reads: &mut ColumnReads<'a>,
        light: &mut BinLight,
    ) -> Option<HorizonLight> {
        if !p.is_finite() {
            return None;
        }
        let depth = key.depth;
        let neighbour = self.neighbour_light(p, key, which);
        let coarse = neighbour.is_none();
        let (g, hg) = neighbour.or_else(|| match which {
            Response::Sky => Some(self.column_coarse_grid(p, depth, &mut reads.3)),
            Response::Sun => self.coarse_grid(p, depth, which),
        })?;
        if hg.is_some_and(|h| h.desc() != g.desc()) {
            let (l, h) = self.coarse_light_split(p, depth, which);
            *light = l;
            return h;
        }
        // A neighbour of the node's own cell is read where it is (its band is the
        // node's own).
        let p = if coarse && self.params.halo_ground_lift {
            // The column's terrain and material check found once (for `g`).
            let ground = *reads
                .1
                .get_or_insert_with(|| self.heights.height_at(p.x, p.z));
            let id = g as *const LightGrid as usize;
            let clear = &mut reads.2;
            self.lifted_if(p, g, ground, || match *clear {
                Some((at, c)) if at == id => c,
                _ => {
                    let c = self.clear_above_band(p, g, depth, ground);
                    *clear = Some((id, c));
                    c
                }
            })
        } else {
            p
        };
        let (base, hi, f) = trilinear_frame(g.desc().dims(), g.desc().to_grid(p));
        let id = g as *const LightGrid as usize;
        let (nx, nz) = (g.desc().dims().x as usize, g.desc().dims().z as usize);
        let (xs, zs) = (
            [base.x as usize, hi.x as usize],
            [base.z as usize, hi.z as usize],
        );
        let (wx, wz) = ([1.0 - f.x, f.x], [1.0 - f.z, f.z]);
        let level = |y: u32| -> LevelRead {
            let mut light = BinLight::zero();
            let mut halves = hg.map(|_| HorizonLight::zero());
            for c in 0..4 {
                let (bx, bz) = (c & 1, c >> 1);
                // As the trilinear weight `wx · wy · wz` with `wy` = 1.
                let w = wx[bx] * wz[bz];
                if w != 0.0 {
                    let i = xs[bx] + nx * (zs[bz] + nz * y as usize);
                    light.add_scaled(&g.data()[i], w);
                    if let (Some(acc), Some(h)) = (halves.as_mut(), hg) {
                        acc.add_scaled(&h.data()[i], w);
                    }
                }
            }
            (id, y, light, halves)
        };
        let mut halves = hg.map(|_| HorizonLight::zero());
        for (y, wy) in [(base.y, 1.0 - f.y), (hi.y, f.y)] {
            if wy == 0.0 {
                continue;
            }
            let slot = match reads.0.iter().position(|r| {
                r.as_ref()
                    .is_some_and(|(rid, ry, ..)| *rid == id && *ry == y)
            }) {
                Some(k) => k,
                None => {
                    // Keep the slot holding the other level this point reads.
                    let other = if y == base.y { hi.y } else { base.y };
                    let k = match &reads.0[0] {
                        Some((rid, ry, ..)) if *rid == id && *ry == other && other != y => 1,
                        _ => 0,
                    };
                    reads.0[k] = Some(level(y));
                    k
                }
            };
            let (_, _, l, h) = reads.0[slot].as_ref().expect("filled above");
            light.add_scaled(l, wy);
            if let (Some(acc), Some(h)) = (halves.as_mut(), h) {
                acc.add_scaled(h, wy);
            }
        }
        halves
    }

    /// Where coarser grid `g` is read for a halo point `p` of a node at `depth`, the
    /// terrain `ground` high under it
    /// ([`HierarchyParams::halo_ground_lift`](crate::HierarchyParams::halo_ground_lift)):
    /// `p` lifted to [`GROUND_LIFT`] of `g`'s cells above the terrain where it lies
    /// below that (and above a cell under the terrain) and `g`'s material is empty from
    /// the level above its band (the point nearest the terrain) to that height in the
    /// four columns around `p` ([`Hierarchy::clear_above_band`]); else `p`. The lifted
    /// read's two levels then both lie above the band (a point of the band lies within
    /// half a cell of the terrain).
    fn ground_lifted(&self, p: Vec3, g: &LightGrid, depth: u32, ground: f32) -> Vec3 {
        self.lifted_if(p, g, ground, || self.clear_above_band(p, g, depth, ground))
    }

    /// [`Hierarchy::ground_lifted`] with the material's check `clear` (asked only for a
    /// point near the ground).
    fn lifted_if(&self, p: Vec3, g: &LightGrid, ground: f32, clear: impl FnOnce() -> bool) -> Vec3 {
        if !self.params.halo_ground_lift {
            return p;
        }
        let h = g.desc().h();
        let lifted = ground + GROUND_LIFT * h;
        if p.y < lifted && p.y > ground - h && clear() {
            Vec3::new(p.x, lifted, p.z)
        } else {
            p
        }
    }

    /// Whether coarser grid `g`'s material (the grid a node at `depth` reads at `p`,
    /// over terrain `ground` high) is empty from the level above its band to
    /// [`GROUND_LIFT`] cells above the terrain in the four columns around `p` (the
    /// same for every point of a halo column reading `g`); `false` where `g` has no
    /// material of its own points.
    fn clear_above_band(&self, p: Vec3, g: &LightGrid, depth: u32, ground: f32) -> bool {
        let Some(m) = self.material_of(g, p, depth) else {
            return false;
        };
        let d = m.desc();
        let dims = d.dims().as_ivec3();
        let at = d.to_grid(Vec3::new(p.x, ground, p.z));
        let first = (at.y.round() as i32 + 1).max(0);
        let top = ground + GROUND_LIFT * d.h();
        let last = (d.to_grid(Vec3::new(p.x, top, p.z)).y.ceil() as i32).min(dims.y - 1);
        let around =
            |c: f32, n: i32| (c.floor() as i32).clamp(0, n - 1)..=(c.ceil() as i32).clamp(0, n - 1);
        around(at.x, dims.x).all(|x| {
            around(at.z, dims.z).all(|z| {
                (first..=last)
                    .all(|y| m.data()[(x + dims.x * (z + dims.z * y)) as usize].is_empty())
            })
        })
    }

    /// The material of coarser grid `g` (a node's above `depth` holding `p`, or the
    /// world grid), if it is on `g`'s points; `None` for other grids (a neighbour's
    /// band).
    fn material_of(&self, g: &LightGrid, p: Vec3, depth: u32) -> Option<&MaterialGrid> {
        let on_g = |m: &&MaterialGrid| m.desc() == g.desc();
        (1..depth)
            .rev()
            .filter_map(|d| self.nodes.get(&self.node_at(d, Vec2::new(p.x, p.z))))
            .map(|n| &n.material.grid)
            .find(on_g)
            .or_else(|| self.world_material.as_ref().filter(on_g))
    }

    /// [`Hierarchy::coarse_grid`]'s sky grid at `p`, a point of a halo column whose
    /// coarser nodes `column` keeps (found at the column's first point).
    fn column_coarse_grid<'a>(
        &'a self,
        p: Vec3,
        depth: u32,
        column: &mut Option<Vec<Coarser<'a>>>,
    ) -> (&'a LightGrid, Option<&'a HorizonGrid>) {
        let found = column.get_or_insert_with(|| self.coarser_over(p, depth).collect());
        self.sky_grid_of(p, found.iter().cloned())
    }

    /// The nodes coarser than `depth` over `p`'s column, finest first ([`Coarser`]).
    fn coarser_over(&self, p: Vec3, depth: u32) -> impl Iterator<Item = Coarser<'_>> {
        (1..depth).rev().map(move |d| {
            let key = self.node_at(d, Vec2::new(p.x, p.z));
            match self.nodes.get(&key) {
                Some(n) => {
                    let (lo, hi) = n.light.desc().point_bounds();
                    Coarser::Built {
                        light: &n.light,
                        horizon: n.horizon.as_ref(),
                        levels: (lo.y, hi.y),
                    }
                }
                None => Coarser::Missing(key),
            }
        })
    }

    /// The sky's grid at `p` among `coarser` (finest first): the first built node
    /// whose levels hold `p`, or where one is not built a neighbour's band that holds
    /// the read ([`Hierarchy::band_light`]); else the world grid.
    fn sky_grid_of<'a>(
        &'a self,
        p: Vec3,
        coarser: impl Iterator<Item = Coarser<'a>>,
    ) -> (&'a LightGrid, Option<&'a HorizonGrid>) {
        for c in coarser {
            match c {
                Coarser::Built {
                    light,
                    horizon,
                    levels: (lo, hi),
                } if p.y >= lo && p.y <= hi => return (light, horizon),
                Coarser::Built { .. } => {}
                Coarser::Missing(key) => {
                    if let Some(r) = self.band_light(p, key) {
                        return r;
                    }
                }
            }
        }
        (&self.world, self.world_horizon.as_ref())
    }

    /// The grid [`Hierarchy::coarse_light_split`] reads at `p`, and its halves if kept.
    pub(crate) fn coarse_grid(
        &self,
        p: Vec3,
        depth: u32,
        which: Response,
    ) -> Option<(&LightGrid, Option<&HorizonGrid>)> {
        if which == Response::Sun {
            return self
                .coarse_sun(p, depth, false)
                .and_then(|s| Some((s.scattered.as_ref()?, s.horizon.as_ref())));
        }
        Some(self.sky_grid_of(p, self.coarser_over(p, depth)))
    }

    /// For `p` in wanted node `missing`'s rectangle while it is not built, the light of
    /// the nearest built node of its depth beside it whose apron's band holds the read
    /// at `p` ([`crate::apron::Band`]; the first in row order among equals).
    fn band_light(&self, p: Vec3, missing: NodeKey) -> Option<(&LightGrid, Option<&HorizonGrid>)> {
        if !self.wanted_now.contains(&missing) {
            return None;
        }
        let q = Vec2::new(p.x, p.z);
        let mut best: Option<(f32, (&LightGrid, Option<&HorizonGrid>))> = None;
        for k in crate::apron::around(missing) {
            let Some(band) = self.nodes.get(&k).and_then(|n| n.band.as_ref()) else {
                continue;
            };
            let Some(read) = band.at(p) else { continue };
            let (lo, hi) = self.node_rect(k);
            let far = (q - q.clamp(lo, hi)).length();
            if best.is_none_or(|(b, _)| far < b) {
                best = Some((far, read));
            }
        }
        best.map(|(_, r)| r)
    }

    /// Whether a boundary may read node `key`'s band: a wanted node of its depth beside
    /// it is not built.
    pub(crate) fn band_read(&self, key: NodeKey) -> bool {
        crate::apron::around(key)
            .any(|b| self.wanted_now.contains(&b) && !self.nodes.contains_key(&b))
    }

    /// Drops the bands no boundary can read any more ([`Hierarchy::band_read`]).
    pub(crate) fn drop_unread_bands(&mut self) {
        let unread: Vec<NodeKey> = (self.nodes.iter())
            .filter(|(k, n)| n.band.is_some() && !self.band_read(**k))
            .map(|(k, _)| *k)
            .collect();
        for k in unread {
            if let Some(n) = self.nodes.get_mut(&k) {
                n.band = None;
            }
        }
    }

    /// The boundary of node `key`'s grid `desc` (its own or widened by its apron) from
    /// the coarser grids: the top from the downward light just above it, the sides
    /// from the full light in the halo (and, with
    /// [`HierarchyParams::neighbour_halo`](crate::HierarchyParams::neighbour_halo),
    /// from the nodes of its depth before it where they are built).
    pub(crate) fn node_boundary(
        &self,
        desc: &GridDesc,
        key: NodeKey,
        cells: HaloMaterial<'_>,
    ) -> Boundary {
        self.node_boundary_of(desc, key, Response::Sky, cells)
    }

    /// [`Hierarchy::node_boundary`] of one response.
    pub(crate) fn node_boundary_of(
        &self,
        desc: &GridDesc,
        key: NodeKey,
        which: Response,
        cells: HaloMaterial<'_>,
    ) -> Boundary {
        let depth = key.depth;
        let dims = desc.dims();
        let h = desc.h();
        // Over the halo's columns too (`HaloLayout::columns`): paths from above the top
        // that enter through a side start there.
        let (w, nx, nz) = (HALO_WIDTH, dims.x as i32, dims.z as i32);
        let top_y = (dims.y - 1) as f32 + 1.0;
        let mut top = Vec::with_capacity(HaloLayout::new(dims).columns());
        for k in -w..nz + w {
            for i in -w..nx + w {
                let p = desc.origin() + h * Vec3::new(i as f32, top_y, k as f32);
                // The downward light: where the coarser grid keeps its horizon halves,
                // its horizontal bins' downward halves as they are.
                let (light, halves) = self.coarse_light_split(p, depth, which);
                let mut down = light.split_vertical_by_neighbours().0;
                if let Some(halves) = halves {
                    for (k, half) in halves.within(&light).0.iter().enumerate() {
                        down.0[lightgrid_core::dirs::FIRST_HORIZONTAL + k] = *half;
                    }
                }
                top.push(down);
            }
        }
        // The sides: the full light, and where the coarser grids keep their horizon
        // halves, the downward halves as they are (a split by the neighbours left
        // surfaces facing down 6 % too bright in the finest nodes).
        // Pushed in the layout's order (level, then z, then x; no zeroed vectors
        // written over: a fifth of a boundary's time went there).
        let layout = HaloLayout::new(dims);
        let mut halo = Vec::with_capacity(layout.len());
        let mut down = Vec::with_capacity(layout.len());
        let mut halves_everywhere = true;
        // Each column's last coarse levels read, in the layout's column order.
        let mut reads = vec![ColumnReads::default(); layout.per_level()];
        for j in 0..dims.y {
            let mut column = reads.iter_mut();
            for z in -w..nz + w {
                let inside_z = (0..nz).contains(&z);
                for x in (-w..nx + w).filter(|x| !inside_z || !(0..nx).contains(x)) {
                    let p = desc.origin() + h * Vec3::new(x as f32, j as f32, z as f32);
                    let column = column.next().expect("one read a column of the layout");
                    // Blended where it is kept (a copy of 312 bytes less a point).
                    halo.push(BinLight::zero());
                    let light = halo.last_mut().expect("pushed");
                    match self.column_light_split(p, key, which, column, light) {
                        Some(d) if halves_everywhere => down.push(d.within(light)),
                        _ => halves_everywhere = false,
                    }
                }
            }
        }
        debug_assert_eq!(halo.len(), layout.len());
        let sides = if halves_everywhere {
            SideBoundary::GivenHalves {
                light: halo,
                down,
                cells: self.halo_cells_of(desc, key, which, cells),
            }
        } else {
            SideBoundary::Given(halo)
        };
        Boundary {
            top: TopBoundary::PerPoint(top),
            bottom: BinLight::ZERO,
            sides,
        }
    }

    /// The material of the cells of `desc`'s halo for node `key`'s sweeps
    /// ([`HierarchyParams::halo_cells`](crate::HierarchyParams::halo_cells)): with
    /// [`HaloCells::Composed`](crate::HaloCells::Composed), from `own.outer` (the node's
    /// grid composed over them); with [`HaloCells::Coarser`](crate::HaloCells::Coarser),
    /// each cell's from the first grid that holds it of `own.outer` and the coarser
    /// depths' materials (the nodes' grids over the halo whose `which` light its halo
    /// reads, finest first, then the world grid's), a coarser cell's pass-through
    /// taken to the finer cell's length; empty beyond them all. Near the ground (the
    /// fine cell within one of the coarser grid's cells above the terrain, so that the
    /// coarser cell may hold the terrain's band, cut at its own size) the nearest cell
    /// of `own.swept` at the same height above the terrain stands in, and a cell
    /// holding the terrain's surface is left empty: the coarser band taken for a finer
    /// cell's medium lit bare ground's sideways light 2.5–5 % bright, the surface's
    /// cell 3–5 % (`tests/ground_lift.rs`).
    pub(crate) fn halo_cells_of(
        &self,
        desc: &GridDesc,
        key: NodeKey,
        which: Response,
        own: HaloMaterial<'_>,
    ) -> Option<Vec<lightgrid_core::Material>> {
        use crate::HaloCells;
        match self.params.halo_cells {
            HaloCells::Off => return None,
            HaloCells::Composed => return own.outer.and_then(|m| halo_cells(desc, m)),
            HaloCells::Coarser => {}
        }
        // Each coarser depth's nodes over the halo (their grids, not their aprons'
        // widened ones: those cells are their neighbours', and a bake's task holds
        // the grids alone, its nodes then the live ones bit for bit), finest first:
        // those at the halo's corners, every one over it where a coarser node is as
        // wide as the node with its apron and halo, as at the defaults (one missed
        // leaves its cells to a coarser depth).
        let mut grids: Vec<&MaterialGrid> = own.outer.into_iter().collect();
        let (lo, hi) = {
            let d = desc.dims().as_vec3() - Vec3::ONE;
            let w = HALO_WIDTH as f32 * desc.h();
            let (a, b) = (desc.origin(), desc.origin() + d * desc.h());
            (Vec2::new(a.x - w, a.z - w), Vec2::new(b.x + w, b.z + w))
        };
        for depth in (1..key.depth).rev() {
            let mut keys: Vec<NodeKey> = [lo, Vec2::new(hi.x, lo.y), Vec2::new(lo.x, hi.y), hi]
                .into_iter()
                .map(|p| self.node_at(depth, p))
                .collect();
            keys.sort();
            keys.dedup();
            // (For a sun response, those whose sun the halo's light reads: the
            // nodes a hierarchy built afresh there would hold.)
            grids.extend(
                keys.iter()
                    .filter(|&&k| which == Response::Sky || self.sun_current(k))
                    .filter_map(|k| self.nodes.get(k))
                    .map(|n| &n.material.grid),
            );
        }
        grids.extend(self.world_material.as_ref());
        let (dims, h, w) = (desc.dims(), desc.h(), HALO_WIDTH);
        let (nx, nz) = (dims.x as i32, dims.z as i32);
        let mut cells = Vec::with_capacity(HaloLayout::new(dims).len());
        // A level's points lie on one level of each grid, a row (column) of them on
        // one row (column): their cells found once a level and once a row and column.
        let at = |g: &MaterialGrid, v: f32, axis: usize| {
            let d = g.desc();
            let q = ((v - d.origin()[axis]) / d.h()).round();
            (q >= 0.0 && q < d.dims()[axis] as f32).then_some(q as u32)
        };
        let corner = desc.origin() - h * Vec3::new(w as f32, 0.0, w as f32);
        let span = |axis: usize, n: i32| -> Vec<Vec<Option<u32>>> {
            grids
                .iter()
                .map(|g| {
                    (0..n + 2 * w)
                        .map(|k| at(g, corner[axis] + h * k as f32, axis))
                        .collect()
                })
                .collect()
        };
        let (xs, zs) = (span(0, nx), span(2, nz));
        let near = self.near_ground_stand_ins(desc, own.swept);
        // A coarser cell's pass-through over the finer cell's length, for the few
        // distinct values a composed material holds.
        let mut seen: Vec<(u32, f32, f32)> = Vec::new();
        let mut scaled = |pass: f32, f: f32| -> f32 {
            if let Some(&(_, _, p)) = seen.iter().find(|s| s.0 == pass.to_bits() && s.1 == f) {
                return p;
            }
            let p = pass.powf(f);
            if seen.len() < 64 {
                seen.push((pass.to_bits(), f, p));
            }
            p
        };
        for j in 0..dims.y {
            let y = desc.origin().y + h * j as f32;
            let ys: Vec<Option<u32>> = grids.iter().map(|g| at(g, y, 1)).collect();
            let mut column = 0;
            for z in -w..nz + w {
                let inside_z = (0..nz).contains(&z);
                for x in (-w..nx + w).filter(|x| !inside_z || !(0..nx).contains(x)) {
                    let (kx, kz) = ((x + w) as usize, (z + w) as usize);
                    let found = grids.iter().enumerate().find_map(|(g, grid)| {
                        let q = UVec3::new(xs[g][kx]?, ys[g]?, zs[g][kz]?);
                        grid.get(q).map(|m| (m, h / grid.desc().h()))
                    });
                    let stand_in = near.as_ref().and_then(|(swept, near)| {
                        let StandIn {
                            ground,
                            column: q,
                            shift,
                        } = near[column];
                        // The terrain's surface: the carry's even source
                        // misplaces a surface's light, and where the ground lift
                        // applies the halo value is light read clear of the band,
                        // not the cell's mean (carried, bare ground's sideways
                        // light nested 3–5 % bright).
                        if (y - ground).abs() < 0.5 * h {
                            return Some(lightgrid_core::Material::EMPTY);
                        }
                        // Within the coarser cell found of the terrain.
                        let (_, f) = found?;
                        (f != 1.0 && y < ground + h / f).then(|| {
                            let level = (j as i32 + shift).clamp(0, dims.y as i32 - 1);
                            swept.data()[(q + level as u32 * dims.x * dims.z) as usize]
                        })
                    });
                    column += 1;
                    cells.push(match (stand_in, found) {
                        (Some(m), _) => m,
                        (None, Some((m, f))) if m.pass > 0.0 && m.pass < 1.0 && f != 1.0 => {
                            lightgrid_core::Material {
                                pass: scaled(m.pass, f),
                                ..*m
                            }
                        }
                        (None, Some((m, _))) => *m,
                        (None, None) => lightgrid_core::Material::EMPTY,
                    });
                }
            }
        }
        Some(cells)
    }

    /// For each halo column of `desc` (the layout's order in a level): the terrain's
    /// height at its centre, the index within a level of `swept`'s nearest column
    /// (`desc`'s points), and the levels from a halo cell to the cell of that column at
    /// the same height above the terrain; `None` without `swept` on `desc`'s points.
    fn near_ground_stand_ins<'m>(
        &self,
        desc: &GridDesc,
        swept: Option<&'m MaterialGrid>,
    ) -> Option<(&'m MaterialGrid, Vec<StandIn>)> {
        let swept = swept.filter(|m| m.desc() == desc)?;
        let (dims, h, w) = (desc.dims(), desc.h(), HALO_WIDTH);
        let (nx, nz) = (dims.x as i32, dims.z as i32);
        let ground = |x: i32, z: i32| {
            let p = desc.origin() + h * Vec3::new(x as f32, 0.0, z as f32);
            self.heights.height_at(p.x, p.z)
        };
        let mut out = Vec::with_capacity(HaloLayout::new(dims).per_level());
        for z in -w..nz + w {
            let inside_z = (0..nz).contains(&z);
            for x in (-w..nx + w).filter(|x| !inside_z || !(0..nx).contains(x)) {
                let (cx, cz) = (x.clamp(0, nx - 1), z.clamp(0, nz - 1));
                let g = ground(x, z);
                let shift = ((ground(cx, cz) - g) / h).round() as i32;
                out.push(StandIn {
                    ground: g,
                    column: (cx + cz * nx) as u32,
                    shift,
                });
            }
        }
        Some((swept, out))
    }
}

/// The material of the cells of `desc`'s halo ([`HaloLayout`]'s order) from `outer`, a
/// grid of the same cells and levels around it ([`crate::NodeMaterial`]'s `outer`);
/// `None` where `outer` does not hold the whole halo on `desc`'s lattice.
fn halo_cells(desc: &GridDesc, outer: &MaterialGrid) -> Option<Vec<lightgrid_core::Material>> {
    let o = outer.desc();
    let off = (desc.origin() - o.origin()) / desc.h();
    let (dims, odims) = (desc.dims(), o.dims());
    let w = HALO_WIDTH;
    let fits = (o.h() - desc.h()).abs() <= 1e-6 * desc.h()
        && (off - off.round()).abs().max_element() < 1e-3
        && off.y.round() == 0.0
        && off.x.round() >= w as f32
        && off.z.round() >= w as f32
        && off.x.round() as u32 + dims.x + w as u32 <= odims.x
        && off.z.round() as u32 + dims.z + w as u32 <= odims.z
        && dims.y <= odims.y;
    if !fits {
        return None;
    }
    let (ox, oz) = (off.x.round() as i32, off.z.round() as i32);
    let (nx, nz) = (dims.x as i32, dims.z as i32);
    let mut cells = Vec::with_capacity(HaloLayout::new(dims).len());
    for j in 0..dims.y {
        for z in -w..nz + w {
            let inside_z = (0..nz).contains(&z);
            for x in (-w..nx + w).filter(|x| !inside_z || !(0..nx).contains(x)) {
                let q = UVec3::new((x + ox) as u32, j, (z + oz) as u32);
                cells.push(*outer.get(q)?);
            }
        }
    }
    Some(cells)
}

#[cfg(test)]
mod tests {
    use lightgrid_core::GridDesc;
    use lightgrid_core::glam::{Vec2, Vec3};

    use super::trilinear_frame;
    use crate::Response;
    use crate::testing::{budgeted_layer_hierarchy, layer_hierarchy};

    /// The halo points of a grid `desc`, in the layout's order (level, then z, then x).
    fn halo_points(desc: &GridDesc) -> Vec<Vec3> {
        let (w, nx, nz) = (
            lightgrid_core::HALO_WIDTH,
            desc.dims().x as i32,
            desc.dims().z as i32,
        );
        let mut out = Vec::new();
        for j in 0..desc.dims().y {
            for z in -w..nz + w {
                for x in -w..nx + w {
                    if !((0..nx).contains(&x) && (0..nz).contains(&z)) {
                        out.push(
                            desc.origin() + desc.h() * Vec3::new(x as f32, j as f32, z as f32),
                        );
                    }
                }
            }
        }
        assert_eq!(
            out.len(),
            lightgrid_core::HaloLayout::new(desc.dims()).len()
        );
        out
    }

    /// The halo's cells near flat ground (`HaloCells::Coarser`, the default): the cell
    /// holding the terrain's surface is empty, and those above it within one of the
    /// next coarser depth's cells are the node's own nearest cells (the ground flat:
    /// at their own level), not the coarser grids' band cut at their size.
    #[test]
    fn near_the_ground_the_halos_cells_are_the_nodes_own() {
        use lightgrid_core::Material;
        let h = layer_hierarchy(0, false);
        let (lo, hi) = h.world.desc().point_bounds();
        let (mut surface, mut own) = (0, 0);
        for key in h.ready_nodes() {
            let m = &h.nodes[&key].material.grid;
            let desc = *m.desc();
            let given = super::HaloMaterial {
                swept: Some(m),
                outer: None,
            };
            let cells = h
                .halo_cells_of(&desc, key, Response::Sky, given)
                .expect("given by default");
            let coarser = h.params.cell(key.depth - 1);
            let dims = desc.dims().as_ivec3();
            for (c, p) in cells.iter().zip(halo_points(&desc)) {
                // (Within the world grid: beyond it no grid holds a cell.)
                if p.x < lo.x || p.x > hi.x || p.z < lo.z || p.z > hi.z {
                    continue;
                }
                let q = ((p - desc.origin()) / desc.h()).round().as_ivec3();
                if p.y.abs() < 0.5 * desc.h() {
                    assert_eq!(*c, Material::EMPTY, "{key:?} at {p}");
                    surface += 1;
                } else if p.y > 0.0 && p.y < coarser {
                    let at = q.clamp(lightgrid_core::glam::IVec3::ZERO, dims - 1);
                    let want = m.get(at.as_uvec3()).expect("in the grid");
                    assert_eq!(c, want, "{key:?} at {p}");
                    own += 1;
                }
            }
        }
        assert!(surface > 0 && own > 0, "{surface} surface cells, {own} own");
    }

    /// Every halo point of every node, sky and sun: the column's reads equal the
    /// trilinear ones to rounding, and bit for bit where the point lies on a level of
    /// the coarser grid read.
    #[test]
    fn column_reads_are_the_trilinear_reads() {
        let h = layer_hierarchy(0, false);
        let (mut points, mut exact, mut between) = (0, 0, 0);
        for key in h.ready_nodes().into_iter().filter(|k| k.depth >= 2) {
            let desc = *h.node(key).unwrap().desc();
            for which in [Response::Sky, Response::Sun] {
                let b = h.node_boundary_of(&desc, key, which, Default::default());
                let (light, down) = match &b.sides {
                    lightgrid_core::SideBoundary::GivenHalves { light, down, .. } => {
                        (light, Some(down))
                    }
                    lightgrid_core::SideBoundary::Given(light) => (light, None),
                    other => panic!("sides {other:?}"),
                };
                let at = halo_points(&desc);
                assert_eq!(light.len(), at.len());
                for (i, &p) in at.iter().enumerate() {
                    let (l, d) = h.coarse_light_split(p, key.depth, which);
                    // On a coarse level: the trilinear read's weights along y are 1 and 0
                    // (where it is read: lifted near bare ground).
                    let on_level = h.coarse_grid(p, key.depth, which).is_some_and(|(g, _)| {
                        let q = h.ground_lifted(p, g, key.depth, 0.0);
                        let f = trilinear_frame(g.desc().dims(), g.desc().to_grid(q)).2;
                        f.y == 0.0 || f.y == 1.0
                    });
                    let close = |a: &[f32], b: &[f32]| {
                        a.iter().zip(b).all(|(a, b)| {
                            if on_level {
                                a.to_bits() == b.to_bits()
                            } else {
                                (a - b).abs() <= 1e-5 * (1.0 + b.abs())
                            }
                        })
                    };
                    let (got, want) = (&light[i], &l);
                    assert!(
                        close(
                            bytemuck::cast_slice(&got.0[..]),
                            bytemuck::cast_slice(&want.0[..])
                        ),
                        "{key:?} {which:?} {p}: {got:?} against {want:?}"
                    );
                    if let (Some(down), Some(d)) = (down, d) {
                        let want = d.within(&l);
                        assert!(
                            close(
                                bytemuck::cast_slice(&down[i].0[..]),
                                bytemuck::cast_slice(&want.0[..])
                            ),
                            "{key:?} {which:?} {p}: halves"
                        );
                    }
                    points += 1;
                    if on_level { exact += 1 } else { between += 1 }
                }
            }
        }
        // (Else nothing here could fail.)
        assert!(
            exact > 1000 && between > 1000,
            "{points} points: {exact} on a coarse level, {between} between"
        );
    }

    /// With `neighbour_halo`, every halo point among the points of a built node of the
    /// same depth before the node (and wanted) holds that node's own value there, bit
    /// for bit, sky and scattered sun, halves too; every other halo point the coarser
    /// grids' read.
    /// Over columns of medium of many heights on a flat ground: a halo point near the
    /// ground is lifted ([`crate::HierarchyParams::halo_ground_lift`]) to
    /// [`crate::GROUND_LIFT`] coarse cells above it only where the coarser grid it
    /// reads holds no material between its band and that height around the point
    /// (checked here on the material's points by position); both kinds occur.
    #[test]
    fn halo_points_are_lifted_only_through_empty_cells() {
        let h = crate::testing::built_over(Box::new(crate::testing::Columns), 0, false);
        let (mut lifted, mut kept) = (0, 0);
        for key in h.ready_nodes().into_iter().filter(|k| k.depth >= 2) {
            let desc = *h.node(key).unwrap().desc();
            for p in halo_points(&desc) {
                let Some((g, _)) = h.coarse_grid(p, key.depth, Response::Sky) else {
                    continue;
                };
                let c = g.desc().h();
                // The flat ground lies at 0.
                if !(p.y < crate::GROUND_LIFT * c && p.y > -c) {
                    assert_eq!(h.ground_lifted(p, g, key.depth, 0.0), p);
                    continue;
                }
                let m = h.material_of(g, p, key.depth).expect("the grid's material");
                let d = m.desc();
                let empty_above_band = (0..4).all(|corner| {
                    let at = d.to_grid(p);
                    let x = if corner & 1 == 0 {
                        at.x.floor()
                    } else {
                        at.x.ceil()
                    };
                    let z = if corner & 2 == 0 {
                        at.z.floor()
                    } else {
                        at.z.ceil()
                    };
                    let mut y = d.to_grid(Vec3::ZERO).y.round() + 1.0;
                    let top = d.to_grid(Vec3::Y * crate::GROUND_LIFT * c).y.ceil();
                    let mut clear = true;
                    while y <= top.min(d.dims().y as f32 - 1.0) {
                        let q = lightgrid_core::glam::UVec3::new(
                            x.clamp(0.0, d.dims().x as f32 - 1.0) as u32,
                            y as u32,
                            z.clamp(0.0, d.dims().z as f32 - 1.0) as u32,
                        );
                        clear &= m.get(q).unwrap().is_empty();
                        y += 1.0;
                    }
                    clear
                });
                let q = h.ground_lifted(p, g, key.depth, 0.0);
                if empty_above_band {
                    assert_eq!(q, Vec3::new(p.x, crate::GROUND_LIFT * c, p.z), "{p}");
                    lifted += 1;
                } else {
                    assert_eq!(q, p);
                    kept += 1;
                }
            }
        }
        assert!(lifted > 100 && kept > 100, "{lifted} lifted, {kept} kept");
    }

    #[test]
    fn halo_points_among_a_node_before_hold_its_light() {
        let h = layer_hierarchy(1, true);
        let (mut theirs, mut coarse) = (0, 0);
        for key in h.ready_nodes().into_iter().filter(|k| k.depth >= 2) {
            for which in [Response::Sky, Response::Sun] {
                // The sky's boundary is made around the grid widened by the apron.
                let n = &h.nodes[&key];
                let desc = match which {
                    Response::Sky => *n.material.widened.as_ref().unwrap().desc(),
                    Response::Sun => *n.light.desc(),
                };
                let b = h.node_boundary_of(&desc, key, which, Default::default());
                let (light, down) = match &b.sides {
                    lightgrid_core::SideBoundary::GivenHalves { light, down, .. } => (light, down),
                    other => panic!("sides {other:?}"),
                };
                for (i, &p) in halo_points(&desc).iter().enumerate() {
                    let at = h.node_at(key.depth, Vec2::new(p.x, p.z));
                    let held = h.nodes.get(&at).and_then(|m| {
                        let g = m.light.desc().to_grid(p);
                        let top = (m.light.desc().dims() - 1).as_vec3();
                        let on = g.cmpge(Vec3::ZERO).all() && g.cmple(top).all();
                        on.then(|| (m, g.round().as_uvec3()))
                    });
                    match held.filter(|_| crate::neighbours::before(at, key)) {
                        Some((m, q)) => {
                            let (grid, halves) = match which {
                                Response::Sky => (&m.light, m.horizon.as_ref()),
                                Response::Sun => {
                                    let s = m.sun.as_ref().unwrap();
                                    (s.scattered.as_ref().unwrap(), s.horizon.as_ref())
                                }
                            };
                            assert!(
                                grid.get(q) == Some(&light[i]),
                                "{key:?} {which:?} {p}: not {at:?}'s light"
                            );
                            let want = halves.unwrap().get(q).unwrap().within(&light[i]);
                            assert!(down[i] == want, "{key:?} {which:?} {p}: halves");
                            theirs += 1;
                        }
                        None => {
                            let (l, _) = h.coarse_light_split(p, key.depth, which);
                            let close = bytemuck::cast_slice::<_, f32>(&l.0[..])
                                .iter()
                                .zip(bytemuck::cast_slice::<_, f32>(&light[i].0[..]))
                                .all(|(a, b)| (a - b).abs() <= 1e-5 * (1.0 + a.abs()));
                            assert!(close, "{key:?} {which:?} {p}: not the coarser read");
                            coarse += 1;
                        }
                    }
                }
            }
        }
        assert!(
            theirs > 1000 && coarse > 1000,
            "{theirs} from a node before, {coarse} from the coarser grids"
        );
    }

    /// A node swept while a wanted node beside its parent is not built reads its halo
    /// points in that node's rectangle from the apron band of a built node beside it
    /// (the widened sweep's light there, not the next coarser grid's), while no
    /// settled node reads one; and the bands go once nothing can read them.
    #[test]
    fn a_node_waiting_for_a_coarser_neighbour_reads_the_band_beside_it() {
        let mut h = budgeted_layer_hierarchy();
        let camera = Vec3::new(62.0, 12.0, 66.0);
        let (mut from_band, mut changed, mut banded) = (0, 0, 0);
        for i in (0..=6).rev() {
            h.update(camera + Vec3::new(4.0, 0.0, 4.0) * i as f32)
                .unwrap();
            // Every band kept has a wanted node beside it still to come.
            for (k, n) in &h.nodes {
                if n.band.is_some() {
                    assert!(h.band_read(*k), "{k:?} keeps a band nothing reads");
                    assert!(k.depth < h.params.depths());
                    banded += 1;
                }
            }
            for key in h.ready_nodes().into_iter().filter(|k| k.depth >= 2) {
                let n = &h.nodes[&key];
                let desc = *n.material.widened.as_ref().unwrap().desc();
                let b = h.node_boundary_of(&desc, key, Response::Sky, Default::default());
                let lightgrid_core::SideBoundary::GivenHalves { light, .. } = &b.sides else {
                    panic!("sides {:?}", b.sides);
                };
                for (i, &p) in halo_points(&desc).iter().enumerate() {
                    let at = h.node_at(key.depth - 1, Vec2::new(p.x, p.z));
                    if h.nodes.contains_key(&at) || !h.wanted_now.contains(&at) {
                        continue;
                    }
                    let reads: Vec<_> = crate::apron::around(at)
                        .filter_map(|k| h.nodes.get(&k)?.band.as_ref()?.at(p))
                        .map(|(g, _)| g.sample(p).unwrap())
                        .collect();
                    if reads.is_empty() {
                        continue;
                    }
                    // A node reading a band is provisional: swept again once `at` is.
                    assert!(n.provisional || h.halo_waits(key, &h.wanted_now), "{key:?}");
                    let close = |a: &lightgrid_core::BinLight| {
                        (a.0.iter().zip(&light[i].0)).all(|(a, b)| {
                            (*a - *b).abs().max_element() <= 1e-5 * (1.0 + a.max_element())
                        })
                    };
                    assert!(reads.iter().any(close), "{key:?} {p}: not a band's read");
                    from_band += 1;
                    // The coarser grid's read there, which the band replaces.
                    let coarser = h.coarse_light_split(p, key.depth - 1, Response::Sky).0;
                    changed += !close(&coarser) as u32;
                }
            }
        }
        assert!(
            banded > 0 && from_band > 100,
            "{banded} bands, {from_band} halo points read one"
        );
        assert!(
            changed > from_band / 2,
            "{changed} of {from_band} differ from the coarser grid's"
        );
        // Settled: every wanted node built, no band left.
        for _ in 0..60 {
            if h.update(camera).unwrap().pending == 0 {
                break;
            }
        }
        // (A node left behind may stay provisional: no frame wants it.)
        for (k, n) in &h.nodes {
            assert!(n.band.is_none(), "{k:?} keeps its band, settled");
            assert!(!n.provisional || !h.wanted_now.contains(k), "{k:?}");
        }
    }
}
