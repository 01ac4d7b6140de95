//! The sun's beam beyond a grid: what it has lost before it reaches a node's box.
//!
//! A node's sun transmittance is marched exactly inside the node
//! (`lightgrid_sweep_cpu::sun::SunTransmittance::march`); where a point's ray leaves the
//! box it is multiplied by what the beam lost outside (`outside`). That loss is marched
//! on, toward the sun, through the finest material the hierarchy holds at each place:
//! the ready nodes' own materials (kept with them), the materials composed this frame
//! for the depth being built or kept for a later frame, the sun's casters (nodes
//! composed for the march alone, [`crate::casters`]), and the world grid's, until the
//! ray leaves every grid (open sky: nothing more is lost).
//!
//! Reading the coarser grids' *transmittance* there instead (a trilinear read of a grid
//! 2 to 16 times coarser) blurred every shadow cast from outside a node by the coarse
//! spacing: on the 16-point flythrough (`cargo xtask frame`), the finest nodes' direct
//! sun against one 1 m sweep had an RMSE of 82 % at 10° and 25 % at 30°.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use lightgrid_core::dda::box_exit;
use lightgrid_core::glam::{IVec2, IVec3, Vec2, Vec3};
use lightgrid_core::{GridDesc, MaterialGrid};

use crate::{Hierarchy, KeyHasher, NodeKey, NodeMaterial};

/// Materials composed this frame for nodes not yet stored (the depth being built), by
/// node; the march reads them as it reads the ready nodes'. Hashed as the nodes are
/// ([`KeyHasher`]): the march looks a ray's place up in it at every grid the ray
/// crosses, and std's SipHash there was 3 % of a frame's sweeping time.
pub(crate) type Fresh<'a> = HashMap<NodeKey, &'a NodeMaterial, BuildHasherDefault<KeyHasher>>;

/// What the march meets at a place.
enum Along<'a> {
    /// A grid's material.
    Grid(&'a MaterialGrid),
    /// The empty column above a node's grid ([`NodeMaterial::open_above`]): nothing
    /// to the box's faces, given as (x, z) lower and upper corners.
    Clear(Vec2, Vec2),
}

/// Most grids one ray crosses before it is taken as lost in the sky (a guard; a ray
/// crosses a handful of nodes and the world grid).
const MAX_HOPS: usize = 4096;

/// Where the beam is darker than `e^-LOG_DARK` it counts as 0 (as in the node march).
const LOG_DARK: f32 = -60.0;

/// Whether `p` lies in the box of `desc`'s cells (`[origin - h/2, origin + (dims - 1/2) h]`).
fn cells_contain(desc: &GridDesc, p: Vec3) -> bool {
    let g = (p - desc.origin()) / desc.h();
    g.cmpge(Vec3::splat(-0.5)).all() && g.cmple(desc.dims().as_vec3() - 0.5).all()
}

/// The top of each column's highest non-empty cell of `m` (pass-through under 1: the
/// only cells that take from the beam), x fastest, −∞ where none
/// ([`crate::casters::column_tops`] over the whole grid).
pub(crate) fn column_tops(m: &MaterialGrid) -> Vec<f32> {
    let d = m.desc();
    let (dims, h) = (d.dims(), d.h());
    let lo = Vec2::new(d.origin().x, d.origin().z) - 0.5 * h;
    let mut tops = vec![f32::NEG_INFINITY; (dims.x * dims.z) as usize];
    let all = Vec2::splat(f32::INFINITY);
    crate::casters::column_tops(m, -all, all, |clo, _, top| {
        let c = ((clo - lo) / h).round();
        tops[(c.x as u32 + dims.x * c.y as u32) as usize] = top;
        false
    });
    tops
}

/// Upper bounds of the material a march reads, by column of the world grid's cells:
/// the world material's own tops and the box tops of every node material the march
/// may read over them. A ray above a column's bound while it crosses the column takes
/// nothing from the beam there ([`SkyMarch::to_sky`] stops once nothing ahead can).
struct Tops {
    /// The (x, z) corner of the world grid's cells.
    lo: Vec2,
    /// A column's side (the world grid's cell).
    cell: f32,
    size: IVec2,
    top: Vec<f32>,
}

impl Tops {
    /// The bounds over `world` (its [`column_tops`] `tops`) and `nodes`' grids; `None`
    /// where a node's box reaches beyond the world grid's columns.
    fn new<'m>(
        world: &MaterialGrid,
        tops: &[f32],
        nodes: impl Iterator<Item = &'m MaterialGrid>,
    ) -> Option<Self> {
        let d = world.desc();
        let (o, h) = (d.origin(), d.h());
        let size = IVec2::new(d.dims().x as i32, d.dims().z as i32);
        let mut t = Self {
            lo: Vec2::new(o.x, o.z) - 0.5 * h,
            cell: h,
            size,
            top: tops.to_vec(),
        };
        if t.top.len() != (size.x * size.y) as usize {
            return None;
        }
        for m in nodes {
            let (md, mh) = (m.desc(), m.desc().h());
            let blo = md.origin() - 0.5 * mh;
            let bhi = blo + md.dims().as_vec3() * mh;
            let col = |v: Vec2| {
                let g = (v - t.lo) / t.cell;
                IVec2::new(floor_i32(g.x), floor_i32(g.y))
            };
            let (c0, c1) = (col(Vec2::new(blo.x, blo.z)), col(Vec2::new(bhi.x, bhi.z)));
            if c0.cmplt(IVec2::ZERO).any() || c1.cmpge(size).any() {
                return None;
            }
            for z in c0.y..=c1.y {
                for x in c0.x..=c1.x {
                    let k = (x + size.x * z) as usize;
                    t.top[k] = t.top[k].max(bhi.y);
                }
            }
        }
        Some(t)
    }

    /// `None` where the ray from `q` along unit `dir` (rising) stays above every
    /// column's bound until it leaves the columns; else how far along it the first
    /// column whose bound it may not clear ends (where to ask again).
    fn blocked_for(&self, q: Vec3, dir: Vec3) -> Option<f32> {
        // A margin for the rounding between this walk and the march's.
        let margin = 1e-3 * self.cell;
        let g = (Vec2::new(q.x, q.z) - self.lo) / self.cell;
        let mut c = IVec2::new(floor_i32(g.x), floor_i32(g.y));
        let inside = |c: IVec2| c.cmpge(IVec2::ZERO).all() && c.cmplt(self.size).all();
        // Ray length a column's side takes along x and z, and to the next side of each.
        let along = |d: f32, g: f32, c: i32| -> (f32, f32) {
            if d > 0.0 {
                let per = self.cell / d;
                ((c as f32 + 1.0 - g) * per, per)
            } else if d < 0.0 {
                let per = self.cell / -d;
                ((g - c as f32) * per, per)
            } else {
                (f32::INFINITY, f32::INFINITY)
            }
        };
        let ((mut next_x, per_x), (mut next_z, per_z)) =
            (along(dir.x, g.x, c.x), along(dir.z, g.y, c.y));
        let mut entry = 0.0f32;
        // (At most every column once, and one more.)
        for _ in 0..=(self.size.x + self.size.y) {
            if !inside(c) {
                return None;
            }
            let exit = next_x.min(next_z);
            if q.y + dir.y * entry <= self.top[(c.x + self.size.x * c.y) as usize] + margin {
                return Some(if exit.is_finite() {
                    exit
                } else {
                    // Straight up: until it is above the column's bound.
                    (self.top[(c.x + self.size.x * c.y) as usize] + margin - q.y) / dir.y
                });
            }
            entry = exit;
            if next_x < next_z {
                c.x += if dir.x > 0.0 { 1 } else { -1 };
                next_x += per_x;
            } else {
                c.y += if dir.z > 0.0 { 1 } else { -1 };
                next_z += per_z;
            }
        }
        Some(0.0)
    }
}

/// Node indices of one depth a march reads ([`SkyMarch`]): the materials held over
/// the box of indices `lo .. lo + size`, x fastest.
struct DepthIndex<'a> {
    lo: IVec2,
    size: IVec2,
    cells: Vec<Option<&'a NodeMaterial>>,
}

/// Largest [`DepthIndex`] built (entries); beyond it a depth is looked up in the maps.
const MAX_INDEX: i64 = 1 << 20;

/// `floor(x) as i32` without a call to `floorf` (the baseline x86-64 has no rounding
/// instruction): the same integer for every `f32`, NaN (0) and the saturated ends
/// included.
pub(crate) fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) > x {
        i.saturating_sub(1)
    } else {
        i
    }
}

/// A march toward the sun through the materials the hierarchy holds, down to `depth`
/// ([`SkyMarch::material_at`]), set up once for the many rays of a node's march: each
/// depth's materials indexed by node in a dense table, so that a ray's hop from grid
/// to grid looks its place up by index instead of in four hash maps a depth (the
/// lookups were most of the march's cost; the result is the same bit for bit).
pub(crate) struct SkyMarch<'a> {
    h: &'a Hierarchy,
    depth: u32,
    fresh: &'a Fresh<'a>,
    /// Depth `d`'s index at `d - 1` (`None`: looked up in the maps).
    index: Vec<Option<DepthIndex<'a>>>,
    /// Depth `d`'s node size at `d - 1`.
    sizes: Vec<f32>,
    /// Bounds of the material it reads, by column (`None`: none kept, every ray
    /// marched until it leaves every grid).
    tops: Option<Tops>,
}

impl<'a> SkyMarch<'a> {
    /// The march for the grids of `depth`, `fresh` the materials composed this frame.
    pub(crate) fn new(h: &'a Hierarchy, depth: u32, fresh: &'a Fresh<'a>) -> Self {
        let depth = depth.min(h.params.depths());
        let index = (1..=depth).map(|d| Self::index(h, d, fresh)).collect();
        let read = |k: &NodeKey| k.depth <= depth;
        let nodes = (h
            .nodes
            .iter()
            .filter(|(k, _)| read(k))
            .map(|(_, n)| &n.material))
        .chain(fresh.iter().filter(|(k, _)| read(k)).map(|(_, m)| *m))
        .chain(h.composed.iter().filter(|(k, _)| read(k)).map(|(_, m)| m))
        .chain(h.casters.iter().filter(|(k, _)| read(k)).map(|(_, m)| m))
        .map(|m| &m.grid);
        let tops = (h.world_material.as_ref()).and_then(|w| Tops::new(w, &h.world_tops, nodes));
        Self {
            h,
            depth,
            fresh,
            index,
            sizes: (1..=depth).map(|d| h.params.node_size(d)).collect(),
            tops,
        }
    }

    /// [`SkyMarch::new`] marching every ray until it leaves every grid (the early end's
    /// reference).
    #[cfg(test)]
    pub(crate) fn to_the_end(h: &'a Hierarchy, depth: u32, fresh: &'a Fresh<'a>) -> Self {
        Self {
            tops: None,
            ..Self::new(h, depth, fresh)
        }
    }

    /// [`SkyMarch::new`] with every depth looked up in the maps (the index's reference).
    #[cfg(test)]
    pub(crate) fn unindexed(h: &'a Hierarchy, depth: u32, fresh: &'a Fresh<'a>) -> Self {
        let depth = depth.min(h.params.depths());
        Self {
            index: (1..=depth).map(|_| None).collect(),
            ..Self::new(h, depth, fresh)
        }
    }

    /// Depth `d`'s materials by node, in the maps' order of precedence (a ready node's,
    /// a fresh one's, a composed one's, a caster's); `None` where their box of indices
    /// passes [`MAX_INDEX`].
    fn index(h: &'a Hierarchy, d: u32, fresh: &'a Fresh<'a>) -> Option<DepthIndex<'a>> {
        let at = |k: &NodeKey| k.depth == d;
        let keys = || {
            (h.nodes.keys().filter(|k| at(k)))
                .chain(fresh.keys().filter(|k| at(k)))
                .chain(h.composed.keys().filter(|k| at(k)))
                .chain(h.casters.keys().filter(|k| at(k)))
        };
        let (lo, hi) = keys().fold(
            (IVec2::splat(i32::MAX), IVec2::splat(i32::MIN)),
            |(lo, hi), k| (lo.min(k.index), hi.max(k.index)),
        );
        if lo.cmpgt(hi).any() {
            return Some(DepthIndex {
                lo: IVec2::ZERO,
                size: IVec2::ZERO,
                cells: Vec::new(),
            });
        }
        let span = |a: i32, b: i32| b as i64 - a as i64 + 1;
        let (sx, sz) = (span(lo.x, hi.x), span(lo.y, hi.y));
        if sx * sz > MAX_INDEX {
            return None;
        }
        let size = IVec2::new(sx as i32, sz as i32);
        let mut cells = vec![None; (size.x * size.y) as usize];
        let mut put = |k: &NodeKey, m: &'a NodeMaterial| {
            let c = k.index - lo;
            cells[(c.x + size.x * c.y) as usize] = Some(m);
        };
        // Lowest precedence first: each later one overwrites.
        for (k, m) in h.casters.iter().filter(|(k, _)| at(k)) {
            put(k, m);
        }
        for (k, m) in h.composed.iter().filter(|(k, _)| at(k)) {
            put(k, m);
        }
        for (k, m) in fresh.iter().filter(|(k, _)| at(k)) {
            put(k, m);
        }
        for (k, n) in h.nodes.iter().filter(|(k, _)| at(k)) {
            put(k, &n.material);
        }
        Some(DepthIndex { lo, size, cells })
    }

    /// The material held for node `key` (of depth `key.depth`, at most the march's).
    fn held(&self, key: NodeKey) -> Option<&'a NodeMaterial> {
        match &self.index[key.depth as usize - 1] {
            Some(ix) => {
                let c = key.index - ix.lo;
                if c.cmplt(IVec2::ZERO).any() || c.cmpge(ix.size).any() {
                    return None;
                }
                ix.cells[(c.x + ix.size.x * c.y) as usize]
            }
            None => match self.h.nodes.get(&key) {
                Some(n) => Some(&n.material),
                None => (self.fresh.get(&key).copied())
                    .or_else(|| self.h.composed.get(&key))
                    .or_else(|| self.h.casters.get(&key)),
            },
        }
    }

    /// The finest material holding `p` at the march's depth or coarser: a ready node's
    /// or a fresh one's, finest depth first, else the world grid's; `None` outside every
    /// grid.
    fn material_at(&self, p: Vec3) -> Option<Along<'a>> {
        let h = self.h;
        for d in (1..=self.depth).rev() {
            // `Hierarchy::node_at`'s key.
            let g = (Vec2::new(p.x, p.z) - h.heightmap_lo) / self.sizes[d as usize - 1];
            let key = NodeKey {
                depth: d,
                index: IVec2::new(floor_i32(g.x), floor_i32(g.y)),
            };
            let Some(m) = self.held(key) else {
                continue;
            };
            let desc = m.grid.desc();
            if cells_contain(desc, p) {
                return Some(Along::Grid(&m.grid));
            }
            let lo = desc.origin() - 0.5 * desc.h();
            let hi = lo + desc.dims().as_vec3() * desc.h();
            let inside_xz = p.x >= lo.x && p.x <= hi.x && p.z >= lo.z && p.z <= hi.z;
            if m.open_above && inside_xz && p.y > hi.y {
                return Some(Along::Clear(Vec2::new(lo.x, lo.z), Vec2::new(hi.x, hi.z)));
            }
        }
        h.world_material
            .as_ref()
            .filter(|m| cells_contain(m.desc(), p))
            .map(Along::Grid)
    }

    /// The sun's transmittance from the sky down to `p` along `dir` (unit, toward the
    /// sun), marched through the finest material at the march's depth or coarser held
    /// along the way ([`SkyMarch::material_at`]); 1 where the ray meets no grid.
    ///
    /// Finer nodes are not read: a node's sun responses depend on its own depth's
    /// materials and coarser ones only, and so come out the same whether finer nodes
    /// exist yet or not (after a sun move as when built fresh: tested).
    pub(crate) fn to_sky(&self, p: Vec3, dir: Vec3) -> f32 {
        if !p.is_finite() || dir.y <= 0.0 {
            return 0.0;
        }
        // A nudge past a box's face into the next grid: a thousandth of the finest cell.
        let nudge = 1e-3 * self.h.params.finest_cell;
        let mut q = p;
        let mut log_t = 0.0f32;
        // How far along the ray the bounds are asked again.
        let mut ask_at = 0.0f32;
        for _ in 0..MAX_HOPS {
            if let Some(tops) = &self.tops {
                let s = (q - p).dot(dir);
                if s >= ask_at {
                    match tops.blocked_for(q, dir) {
                        // Only cells of pass-through 1 ahead (each adds `len · ln 1`,
                        // 0): the sum as the march to the end leaves it, bit for bit.
                        None => return log_t.exp(),
                        Some(ahead) => ask_at = s + ahead,
                    }
                }
            }
            let m = match self.material_at(q + dir * nudge) {
                None => return log_t.exp(),
                Some(Along::Grid(m)) => m,
                Some(Along::Clear(lo, hi)) => {
                    // To the column's side (it climbs forever): nothing lost.
                    let t = box_exit(
                        q,
                        dir,
                        Vec3::new(lo.x, f32::NEG_INFINITY, lo.y),
                        Vec3::new(hi.x, f32::INFINITY, hi.y),
                    );
                    if !t.is_finite() {
                        return log_t.exp(); // straight up: open sky
                    }
                    q += dir * (t.max(0.0) + 2.0 * nudge);
                    continue;
                }
            };
            let d = m.desc();
            let dims = d.dims();
            let a = (q - d.origin()) / d.h();
            let t = box_exit(a, dir, Vec3::splat(-0.5), dims.as_vec3() - 0.5) + 2.0 * nudge / d.h();
            let b = a + dir * t;
            let cells = m.data();
            let mut opaque = false;
            lightgrid_core::dda::walk_segment(a, b, dims.as_ivec3(), |c: IVec3, len| {
                let pass = cells[d.index_unchecked(c.as_uvec3())].pass;
                if pass <= 0.0 {
                    opaque = true;
                } else {
                    log_t += len * pass.ln();
                }
            });
            if opaque || log_t < LOG_DARK {
                return 0.0;
            }
            q = d.origin() + b * d.h();
        }
        log_t.exp()
    }
}

#[cfg(test)]
mod tests {
    use lightgrid_core::glam::Vec3;

    use super::{Fresh, SkyMarch, floor_i32};
    use crate::testing::layer_hierarchy;

    /// `floor_i32` is `floor(x) as i32` for every kind of `f32`.
    #[test]
    fn floor_i32_is_floor_as_i32() {
        let mut rng = fastrand::Rng::with_seed(5);
        let special = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            -1.0,
            1.0,
            -1e-30,
            2147483520.0,
            2147483648.0,
            -2147483648.0,
            -2147484672.0,
            1e30,
            -1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
        ];
        let random = (0..100_000).map(|_| (rng.f32() - 0.5) * 10f32.powi(rng.i32(-3..12)));
        for x in special.into_iter().chain(random) {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
        }
    }

    /// The march's dense index of the nodes gives the transmittance the maps give, bit
    /// for bit, from points over the whole hierarchy toward suns high and low, at every
    /// depth; and the march is not trivially 1 (some rays cross the medium).
    #[test]
    fn indexed_march_equals_the_maps() {
        let h = layer_hierarchy(0, false);
        let fresh = Fresh::default();
        let mut rng = fastrand::Rng::with_seed(9);
        let mut dimmed = 0;
        for depth in 0..=h.params.depths() + 1 {
            let indexed = SkyMarch::new(&h, depth, &fresh);
            let maps = SkyMarch::unindexed(&h, depth, &fresh);
            for _ in 0..2000 {
                let p = Vec3::new(
                    rng.f32() * 70.0 - 3.0,
                    rng.f32() * 12.0 - 1.0,
                    rng.f32() * 70.0 - 3.0,
                );
                let dir = Vec3::new(rng.f32() - 0.5, 0.05 + rng.f32(), rng.f32() - 0.5).normalize();
                let (a, b) = (indexed.to_sky(p, dir), maps.to_sky(p, dir));
                assert_eq!(a.to_bits(), b.to_bits(), "depth {depth}, {p} toward {dir}");
                dimmed += (a < 0.99) as u32;
            }
        }
        assert!(dimmed > 1000, "{dimmed} rays crossed the medium");
    }

    /// The march that stops once only clear air lies ahead (under every column's bound
    /// of the material it reads) gives the march to the end's transmittance bit for
    /// bit, over a layer and over columns of many heights, for suns high and low; and
    /// it does stop early (rays start clear of every bound ahead), and not only there
    /// (others start under one).
    #[test]
    fn the_march_ends_early_only_where_nothing_lies_ahead() {
        for h in [
            layer_hierarchy(0, false),
            crate::testing::built_over(Box::new(crate::testing::Columns), 2, false),
        ] {
            let fresh = Fresh::default();
            let mut rng = fastrand::Rng::with_seed(11);
            let (mut clear, mut blocked, mut dimmed) = (0, 0, 0);
            for depth in 0..=h.params.depths() + 1 {
                let early = SkyMarch::new(&h, depth, &fresh);
                let end = SkyMarch::to_the_end(&h, depth, &fresh);
                let tops = early
                    .tops
                    .as_ref()
                    .expect("bounds kept over the world grid");
                for _ in 0..2000 {
                    let p = Vec3::new(
                        rng.f32() * 70.0 - 3.0,
                        rng.f32() * 16.0 - 1.0,
                        rng.f32() * 70.0 - 3.0,
                    );
                    let up = 0.02 + rng.f32() * rng.f32();
                    let dir = Vec3::new(rng.f32() - 0.5, up, rng.f32() - 0.5).normalize();
                    let (a, b) = (early.to_sky(p, dir), end.to_sky(p, dir));
                    assert_eq!(a.to_bits(), b.to_bits(), "depth {depth}, {p} toward {dir}");
                    dimmed += (a < 0.99) as u32;
                    match tops.blocked_for(p, dir) {
                        None => clear += 1,
                        Some(_) => blocked += 1,
                    }
                }
            }
            assert!(dimmed > 1000, "{dimmed} rays crossed the medium");
            assert!(
                clear > 500 && blocked > 500,
                "{clear} clear, {blocked} blocked"
            );
        }
    }
}
