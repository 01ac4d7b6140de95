//! Area composition: the material grid of a light grid's box, from a terrain heightmap
//! with a ground colour and from instances of model material grids.
//!
//! **Per area cell** (centre `c`, size `h`), on `k³` sample points spread over the cell
//! (`k = ceil(h / finest model cell)` of the instances overlapping the cell, model cell
//! times scale, at most [`ComposeParams::max_samples_per_axis`]; one where none does: a
//! cell is composed from its own box, whatever else the area holds):
//!
//! * *Objects.* Each instance overlapping the sample maps it into model space
//!   (`m = R⁻¹ (c - position) / scale`) and samples its model grid trilinearly (outside
//!   the model grid: empty). The model's pass-through is per model cell length
//!   `h_m · scale`; over the area cell's length it is `p^(h / (h_m · scale))`.
//!   Overlapping objects multiply their pass-through; their reflectances are weighted by
//!   what each blocks (`1 - p`).
//! * *Ground.* With `g` the terrain height at the sample's `(x, z)` lowered by
//!   [`ComposeParams::ground_bias`], the ground covers the sample by
//!   `w = clamp((g - y) / band + 1/2, 0, 1)` (a linear transition over
//!   [`ComposeParams::ground_band`] metres): pass-through `1 - w`, colour the ground's.
//!   Seed 000 explains the bias: interpolated light at hilltops would otherwise be
//!   shadowed by ground cells that are barely underground.
//!
//! The cell's pass-through is the mean of its samples' and its reflectance the mean of
//! their blocking-weighted colours (the ground's colour, or in cells it covers in part
//! the albedo [`ComposeParams::band_albedo`] gives it). For a homogeneous model this is exact:
//! composing at `2h` gives the square of the pass-through at `h`.
//!
//! **Cost.** Instances are binned into square tiles by their world bounds (seed 000's
//! per-thread-group object lists), so an area only looks at the instances of the tiles it
//! overlaps: the cost follows the objects near it, not the world's. Within a cell, an
//! instance whose lookups there all land in clear cubes of its model (air: eight clear
//! corners, which read as pass-through 1) is left out before its samples are taken; a
//! summed-volume table of each model's clear cubes answers that for the cell's whole
//! box at once. Most of a tree's box is air.

use std::collections::HashMap;
use std::path::Path;

use lightgrid_core::glam::{IVec2, Quat, UVec3, Vec2, Vec3};
pub use lightgrid_core::terrain::{Heightmap, MAX_HEIGHTMAP_SAMPLES};
use lightgrid_core::{GridDesc, GridError, Material, MaterialGrid, MaterialSource};

/// Largest heightmap PNG read: 1 GiB.
pub const MAX_HEIGHTMAP_FILE_BYTES: u64 = 1 << 30;

use crate::model::Texture;

/// Decodes an image whose sides are at most `max_side`, refusing before decoding one
/// whose `bytes_per_texel` × texels would pass the memory limit. Panics of the decoder
/// become errors.
pub fn decode_limited(
    bytes: &[u8],
    max_side: u32,
    bytes_per_texel: u64,
) -> Result<image::DynamicImage, String> {
    let open = || {
        image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| e.to_string())
    };
    let run = |f: &dyn Fn() -> Result<image::DynamicImage, String>| {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
            .unwrap_or_else(|_| Err("malformed image (the decoder failed on it)".to_string()))
    };
    run(&|| {
        let (w, h) = open()?
            .into_dimensions()
            .map_err(|e| format!("cannot read the image size: {e}"))?;
        if w == 0 || h == 0 || w > max_side || h > max_side {
            return Err(format!(
                "{w} x {h} pixels (each side must be in 1..={max_side})"
            ));
        }
        let need = w as u64 * h as u64 * bytes_per_texel;
        lightgrid_core::limits::check_memory(&format!("a {w} x {h} image"), need)
            .map_err(|e| e.to_string())?;
        let mut reader = open()?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(max_side);
        limits.max_image_height = Some(max_side);
        limits.max_alloc = Some(need.max(1 << 20));
        reader.limits(limits);
        reader.decode().map_err(|e| e.to_string())
    })
}

/// Loads a 16-bit (or 8-bit) greyscale PNG: height = `offset + scale × value`, row 0
/// at `z = origin.y`. Errors name the file.
pub fn load_heightmap_png(
    path: impl AsRef<Path>,
    origin: Vec2,
    spacing: f32,
    scale: f32,
    offset: f32,
) -> Result<Heightmap, GridError> {
    let path = path.as_ref();
    let bytes = lightgrid_core::limits::read_file(path, MAX_HEIGHTMAP_FILE_BYTES)?;
    let img = decode_limited(&bytes, 1 << 16, 8).map_err(|e| GridError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
    })?;
    let luma = img.into_luma16();
    let (w, d) = luma.dimensions();
    let heights = luma
        .pixels()
        .map(|p| offset + scale * p.0[0] as f32)
        .collect();
    Heightmap::new(origin, spacing, w, d, heights)
}

/// The ground's colour: uniform, or a texture stretched over a world rectangle.
#[derive(Debug, Clone, PartialEq)]
pub enum GroundColour {
    /// One linear RGB colour.
    Uniform(Vec3),
    /// A texture over the rectangle `origin .. origin + size` in world `(x, z)`.
    Texture {
        /// The texture (linear).
        texture: Texture,
        /// World `(x, z)` of the texture's top-left corner.
        origin: Vec2,
        /// World size of the texture.
        size: Vec2,
    },
}

impl GroundColour {
    fn at(&self, x: f32, z: f32) -> Vec3 {
        match self {
            GroundColour::Uniform(c) => *c,
            GroundColour::Texture {
                texture,
                origin,
                size,
            } => {
                let uv = (Vec2::new(x, z) - *origin) / *size;
                texture
                    .sample(uv.clamp(Vec2::ZERO, Vec2::ONE))
                    .truncate()
                    .clamp(Vec3::ZERO, Vec3::ONE)
            }
        }
    }
}

/// Terrain: a heightmap and its colour.
#[derive(Debug, Clone, PartialEq)]
pub struct Terrain {
    /// Heights.
    pub heightmap: Heightmap,
    /// Colour of the ground.
    pub colour: GroundColour,
}

/// One placed model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instance {
    /// Index into the composer's models.
    pub model: u32,
    /// World position of the model's origin.
    pub position: Vec3,
    /// Rotation (about any axis).
    pub rotation: Quat,
    /// Uniform scale (> 0).
    pub scale: f32,
}

/// Composition parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComposeParams {
    /// Width of the ground's linear transition, metres.
    pub ground_band: f32,
    /// How far the ground is lowered, metres.
    pub ground_bias: f32,
    /// What the cells the ground covers in part scatter ([`GroundBand`]).
    pub band_albedo: GroundBand,
    /// Side of the square tiles instances are binned into, metres.
    pub tile: f32,
    /// Most sample points per axis within one area cell.
    pub max_samples_per_axis: u32,
}

impl Default for ComposeParams {
    fn default() -> Self {
        Self {
            ground_band: 1.0,
            ground_bias: 0.25,
            band_albedo: GroundBand::Reflecting,
            tile: 16.0,
            max_samples_per_axis: 4,
        }
    }
}

/// The albedo of the cells the ground covers in part ([`ComposeParams::band_albedo`]):
/// the sweeps read such a cell as a medium (pass-through `1 - w`), and a medium whose
/// albedo is the ground's colour `a` reflects far less than a surface of that colour
/// (a half-space of isotropic scatterers of albedo 0.2 reflects about a fifth of what
/// the surface does), and over the ground's opaque cells it also darkens what they
/// reflect. Over flat ground of colour 0.2 under a uniform sky, a surface facing down
/// above it receives 25–100 % of the exact `a π` with `Colour` and 89–100 % with
/// `Reflecting` (the default), depending on where the surface falls in a cell, at
/// cells of 0.5–4 m (`cargo run --release -p lightgrid-terrain-lod --example
/// ground_band`). Over a slope both reflect less: `Reflecting` 83–88 % of a plane rising
/// 1 in 5 at 0.5 m cells, and the light it sends near the horizon changes with the
/// cell size (`--example slope_horizon`).
/// Opaque cells (wholly under the band) are surfaces and keep the ground's colour
/// either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GroundBand {
    /// The ground's colour, as composed before `Reflecting` (its defect above).
    Colour,
    /// The albedo `w = 1 - ((1 - a) / (1 + a))^2` per channel, whose half-space
    /// reflects `a` (Kubelka–Munk's `R_inf`, Hapke's diffusive reflectance): a layer of
    /// it over ground that reflects `a` reflects `a` whatever its depth (Kubelka–Munk),
    /// so the reflected sky is near right wherever the surface falls in a cell (an
    /// isotropic medium's radiative transfer is not the two-stream one: up to 11 %
    /// short, in Monte Carlo of the same material too). A medium's
    /// reflection is not Lambertian in angle: the reflected direct sun reads 0.75–1.00
    /// of the exact at a 60° sun and 1.00–1.18 at 15° (against 0.20–1.00 and 0.33–1.00
    /// with `Colour`). The default.
    #[default]
    Reflecting,
}

impl GroundBand {
    /// The albedo of a partly covered ground cell for a ground of colour `a`.
    #[inline]
    pub fn albedo(self, a: Vec3) -> Vec3 {
        match self {
            GroundBand::Colour => a,
            GroundBand::Reflecting => {
                let a = a.clamp(Vec3::ZERO, Vec3::ONE);
                let g = (Vec3::ONE - a) / (Vec3::ONE + a);
                Vec3::ONE - g * g
            }
        }
    }
}

/// Counters of one composition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ComposeStats {
    /// Instances in the tiles the area overlaps (what the area looked at).
    pub candidates: u64,
    /// Instances whose bounds overlap the area.
    pub overlapping: u64,
}

/// A composing thread's scratch: the instances overlapping a cell.
#[derive(Default)]
struct Scratch<'a> {
    local: Vec<&'a Sampling<'a>>,
    /// The local instances within reach: a cell's centre in the model's space, and
    /// the instance's index in `local`.
    centres: Vec<(Vec3, usize)>,
    /// The samples of the cell being composed, and a copy of them before the ground
    /// ([`sample_cell`]).
    samples: [Vec<SampleState>; 2],
}

/// One candidate instance as a composition samples it: its model, the model-space
/// position of a cell's centre (`to_model`), the model-space offsets of the cell's
/// `k³` sample points from it, and the exponent that turns the model's transmittance
/// over its voxel into the area cell's.
struct Sampling<'a> {
    placed: &'a Placed,
    model: &'a MaterialGrid,
    /// The model's [`clear_cubes`].
    clear: &'a ClearCubes,
    bounds: (Vec3, Vec3),
    /// For `k` samples a side (`offsets[k - 1]`), `inv_rot * (o - 0.5) h / scale` of
    /// each sample offset `o` (x fastest).
    offsets: Vec<Vec<Vec3>>,
    /// For `k` samples a side, the largest `|offset|` per axis: a cell whose centre
    /// lies farther than this outside `bounds` has no sample inside the model.
    reach: Vec<Vec3>,
    ratio: f32,
    /// The model's cell times the instance's scale: the samples a side a cell it
    /// overlaps asks (`ceil(h / cell)`).
    cell: f32,
}

impl<'a> Sampling<'a> {
    /// The instance sampled in cells of size `h`, with up to `max_k` samples a side.
    fn new(
        placed: &'a Placed,
        (model, clear): (&'a MaterialGrid, &'a ClearCubes),
        h: f32,
        max_k: u32,
    ) -> Self {
        let inv_scale = 1.0 / placed.inst.scale;
        let cell = model.desc().h() * placed.inst.scale;
        let offsets: Vec<Vec<Vec3>> = (1..=max_k.max(1))
            .map(|k| {
                (0..k * k * k)
                    .map(|s| {
                        let o = UVec3::new(s % k, (s / k) % k, s / (k * k)).as_vec3();
                        placed.inv_rot * (((o + 0.5) / k as f32 - 0.5) * h) * inv_scale
                    })
                    .collect()
            })
            .collect();
        let reach = offsets
            .iter()
            .map(|o| o.iter().fold(Vec3::ZERO, |r, o| r.max(o.abs())))
            .collect();
        Self {
            placed,
            model,
            clear,
            bounds: model.desc().cell_bounds(),
            offsets,
            reach,
            ratio: h / cell,
            cell,
        }
    }

    /// The offsets of `k` samples a side (at most the `max_k` it was made for).
    #[inline]
    fn offsets(&self, k: u32) -> &[Vec3] {
        &self.offsets[k as usize - 1]
    }

    /// Model-space position of world point `p`.
    #[inline]
    fn to_model(&self, p: Vec3) -> Vec3 {
        self.placed.inv_rot * (p - self.placed.inst.position) / self.placed.inst.scale
    }

    /// The model's material at model-space `p` (`MaterialGrid::sample`, bit for bit),
    /// or `None` where it is clear (pass-through 1). A lookup whose eight corners are
    /// all clear ([`clear_cubes`]) is clear: most of a tree's box is air. (Sampled, its
    /// weights could sum to 1 − 2⁻²⁴ and read a pass-through a rounding below 1.)
    #[inline]
    fn read(&self, p: Vec3) -> Option<Material> {
        if !p.is_finite() {
            return None;
        }
        let d = self.model.desc();
        let lookup = lightgrid_core::trilinear_indices(d.dims(), d.to_grid(p));
        if self.clear.cube[lookup.0[0]] {
            return None;
        }
        let m = self.model.blend(lookup);
        (m.pass < 1.0).then_some(m)
    }

    /// Whether every read within `reach` of model-space `c` (the samples of a cell whose
    /// centre maps to `c`) is clear: their lookups' base points all lie in the box of
    /// those of `c ± reach` (the base is monotonic in the position), and it holds clear
    /// cubes only. Then the instance adds nothing to the cell and is left out.
    #[inline]
    fn clear_around(&self, c: Vec3, k: u32) -> bool {
        if !c.is_finite() {
            return false;
        }
        let d = self.model.desc();
        let reach = self.reach[k as usize - 1];
        let lo = lightgrid_core::trilinear_base(d.dims(), d.to_grid(c - reach));
        let hi = lightgrid_core::trilinear_base(d.dims(), d.to_grid(c + reach));
        self.clear.none_blocked(lo, hi)
    }
}

/// A model's [`clear_cubes`], and the count of cubes that are not clear in every box
/// from the origin (a summed-volume table), for [`ClearCubes::none_blocked`].
struct ClearCubes {
    cube: Vec<bool>,
    /// `(nx + 1) × (ny + 1) × (nz + 1)`, x fastest then z: the cubes not clear with
    /// coordinates below `(x, y, z)`.
    blocked: Vec<u32>,
    dims: UVec3,
}

impl ClearCubes {
    fn new(m: &MaterialGrid) -> Self {
        let cube = clear_cubes(m);
        let dims = m.desc().dims();
        let (nx, nz) = (dims.x as usize + 1, dims.z as usize + 1);
        let mut blocked = vec![0u32; nx * nz * (dims.y as usize + 1)];
        let at = |x: usize, y: usize, z: usize| x + nx * (z + nz * y);
        for y in 1..=dims.y as usize {
            for z in 1..=dims.z as usize {
                for x in 1..=dims.x as usize {
                    let i = m.desc().index_unchecked(UVec3::new(
                        x as u32 - 1,
                        y as u32 - 1,
                        z as u32 - 1,
                    ));
                    blocked[at(x, y, z)] = u32::from(!cube[i])
                        + blocked[at(x - 1, y, z)]
                        + blocked[at(x, y - 1, z)]
                        + blocked[at(x, y, z - 1)]
                        + blocked[at(x - 1, y - 1, z - 1)]
                        - blocked[at(x - 1, y - 1, z)]
                        - blocked[at(x - 1, y, z - 1)]
                        - blocked[at(x, y - 1, z - 1)];
                }
            }
        }
        Self {
            cube,
            blocked,
            dims,
        }
    }

    /// Whether every cube with base point in `lo..=hi` (each axis) is clear.
    fn none_blocked(&self, lo: UVec3, hi: UVec3) -> bool {
        let (nx, nz) = (self.dims.x as usize + 1, self.dims.z as usize + 1);
        let at =
            |x: u32, y: u32, z: u32| self.blocked[x as usize + nx * (z as usize + nz * y as usize)];
        let (a, b) = (lo, hi + UVec3::ONE);
        let n = at(b.x, b.y, b.z) + at(a.x, a.y, b.z) + at(a.x, b.y, a.z) + at(b.x, a.y, a.z)
            - at(a.x, b.y, b.z)
            - at(b.x, a.y, b.z)
            - at(b.x, b.y, a.z)
            - at(a.x, a.y, a.z);
        n == 0
    }
}

/// Per point of a model grid: whether the trilinear lookups based at it (it and the
/// points one step up each axis, clamped into the grid) read only clear cells
/// (pass-through exactly 1).
fn clear_cubes(m: &MaterialGrid) -> Vec<bool> {
    let d = m.desc();
    let top = d.dims().saturating_sub(UVec3::ONE);
    (0..d.point_count())
        .map(|i| {
            let q = d.coords(i).expect("index in range");
            let hi = (q + UVec3::ONE).min(top);
            (q.y..=hi.y).all(|y| {
                (q.z..=hi.z).all(|z| {
                    (q.x..=hi.x)
                        .all(|x| m.data()[d.index_unchecked(UVec3::new(x, y, z))].pass == 1.0)
                })
            })
        })
        .collect()
}

struct Placed {
    inst: Instance,
    inv_rot: Quat,
    lo: Vec3,
    hi: Vec3,
}

/// Composes area material grids from a terrain and instances of model grids; implements
/// [`MaterialSource`].
pub struct AreaComposer {
    models: Vec<MaterialGrid>,
    /// Each model's [`ClearCubes`].
    clear: Vec<ClearCubes>,
    placed: Vec<Placed>,
    tiles: HashMap<IVec2, Vec<u32>>,
    /// Instances covering more than [`MAX_TILES_PER_INSTANCE`] tiles, not binned.
    large: Vec<u32>,
    terrain: Option<Terrain>,
    /// The terrain's highest height (worked out once: a pass over the heights).
    ground_top: Option<f32>,
    params: ComposeParams,
}

/// Most tiles one instance is binned into; larger instances are checked by every area.
pub const MAX_TILES_PER_INSTANCE: u64 = 4096;
/// Most (tile, instance) entries of one composer.
pub const MAX_TILE_ENTRIES: u64 = 1 << 26;

impl AreaComposer {
    /// Validates the instances (model index, finite transform, scale > 0) and bins them.
    pub fn new(
        models: Vec<MaterialGrid>,
        instances: &[Instance],
        terrain: Option<Terrain>,
        params: ComposeParams,
    ) -> Result<Self, GridError> {
        if !(params.tile.is_finite() && params.tile > 0.0) {
            return Err(GridError::invalid(
                "tile",
                params.tile,
                "must be finite and > 0",
            ));
        }
        if !(params.ground_band.is_finite() && params.ground_band > 0.0) {
            return Err(GridError::invalid(
                "ground_band",
                params.ground_band,
                "must be finite and > 0",
            ));
        }
        if !params.ground_bias.is_finite() {
            return Err(GridError::invalid(
                "ground_bias",
                params.ground_bias,
                "must be finite",
            ));
        }
        if params.max_samples_per_axis == 0 {
            return Err(GridError::invalid(
                "max_samples_per_axis",
                0,
                "must be at least 1",
            ));
        }
        lightgrid_core::limits::check_memory(
            &format!("{} instances", instances.len()),
            instances.len() as u64 * std::mem::size_of::<Placed>() as u64 * 2,
        )?;
        let mut placed = Vec::with_capacity(instances.len());
        let mut tiles: HashMap<IVec2, Vec<u32>> = HashMap::new();
        let mut large: Vec<u32> = Vec::new();
        let mut tile_entries = 0u64;
        for (i, inst) in instances.iter().enumerate() {
            let field = |f: &str| format!("instances[{i}].{f}");
            let Some(model) = models.get(inst.model as usize) else {
                return Err(GridError::invalid(
                    field("model"),
                    inst.model,
                    "no such model",
                ));
            };
            if !inst.position.is_finite() {
                return Err(GridError::invalid(
                    field("position"),
                    inst.position,
                    "must be finite",
                ));
            }
            if !(inst.rotation.is_finite() && (inst.rotation.length() - 1.0).abs() < 1e-3) {
                return Err(GridError::invalid(
                    field("rotation"),
                    inst.rotation,
                    "must be a unit quaternion",
                ));
            }
            if !(inst.scale.is_finite() && inst.scale > 0.0) {
                return Err(GridError::invalid(
                    field("scale"),
                    inst.scale,
                    "must be finite and > 0",
                ));
            }
            let (mlo, mhi) = model.desc().cell_bounds();
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for c in 0..8 {
                let corner = Vec3::new(
                    if c & 1 != 0 { mhi.x } else { mlo.x },
                    if c & 2 != 0 { mhi.y } else { mlo.y },
                    if c & 4 != 0 { mhi.z } else { mlo.z },
                );
                let w = inst.position + inst.rotation * (corner * inst.scale);
                lo = lo.min(w);
                hi = hi.max(w);
            }
            let t0 = (Vec2::new(lo.x, lo.z) / params.tile).floor().as_ivec2();
            let t1 = (Vec2::new(hi.x, hi.z) / params.tile).floor().as_ivec2();
            let covered =
                (t1.x as i64 - t0.x as i64 + 1) as u64 * (t1.y as i64 - t0.y as i64 + 1) as u64;
            if covered > MAX_TILES_PER_INSTANCE {
                // A huge instance (or tiny tiles) would add one entry per tile: keep it in
                // one list that every area checks by its bounds instead.
                large.push(i as u32);
            } else {
                tile_entries += covered;
                if tile_entries > MAX_TILE_ENTRIES {
                    return Err(GridError::invalid(
                        "tile",
                        params.tile,
                        "instances cover more than 2^26 tile entries: use larger tiles",
                    ));
                }
                for tz in t0.y..=t1.y {
                    for tx in t0.x..=t1.x {
                        tiles.entry(IVec2::new(tx, tz)).or_default().push(i as u32);
                    }
                }
            }
            placed.push(Placed {
                inst: *inst,
                inv_rot: inst.rotation.inverse(),
                lo,
                hi,
            });
        }
        Ok(Self {
            clear: models.iter().map(ClearCubes::new).collect(),
            models,
            placed,
            tiles,
            large,
            ground_top: terrain.as_ref().map(|t| t.heightmap.range().1),
            terrain,
            params,
        })
    }

    /// The instances whose bounds overlap the box `alo..ahi`, sorted, found through the
    /// tiles the box covers; and how many the tiles held (before the overlap test).
    fn candidates(&self, alo: Vec3, ahi: Vec3) -> (Vec<u32>, u64) {
        // Instances in the tiles the area overlaps.
        let t0 = (Vec2::new(alo.x, alo.z) / self.params.tile)
            .floor()
            .as_ivec2();
        let t1 = (Vec2::new(ahi.x, ahi.z) / self.params.tile)
            .floor()
            .as_ivec2();
        let mut cand: Vec<u32> = self.large.clone();
        let area_tiles =
            (t1.x as i64 - t0.x as i64 + 1) as u64 * (t1.y as i64 - t0.y as i64 + 1) as u64;
        if area_tiles > self.tiles.len() as u64 {
            // More tiles under the area than occupied tiles: walk the occupied ones.
            for (t, v) in &self.tiles {
                if t.cmpge(t0).all() && t.cmple(t1).all() {
                    cand.extend_from_slice(v);
                }
            }
        } else {
            for tz in t0.y..=t1.y {
                for tx in t0.x..=t1.x {
                    if let Some(v) = self.tiles.get(&IVec2::new(tx, tz)) {
                        cand.extend_from_slice(v);
                    }
                }
            }
        }
        cand.sort_unstable();
        cand.dedup();
        let candidates = cand.len() as u64;
        cand.retain(|&i| {
            let p = &self.placed[i as usize];
            p.lo.cmple(ahi).all() && p.hi.cmpge(alo).all()
        });
        (cand, candidates)
    }

    /// For each column of `desc` (x fastest), the positions in `cand` of the candidates
    /// whose bounds overlap the column's `(x, z)` extent, in `cand`'s order. A
    /// candidate's columns are a rectangle of them (the extents grow with the index),
    /// found by two binary searches an axis: the work is the entries, not columns ×
    /// candidates (a coarse node over a forest: thousands of candidates).
    fn column_candidates(&self, desc: &GridDesc, cand: &[u32]) -> Vec<Vec<u32>> {
        let half = desc.h() * 0.5;
        let d = desc.dims();
        let nx = d.x as usize;
        // Each column's extent along x and along z: a cell centre's coordinate ± half.
        let xs: Vec<(f32, f32)> = (0..d.x)
            .map(|x| desc.position(UVec3::new(x, 0, 0)).x)
            .map(|c| (c - half, c + half))
            .collect();
        let zs: Vec<(f32, f32)> = (0..d.z)
            .map(|z| desc.position(UVec3::new(0, 0, z)).z)
            .map(|c| (c - half, c + half))
            .collect();
        // The columns `i` with `lo <= extent.1 && hi >= extent.0`.
        let overlapping = |e: &[(f32, f32)], lo: f32, hi: f32| {
            e.partition_point(|x| x.1 < lo)..e.partition_point(|x| x.0 <= hi)
        };
        let mut columns = vec![Vec::new(); nx * d.z as usize];
        for (c, &j) in cand.iter().enumerate() {
            let p = &self.placed[j as usize];
            for z in overlapping(&zs, p.lo.z, p.hi.z) {
                for x in overlapping(&xs, p.lo.x, p.hi.x) {
                    columns[x + nx * z].push(c as u32);
                }
            }
        }
        columns
    }

    /// Composes the area `desc`, with counters.
    pub fn compose(&self, desc: &GridDesc) -> Result<(MaterialGrid, ComposeStats), GridError> {
        self.compose_sampled(desc, 1.0)
    }

    /// Composes the area `desc` with a sample a side every `spacing` of the finest
    /// overlapping instance's cells (1: [`AreaComposer::compose`]; at most
    /// [`ComposeParams::max_samples_per_axis`] a side).
    fn compose_sampled(
        &self,
        desc: &GridDesc,
        spacing: f32,
    ) -> Result<(MaterialGrid, ComposeStats), GridError> {
        let max_k = self.params.max_samples_per_axis;
        let _span = tracing::debug_span!("compose", points = desc.point_count()).entered();
        let (alo, ahi) = desc.cell_bounds();
        let (cand, candidates) = self.candidates(alo, ahi);
        let stats = ComposeStats {
            candidates,
            overlapping: cand.len() as u64,
        };
        let h = desc.h();
        let finest = cand
            .iter()
            .map(|&i| {
                let p = &self.placed[i as usize];
                self.models[p.inst.model as usize].desc().h() * p.inst.scale
            })
            .fold(f32::INFINITY, f32::min);
        // The most samples a side any cell of the area takes (each takes those its own
        // instances ask: a cell is composed from its own box).
        let k = if finest.is_finite() {
            cell_samples(h, finest, max_k, spacing)
        } else {
            1
        };
        lightgrid_core::limits::check_memory(
            &format!("area material grid of {} points", desc.point_count()),
            desc.point_count() as u64 * std::mem::size_of::<Material>() as u64,
        )?;
        let mut cells = vec![Material::EMPTY; desc.point_count()];
        let ground_top = self.ground_top;
        use rayon::prelude::*;
        let half = Vec3::splat(h * 0.5);
        // Candidates overlapping each column's (x, z) extent, in `cand`'s order: a cell
        // then tests only its column's (a 16 m node over a forest: 1–3 of its 10–20).
        let nx = desc.dims().x as usize;
        let columns = self.column_candidates(desc, &cand);
        let samplings: Vec<Sampling<'_>> = cand
            .iter()
            .map(|&j| {
                let placed = &self.placed[j as usize];
                let mi = placed.inst.model as usize;
                Sampling::new(placed, (&self.models[mi], &self.clear[mi]), h, k)
            })
            .collect();
        // The ground under each column of cells: the same for every level.
        let grounds = self.column_grounds(desc, k);
        cells
            .par_iter_mut()
            .enumerate()
            .for_each_init(Scratch::default, |scratch, (i, cell)| {
                let Scratch {
                    local,
                    centres,
                    samples,
                } = scratch;
                let q = desc.coords(i).expect("index in range");
                let centre = desc.position(q);
                // Instances overlapping this cell (the same test as over all candidates),
                // whose model's box the cell's samples reach.
                local.clear();
                local.extend(
                    columns[q.x as usize + nx * q.z as usize]
                        .iter()
                        .map(|&c| &samplings[c as usize])
                        .filter(|sm| {
                            let p = sm.placed;
                            p.lo.cmple(centre + half).all() && p.hi.cmpge(centre - half).all()
                        }),
                );
                let local: &Vec<&Sampling> = local;
                let ground_possible = ground_top.is_some_and(|top| {
                    centre.y - h * 0.5
                        <= top - self.params.ground_bias + self.params.ground_band * 0.5
                });
                if local.is_empty() && !ground_possible {
                    return;
                }
                let column = grounds
                    .as_ref()
                    .map(|g| &g[q.x as usize + nx * q.z as usize]);
                // Wholly under the ground's transition band: dense ground, nothing to sample.
                if let (Some(t), Some(c)) = (&self.terrain, column) {
                    let slope_room = t.heightmap.spacing.min(h) * 4.0;
                    if centre.y + h * 0.5 + slope_room < c.one[0].0 - self.params.ground_band * 0.5
                    {
                        *cell = Material::opaque(t.colour.at(centre.x, centre.z));
                        return;
                    }
                }
                // Ground alone is smooth: one sample; objects need a sample a side per
                // cell of the finest instance overlapping this cell (at most `k`).
                let k = match local.iter().map(|sm| sm.cell).reduce(f32::min) {
                    Some(finest) => cell_samples(h, finest, k, spacing),
                    None => 1,
                };
                let ground: &[(f32, Vec3)] = match column {
                    Some(c) if k == 1 => &c.one,
                    Some(c) => &c.samples[k as usize - 2],
                    None => &[],
                };
                // Each instance's cell centre in its model's space, once a cell; the
                // samples are offsets from it. Instances out of reach are dropped.
                // Instances whose every read here is clear add nothing: left out too.
                centres.clear();
                for (li, sm) in local.iter().enumerate() {
                    let c = sm.to_model(centre);
                    let (mlo, mhi) = sm.bounds;
                    let reach = sm.reach[k as usize - 1];
                    if (c + reach).cmpge(mlo).all()
                        && (c - reach).cmple(mhi).all()
                        && !sm.clear_around(c, k)
                    {
                        centres.push((c, li));
                    }
                }
                if centres.is_empty() && !ground_possible {
                    return; // as if no instance were here: Material::EMPTY
                }
                *cell = sample_cell(
                    (centre, h, k),
                    (local, centres),
                    (ground, self.params.ground_band, self.params.band_albedo),
                    samples,
                );
            });
        Ok((MaterialGrid::new(*desc, cells)?, stats))
    }
}

/// The ground under one column of an area's cells (height less the bias, and colour)
/// under each column of a cell's samples, for one sample a cell (the cells' centre,
/// which the dense-ground test reads too) and for `k` a side (x fastest).
struct ColumnGround {
    /// One sample: at the column's centre.
    one: Vec<(f32, Vec3)>,
    /// `k` a side for `k` in `2..=max_k` (`samples[k - 2]`).
    samples: Vec<Vec<(f32, Vec3)>>,
}

impl AreaComposer {
    /// [`ColumnGround`] of every column of `desc` (x fastest; `None` without terrain):
    /// looked up once a column instead of once a cell of every level.
    fn column_grounds(&self, desc: &GridDesc, k: u32) -> Option<Vec<ColumnGround>> {
        use rayon::prelude::*;
        let t = self.terrain.as_ref()?;
        let (h, bias) = (desc.h(), self.params.ground_bias);
        let nx = desc.dims().x as usize;
        let under = |centre: Vec3, k: u32| -> Vec<(f32, Vec3)> {
            (0..k * k)
                .map(|c| {
                    let o = UVec3::new(c % k, 0, c / k).as_vec3();
                    let p = centre + ((o + 0.5) / k as f32 - 0.5) * h;
                    (
                        t.heightmap.height_at(p.x, p.z) - bias,
                        t.colour.at(p.x, p.z),
                    )
                })
                .collect()
        };
        Some(
            (0..nx * desc.dims().z as usize)
                .into_par_iter()
                .map(|c| {
                    // (A cell's centre at any level has this x and z.)
                    let centre = desc.position(UVec3::new((c % nx) as u32, 0, (c / nx) as u32));
                    ColumnGround {
                        one: under(centre, 1),
                        samples: (2..=k).map(|k| under(centre, k)).collect(),
                    }
                })
                .collect(),
        )
    }
}

/// Samples a side in a cell of size `h` whose finest overlapping instance has cells of
/// `finest`, a sample every `spacing` of those cells: [`samples_a_side`] of
/// `finest × spacing`, but no fewer than two where `spacing` 1 takes two or more (an
/// object the samples miss then reaches at most a quarter of a cell above the top of
/// the highest cell found: the margin of `lightgrid_terrain_lod`'s casters).
#[inline]
fn cell_samples(h: f32, finest: f32, max_k: u32, spacing: f32) -> u32 {
    let k = samples_a_side(h, finest, max_k);
    if spacing == 1.0 {
        return k;
    }
    samples_a_side(h, finest * spacing, max_k).max(k.min(2))
}

/// Samples a side in a cell of size `h` whose finest overlapping instance has cells of
/// `finest` (model cell times scale): `ceil(h / finest)`, in `1..=max_k`.
#[inline]
fn samples_a_side(h: f32, finest: f32, max_k: u32) -> u32 {
    ((h / finest).ceil() as u32).clamp(1, max_k.max(1))
}

/// A cell's material from its `k³` samples: each sample's transmittance the product of
/// the instances' within reach (`centres`: a cell centre in a model's space and the
/// instance's index in `local`) and the ground's band (`ground`: the height less the
/// bias and colour under each column of samples), its colour their blocked-weighted
/// mean; the cell the samples' mean.
///
/// Instance by instance over the samples (each sample's state in `acc`), then the
/// ground, then the samples' mean in sample order: every sample sees its instances in
/// `centres`' order and the ground last, the sums the order they had sample by
/// sample. (Sample by sample, every sample's instances were looked up anew: twice the
/// time of a forest node's composition.)
fn sample_cell(
    (centre, h, k): (Vec3, f32, u32),
    (local, centres): (&[&Sampling<'_>], &[(Vec3, usize)]),
    (ground, ground_band, band): (&[(f32, Vec3)], f32, GroundBand),
    [acc, surface]: &mut [Vec<SampleState>; 2],
) -> Material {
    let n = (k * k * k) as usize;
    acc.clear();
    acc.resize(n, SampleState::CLEAR);
    for &(c, li) in centres.iter() {
        let sm = local[li];
        let (mlo, mhi) = sm.bounds;
        for (a, &offset) in acc.iter_mut().zip(sm.offsets(k)) {
            let mpos = c + offset;
            if mpos.cmplt(mlo).any() || mpos.cmpgt(mhi).any() {
                continue;
            }
            // Clear: `1^ratio` blocks nothing (skipping it is exact).
            let Some(m) = sm.read(mpos) else {
                continue;
            };
            a.add(m.pass.clamp(0.0, 1.0).powf(sm.ratio), m.reflectance);
        }
    }
    // A sample's height (`centre + ((o + 0.5) / k − 0.5) h`, its y alone).
    let sample_y = |y: u32| centre.y + ((y as f32 + 0.5) / k as f32 - 0.5) * h;
    let weight = |g: f32, y: f32| ((g - y) / ground_band + 0.5).clamp(0.0, 1.0);
    // The ground adds nothing to a sample above its band (a weight of 0 blocks
    // nothing): where the highest ground under the cell gives its lowest sample none,
    // it gives none to any (each step of the weight is monotonic in `g` and `y`).
    let highest = ground.iter().map(|g| g.0).fold(f32::NEG_INFINITY, f32::max);
    // The samples before the ground, kept (in `surface`) where the ground's albedo in
    // the band is not its colour: a cell that comes out opaque is a surface, of the
    // colour itself.
    let mut kept = false;
    // What a ground of height `g` lets through at the samples' level `y`.
    let ground_pass = |g: f32, y: u32| 1.0 - weight(g, sample_y(y));
    if !ground.is_empty() && weight(highest, sample_y(0)) > 0.0 {
        if band != GroundBand::Colour {
            surface.clear();
            surface.extend_from_slice(acc);
            kept = true;
        }
        add_ground(acc, k, (ground, band), ground_pass);
    }
    let mut pass_sum = 0.0;
    for a in acc.iter() {
        pass_sum += a.pass;
    }
    let n = n as f32;
    let acc = if kept && (pass_sum / n).clamp(0.0, 1.0) <= 0.0 {
        add_ground(surface, k, (ground, GroundBand::Colour), ground_pass);
        surface
    } else {
        acc
    };
    let mut colour_sum = Vec3::ZERO;
    let mut block_sum = 0.0;
    for a in acc.iter() {
        if a.weight > 0.0 {
            colour_sum += a.colour / a.weight * (1.0 - a.pass);
            block_sum += 1.0 - a.pass;
        }
    }
    Material {
        reflectance: if block_sum > 0.0 {
            (colour_sum / block_sum).clamp(Vec3::ZERO, Vec3::ONE)
        } else {
            Vec3::ZERO
        },
        pass: (pass_sum / n).clamp(0.0, 1.0),
    }
}

/// The ground added to the samples `acc` (`k` a side) from the ground under each column
/// of them, with its albedo in the band ([`GroundBand::albedo`]); `pass(g, y)` is what a
/// ground of height `g` lets through at the samples' level `y`. Row by row (x fastest
/// within a row of fixed y and z): no division a sample.
fn add_ground(
    acc: &mut [SampleState],
    k: u32,
    (ground, band): (&[(f32, Vec3)], GroundBand),
    pass: impl Fn(f32, u32) -> f32,
) {
    for (r, row) in acc.chunks_exact_mut(k as usize).enumerate() {
        let (y, z) = (r as u32 % k, r as u32 / k);
        let under = ground.get((k * z) as usize..).unwrap_or_default();
        for (a, &(g, colour)) in row.iter_mut().zip(under) {
            a.add(pass(g, y), band.albedo(colour));
        }
    }
}

/// One sample's transmittance, and its blocked-weighted colour and weight so far
/// ([`sample_cell`]).
#[derive(Clone, Copy)]
struct SampleState {
    pass: f32,
    colour: Vec3,
    weight: f32,
}

impl SampleState {
    const CLEAR: Self = Self {
        pass: 1.0,
        colour: Vec3::ZERO,
        weight: 0.0,
    };

    /// A blocker of transmittance `m_pass` and colour `m_colour` crossed.
    #[inline]
    fn add(&mut self, m_pass: f32, m_colour: Vec3) {
        let blocked = 1.0 - m_pass;
        if blocked > 0.0 {
            self.colour += m_colour * blocked;
            self.weight += blocked;
            self.pass *= m_pass;
        }
    }
}

/// The spacing of [`MaterialSource::shadow_material`]'s samples, in the finest
/// overlapping instance's cells (the material's own: one): a march of the sun crosses
/// it and nothing is swept on it (the hierarchy's sun casters). A cell takes about half
/// the samples a side (an eighth of them), no fewer than two where the material takes
/// two or more: over the frame bench's forest (trees of 0.5 m cells scaled 0.8–1.3)
/// its 1 m cells take two a side instead of two or three, its 2 m cells two or three
/// instead of four, its 4 m cells and coarser four as the material does.
pub const SHADOW_SAMPLE_SPACING: f32 = 2.0;

impl MaterialSource for AreaComposer {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        Ok(self.compose(desc)?.0)
    }
    /// [`AreaComposer::compose`] with a sample a side every [`SHADOW_SAMPLE_SPACING`] of
    /// the finest instance's cells.
    fn shadow_material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        Ok(self.compose_sampled(desc, SHADOW_SAMPLE_SPACING)?.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Model 0 placed at the origin, unturned, unscaled.
    fn at_origin() -> Placed {
        Placed {
            inst: Instance {
                model: 0,
                position: Vec3::ZERO,
                rotation: Quat::IDENTITY,
                scale: 1.0,
            },
            inv_rot: Quat::IDENTITY,
            lo: Vec3::ZERO,
            hi: Vec3::ZERO,
        }
    }

    #[test]
    fn a_read_is_the_model_grids_sample_bit_for_bit() {
        // A model of clear cells with a few blocks of medium and an opaque cell, and
        // grids one point thin along an axis; lookups everywhere, outside included
        // (clamped): `read` is `MaterialGrid::sample`, or `None` where that is clear.
        let mut rng = fastrand::Rng::with_seed(11);
        for dims in [
            UVec3::new(9, 7, 8),
            UVec3::new(1, 6, 5),
            UVec3::new(5, 4, 1),
        ] {
            let d = GridDesc::new(Vec3::new(-1.0, 0.0, -0.5), 0.5, dims).unwrap();
            let cells: Vec<Material> = (0..d.point_count())
                .map(|i| {
                    let q = d.coords(i).unwrap();
                    match (q.x + 2 * q.y + 3 * q.z) % 7 {
                        0 if q.y > 1 => Material {
                            reflectance: Vec3::new(rng.f32(), rng.f32(), rng.f32()),
                            pass: rng.f32(),
                        },
                        1 if q.x == 2 && q.z == 3 => Material::opaque(Vec3::splat(0.4)),
                        _ => Material::EMPTY,
                    }
                })
                .collect();
            let model = MaterialGrid::new(d, cells).unwrap();
            let clear = ClearCubes::new(&model);
            assert!(clear.cube.iter().any(|&c| c) && !clear.cube.iter().all(|&c| c));
            let placed = at_origin();
            let sm = Sampling::new(&placed, (&model, &clear), 1.0, 1);
            let (mut seen, mut skipped) = (0, 0);
            for _ in 0..20_000 {
                let p = d.origin()
                    + (Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 1.4 - 0.2)
                        * dims.as_vec3()
                        * d.h();
                let want = model.sample(p).unwrap();
                match sm.read(p) {
                    None => {
                        // Clear, but for the weights' rounding (a few 2^-24 at most).
                        assert!(want.pass >= 1.0 - 1e-6, "{p}: {want:?} read as clear");
                        skipped += 1;
                    }
                    Some(m) => {
                        assert_eq!(m.pass.to_bits(), want.pass.to_bits(), "{p}");
                        for k in 0..3 {
                            assert_eq!(m.reflectance[k].to_bits(), want.reflectance[k].to_bits());
                        }
                        seen += 1;
                    }
                }
            }
            assert!(
                seen > 100 && skipped > 100,
                "{dims}: {seen} read, {skipped} clear"
            );
        }
    }

    /// [`sample_cell`] (instance by instance over the samples, the ground skipped where
    /// it adds nothing) is the composition sample by sample, bit for bit: two turned,
    /// scaled instances of a model, ground under, in and far below the cell's band,
    /// `k` from 1 to 4.
    #[test]
    fn sample_cell_is_the_sample_by_sample_composition() {
        let mut rng = fastrand::Rng::with_seed(17);
        let d = GridDesc::new(Vec3::new(-2.0, 0.0, -2.0), 0.5, UVec3::new(9, 9, 9)).unwrap();
        let cells: Vec<Material> = (0..d.point_count())
            .map(|_| match rng.u32(0..3) {
                0 => Material {
                    reflectance: Vec3::new(rng.f32(), rng.f32(), rng.f32()),
                    pass: rng.f32(),
                },
                1 if rng.u32(0..8) == 0 => Material::opaque(Vec3::splat(0.3)),
                _ => Material::EMPTY,
            })
            .collect();
        let model = MaterialGrid::new(d, cells).unwrap();
        let clear = ClearCubes::new(&model);
        let placed: Vec<Placed> = [(0.3f32, 1.1f32), (1.9, 0.8)]
            .iter()
            .map(|&(angle, scale)| {
                let rotation = Quat::from_rotation_y(angle);
                Placed {
                    inst: Instance {
                        model: 0,
                        position: Vec3::new(angle, 0.2, -angle),
                        rotation,
                        scale,
                    },
                    inv_rot: rotation.inverse(),
                    lo: Vec3::splat(-10.0),
                    hi: Vec3::splat(10.0),
                }
            })
            .collect();
        let (mut skipped, mut banded, mut reflecting, mut opaque) = (0, 0, 0, 0);
        for k in 1..=4u32 {
            let h = 1.0;
            let samplings: Vec<Sampling<'_>> = placed
                .iter()
                .map(|p| Sampling::new(p, (&model, &clear), h, k))
                .collect();
            let local: Vec<&Sampling<'_>> = samplings.iter().collect();
            let mut acc = [Vec::new(), Vec::new()];
            for _ in 0..300 {
                let centre = Vec3::new(
                    rng.f32() * 4.0 - 2.0,
                    rng.f32() * 5.0,
                    rng.f32() * 4.0 - 2.0,
                );
                let centres: Vec<(Vec3, usize)> = local
                    .iter()
                    .enumerate()
                    .map(|(i, sm)| (sm.to_model(centre), i))
                    .collect();
                // Ground well below, about the cell, or over it.
                let base = centre.y + (rng.f32() * 6.0 - 4.0);
                let ground: Vec<(f32, Vec3)> = (0..k * k)
                    .map(|_| (base + rng.f32() * 0.6, Vec3::new(0.2, rng.f32(), 0.1)))
                    .collect();
                let band = 1.0;
                // Sample by sample: each sample's instances, then its ground of albedo
                // `rule.albedo(colour)`.
                let sample_by_sample = |rule: GroundBand| {
                    let (mut pass_sum, mut colour_sum, mut block_sum) =
                        (0.0f32, Vec3::ZERO, 0.0f32);
                    let mut any_ground = false;
                    for s in 0..(k * k * k) as usize {
                        let q = UVec3::new(s as u32 % k, (s as u32 / k) % k, s as u32 / (k * k));
                        let p = centre + ((q.as_vec3() + 0.5) / k as f32 - 0.5) * h;
                        let (mut pass, mut colour, mut weight) = (1.0f32, Vec3::ZERO, 0.0f32);
                        let mut add = |m_pass: f32, m_colour: Vec3| {
                            let blocked = 1.0 - m_pass;
                            if blocked > 0.0 {
                                colour += m_colour * blocked;
                                weight += blocked;
                                pass *= m_pass;
                            }
                        };
                        for &(c, li) in &centres {
                            let sm = local[li];
                            let mpos = c + sm.offsets(k)[s];
                            if mpos.cmplt(sm.bounds.0).any() || mpos.cmpgt(sm.bounds.1).any() {
                                continue;
                            }
                            if let Some(m) = sm.read(mpos) {
                                add(m.pass.clamp(0.0, 1.0).powf(sm.ratio), m.reflectance);
                            }
                        }
                        let (g, c) = ground[(q.x + k * q.z) as usize];
                        let w = ((g - p.y) / band + 0.5).clamp(0.0, 1.0);
                        any_ground |= w > 0.0;
                        add(1.0 - w, rule.albedo(c));
                        pass_sum += pass;
                        if weight > 0.0 {
                            colour_sum += colour / weight * (1.0 - pass);
                            block_sum += 1.0 - pass;
                        }
                    }
                    let m = Material {
                        reflectance: if block_sum > 0.0 {
                            (colour_sum / block_sum).clamp(Vec3::ZERO, Vec3::ONE)
                        } else {
                            Vec3::ZERO
                        },
                        pass: (pass_sum / (k * k * k) as f32).clamp(0.0, 1.0),
                    };
                    (m, any_ground)
                };
                let (plain, any_ground) = sample_by_sample(GroundBand::Colour);
                for rule in [GroundBand::Colour, GroundBand::Reflecting] {
                    let got = sample_cell(
                        (centre, h, k),
                        (&local, &centres),
                        (&ground, band, rule),
                        &mut acc,
                    );
                    // A cell that comes out opaque is a surface of the colours themselves.
                    let want = match sample_by_sample(rule).0 {
                        m if m.pass <= 0.0 => plain,
                        m => m,
                    };
                    assert_eq!(got.pass.to_bits(), want.pass.to_bits(), "k {k} at {centre}");
                    for c in 0..3 {
                        assert_eq!(
                            got.reflectance[c].to_bits(),
                            want.reflectance[c].to_bits(),
                            "k {k} at {centre}, {rule:?}"
                        );
                    }
                    if rule == GroundBand::Reflecting {
                        if want.pass <= 0.0 && any_ground {
                            opaque += 1;
                        } else if want != plain {
                            reflecting += 1;
                        }
                    }
                }
                if any_ground {
                    banded += 1;
                } else {
                    skipped += 1;
                }
            }
        }
        assert!(
            skipped > 100 && banded > 100 && reflecting > 50 && opaque > 10,
            "{skipped} above the band, {banded} in it ({reflecting} changed by the \
             reflecting band, {opaque} opaque)"
        );
    }

    /// `Colour` leaves the ground's colour as it is; `Reflecting` maps 0 to 0 and 1 to
    /// 1, rises with the colour, and is the albedo whose half-space reflects the colour
    /// (Hapke's diffusive reflectance `(1 - γ) / (1 + γ)`, `γ = sqrt(1 - w)`, of it).
    #[test]
    fn the_band_albedo_is_the_one_whose_half_space_reflects_the_colour() {
        let mut last = -1.0;
        for i in 0..=100 {
            let a = i as f32 / 100.0;
            let c = Vec3::new(a, 0.5 * a, 1.0 - a);
            assert_eq!(GroundBand::Colour.albedo(c), c);
            let w = GroundBand::Reflecting.albedo(c);
            for (w, a) in w.to_array().into_iter().zip(c.to_array()) {
                let g = (1.0 - w).sqrt();
                let r = (1.0 - g) / (1.0 + g);
                assert!((r - a).abs() < 1e-5, "{a}: albedo {w} reflects {r}");
                assert!((0.0..=1.0).contains(&w) && w >= a, "{a}: {w}");
            }
            assert!(w.x > last || i == 0, "rises: {} after {last}", w.x);
            last = w.x;
        }
        assert_eq!(GroundBand::Reflecting.albedo(Vec3::ZERO), Vec3::ZERO);
        assert_eq!(GroundBand::Reflecting.albedo(Vec3::ONE), Vec3::ONE);
    }

    /// Flat ground composed with each band albedo: the cells the ground covers in part
    /// take `GroundBand::albedo` of its colour, the cells wholly under it (surfaces) its
    /// colour, and every other cell and every pass-through is the same bit for bit.
    #[test]
    fn only_the_partly_covered_ground_cells_change_albedo() {
        let colour = Vec3::new(0.25, 0.22, 0.18);
        let hm = Heightmap::from_fn(Vec2::splat(-8.0), 1.0, 32, 32, |x, z| {
            10.3 + 0.2 * x + 0.1 * z
        })
        .unwrap();
        let compose = |band| {
            let terrain = Terrain {
                heightmap: hm.clone(),
                colour: GroundColour::Uniform(colour),
            };
            let params = ComposeParams {
                band_albedo: band,
                ..ComposeParams::default()
            };
            let d =
                GridDesc::new(Vec3::new(0.25, 8.25, 0.25), 0.5, UVec3::new(12, 16, 12)).unwrap();
            AreaComposer::new(Vec::new(), &[], Some(terrain), params)
                .unwrap()
                .compose(&d)
                .unwrap()
                .0
        };
        let (plain, reflecting) = (compose(GroundBand::Colour), compose(GroundBand::Reflecting));
        let (mut partial, mut opaque) = (0, 0);
        for (p, r) in plain.data().iter().zip(reflecting.data()) {
            assert_eq!(p.pass.to_bits(), r.pass.to_bits());
            if p.pass > 0.0 && p.pass < 1.0 {
                partial += 1;
                assert!((p.reflectance - colour).abs().max_element() < 1e-6, "{p:?}");
                let want = GroundBand::Reflecting.albedo(colour);
                assert!((r.reflectance - want).abs().max_element() < 1e-6, "{r:?}");
            } else {
                opaque += usize::from(p.pass == 0.0);
                assert_eq!(p, r);
            }
        }
        assert!(
            partial > 50 && opaque > 50,
            "{partial} partly covered, {opaque} opaque"
        );
    }

    /// The summed-volume table's boxes count what testing every cube counts, and a
    /// place whose box is clear reads clear at every offset within the reach.
    #[test]
    fn clear_boxes_are_the_brute_force_and_read_clear() {
        let mut rng = fastrand::Rng::with_seed(5);
        let d = GridDesc::new(Vec3::new(-1.0, 0.0, -0.5), 0.5, UVec3::new(10, 8, 9)).unwrap();
        let cells: Vec<Material> = (0..d.point_count())
            .map(|_| match rng.u32(0..40) {
                0 => Material {
                    reflectance: Vec3::splat(0.5),
                    pass: rng.f32(),
                },
                _ => Material::EMPTY,
            })
            .collect();
        let model = MaterialGrid::new(d, cells).unwrap();
        let clear = ClearCubes::new(&model);
        for _ in 0..2000 {
            let a = UVec3::new(rng.u32(0..10), rng.u32(0..8), rng.u32(0..9));
            let b = UVec3::new(rng.u32(a.x..10), rng.u32(a.y..8), rng.u32(a.z..9));
            let brute = (a.y..=b.y).all(|y| {
                (a.z..=b.z).all(|z| {
                    (a.x..=b.x).all(|x| clear.cube[d.index_unchecked(UVec3::new(x, y, z))])
                })
            });
            assert_eq!(clear.none_blocked(a, b), brute, "{a} {b}");
        }
        let placed = at_origin();
        let sm = Sampling::new(&placed, (&model, &clear), 1.0, 3);
        let (mut clear_places, mut others) = (0, 0);
        for _ in 0..4000 {
            let c = d.origin() + (Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 1.4 - 0.2) * 5.0;
            if sm.clear_around(c, 3) {
                clear_places += 1;
                for o in sm.offsets(3) {
                    assert!(sm.read(c + *o).is_none(), "{c} + {o}");
                }
            } else {
                others += 1;
            }
        }
        assert!(
            clear_places > 100 && others > 100,
            "{clear_places} clear, {others} not"
        );
    }

    #[test]
    fn column_candidates_are_the_brute_force_overlap_tests() {
        // Instances of a small model at random places, turns and scales; areas of
        // several cell sizes and offsets, partly outside the instances: each column's
        // list is what testing every candidate against the column's extent gives, in
        // the candidates' order.
        let md = GridDesc::new(Vec3::new(-1.0, 0.0, -0.5), 0.5, UVec3::new(4, 6, 3)).unwrap();
        let model = MaterialGrid::filled(md, Material::EMPTY).unwrap();
        let mut rng = fastrand::Rng::with_seed(7);
        let instances: Vec<Instance> = (0..300)
            .map(|_| Instance {
                model: 0,
                position: Vec3::new(rng.f32() * 60.0 - 10.0, 0.0, rng.f32() * 60.0 - 10.0),
                rotation: Quat::from_rotation_y(rng.f32() * 6.3) * Quat::from_rotation_x(rng.f32()),
                scale: 0.3 + rng.f32() * 3.0,
            })
            .chain(
                // Touching columns of the first area exactly: one's box ends at x = z = 5
                // (column 5's low side), one's starts at x = z = 7 (column 6's high side).
                [4.25, 8.25].map(|p| Instance {
                    model: 0,
                    position: Vec3::new(p, 0.0, p),
                    rotation: Quat::IDENTITY,
                    scale: 1.0,
                }),
            )
            .collect();
        let c = AreaComposer::new(vec![model], &instances, None, ComposeParams::default()).unwrap();
        assert_eq!(c.placed[300].hi.x, 5.0);
        assert_eq!(c.placed[301].lo.x, 7.0);
        let mut entries = 0;
        for (origin, h, n) in [
            (Vec3::new(0.5, 0.0, 0.5), 1.0, 16),
            (Vec3::new(-3.25, 1.0, 7.75), 0.5, 23),
            (Vec3::new(4.0, -2.0, -4.0), 4.0, 9),
            (Vec3::new(100.0, 0.0, 0.0), 2.0, 8),
        ] {
            let desc = GridDesc::new(origin, h, UVec3::new(n, 3, n + 1)).unwrap();
            let (alo, ahi) = desc.cell_bounds();
            let (cand, _) = c.candidates(alo, ahi);
            let got = c.column_candidates(&desc, &cand);
            let half = Vec3::splat(h * 0.5);
            for z in 0..desc.dims().z {
                for x in 0..desc.dims().x {
                    let centre = desc.position(UVec3::new(x, 0, z));
                    let (lo, hi) = (centre - half, centre + half);
                    let want: Vec<u32> = (0..cand.len() as u32)
                        .filter(|&k| {
                            let p = &c.placed[cand[k as usize] as usize];
                            p.lo.x <= hi.x && p.lo.z <= hi.z && p.hi.x >= lo.x && p.hi.z >= lo.z
                        })
                        .collect();
                    entries += want.len();
                    assert_eq!(
                        got[(x + desc.dims().x * z) as usize],
                        want,
                        "column {x}, {z}"
                    );
                }
            }
        }
        assert!(
            entries > 1000,
            "{entries} entries: the test must see overlaps"
        );
    }
}
