//! Tracing one light's indirect (and direct) light into a volume, 3DWorld's way: rays
//! from the light, closest hits in the mesh BVH, diffuse bounces with the surface's
//! albedo, every segment deposited into every grid cell it crosses (the exact walk of
//! [`lightgrid_core::dda`], shared with sweep-cpu's Monte Carlo reference).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use lightgrid_core::glam::Vec3;
use lightgrid_core::{BinLight, GridDesc, GridError, LightGrid, NUM_DIRS, dda, dirs};
use lightgrid_material_voxelizer::voxelize::RayScene;
use rayon::prelude::*;

use crate::light::{Light, cosine};

/// How to trace a light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceParams {
    /// Rays emitted (1 M is a typical default).
    pub rays: u64,
    /// Bounces traced in full; beyond them Russian roulette (survival = the albedo's
    /// largest channel) ends paths without bias.
    pub max_bounces: u32,
    /// Hard limit of bounces (with roulette).
    pub bounce_limit: u32,
    /// Random seed: the same seed gives the same volume on any thread count.
    pub seed: u64,
}

impl TraceParams {
    /// A quick preview: 100 k rays, 2 full bounces.
    pub const fn preview() -> Self {
        Self {
            rays: 100_000,
            max_bounces: 2,
            bounce_limit: 16,
            seed: 1,
        }
    }
    /// The default: 1 M rays, 4 full bounces.
    pub const fn standard() -> Self {
        Self {
            rays: 1_000_000,
            max_bounces: 4,
            bounce_limit: 32,
            seed: 1,
        }
    }
}

impl Default for TraceParams {
    fn default() -> Self {
        Self::standard()
    }
}

/// What a trace did, with its time split between BVH queries and deposits.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TraceStats {
    /// Rays emitted.
    pub rays: u64,
    /// Ray segments traced (emission and bounces).
    pub segments: u64,
    /// Segments that hit a surface.
    pub hits: u64,
    /// Summed over threads: time in BVH queries.
    pub bvh_time: Duration,
    /// Summed over threads: time depositing segments into cells.
    pub deposit_time: Duration,
    /// Wall time.
    pub wall: Duration,
}

impl TraceStats {
    /// Segments per second of BVH time (per thread).
    pub fn rays_per_second_bvh(&self) -> f64 {
        self.segments as f64 / self.bvh_time.as_secs_f64().max(1e-12)
    }
    /// Segments per second of wall time, deposits included (all threads).
    pub fn rays_per_second(&self) -> f64 {
        self.segments as f64 / self.wall.as_secs_f64().max(1e-12)
    }
}

const CHUNK: u64 = 8192;

/// Traces `light` through `scene` into a volume on `desc` (white light of unit power:
/// the volume's bins hold fluence per unit emitted power). `progress(done, total)` is
/// called as chunks of rays finish. Deterministic for a seed on any thread count: rays
/// are drawn from per-ray random streams, each chunk sums its deposits (in `f32`), and
/// the chunks are merged in order (in `f64`).
pub fn trace_light(
    scene: &RayScene<'_>,
    desc: &GridDesc,
    light: &Light,
    params: &TraceParams,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(LightGrid, TraceStats), GridError> {
    light.validate()?;
    if params.rays == 0 {
        return Err(GridError::invalid("rays", 0, "must be at least 1"));
    }
    let _span = tracing::info_span!("trace light", rays = params.rays).entered();
    let start = Instant::now();
    let dims = desc.dims().as_ivec3();
    let h = desc.h();
    let origin = desc.origin();
    // The grid's box in world space (cells span ± h/2 around points): rays leaving it
    // are followed no further than its far side.
    let lo = origin - Vec3::splat(0.5 * h);
    let hi = origin + (desc.dims().as_vec3() - Vec3::splat(0.5)) * h;
    let diag = (hi - lo).length();
    let to_grid = |p: Vec3| (p - origin) / h;
    let chunks = params.rays.div_ceil(CHUNK);
    let done = AtomicU64::new(0);
    let bvh_ns = AtomicU64::new(0);
    let dep_ns = AtomicU64::new(0);
    let seg_count = AtomicU64::new(0);
    let hit_count = AtomicU64::new(0);
    let sums: Vec<Vec<(u32, Vec3)>> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            // This chunk's deposits, in ray order (summed in f32 below, per slot).
            let mut acc: Vec<(u32, Vec3)> = Vec::with_capacity(1 << 16);
            let (mut t_bvh, mut t_dep) = (Duration::ZERO, Duration::ZERO);
            let (mut segs, mut hits) = (0u64, 0u64);
            let end = ((c + 1) * CHUNK).min(params.rays);
            for i in c * CHUNK..end {
                let mut rng =
                    fastrand::Rng::with_seed(params.seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15));
                let (mut o, mut d, w) = light.emit([rng.f32(), rng.f32(), rng.f32(), rng.f32()]);
                let mut w = Vec3::splat(w);
                let mut bounce = 0u32;
                loop {
                    let t = Instant::now();
                    let hit = scene.closest_hit(o, d, diag * 2.0, rng.f32());
                    t_bvh += t.elapsed();
                    segs += 1;
                    let end_t = hit.map_or(diag * 2.0, |h| h.t);
                    let t = Instant::now();
                    let bin = dirs::nearest_dir(d) as u32;
                    dda::walk_segment(to_grid(o), to_grid(o + d * end_t), dims, |cell, len| {
                        let ci = (cell.x + dims.x * (cell.z + dims.z * cell.y)) as u32;
                        acc.push((ci * NUM_DIRS as u32 + bin, w * len));
                    });
                    t_dep += t.elapsed();
                    let Some(hit) = hit else { break };
                    hits += 1;
                    w *= hit.colour;
                    bounce += 1;
                    if bounce > params.max_bounces {
                        let survive = hit.colour.max_element().min(0.95);
                        if bounce > params.bounce_limit || rng.f32() >= survive {
                            break;
                        }
                        w /= survive;
                    }
                    if w.max_element() <= 0.0 {
                        break;
                    }
                    o = o + d * hit.t + hit.normal * 1e-4;
                    d = cosine(hit.normal, rng.f32(), rng.f32());
                }
            }
            bvh_ns.fetch_add(t_bvh.as_nanos() as u64, Ordering::Relaxed);
            dep_ns.fetch_add(t_dep.as_nanos() as u64, Ordering::Relaxed);
            seg_count.fetch_add(segs, Ordering::Relaxed);
            hit_count.fetch_add(hits, Ordering::Relaxed);
            let n = done.fetch_add(end - c * CHUNK, Ordering::Relaxed) + end - c * CHUNK;
            progress(n, params.rays);
            // Sum per slot in f32 (a chunk's sums are small), sorted by slot.
            acc.sort_by_key(|d| d.0);
            let mut summed: Vec<(u32, Vec3)> = Vec::with_capacity(acc.len() / 4);
            for (slot, v) in acc {
                match summed.last_mut() {
                    Some(last) if last.0 == slot => last.1 += v,
                    _ => summed.push((slot, v)),
                }
            }
            summed
        })
        .collect();
    // Merge the chunks in order, in f64.
    let n = desc.point_count();
    let mut total = vec![[0f64; 3]; n * NUM_DIRS];
    for chunk in &sums {
        for &(k, v) in chunk {
            let t = &mut total[k as usize];
            t[0] += v.x as f64;
            t[1] += v.y as f64;
            t[2] += v.z as f64;
        }
    }
    // Fluence per unit power: Σ w·length / (rays · cell volume); lengths are in cells.
    let scale = 1.0 / (params.rays as f64 * (h as f64).powi(2));
    let data = (0..n)
        .map(|p| {
            BinLight(std::array::from_fn(|d| {
                let t = total[p * NUM_DIRS + d];
                Vec3::new(
                    (t[0] * scale) as f32,
                    (t[1] * scale) as f32,
                    (t[2] * scale) as f32,
                )
            }))
        })
        .collect();
    let stats = TraceStats {
        rays: params.rays,
        segments: seg_count.into_inner(),
        hits: hit_count.into_inner(),
        bvh_time: Duration::from_nanos(bvh_ns.into_inner()),
        deposit_time: Duration::from_nanos(dep_ns.into_inner()),
        wall: start.elapsed(),
    };
    Ok((lightgrid_core::Grid::from_trusted(*desc, data), stats))
}
