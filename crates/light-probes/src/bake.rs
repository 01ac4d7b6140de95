//! Baking a probe set: where probes go, what each one sees (surfels in bricks, and the
//! sky), and which probes light each surfel.

use std::collections::HashMap;

use lightgrid_core::dirs::{self, NUM_DIRS};
use lightgrid_core::glam::{IVec3, Vec3};
use lightgrid_core::light::AMBIENT_AXES;
use lightgrid_material_voxelizer::voxelize::RayScene;
use rayon::prelude::*;

use crate::interior::{InteriorBox, nearest_visible};
use crate::{ProbeError, ProbeParams};

/// A patch of surface the probes see: the mean of the ray hits in one surfel cell on
/// faces turned the same way (the same dominant normal axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surfel {
    /// Mean hit position.
    pub position: Vec3,
    /// Mean normal (unit; facing the probes that hit it).
    pub normal: Vec3,
    /// Mean diffuse albedo.
    pub albedo: Vec3,
    /// Probe rays that hit it (its weight in its brick: a proxy of its visible area).
    pub hits: u32,
}

/// What one probe sees of one brick: the irradiance weights on the six ambient-cube
/// axes, `Σ_rays max(0, d · a_k) 4π / N` over the probe's rays that hit the brick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrickFactor {
    /// Brick index.
    pub brick: u32,
    /// Weight per axis (`+X, -X, +Y, -Y, +Z, -Z`), steradians.
    pub weights: [f32; 6],
}

/// One probe: its position, the sky it sees and the bricks it sees.
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// World position.
    pub position: Vec3,
    /// Sky visibility: `sky[k][b]` turns the sky's bin `b` (radiance × solid angle) into
    /// irradiance on axis `k`: `Σ_missed rays max(0, d · a_k) (4π / N) / ω_b`. An
    /// unoccluded probe under a uniform sky of radiance `L` gets `π L` on every axis.
    pub sky: [[f32; NUM_DIRS]; 6],
    /// Range of its factors in [`ProbeSet::factors`].
    pub factors: std::ops::Range<u32>,
}

/// Probes, surfels, bricks and the links between them.
///
/// Memory (as stored): `624 + 20` bytes a probe (sky visibility, position, factor range), `28` bytes
/// a brick factor, `40` bytes a surfel, `4` bytes a brick member, `8` bytes a
/// surfel-to-probe link.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeSet {
    params: ProbeParams,
    probes: Vec<Probe>,
    surfels: Vec<Surfel>,
    /// Surfel indices of brick `b`: `brick_surfels[brick_start[b]..brick_start[b + 1]]`.
    brick_start: Vec<u32>,
    brick_surfels: Vec<u32>,
    factors: Vec<BrickFactor>,
    /// Probes lighting surfel `s` and their weights (summing to 1):
    /// `links[link_start[s]..link_start[s + 1]]`.
    link_start: Vec<u32>,
    links: Vec<(u32, f32)>,
    /// Interior sets: the room's box, which surfels lie outside it (seen through
    /// openings, lit by the exterior set's probes: `links` then index those), and how
    /// many probes that exterior set has.
    interior: Option<InteriorBox>,
    outside: Vec<bool>,
    exterior_probes: u32,
}

/// Key of a surfel cell: its integer cell and the dominant axis of the hit normal.
type CellKey = (IVec3, u8);

fn axis_of(n: Vec3) -> u8 {
    let a = n.abs();
    let (axis, v) = if a.x >= a.y && a.x >= a.z {
        (0, n.x)
    } else if a.y >= a.z {
        (1, n.y)
    } else {
        (2, n.z)
    };
    2 * axis + (v < 0.0) as u8
}

/// Direction `i` of `n` on a Fibonacci sphere (deterministic, near-uniform). `n = 0`
/// gives `+Y`; `i` past `n` is read as `n − 1`.
pub fn fibonacci(i: u32, n: u32) -> Vec3 {
    if n == 0 {
        return Vec3::Y;
    }
    let i = i.min(n - 1);
    let y = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
    let r = (1.0 - y * y).max(0.0).sqrt();
    let phi = i as f32 * 2.399_963_1;
    Vec3::new(r * phi.cos(), y, r * phi.sin())
}

/// One probe ray's outcome.
enum RayOut {
    Hit {
        key: CellKey,
        point: Vec3,
        normal: Vec3,
        albedo: Vec3,
        t: f32,
        dir: Vec3,
        /// An interior probe's hit beyond its box (through an opening).
        outside: bool,
    },
    Sky {
        dir: Vec3,
    },
}

/// The automatic probe positions (The Division's first rule): a grid of `spacing`
/// over the box `lo..hi` in x and z; down each column a ray from above the box finds the
/// first surface, and a probe goes `height` above it. Columns that hit nothing get none.
pub fn place(scene: &RayScene<'_>, lo: Vec3, hi: Vec3, params: &ProbeParams) -> Vec<Vec3> {
    let nx = ((hi.x - lo.x) / params.spacing).floor().max(0.0) as u32 + 1;
    let nz = ((hi.z - lo.z) / params.spacing).floor().max(0.0) as u32 + 1;
    let top = hi.y + 1.0;
    let depth = hi.y - lo.y + 2.0;
    (0..nz)
        .flat_map(|k| (0..nx).map(move |i| (i, k)))
        .filter_map(|(i, k)| {
            let x = lo.x + (i as f32 + 0.5) * params.spacing - 0.5 * params.spacing;
            let z = lo.z + (k as f32 + 0.5) * params.spacing - 0.5 * params.spacing;
            let o = Vec3::new(x, top, z);
            scene
                .closest_hit(o, Vec3::NEG_Y, depth, 0.5)
                .map(|h| o + Vec3::NEG_Y * h.t + Vec3::Y * params.height)
        })
        .collect()
}

/// Extra probes along walls (The Division's second rule, against flat-looking walls):
/// from each of `columns` (the automatic probes of [`place`]), rays along ±X and ±Z find
/// walls (surfaces steeper than 60°) within `1.5 × spacing`; a probe goes `wall_offset` in
/// front of each, and again every `spacing` metres up while the wall goes on (at most 16
/// storeys). A probe closer than half a spacing to one already placed (columns
/// included) is dropped, so the result does not crowd. `wall_offset = 0`: none.
pub fn place_walls(scene: &RayScene<'_>, columns: &[Vec3], params: &ProbeParams) -> Vec<Vec3> {
    if params.wall_offset <= 0.0 || !params.spacing.is_finite() || params.spacing <= 0.0 {
        return Vec::new();
    }
    let (spacing, offset) = (params.spacing, params.wall_offset);
    let wall = |o: Vec3, d: Vec3, reach: f32| {
        scene
            .closest_hit(o, d, reach, 0.5)
            .filter(|h| h.normal.y.abs() < 0.5 && h.t > 0.5 * offset)
    };
    let found: Vec<Vec<Vec3>> = columns
        .par_iter()
        .map(|&c| {
            let mut out = Vec::new();
            for d in [Vec3::X, Vec3::NEG_X, Vec3::Z, Vec3::NEG_Z] {
                let Some(h) = wall(c, d, 1.5 * spacing) else {
                    continue;
                };
                let q = c + d * (h.t - offset);
                for k in 0..16 {
                    let qk = q + Vec3::Y * (k as f32 * spacing);
                    if k > 0 && wall(qk - d * offset, d, 3.0 * offset).is_none() {
                        break;
                    }
                    out.push(qk);
                }
            }
            out
        })
        .collect();
    // Sequential thinning in column order: deterministic.
    let r = 0.5 * spacing;
    let key = |p: Vec3| (p / r).floor().as_ivec3();
    let mut hash: HashMap<IVec3, Vec<Vec3>> = HashMap::new();
    for &c in columns {
        hash.entry(key(c)).or_default().push(c);
    }
    let mut out = Vec::new();
    for p in found.into_iter().flatten() {
        let k = key(p);
        let crowded = (-1..=1).any(|x| {
            (-1..=1).any(|y| {
                (-1..=1).any(|z| {
                    hash.get(&(k + IVec3::new(x, y, z)))
                        .is_some_and(|v| v.iter().any(|q| q.distance(p) < r))
                })
            })
        });
        if !crowded {
            hash.entry(k).or_default().push(p);
            out.push(p);
        }
    }
    out
}

impl ProbeSet {
    /// Bakes probes at `positions` in `scene`: each casts `params.rays` rays; hits
    /// become surfels (per cell and normal axis), grouped in bricks; misses become its
    /// sky visibility. `progress(done, total)` is called as probes finish.
    pub fn bake(
        scene: &RayScene<'_>,
        positions: &[Vec3],
        params: &ProbeParams,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self, ProbeError> {
        Self::bake_with(scene, positions, params, progress, None)
    }

    /// Bakes an interior volume (The Division's rooms): probes at `positions`, all
    /// inside `room`. Their rays see the room's surfaces as the set's own surfels, lit by
    /// the room's probes; through openings (windows, doors) they see the sky (their sky
    /// visibility counts only what the openings let through) and the outside's surfaces,
    /// which become surfels lit by the `exterior` set's probes (the nearest that see
    /// them), since the room's probes know nothing of the outside's light. Relight with
    /// [`crate::ProbeLight::frame_interior`] after the exterior set; [`crate::ProbeVolume`]
    /// keeps each set's light to its side of the box's faces (no bleeding through
    /// walls, a blend at openings). A surface up to a surfel cell beyond the box still
    /// counts as the room's (the box may lie just inside its walls).
    pub fn bake_interior(
        scene: &RayScene<'_>,
        positions: &[Vec3],
        room: &InteriorBox,
        exterior: &ProbeSet,
        params: &ProbeParams,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self, ProbeError> {
        room.validate()?;
        if let Some(p) = positions.iter().find(|p| !room.contains(**p)) {
            return Err(lightgrid_core::GridError::invalid(
                "positions",
                p,
                "interior probes must lie inside the room's box",
            )
            .into());
        }
        Self::bake_with(scene, positions, params, progress, Some((room, exterior)))
    }

    fn bake_with(
        scene: &RayScene<'_>,
        positions: &[Vec3],
        params: &ProbeParams,
        progress: &(dyn Fn(usize, usize) + Sync),
        interior: Option<(&InteriorBox, &ProbeSet)>,
    ) -> Result<Self, ProbeError> {
        params.validate()?;
        let _span = tracing::info_span!(
            "bake probes",
            probes = positions.len(),
            rays = params.rays,
            interior = interior.is_some()
        )
        .entered();
        if let Some(p) = positions.iter().find(|p| !p.is_finite()) {
            return Err(
                lightgrid_core::GridError::invalid("positions", p, "must be finite").into(),
            );
        }
        let done = std::sync::atomic::AtomicUsize::new(0);
        let trace = |p: Vec3| -> Vec<RayOut> {
            let out = trace_probe(scene, p, params, interior.map(|(room, _)| room));
            let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(k, positions.len());
            out
        };
        // Probes are traced a chunk at a time (in parallel) and folded in probe and ray
        // order, so memory holds one chunk's rays and the result does not depend on the
        // thread count.
        let mut fold = Fold::new(params);
        fold.probes.reserve(positions.len());
        const CHUNK: usize = 64;
        for (c, chunk) in positions.chunks(CHUNK).enumerate() {
            let rays: Vec<Vec<RayOut>> = chunk.par_iter().map(|&p| trace(p)).collect();
            for (j, (rays, &p)) in rays.iter().zip(chunk).enumerate() {
                fold.probe((c * CHUNK + j) as u32, p, rays);
            }
        }
        Ok(fold.finish(scene, interior))
    }

    /// The room's box of an interior set ([`ProbeSet::bake_interior`]); `None` outside.
    pub fn interior(&self) -> Option<&InteriorBox> {
        self.interior.as_ref()
    }

    /// Whether surfel `s` lies outside an interior set's box (seen through an opening;
    /// its links index the exterior set's probes). Always false for an exterior set.
    pub fn surfel_outside(&self, s: usize) -> bool {
        self.outside.get(s).copied().unwrap_or(false)
    }

    /// Probes of the exterior set an interior set looks out to (0 for an exterior set).
    pub fn exterior_probes(&self) -> usize {
        self.exterior_probes as usize
    }

    /// The parameters it was baked with.
    pub fn params(&self) -> &ProbeParams {
        &self.params
    }

    /// The probes.
    pub fn probes(&self) -> &[Probe] {
        &self.probes
    }

    /// The surfels.
    pub fn surfels(&self) -> &[Surfel] {
        &self.surfels
    }

    /// Number of bricks.
    pub fn brick_count(&self) -> usize {
        self.brick_start.len().saturating_sub(1)
    }

    /// The surfels of brick `b`.
    pub fn brick(&self, b: usize) -> &[u32] {
        &self.brick_surfels[self.brick_start[b] as usize..self.brick_start[b + 1] as usize]
    }

    /// All brick factors (each probe's are `factors[probe.factors]`).
    pub fn factors(&self) -> &[BrickFactor] {
        &self.factors
    }

    /// The probes lighting surfel `s`, with weights summing to 1.
    pub fn surfel_links(&self, s: usize) -> &[(u32, f32)] {
        &self.links[self.link_start[s] as usize..self.link_start[s + 1] as usize]
    }

    /// Bytes as stored (the figure of the crate docs' table).
    pub fn bytes(&self) -> usize {
        self.probes.len() * (NUM_DIRS * 6 * 4 + 12 + 8)
            + self.factors.len() * 28
            + self.outside.len()
            + self.surfels.len() * 40
            + self.brick_surfels.len() * 4
            + self.brick_start.len() * 4
            + self.links.len() * 8
            + self.link_start.len() * 4
    }

    /// Each surfel's sun visibility read from a light field's transmittance of the sun
    /// it keeps apart (the sweep's sun channel, `LightField::sun_transmittance`, half a
    /// cell along the surfel's normal): partial through foliage and media, where
    /// [`ProbeSet::sun_visibility`]'s shadow rays see leaves as opaque or not at the
    /// mask's cutoff. Surfels facing away from `to_sun` get 0. Errors name a bad
    /// `to_sun`, or pass on the field's.
    pub fn sun_visibility_from<F: lightgrid_core::LightField + Sync + ?Sized>(
        &self,
        field: &F,
        to_sun: Vec3,
    ) -> Result<Vec<f32>, ProbeError> {
        let s = lightgrid_core::unit(to_sun).ok_or_else(|| {
            lightgrid_core::GridError::invalid("to_sun", to_sun, "must be finite and non-zero")
        })?;
        self.surfels
            .par_iter()
            .map(|sf| {
                if sf.normal.dot(s) <= 0.0 {
                    return Ok(0.0);
                }
                let t = field.sun_transmittance(sf.position, Some(sf.normal))?;
                Ok(if t.is_finite() {
                    t.clamp(0.0, 1.0)
                } else {
                    0.0
                })
            })
            .collect()
    }

    /// Whether each surfel sees the sun toward `to_sun` (1 or 0, alpha-tested at the
    /// mask's cutoff): one shadow ray from its position, lifted a twentieth of a cell
    /// along its normal. Surfels facing away get 0. Recompute when the sun moves.
    pub fn sun_visibility(&self, scene: &RayScene<'_>, to_sun: Vec3) -> Vec<f32> {
        let Some(s) = lightgrid_core::unit(to_sun) else {
            return vec![0.0; self.surfels.len()];
        };
        let lift = 0.05 * self.params.cell;
        self.surfels
            .par_iter()
            .map(|sf| {
                if sf.normal.dot(s) <= 0.0 {
                    return 0.0;
                }
                let o = sf.position + sf.normal * lift;
                match scene.closest_hit(o, s, self.params.max_distance, 0.5) {
                    Some(_) => 0.0,
                    None => 1.0,
                }
            })
            .collect()
    }
}

/// Probe `p`'s rays (a Fibonacci sphere of `params.rays`), each to its first hit or the
/// sky; with a room (`interior`), whether a hit lies outside it.
fn trace_probe(
    scene: &RayScene<'_>,
    p: Vec3,
    params: &ProbeParams,
    interior: Option<&InteriorBox>,
) -> Vec<RayOut> {
    let n = params.rays;
    (0..n)
        .map(|i| {
            let d = fibonacci(i, n);
            match scene.closest_hit(p, d, params.max_distance, 0.5) {
                Some(h) => {
                    let point = p + d * h.t;
                    let cell = (point / params.cell).floor().as_ivec3();
                    RayOut::Hit {
                        key: (cell, axis_of(h.normal)),
                        point,
                        normal: h.normal,
                        albedo: h.colour,
                        t: h.t,
                        dir: d,
                        outside: interior.is_some_and(|room| room.distance(point) > params.cell),
                    }
                }
                None => RayOut::Sky { dir: d },
            }
        })
        .collect()
}

/// A bake's probes folded in probe and ray order: the surfels their rays hit (one a
/// cell and normal axis, made at its first hit), the bricks that group them (`brick`
/// cells a side, per normal axis), each probe's sky and brick weights, and which probes
/// see each surfel, how near.
struct Fold<'p> {
    params: &'p ProbeParams,
    /// Solid angle of one ray.
    dw: f32,
    surfel_of: HashMap<CellKey, u32>,
    /// Per surfel: sums of hit points, normals, albedos, and the hit count.
    acc: Vec<(Vec3, Vec3, Vec3, u32)>,
    brick_of_key: HashMap<CellKey, u32>,
    brick_members: Vec<Vec<u32>>,
    brick_of_surfel: Vec<u32>,
    probes: Vec<Probe>,
    factors: Vec<BrickFactor>,
    /// Per surfel: the probes that saw it and their nearest distance.
    seen: Vec<Vec<(u32, f32)>>,
    /// Per surfel: it lies outside the room (an interior bake).
    outside: Vec<bool>,
}

impl<'p> Fold<'p> {
    fn new(params: &'p ProbeParams) -> Self {
        Self {
            params,
            dw: 4.0 * std::f32::consts::PI / params.rays as f32,
            surfel_of: HashMap::new(),
            acc: Vec::new(),
            brick_of_key: HashMap::new(),
            brick_members: Vec::new(),
            brick_of_surfel: Vec::new(),
            probes: Vec::new(),
            factors: Vec::new(),
            seen: Vec::new(),
            outside: Vec::new(),
        }
    }

    /// The surfel of a hit's cell and axis, made (with its brick) at its first hit.
    fn surfel(&mut self, key: &CellKey, beyond: bool) -> u32 {
        if let Some(s) = self.surfel_of.get(key) {
            return *s;
        }
        let b = self.params.brick as i32;
        let s = self.acc.len() as u32;
        self.surfel_of.insert(*key, s);
        self.acc.push((Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0));
        self.seen.push(Vec::new());
        self.outside.push(beyond);
        let bk = (key.0.div_euclid(IVec3::splat(b)), key.1);
        let members = &mut self.brick_members;
        let bi = *self.brick_of_key.entry(bk).or_insert_with(|| {
            members.push(Vec::new());
            members.len() as u32 - 1
        });
        self.brick_members[bi as usize].push(s);
        self.brick_of_surfel.push(bi);
        s
    }

    /// Probe `pi` at `p` and its rays: surfels hit, the brick weights it gathers on the
    /// six ambient axes (in the order its rays first reach each brick), and its sky.
    fn probe(&mut self, pi: u32, p: Vec3, rays: &[RayOut]) {
        let (dw, omega) = (self.dw, dirs::solid_angles());
        let mut sky = [[0.0f32; NUM_DIRS]; 6];
        let mut by_brick: HashMap<u32, [f32; 6]> = HashMap::new();
        let mut order: Vec<u32> = Vec::new();
        for r in rays {
            match r {
                RayOut::Hit {
                    key,
                    point,
                    normal,
                    albedo,
                    t,
                    dir,
                    outside: beyond,
                } => {
                    let s = self.surfel(key, *beyond);
                    let a = &mut self.acc[s as usize];
                    a.0 += *point;
                    a.1 += *normal;
                    a.2 += *albedo;
                    a.3 += 1;
                    let bi = self.brick_of_surfel[s as usize];
                    let w = by_brick.entry(bi).or_insert_with(|| {
                        order.push(bi);
                        [0.0; 6]
                    });
                    for (k, ax) in AMBIENT_AXES.iter().enumerate() {
                        w[k] += dir.dot(*ax).max(0.0) * dw;
                    }
                    let near = &mut self.seen[s as usize];
                    match near.iter_mut().find(|(q, _)| *q == pi) {
                        Some(e) => e.1 = e.1.min(*t),
                        None => near.push((pi, *t)),
                    }
                }
                RayOut::Sky { dir } => {
                    // Light arriving from `dir` travels along `-dir`.
                    let bin = dirs::nearest_dir(-*dir);
                    for (k, ax) in AMBIENT_AXES.iter().enumerate() {
                        sky[k][bin] += dir.dot(*ax).max(0.0) * dw / omega[bin];
                    }
                }
            }
        }
        let start = self.factors.len() as u32;
        self.factors.extend(order.iter().map(|bi| BrickFactor {
            brick: *bi,
            weights: by_brick[bi],
        }));
        self.probes.push(Probe {
            position: p,
            sky,
            factors: start..self.factors.len() as u32,
        });
    }

    /// The probe set: surfels as the means of their hits, bricks and links as offset
    /// tables, each surfel linked to its nearest probes (the exterior probes that see it
    /// through an opening, for a surfel outside the room of an interior bake), weighted
    /// by inverse squared distance.
    fn finish(
        mut self,
        scene: &RayScene<'_>,
        interior: Option<(&InteriorBox, &ProbeSet)>,
    ) -> ProbeSet {
        let params = self.params;
        let surfels: Vec<Surfel> = self
            .acc
            .iter()
            .map(|(p, nrm, alb, c)| {
                let c = *c as f32;
                Surfel {
                    position: *p / c,
                    normal: nrm.try_normalize().unwrap_or(Vec3::Y),
                    albedo: (*alb / c).clamp(Vec3::ZERO, Vec3::ONE),
                    hits: c as u32,
                }
            })
            .collect();
        let mut brick_start = Vec::with_capacity(self.brick_members.len() + 1);
        let mut brick_surfels = Vec::new();
        for m in &self.brick_members {
            brick_start.push(brick_surfels.len() as u32);
            brick_surfels.extend_from_slice(m);
        }
        brick_start.push(brick_surfels.len() as u32);
        let mut link_start = Vec::with_capacity(surfels.len() + 1);
        let mut links = Vec::new();
        let floor = params.cell * params.cell;
        for (s, near) in self.seen.iter_mut().enumerate() {
            link_start.push(links.len() as u32);
            if let (true, Some((room, ext))) = (self.outside[s], interior) {
                // Seen through an opening: lit by the exterior probes that see it.
                *near = nearest_visible(
                    scene,
                    ext,
                    room,
                    surfels[s].position + surfels[s].normal * (0.05 * params.cell),
                    params.probes_per_surfel as usize,
                );
            }
            near.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            near.truncate(params.probes_per_surfel as usize);
            let w: Vec<f32> = near.iter().map(|(_, t)| 1.0 / (t * t).max(floor)).collect();
            let sum: f32 = w.iter().sum();
            links.extend(near.iter().zip(&w).map(|((q, _), w)| (*q, w / sum)));
        }
        link_start.push(links.len() as u32);
        ProbeSet {
            params: *params,
            probes: self.probes,
            surfels,
            brick_start,
            brick_surfels,
            factors: self.factors,
            link_start,
            links,
            interior: interior.map(|(room, _)| *room),
            outside: self.outside,
            exterior_probes: interior.map_or(0, |(_, e)| e.probes.len() as u32),
        }
    }
}
