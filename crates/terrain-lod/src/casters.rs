//! The sun's casters: materials of nodes that the sun's march crosses but the
//! hierarchy has not built, composed for the march alone.
//!
//! A node's direct sun is marched through its own depth's material as far as the
//! hierarchy holds it ([`crate::shadow`]), then through coarser material. A low sun's
//! rays leave the built nodes soon (at 10° a ray rises 1 m in 5.7 m) and crossed the
//! coarser nodes' 2–4 m cells: on the frame bench at 10° the finest nodes' direct sun
//! had an RMSE of 28 % against one 1 m sweep. Before a depth's sun responses are
//! computed, every node of that depth that the rays may cross below its highest
//! material is composed (not swept) if no node, fresh material or caster holds it; the
//! march reads casters as it reads nodes.
//!
//! Which nodes: those whose rectangle meets the node's rectangle (one cell wider where
//! it has an apron: the rays of its sun's ring, `apron::SunRing`, start there) swept
//! toward the sun,
//! where over some column of the finest material held above it (a built, composed or
//! caster ancestor's whose column nothing lies above, else the world grid's) the lowest
//! ray (from the node's bottom, at the least horizontal distance to the column, widened
//! by the margin) is still below a bound of the material there: the top of the
//! column's highest non-empty cell, a quarter of that material's cell more
//! (`TOP_MARGIN`: what the composer's samples may miss), and the node's levels above
//! its material (`node_material`: three). The world grid's 16 m cells alone called for
//! 334 casters along the frame bench's path at 10°, its nodes' 2–8 m cells for 289, and
//! those cells column by column (instead of the top over the whole rectangle against
//! the lowest ray at its nearest point) for 275 (at 30° 170 → 166, at 60° 114 → 112),
//! the errors the same to the digit. Above that bound every grid is air at every depth, so
//! whether a caster is there or not changes nothing: a node's march reads its depth's
//! material wherever it could matter, whatever the hierarchy built before, and comes
//! out the same after a sun move as when built fresh.
//!
//! A caster is composed from the source's shadow material
//! ([`lightgrid_core::MaterialSource::shadow_material`]: the area composer's takes
//! about half the samples a side, no fewer than two; over the node's own grid, no
//! apron) and kept while frames need it (the next nodes' rays cross the same places)
//! and for [`KEEP_FRAMES`] after; a node built where a caster lies composes its own
//! material (a sweep's).
//! Under a time budget (`HierarchyParams::budget_ms`) a sun job whose casters are not
//! all held once half the frame is spent waits for a later frame, and `set_sun`'s
//! march composes none (it reads what is held; each node's transmittance is marched
//! again with its casters when the budget sweeps its stale scattered sun).

use std::collections::HashMap;
use std::hash::BuildHasherDefault;
use std::time::Duration;

use lightgrid_core::glam::{IVec2, Vec2, Vec3};
use lightgrid_core::{GridDesc, MaterialGrid};

use crate::{Hierarchy, KeyHasher, LodError, NodeKey, NodeMaterial};

/// Frames a caster is kept after the last frame that needed it.
pub(crate) const KEEP_FRAMES: u64 = 8;

/// What an object may reach above the top of the world grid's highest non-empty cell,
/// in world cells: the area composer samples a cell on 4 points a side by default (a
/// caster's shadow material on 2 or more where its material takes 2 or more), so an
/// object between two samples rises at most a quarter of a cell past the top of the
/// cell that holds the last one that found it. (A whole cell gave the frame bench at
/// 10° 381 casters, a quarter 325, none 304, all with the same error to the digit.)
pub(crate) const TOP_MARGIN: f32 = 0.25;

/// The casters held, each with the last frame that needed it.
#[derive(Default)]
pub(crate) struct Casters {
    materials: HashMap<NodeKey, (NodeMaterial, u64), BuildHasherDefault<KeyHasher>>,
    frame: u64,
}

impl Casters {
    /// The caster at `key`, if held.
    pub(crate) fn get(&self, key: &NodeKey) -> Option<&NodeMaterial> {
        self.materials.get(key).map(|c| &c.0)
    }

    /// Every caster held, by node.
    pub(crate) fn iter(&self) -> impl Iterator<Item = (&NodeKey, &NodeMaterial)> {
        self.materials.iter().map(|(k, c)| (k, &c.0))
    }

    /// The nodes held.
    pub(crate) fn keys(&self) -> impl Iterator<Item = &NodeKey> {
        self.materials.keys()
    }

    /// Drops every caster (the scene may have changed).
    pub(crate) fn clear(&mut self) {
        self.materials.clear();
    }

    /// Bytes of the casters' materials.
    pub(crate) fn bytes(&self) -> u64 {
        self.materials
            .values()
            .map(|(m, _)| m.grid.desc().point_count() as u64 * crate::BYTES_MATERIAL)
            .sum()
    }

    /// A frame ends: casters no frame needed for [`KEEP_FRAMES`] go.
    pub(crate) fn end_frame(&mut self) {
        self.frame += 1;
        let now = self.frame;
        self.materials
            .retain(|_, (_, used)| now.saturating_sub(*used) <= KEEP_FRAMES);
    }
}

/// The top of the highest non-empty cell of `world` over the rectangle `[lo, hi]`
/// (`-inf` where it holds none or lies outside the grid).
pub(crate) fn material_top_over(world: &MaterialGrid, lo: Vec2, hi: Vec2) -> f32 {
    let mut top = f32::NEG_INFINITY;
    column_tops(world, lo, hi, |_, _, t| {
        top = top.max(t);
        false
    });
    top
}

/// Calls `f` with each column of `m` whose cells meet the rectangle `[lo, hi]` and that
/// holds a non-empty cell: the column's part of the rectangle (its cells' `(x, z)`
/// extent clipped to it) and the top of its highest non-empty cell. Stops at the first
/// call that returns `true`, and returns whether one did.
pub(crate) fn column_tops(
    m: &MaterialGrid,
    lo: Vec2,
    hi: Vec2,
    mut f: impl FnMut(Vec2, Vec2, f32) -> bool,
) -> bool {
    let d = m.desc();
    let (o, h, dims) = (d.origin(), d.h(), d.dims());
    // Columns whose cells ([x - h/2, x + h/2]) meet the rectangle.
    let first = |v: f32, o: f32| ((v - o) / h + 0.5).floor().max(0.0) as u32;
    let last = |v: f32, o: f32, n: u32| ((v - o) / h + 0.5).floor().min(n as f32 - 1.0);
    let (x1, z1) = (last(hi.x, o.x, dims.x), last(hi.y, o.z, dims.z));
    if x1 < 0.0 || z1 < 0.0 {
        return false;
    }
    let cells = m.data();
    for z in first(lo.y, o.z)..=z1 as u32 {
        for x in first(lo.x, o.x)..=x1 as u32 {
            if let Some(j) = (0..dims.y).rev().find(|&j| {
                !cells[d.index_unchecked(lightgrid_core::glam::UVec3::new(x, j, z))].is_empty()
            }) {
                let centre = Vec2::new(o.x + x as f32 * h, o.z + z as f32 * h);
                let (clo, chi) = (centre - Vec2::splat(0.5 * h), centre + Vec2::splat(0.5 * h));
                if f(clo.max(lo), chi.min(hi), o.y + (j as f32 + 0.5) * h) {
                    return true;
                }
            }
        }
    }
    false
}

impl Hierarchy {
    /// Adds to `out` the nodes of `key`'s depth (not `key`) whose material the sun's
    /// rays from `key`'s grid (`desc`: the node's, or widened by an apron beyond its
    /// rectangle) may cross along `to_sun`
    /// (module docs), `world_top` the top of the world grid's highest material. None
    /// without the world grid's material (no sun kept apart).
    pub(crate) fn sun_casters(
        &self,
        (key, desc): (NodeKey, GridDesc),
        to_sun: Vec3,
        world_top: f32,
        out: &mut Vec<NodeKey>,
    ) {
        let Some(world) = &self.world_material else {
            return;
        };
        let dir = to_sun.normalize_or_zero();
        let flat = Vec2::new(dir.x, dir.z);
        let along = flat.length();
        if dir.y.is_nan() || dir.y <= 0.0 || along < 1e-6 {
            return; // below the horizon (no beam) or straight up (its own column)
        }
        let (u, slope) = (flat / along, dir.y / along);
        let bottom = desc.origin().y - 0.5 * desc.h();
        let wd = world.desc();
        let node_levels = 3.0 * self.params.cell(key.depth);
        let margin = TOP_MARGIN * wd.h() + node_levels;
        // Past this the lowest ray is above all material.
        let reach = ((world_top + margin - bottom) / slope).max(0.0);
        if !reach.is_finite() {
            return; // no material anywhere
        }
        let (lo, hi) = self.node_rect(key);
        // (An apron's cells lie beyond the rectangle: their rays too.)
        let (clo, chi) = desc.cell_bounds();
        let lo = lo.min(Vec2::new(clo.x, clo.z));
        let hi = hi.max(Vec2::new(chi.x, chi.z));
        let corners = |lo: Vec2, hi: Vec2| [lo, Vec2::new(hi.x, lo.y), Vec2::new(lo.x, hi.y), hi];
        let n = Vec2::new(-u.y, u.x);
        let span = |c: [Vec2; 4], a: Vec2| {
            c.iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), p| {
                    (l.min(a.dot(*p)), h.max(a.dot(*p)))
                })
        };
        let (near, far) = span(corners(lo, hi), u);
        let (side_lo, side_hi) = span(corners(lo, hi), n);
        // The swept rectangle's bounding box, within the terrain.
        let end = u * reach;
        let blo = lo.min(lo + end).max(self.heightmap_lo);
        let bhi = hi.max(hi + end).min(self.heightmap_hi);
        if blo.cmpge(bhi).any() {
            return;
        }
        let s = self.params.node_size(key.depth);
        let first = ((blo - self.heightmap_lo) / s).floor().as_ivec2();
        let last = ((bhi - self.heightmap_lo) / s).ceil().as_ivec2() - IVec2::ONE;
        for iz in first.y..=last.y {
            for ix in first.x..=last.x {
                let k = NodeKey {
                    depth: key.depth,
                    index: IVec2::new(ix, iz),
                };
                if k == key {
                    continue;
                }
                let (qlo, qhi) = self.node_rect(k);
                let c = corners(qlo, qhi);
                let (q_near, q_far) = span(c, u);
                let (q_lo, q_hi) = span(c, n);
                // Beside the swept band, behind the node or beyond the reach.
                if q_hi < side_lo || q_lo > side_hi || q_far < near || q_near > far + reach {
                    continue;
                }
                // Column by column of the bound's material (its top and margin over
                // each, the margin also around it: what its samples may miss to the
                // side), the lowest ray over the column: a caster whose every column
                // the rays pass above is air wherever they cross it, as the coarser
                // material there is.
                let (m, margin) = self.bound_material(k, world);
                let grow = Vec2::splat(margin);
                let needed = column_tops(m, qlo, qhi, |clo, chi, top| {
                    let (c_near, _) = span(corners(clo - grow, chi + grow), u);
                    let lowest_ray = bottom + (c_near - far).max(0.0) * slope;
                    lowest_ray < top + margin + node_levels
                });
                if needed {
                    out.push(k);
                }
            }
        }
    }

    /// A bound of the material over node `key`'s rectangle `(lo, hi)`: the top of the
    /// highest non-empty cell over it, and [`TOP_MARGIN`] of a cell more, in the finest
    /// material held that covers it and whose column nothing lies above (a built,
    /// composed or caster ancestor's; `open_above`), else in the world grid's.
    #[cfg(test)]
    fn material_bound(&self, key: NodeKey, (lo, hi): (Vec2, Vec2), world: &MaterialGrid) -> f32 {
        let (m, margin) = self.bound_material(key, world);
        material_top_over(m, lo, hi) + margin
    }

    /// The material a caster's bound is taken from ([`Hierarchy::material_bound`]) and
    /// its margin ([`TOP_MARGIN`] of its cell).
    fn bound_material<'a>(
        &'a self,
        key: NodeKey,
        world: &'a MaterialGrid,
    ) -> (&'a MaterialGrid, f32) {
        let mut anc = Self::parent(key);
        while let Some(a) = anc {
            let held = self
                .nodes
                .get(&a)
                .map(|n| &n.material)
                .or_else(|| self.composed.get(&a))
                .or_else(|| self.casters.get(&a));
            if let Some(m) = held.filter(|m| m.open_above) {
                return (&m.grid, TOP_MARGIN * m.grid.desc().h());
            }
            anc = Self::parent(a);
        }
        (world, TOP_MARGIN * world.desc().h())
    }

    /// The casters that the sun's march from `grids` (each a node and its grid) along
    /// `dirs` needs and that no node, kept material, caster or `fresh`
    /// node holds; marks the needed casters held as used this frame.
    pub(crate) fn missing_casters(
        &mut self,
        grids: &[(NodeKey, GridDesc)],
        dirs: &[Vec3],
        fresh: &[NodeKey],
    ) -> Vec<NodeKey> {
        if self.world_material.is_none()
            || self.params.skip.sun_casters
            || grids.is_empty()
            || dirs.is_empty()
        {
            return Vec::new(); // no sun kept apart, the casters skipped, or none lit
        }
        let world_top = self.world_top;
        let mut need = Vec::new();
        for &grid in grids {
            for &d in dirs {
                self.sun_casters(grid, d, world_top, &mut need);
            }
        }
        need.sort();
        need.dedup();
        let frame = self.casters.frame;
        need.retain(|k| {
            // A node's material (built, composed or fresh) is read before a caster's:
            // a caster there is not marked used, and goes after `KEEP_FRAMES`.
            if self.nodes.contains_key(k) || self.composed.contains_key(k) || fresh.contains(k) {
                return false;
            }
            match self.casters.materials.get_mut(k) {
                Some(c) => {
                    c.1 = frame;
                    false
                }
                None => true,
            }
        });
        need
    }

    /// Composes the casters [`Hierarchy::missing_casters`] finds, side by side. Returns
    /// how many it composed and the time they took (summed over threads).
    pub(crate) fn compose_casters(
        &mut self,
        grids: &[(NodeKey, GridDesc)],
        dirs: &[Vec3],
        fresh: &[NodeKey],
    ) -> Result<(u32, Duration), LodError> {
        let need = self.missing_casters(grids, dirs, fresh);
        self.compose_missing(need)
    }

    /// Composes `need` (from [`Hierarchy::missing_casters`]) side by side and holds
    /// them. Returns how many and the time they took (summed over threads).
    pub(crate) fn compose_missing(
        &mut self,
        need: Vec<NodeKey>,
    ) -> Result<(u32, Duration), LodError> {
        if need.is_empty() {
            return Ok((0, Duration::ZERO));
        }
        let _span = tracing::trace_span!("sun casters", count = need.len()).entered();
        let composed = self.compose_each(&need, Self::caster_material);
        let mut time = Duration::ZERO;
        let frame = self.casters.frame;
        for (k, (m, t)) in need.iter().zip(composed) {
            time += t;
            self.casters.materials.insert(*k, (m?, frame));
        }
        Ok((need.len() as u32, time))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A node the rule leaves out is air wherever a ray crosses it: over columns of
    /// medium of many heights, every ray from a finest node's bottom (from each of its
    /// points' `(x, z)`, sampled every 0.1 m along it), wherever it lies over
    /// another node of that depth not listed, passes the margins (a quarter of the
    /// bound material's cell, and the node's three levels above its material) above the
    /// bound material's highest cell within a margin of it; for low suns of several
    /// azimuths. And the test is not empty: some rays pass over material of nodes left
    /// out (the whole rectangle's top against the lowest ray at its nearest point
    /// listed those).
    #[test]
    fn a_node_left_out_is_air_wherever_the_rays_cross_it() {
        let h = crate::testing::built_over(Box::new(crate::testing::Columns), 0, false);
        let world = h.world_material.as_ref().unwrap();
        let finest = h.params.depths();
        let size = h.params.node_size(finest);
        let node_levels = 3.0 * h.params.cell(finest);
        let (mut checked, mut old_rule_listed) = (0u64, 0u64);
        let keys: Vec<NodeKey> = h
            .nodes
            .keys()
            .filter(|k| k.depth == finest)
            .copied()
            .collect();
        assert!(!keys.is_empty());
        for &key in &keys {
            let desc = *h.nodes[&key].material.grid.desc();
            let bottom = desc.origin().y - 0.5 * desc.h();
            let (lo, hi) = h.node_rect(key);
            for (elev, azim) in [(5f32, 0f32), (10.0, 35.0), (10.0, 200.0), (20.0, 120.0)] {
                let (e, a) = (elev.to_radians(), azim.to_radians());
                let to_sun = Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin());
                let mut listed = Vec::new();
                h.sun_casters((key, desc), to_sun, h.world_top, &mut listed);
                let u = Vec2::new(to_sun.x, to_sun.z).normalize();
                let slope = to_sun.y / Vec2::new(to_sun.x, to_sun.z).length();
                let d = desc.dims();
                for (i, j) in (0..d.x).flat_map(|i| (0..d.z).map(move |j| (i, j))) {
                    let q = desc.position(lightgrid_core::glam::UVec3::new(i, 0, j));
                    let s = Vec2::new(q.x, q.z);
                    for t in (1..=1600).map(|t| t as f32 * 0.1) {
                        let p = s + u * t;
                        if p.cmplt(h.heightmap_lo).any() || p.cmpge(h.heightmap_hi).any() {
                            break; // no node beyond the terrain
                        }
                        let index = ((p - h.heightmap_lo) / size).floor().as_ivec2();
                        let k = NodeKey {
                            depth: finest,
                            index,
                        };
                        if k == key || listed.contains(&k) {
                            continue;
                        }
                        let (qlo, qhi) = h.node_rect(k);
                        let (m, margin) = h.bound_material(k, world);
                        let around = (p - Vec2::splat(margin)).max(qlo);
                        let top = material_top_over(m, around, (p + Vec2::splat(margin)).min(qhi));
                        if top == f32::NEG_INFINITY {
                            continue;
                        }
                        let y = bottom + t * slope;
                        assert!(
                            y >= top + margin + node_levels - 1e-3,
                            "{key:?} at {elev} deg, {azim} deg: the ray from {s} at {p} is at {y}, \
                             under {k:?}'s material top {top} and its margins"
                        );
                        checked += 1;
                        // Listed by the whole rectangle's rule: its top against the
                        // lowest ray at its nearest point.
                        let dots = |lo: Vec2, hi: Vec2| {
                            [lo, Vec2::new(hi.x, lo.y), Vec2::new(lo.x, hi.y), hi].map(|c| c.dot(u))
                        };
                        let far = dots(lo, hi).into_iter().fold(f32::MIN, f32::max);
                        let near = dots(qlo, qhi).into_iter().fold(f32::MAX, f32::min);
                        let lowest = bottom + (near - far).max(0.0) * slope;
                        old_rule_listed +=
                            (lowest < material_top_over(m, qlo, qhi) + margin + node_levels) as u64;
                    }
                }
            }
        }
        assert!(
            checked > 0 && old_rule_listed > 0,
            "{checked} samples, {old_rule_listed} the whole rectangle's rule listed"
        );
    }

    /// A caster's bound comes from the finest held material above it: the parent's
    /// 4 m cells at the finest depth here, the world grid's 8 m ones at depth 1.
    #[test]
    fn the_bound_is_the_finest_held_materials() {
        let h = crate::testing::layer_hierarchy(0, false);
        let world = h.world_material.as_ref().unwrap();
        let finest = h.params.depths();
        let mut checked = 0;
        for k in h.nodes.keys() {
            let (lo, hi) = h.node_rect(*k);
            let bound = h.material_bound(*k, (lo, hi), world);
            let expected = match Hierarchy::parent(*k) {
                Some(p) => {
                    let parent = &h.nodes[&p].material;
                    assert!(parent.open_above, "{p:?}");
                    material_top_over(&parent.grid, lo, hi) + TOP_MARGIN * parent.grid.desc().h()
                }
                None => material_top_over(world, lo, hi) + TOP_MARGIN * world.desc().h(),
            };
            assert_eq!(bound, expected, "{k:?}");
            checked += (k.depth == finest) as u32;
        }
        assert!(checked > 0, "no finest node");
        // And it is not the world grid's (whose 8 m cells lie elsewhere).
        assert!(h.nodes.keys().any(|k| {
            let (lo, hi) = h.node_rect(*k);
            k.depth == finest
                && h.material_bound(*k, (lo, hi), world)
                    != material_top_over(world, lo, hi) + TOP_MARGIN * world.desc().h()
        }));
    }
}
