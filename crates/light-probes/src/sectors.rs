//! Sectors streamed around the camera (The Division: probes split over a 2D grid of
//! sectors, streamed in and out with the player; the probes of a sector share its
//! surfels). Every probe position is placed once; a sector is baked when it comes
//! within reach and dropped when it leaves, within a memory budget, nearest first.

use std::collections::HashMap;

use lightgrid_core::GridError;
use lightgrid_core::glam::{IVec2, Vec2, Vec3};
use lightgrid_material_voxelizer::voxelize::RayScene;

use crate::{Lighting, ProbeError, ProbeLight, ProbeParams, ProbeSet};

/// One sector in memory: its probes, their light and the sun visibility of its
/// surfels (for the sun direction it was computed for).
pub struct LoadedSector {
    /// The sector's probes and surfels.
    pub set: ProbeSet,
    /// Their relit state.
    pub light: ProbeLight,
    sun: Option<(Vec3, Vec<f32>)>,
}

/// What [`Sectors::update`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SectorStats {
    /// Sectors baked this call (and kept).
    pub loaded: u32,
    /// Sectors dropped this call.
    pub evicted: u32,
    /// Wanted sectors left out by the budget.
    pub over_budget: u32,
    /// Sectors in memory afterwards.
    pub resident: u32,
    /// Their bytes ([`ProbeSet::bytes`]).
    pub bytes: usize,
}

/// The probe sectors of a scene.
pub struct Sectors<'a> {
    scene: &'a RayScene<'a>,
    params: ProbeParams,
    size: f32,
    origin: Vec2,
    reach: f32,
    /// Probe positions per sector.
    positions: HashMap<IVec2, Vec<Vec3>>,
    loaded: HashMap<IVec2, LoadedSector>,
}

impl<'a> Sectors<'a> {
    /// Places probes over the box `lo..hi` ([`crate::place`]) and sorts them into square
    /// sectors of `size` metres; a sector is wanted while the camera is within `reach`
    /// metres of it (horizontally).
    pub fn new(
        scene: &'a RayScene<'a>,
        lo: Vec3,
        hi: Vec3,
        params: &ProbeParams,
        size: f32,
        reach: f32,
    ) -> Result<Self, ProbeError> {
        params.validate()?;
        for (name, v) in [("size", size), ("reach", reach)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GridError::invalid(name, v, "must be finite and > 0").into());
            }
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(GridError::invalid("lo", lo, "bounds must be finite").into());
        }
        let origin = Vec2::new(lo.x, lo.z);
        let mut positions: HashMap<IVec2, Vec<Vec3>> = HashMap::new();
        for p in crate::place(scene, lo, hi, params) {
            let key = ((Vec2::new(p.x, p.z) - origin) / size).floor().as_ivec2();
            positions.entry(key).or_default().push(p);
        }
        Ok(Self {
            scene,
            params: *params,
            size,
            origin,
            reach,
            positions,
            loaded: HashMap::new(),
        })
    }

    /// Horizontal distance from `camera` to sector `key`'s square.
    fn distance(&self, key: IVec2, camera: Vec3) -> f32 {
        let lo = self.origin + key.as_vec2() * self.size;
        let hi = lo + Vec2::splat(self.size);
        let c = Vec2::new(camera.x, camera.z);
        (c - c.clamp(lo, hi)).length()
    }

    /// Streams: sectors within reach are wanted, nearest first; they are baked while the
    /// resident bytes stay within `budget_bytes`; resident sectors not wanted, or beyond
    /// the budget, are dropped.
    pub fn update(&mut self, camera: Vec3, budget_bytes: usize) -> Result<SectorStats, ProbeError> {
        if !camera.is_finite() {
            return Err(GridError::invalid("camera", camera, "must be finite").into());
        }
        let mut wanted: Vec<(f32, IVec2)> = self
            .positions
            .keys()
            .map(|k| (self.distance(*k, camera), *k))
            .filter(|(d, _)| *d <= self.reach)
            .collect();
        wanted.sort_by(|a, b| {
            a.0.total_cmp(&b.0)
                .then(a.1.x.cmp(&b.1.x))
                .then(a.1.y.cmp(&b.1.y))
        });
        let mut stats = SectorStats::default();
        let mut keep: Vec<IVec2> = Vec::new();
        let mut fresh: Vec<IVec2> = Vec::new();
        let mut bytes = 0usize;
        for (_, key) in &wanted {
            if !self.loaded.contains_key(key) {
                if bytes >= budget_bytes {
                    stats.over_budget += 1;
                    continue;
                }
                let set =
                    ProbeSet::bake(self.scene, &self.positions[key], &self.params, &|_, _| {})?;
                let light = ProbeLight::new(&set);
                self.loaded.insert(
                    *key,
                    LoadedSector {
                        set,
                        light,
                        sun: None,
                    },
                );
                fresh.push(*key);
            }
            let b = self.loaded[key].set.bytes();
            if bytes + b > budget_bytes {
                stats.over_budget += 1;
                continue;
            }
            bytes += b;
            keep.push(*key);
        }
        let dropped: Vec<IVec2> = self
            .loaded
            .keys()
            .filter(|k| !keep.contains(k))
            .copied()
            .collect();
        for k in dropped {
            self.loaded.remove(&k);
            if !fresh.contains(&k) {
                stats.evicted += 1;
            }
        }
        stats.loaded = fresh.iter().filter(|k| keep.contains(k)).count() as u32;
        stats.resident = self.loaded.len() as u32;
        stats.bytes = bytes;
        Ok(stats)
    }

    /// One relighting frame of every resident sector; each sector's sun visibility is
    /// computed again when the sun's direction changed.
    pub fn frame(&mut self, lighting: &Lighting) -> Result<(), ProbeError> {
        let to_sun = lighting.sun.map(|(s, _)| s).unwrap_or(Vec3::ZERO);
        for s in self.loaded.values_mut() {
            if s.sun.as_ref().is_none_or(|(d, _)| *d != to_sun) {
                let vis = if to_sun == Vec3::ZERO {
                    vec![0.0; s.set.surfels().len()]
                } else {
                    s.set.sun_visibility(self.scene, to_sun)
                };
                s.sun = Some((to_sun, vis));
            }
            let vis = &s.sun.as_ref().expect("just set").1;
            s.light.frame(&s.set, lighting, vis)?;
        }
        Ok(())
    }

    /// The resident sectors and their keys (sector `(i, k)` spans `origin + (i, k) × size`).
    pub fn resident(&self) -> impl Iterator<Item = (IVec2, &LoadedSector)> {
        self.loaded.iter().map(|(k, s)| (*k, s))
    }

    /// Sectors that hold probes.
    pub fn sector_count(&self) -> usize {
        self.positions.len()
    }

    /// The sector holding world `(x, z)`.
    pub fn sector_at(&self, p: Vec3) -> IVec2 {
        ((Vec2::new(p.x, p.z) - self.origin) / self.size)
            .floor()
            .as_ivec2()
    }
}
