//! Model → material grid by ray queries against an obvhs BVH.
//!
//! **Pass-through.** Per cell, chords cross the cell the way isotropic light does:
//! `directions` stratified directions (a Fibonacci sphere), and per direction
//! `chords_per_direction` entry points spread uniformly over the cell's projected area
//! (a face is picked in proportion to its projected area, then a point on it, from a
//! low-discrepancy sequence). A chord is *blocked* when it meets a surface inside the cell
//! (alpha-masked texels let it through; alpha-blended ones block with probability alpha)
//! or when it lies inside a closed mesh. With `f` the fraction of chords not blocked, the
//! pass-through per cell length is `p = f^(3/2)`: the mean length of such chords in a cube
//! is `4V/S = 2h/3`, and `p` is defined for a path of length `h`.
//!
//! **Reflectance.** The mean surface colour at the blocking hits (base colour × texture,
//! linear), over the blocked chords; chords blocked by a closed mesh's inside take the
//! mesh's mean colour.
//!
//! **Solids.** Triangles are welded by position and split into connected components;
//! a component whose every edge is shared by an even number of its triangles is closed
//! (a trunk, a rock, a building) and its inside is solid. Inside-ness is decided by ray
//! parity (three directions, majority vote).
//!
//! **Cost.** A cell whose box overlaps no triangle's box (a BVH box query) casts no
//! chord: it is empty, or solid when it lies inside a closed mesh (three parity rays).

use std::collections::HashMap;
use std::time::{Duration, Instant};

use lightgrid_core::glam::{IVec3, UVec3, Vec3, Vec3A, Vec4};
use lightgrid_core::{GridDesc, GridError, Material, MaterialGrid};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::ray::{Ray, RayHit};
use rayon::prelude::*;

use crate::model::{AlphaMode, Model, ModelError};

/// Most chords a cell (`directions × chords_per_direction`): 256 times the reference
/// preset's 1024; more would run for hours and their product leaves `u32`.
pub const MAX_CHORDS: u64 = 1 << 18;

/// Voxelization parameters. Start from a preset and change fields.
#[derive(Debug, Clone, Copy)]
pub struct VoxelizeParams {
    /// Cell size, metres (the model grid's `h`).
    pub cell: f32,
    /// Chord directions per cell (stratified over the sphere).
    pub directions: u32,
    /// Chords per direction (stratified over the cell's projected area). Directions
    /// times chords per direction is at most [`MAX_CHORDS`].
    pub chords_per_direction: u32,
    /// Make the inside of closed meshes solid.
    pub fill_closed: bool,
    /// Empty cells added around the model's bounds on every side.
    pub padding: u32,
    /// Largest number of cells accepted (a typed error beyond).
    pub max_cells: u64,
    /// BVH build preset (any obvhs preset gives the same grid).
    pub bvh: BvhBuildParams,
}

impl VoxelizeParams {
    /// 64 chords a cell: quick previews.
    pub const fn preview(cell: f32) -> Self {
        Self {
            cell,
            directions: 16,
            chords_per_direction: 4,
            fill_closed: true,
            padding: 0,
            max_cells: 1 << 26,
            bvh: BvhBuildParams::fast_build(),
        }
    }
    /// 256 chords a cell: the default.
    pub const fn standard(cell: f32) -> Self {
        Self {
            cell,
            directions: 32,
            chords_per_direction: 8,
            fill_closed: true,
            padding: 0,
            max_cells: 1 << 26,
            bvh: BvhBuildParams::medium_build(),
        }
    }
    /// 1024 chords a cell: references.
    pub const fn fine(cell: f32) -> Self {
        Self {
            cell,
            directions: 64,
            chords_per_direction: 16,
            fill_closed: true,
            padding: 0,
            max_cells: 1 << 26,
            bvh: BvhBuildParams::medium_build(),
        }
    }

    /// Checks every field; errors name it.
    pub fn validate(&self) -> Result<(), GridError> {
        if !(self.cell.is_finite()
            && self.cell >= lightgrid_core::CELL_SIZE_RANGE.0
            && self.cell <= lightgrid_core::CELL_SIZE_RANGE.1)
        {
            return Err(GridError::invalid(
                "cell",
                self.cell,
                "cell size must be finite and within [1e-4, 1e5] metres",
            ));
        }
        if self.directions == 0 {
            return Err(GridError::invalid("directions", 0, "must be at least 1"));
        }
        if self.chords_per_direction == 0 {
            return Err(GridError::invalid(
                "chords_per_direction",
                0,
                "must be at least 1",
            ));
        }
        let chords = self.directions as u64 * self.chords_per_direction as u64;
        if chords > MAX_CHORDS {
            return Err(GridError::invalid(
                "chords_per_direction",
                (self.directions, self.chords_per_direction),
                "directions x chords_per_direction must be at most MAX_CHORDS (262144)",
            ));
        }
        Ok(())
    }
}

/// What a voxelization did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VoxelizeStats {
    /// Cells in the grid.
    pub cells: u64,
    /// Cells that cast chords (the others were ruled out by the box query).
    pub cells_traced: u64,
    /// Cells with material (`p < 1`).
    pub cells_filled: u64,
    /// Rays cast (chords and parity rays).
    pub rays: u64,
    /// Triangles in closed components.
    pub closed_triangles: u64,
    /// Time building the BVH.
    pub bvh_time: Duration,
    /// Total time.
    pub time: Duration,
}

/// A ray's first blocking surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray.
    pub t: f32,
    /// Surface colour (linear RGB, the diffuse albedo).
    pub colour: Vec3,
    /// Unit geometric normal, facing the ray's origin.
    pub normal: Vec3,
    /// Triangle index in the model.
    pub triangle: u32,
}

/// A model prepared for ray queries.
pub struct RayScene<'a> {
    model: &'a Model,
    bvh: Bvh2,
    tris: Vec<obvhs::triangle::Triangle>,
    /// Closed component id per triangle (`u32::MAX`: open).
    closed: Vec<u32>,
    /// Mean colour and bounds per closed component.
    solids: Vec<(Vec3, Vec3, Vec3)>,
}

fn a(v: Vec3) -> Vec3A {
    Vec3A::from(v)
}

impl<'a> RayScene<'a> {
    /// Builds the BVH and finds the closed components.
    pub fn new(model: &'a Model, bvh_params: BvhBuildParams) -> Self {
        let tris: Vec<obvhs::triangle::Triangle> = model
            .triangles
            .iter()
            .map(|t| obvhs::triangle::Triangle {
                v0: a(t.positions[0]),
                v1: a(t.positions[1]),
                v2: a(t.positions[2]),
            })
            .collect();
        let bvh =
            obvhs::bvh2::builder::build_bvh2_from_tris(&tris, bvh_params, &mut Duration::default());
        let (closed, solids) = closed_components(model);
        Self {
            model,
            bvh,
            tris,
            closed,
            solids,
        }
    }

    /// Möller–Trumbore: `(t, u, v)` of the hit of `ray` with triangle `i` in
    /// `(tmin, tmax)`, or `None`.
    fn hit(
        &self,
        i: usize,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        let t = &self.model.triangles[i].positions;
        let e1 = t[1] - t[0];
        let e2 = t[2] - t[0];
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let inv = 1.0 / det;
        let s = origin - t[0];
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(e1);
        let v = dir.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let d = e2.dot(q) * inv;
        (d > tmin && d < tmax).then_some((d, u, v))
    }

    /// Whether a hit on triangle `i` at `(u, v)` blocks light; `xi` in [0, 1) decides
    /// alpha-blended hits. Returns the surface colour when it does.
    fn blocks(&self, i: usize, u: f32, v: f32, xi: f32) -> Option<Vec3> {
        let tri = &self.model.triangles[i];
        let c: Vec4 = self.model.surface_at(tri, u, v);
        let pass = match self.model.materials[tri.material as usize].alpha {
            AlphaMode::Opaque => true,
            AlphaMode::Mask(cut) => c.w >= cut,
            AlphaMode::Blend => xi < c.w,
        };
        pass.then(|| c.truncate().clamp(Vec3::ZERO, Vec3::ONE))
    }

    /// The first blocking surface along `origin + t dir`, `t` in `(0, tmax)`: its colour.
    pub fn first_block(&self, origin: Vec3, dir: Vec3, tmax: f32, xi: f32) -> Option<Vec3> {
        self.closest_hit(origin, dir, tmax, xi).map(|h| h.colour)
    }

    /// The first blocking surface along `origin + t dir`, `t` in `(0, tmax)`: distance,
    /// colour and the triangle's normal turned to face the ray's origin.
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32, xi: f32) -> Option<Hit> {
        let ray = Ray::new(a(origin), a(dir), 0.0, tmax);
        let mut hit = RayHit::none();
        let mut best = None;
        let found = self.bvh.ray_traverse(ray, &mut hit, |r, id| {
            let tri = self.bvh.primitive_indices[id] as usize;
            match self.hit(tri, origin, dir, 0.0, r.tmax) {
                Some((t, u, v)) => match self.blocks(tri, u, v, xi) {
                    Some(c) => {
                        best = Some((t, c, tri));
                        t
                    }
                    None => f32::INFINITY,
                },
                None => f32::INFINITY,
            }
        });
        let (t, colour, tri) = best.filter(|_| found)?;
        let p = &self.model.triangles[tri].positions;
        let mut normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        if normal.dot(dir) > 0.0 {
            normal = -normal;
        }
        Some(Hit {
            t,
            colour,
            normal,
            triangle: tri as u32,
        })
    }

    /// Brute force over all triangles (no BVH): the reference for tests.
    pub fn first_block_brute(&self, origin: Vec3, dir: Vec3, tmax: f32, xi: f32) -> Option<Vec3> {
        let mut best = (tmax, None);
        for i in 0..self.model.triangles.len() {
            if let Some((t, u, v)) = self.hit(i, origin, dir, 0.0, best.0)
                && let Some(c) = self.blocks(i, u, v, xi)
            {
                best = (t, Some(c));
            }
        }
        best.1
    }

    /// Closed component containing `p` (odd crossings along `dir`), if any.
    fn inside_along(&self, p: Vec3, dir: Vec3) -> Option<u32> {
        let ray = Ray::new_inf(a(p), a(dir));
        let mut hits: Vec<(u32, u32)> = Vec::new();
        self.bvh.ray_traverse_anyhit(ray, |_, id| {
            let tri = self.bvh.primitive_indices[id];
            let comp = self.closed[tri as usize];
            if comp != u32::MAX && self.hit(tri as usize, p, dir, 0.0, f32::INFINITY).is_some() {
                hits.push((comp, tri));
            }
        });
        hits.sort_unstable();
        hits.dedup(); // pre-split BVHs list a triangle in several leaves
        let mut counts: HashMap<u32, u32> = HashMap::new();
        for (c, _) in hits {
            *counts.entry(c).or_default() += 1;
        }
        counts
            .into_iter()
            .filter(|(_, n)| n % 2 == 1)
            .map(|(c, _)| c)
            .min()
    }

    /// Closed component containing `p` by a majority of three parity rays.
    pub fn inside(&self, p: Vec3) -> Option<u32> {
        const DIRS: [Vec3; 3] = [
            Vec3::new(0.577_350_3, 0.577_350_3, 0.577_350_3),
            Vec3::new(-0.267_261_24, 0.534_522_5, -0.801_783_7),
            Vec3::new(0.872_871_6, -0.218_217_9, -0.436_435_8),
        ];
        let votes: Vec<Option<u32>> = DIRS.iter().map(|d| self.inside_along(p, *d)).collect();
        for v in &votes {
            if v.is_some() && votes.iter().filter(|w| *w == v).count() >= 2 {
                return *v;
            }
        }
        None
    }

    /// True when any triangle's box overlaps the box `[lo, hi]`.
    fn near_triangles(&self, lo: Vec3, hi: Vec3) -> bool {
        let query = Aabb::new(a(lo), a(hi));
        let mut found = false;
        self.bvh.aabb_traverse(query, |bvh, node| {
            let n = &bvh.nodes[node as usize];
            if n.is_leaf() {
                for k in n.first_index..n.first_index + n.prim_count {
                    let tri = &self.tris[bvh.primitive_indices[k as usize] as usize];
                    if tri.aabb().intersect_aabb(&query) {
                        found = true;
                        return false;
                    }
                }
            }
            true
        });
        found
    }
}

/// Welds vertices, splits triangles into connected components, and marks the closed
/// ones: `(component id per triangle or u32::MAX, (mean colour, min, max) per closed
/// component)`.
fn closed_components(model: &Model) -> (Vec<u32>, Vec<(Vec3, Vec3, Vec3)>) {
    let n = model.triangles.len();
    let Some((lo, hi)) = model.bounds() else {
        return (Vec::new(), Vec::new());
    };
    let scale = (hi - lo).max_element().max(1e-6) * 1e-5;
    let key = |p: Vec3| ((p - lo) / scale).round().as_ivec3();
    let mut ids: HashMap<IVec3, u32> = HashMap::new();
    let tri_verts: Vec<[u32; 3]> = model
        .triangles
        .iter()
        .map(|t| {
            t.positions.map(|p| {
                let len = ids.len() as u32;
                *ids.entry(key(p)).or_insert(len)
            })
        })
        .collect();
    // Union-find over vertices.
    let mut parent: Vec<u32> = (0..ids.len() as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for v in &tri_verts {
        for k in 1..3 {
            let (ra, rb) = (find(&mut parent, v[0]), find(&mut parent, v[k]));
            if ra != rb {
                parent[ra as usize] = rb;
            }
        }
    }
    let comp: Vec<u32> = tri_verts.iter().map(|v| find(&mut parent, v[0])).collect();
    // Edge counts per component.
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for v in &tri_verts {
        for (x, y) in [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])] {
            if x != y {
                *edges.entry((x.min(y), x.max(y))).or_default() += 1;
            }
        }
    }
    let mut open_comp: HashMap<u32, bool> = HashMap::new();
    for (i, v) in tri_verts.iter().enumerate() {
        let c = comp[i];
        let open = [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])]
            .iter()
            .any(|&(x, y)| x == y || edges[&(x.min(y), x.max(y))] % 2 == 1);
        *open_comp.entry(c).or_default() |= open;
    }
    let mut index: HashMap<u32, u32> = HashMap::new();
    let mut solids: Vec<(Vec3, f32, Vec3, Vec3)> = Vec::new();
    let mut out = vec![u32::MAX; n];
    for i in 0..n {
        let c = comp[i];
        if open_comp[&c] {
            continue;
        }
        let id = *index.entry(c).or_insert_with(|| {
            solids.push((
                Vec3::ZERO,
                0.0,
                Vec3::splat(f32::INFINITY),
                Vec3::splat(f32::NEG_INFINITY),
            ));
            solids.len() as u32 - 1
        });
        out[i] = id;
        let t = &model.triangles[i];
        let area = (t.positions[1] - t.positions[0])
            .cross(t.positions[2] - t.positions[0])
            .length()
            * 0.5;
        let colour = model.surface_at(t, 1.0 / 3.0, 1.0 / 3.0).truncate();
        let s = &mut solids[id as usize];
        s.0 += colour * area;
        s.1 += area;
        for p in t.positions {
            s.2 = s.2.min(p);
            s.3 = s.3.max(p);
        }
    }
    let solids = solids
        .into_iter()
        .map(|(c, w, lo, hi)| ((c / w.max(1e-30)).clamp(Vec3::ZERO, Vec3::ONE), lo, hi))
        .collect();
    (out, solids)
}

/// The `k`-th point of the R2 low-discrepancy sequence in [0, 1)².
fn r2(k: u32, offset: f32) -> (f32, f32) {
    const A1: f64 = 0.754_877_666_246_692_8;
    const A2: f64 = 0.569_840_290_998_053_3;
    let x = (offset as f64 + A1 * (k as f64 + 1.0)).fract();
    let y = (offset as f64 * 0.5 + A2 * (k as f64 + 1.0)).fract();
    (x as f32, y as f32)
}

/// Voxelizes `model` into a material grid covering its bounds. `progress(done, total)`
/// is called as rows of cells finish.
pub fn voxelize(
    model: &Model,
    params: &VoxelizeParams,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(MaterialGrid, VoxelizeStats), ModelError> {
    params.validate()?;
    model.validate()?;
    let _span = tracing::info_span!("voxelize", cell = params.cell).entered();
    let start = Instant::now();
    let (lo, hi) = model
        .bounds()
        .ok_or_else(|| GridError::invalid("model", "no triangles", "has nothing to voxelize"))?;
    let (desc, cells) = grid_around(lo, hi, params)?;
    let dims = desc.dims();
    let t_bvh = Instant::now();
    let scene = RayScene::new(model, params.bvh);
    let bvh_time = t_bvh.elapsed();
    let directions = fibonacci_directions(params.directions);
    let done = std::sync::atomic::AtomicU64::new(0);
    let rows = (dims.y * dims.z) as usize;
    let nx = dims.x as usize;
    let mut out = vec![Material::EMPTY; desc.point_count()];
    let counters: Vec<(u64, u64)> = out
        .par_chunks_mut(nx)
        .enumerate()
        .map(|(row, row_cells)| {
            let (z, y) = (
                (row % dims.z as usize) as u32,
                (row / dims.z as usize) as u32,
            );
            // Cells traced, rays cast.
            let mut counts = (0u64, 0u64);
            for (x, cell) in row_cells.iter_mut().enumerate() {
                let c = UVec3::new(x as u32, y, z);
                *cell = cell_material(&scene, params, &directions, (&desc, c), &mut counts);
            }
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(d, rows as u64);
            counts
        })
        .collect();
    let stats = VoxelizeStats {
        cells,
        cells_traced: counters.iter().map(|c| c.0).sum(),
        cells_filled: out.iter().filter(|m| !m.is_empty()).count() as u64,
        rays: counters.iter().map(|c| c.1).sum(),
        closed_triangles: scene.closed.iter().filter(|&&c| c != u32::MAX).count() as u64,
        bvh_time,
        time: start.elapsed(),
    };
    Ok((MaterialGrid::new(desc, out)?, stats))
}

/// The grid of cells `params.cell` around a model's bounds `lo..hi`, with the padding,
/// centred on the model (cell (0,0,0) starts at the low corner), and its cell count;
/// an error past `max_cells` or the memory limit.
fn grid_around(lo: Vec3, hi: Vec3, params: &VoxelizeParams) -> Result<(GridDesc, u64), ModelError> {
    let h = params.cell;
    // In u64 with checked products: padding near 2^31 or a tiny cell must be an error,
    // not a wrapped size.
    let span = ((hi - lo) / h)
        .ceil()
        .as_dvec3()
        .max(lightgrid_core::glam::DVec3::ONE);
    let pad = 2.0 * params.padding as f64;
    let dims_f = span + lightgrid_core::glam::DVec3::splat(pad);
    let cells_f = dims_f.x * dims_f.y * dims_f.z;
    if cells_f.is_nan() || cells_f > params.max_cells as f64 {
        return Err(GridError::invalid(
            "cell",
            h,
            "gives more cells than max_cells (with the padding)",
        )
        .into());
    }
    let dims = dims_f.as_uvec3();
    let cells = dims.x as u64 * dims.y as u64 * dims.z as u64;
    lightgrid_core::limits::check_memory(
        &format!("a model grid of {dims} cells"),
        (cells_f as u64).saturating_mul(std::mem::size_of::<Material>() as u64),
    )?;
    let origin = (lo + hi) * 0.5 - (dims.as_vec3() - Vec3::ONE) * (0.5 * h);
    Ok((GridDesc::new(origin, h, dims)?, cells))
}

/// The material of cell `c`: empty away from triangles (or inside a closed solid's
/// volume where `fill_closed`), else from the chords through it, `chords_per_direction`
/// along each of `directions`: its pass-through from the share blocked, its colour
/// the mean of what blocked them. `counts`: cells traced and rays cast, added to.
#[inline]
fn cell_material(
    scene: &RayScene<'_>,
    params: &VoxelizeParams,
    directions: &[Vec3],
    (desc, c): (&GridDesc, UVec3),
    counts: &mut (u64, u64),
) -> Material {
    let h = params.cell;
    let centre = desc.position(c);
    let half = Vec3::splat(h * 0.5);
    let (clo, chi) = (centre - half, centre + half);
    let near = scene.near_triangles(clo - half * 1e-3, chi + half * 1e-3);
    if !near {
        if params.fill_closed
            && scene
                .solids
                .iter()
                .any(|s| centre.cmpge(s.1).all() && centre.cmple(s.2).all())
        {
            counts.1 += 3;
            if let Some(s) = scene.inside(centre) {
                return Material::opaque(scene.solids[s as usize].0);
            }
        }
        return Material::EMPTY;
    }
    counts.0 += 1;
    let n_chords = params.directions * params.chords_per_direction;
    let mut blocked = 0u32;
    let mut colour = Vec3::ZERO;
    let seed = (c.x.wrapping_mul(73_856_093)
        ^ c.y.wrapping_mul(19_349_663)
        ^ c.z.wrapping_mul(83_492_791)) as f32
        / u32::MAX as f32;
    for (di, &d) in directions.iter().enumerate() {
        for k in 0..params.chords_per_direction {
            let idx = di as u32 * params.chords_per_direction + k;
            let (p, len) = chord_start((clo, chi, h), d, r2(idx, seed));
            counts.1 += 1;
            let xi = ((idx as f32 + 0.5) / n_chords as f32 + seed).fract();
            if let Some(c) = scene.first_block(p, d, len, xi) {
                blocked += 1;
                colour += c;
            } else if params.fill_closed && !scene.solids.is_empty() {
                let mid = p + d * (len * 0.5);
                if scene
                    .solids
                    .iter()
                    .any(|s| mid.cmpge(s.1).all() && mid.cmple(s.2).all())
                {
                    counts.1 += 1;
                    if let Some(c) = scene.inside_along(mid, d) {
                        blocked += 1;
                        colour += scene.solids[c as usize].0;
                    }
                }
            }
        }
    }
    if blocked == 0 {
        return Material::EMPTY;
    }
    let f = 1.0 - blocked as f32 / n_chords as f32;
    Material {
        reflectance: (colour / blocked as f32).clamp(Vec3::ZERO, Vec3::ONE),
        pass: f.powf(1.5).clamp(0.0, 1.0),
    }
}

/// Where a chord along `d` enters the cell `clo..chi` (side `h`), and its length to the
/// cell's exit: on a face facing `-d`, the face picked by its projected area `|d_axis|`
/// and the point on it by `(s, t)` (a low-discrepancy pair).
#[inline]
fn chord_start((clo, chi, h): (Vec3, Vec3, f32), d: Vec3, (s, t): (f32, f32)) -> (Vec3, f32) {
    let w = d.abs();
    let wsum = w.element_sum();
    let pick = s * wsum;
    let axis = if pick < w.x {
        0
    } else if pick < w.x + w.y {
        1
    } else {
        2
    };
    let frac = match axis {
        0 => pick / w.x.max(1e-12),
        1 => (pick - w.x) / w.y.max(1e-12),
        _ => (pick - w.x - w.y) / w.z.max(1e-12),
    }
    .clamp(0.0, 1.0);
    let mut p = clo;
    let (u_ax, v_ax) = ((axis + 1) % 3, (axis + 2) % 3);
    p[u_ax] = clo[u_ax] + h * frac;
    p[v_ax] = clo[v_ax] + h * t;
    p[axis] = if d[axis] > 0.0 { clo[axis] } else { chi[axis] };
    // Chord length to the exit of the cell.
    (p, lightgrid_core::dda::box_exit(p, d, clo, chi))
}

/// `n` nearly uniform unit vectors (Fibonacci sphere).
fn fibonacci_directions(n: u32) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let phi = golden * i as f32;
            Vec3::new(r * phi.cos(), y, r * phi.sin())
        })
        .collect()
}
