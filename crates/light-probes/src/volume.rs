//! The probes merged into a regular volume (The Division's camera-based volume map):
//! what a renderer samples trilinearly per pixel, so opaque and translucent surfaces
//! both get the probes' light.
//!
//! Which probes light a volume point, and how much, depends on geometry only, so it is
//! worked out once ([`ProbeVolume::new`]: a ray to every probe within reach); each frame
//! is then a sparse sum ([`ProbeVolume::resolve`]).

use std::collections::HashMap;

use lightgrid_core::glam::{IVec3, Vec3};
use lightgrid_core::light::AmbientCube;
use lightgrid_core::{BinLight, Grid, GridDesc, GridError, LightField, dirs};
use lightgrid_material_voxelizer::voxelize::RayScene;
use rayon::prelude::*;

use crate::{ProbeError, ProbeLight, ProbeSet};

/// One probe's share of a volume point.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    set: u32,
    probe: u32,
    weight: f32,
}

/// The weights that merge probe sets into the points of a regular volume.
///
/// A point takes the probes of each set within `1.5 ×` that set's spacing that it can
/// see (a clear ray; so light does not leak through walls), weighted `(1 - (d/r)²)²`
/// and normalised per set. An interior set ([`ProbeSet::bake_interior`]) takes the
/// share [`crate::InteriorBox::weight`] of the points in its box, the exterior set the
/// rest; a set that sees no probe from a point gives its share to the others. A point
/// that sees no probe at all is **uncovered** (inside solid geometry, or where probes
/// are missing: The Division's debug view marks those red).
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeVolume {
    desc: GridDesc,
    start: Vec<u32>,
    entries: Vec<Entry>,
    set_sizes: Vec<usize>,
}

impl ProbeVolume {
    /// The weights for `desc` from `sets` (the exterior set and any interior sets, in
    /// the order [`ProbeVolume::resolve`] gets their light). `progress(done, total)` is
    /// called as levels finish.
    pub fn new(
        scene: &RayScene<'_>,
        desc: GridDesc,
        sets: &[&ProbeSet],
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self, ProbeError> {
        if sets.is_empty() {
            return Err(GridError::invalid("sets", 0, "give at least one probe set").into());
        }
        let index: Vec<SetIndex<'_>> = sets
            .iter()
            .map(|s| {
                let r = 1.5 * s.params().spacing;
                let mut cells: HashMap<IVec3, Vec<u32>> = HashMap::new();
                for (i, p) in s.probes().iter().enumerate() {
                    cells
                        .entry((p.position / r).floor().as_ivec3())
                        .or_default()
                        .push(i as u32);
                }
                SetIndex { set: s, r, cells }
            })
            .collect();
        let level = desc.level_len();
        let levels = desc.levels() as usize;
        let done = std::sync::atomic::AtomicUsize::new(0);
        let per_level: Vec<Vec<Vec<Entry>>> = (0..levels)
            .into_par_iter()
            .map(|j| {
                let out = (0..level)
                    .map(|i| {
                        let p = desc.position(desc.coords(j * level + i).expect("in range"));
                        point_entries(scene, &index, p)
                    })
                    .collect();
                let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(k, levels);
                out
            })
            .collect();

        let mut start = Vec::with_capacity(desc.point_count() + 1);
        let mut entries = Vec::new();
        for e in per_level.into_iter().flatten() {
            start.push(entries.len() as u32);
            entries.extend(e);
        }
        start.push(entries.len() as u32);
        Ok(Self {
            desc,
            start,
            entries,
            set_sizes: sets.iter().map(|s| s.probes().len()).collect(),
        })
    }

    /// The volume's points.
    pub fn desc(&self) -> &GridDesc {
        &self.desc
    }

    /// Points that see at least one probe.
    pub fn covered(&self) -> usize {
        self.start.windows(2).filter(|w| w[1] > w[0]).count()
    }

    /// Bytes of the weights (12 a probe share, 4 a point).
    pub fn bytes(&self) -> usize {
        self.entries.len() * std::mem::size_of::<Entry>() + self.start.len() * 4
    }

    /// This frame's volume from the sets' light (in the order of [`ProbeVolume::new`]):
    /// each covered point the weighted sum of its probes' ambient cubes; uncovered
    /// points next to covered ones take their covered neighbours' mean (two rings), so
    /// trilinear lookups at surfaces do not darken toward the inside of walls.
    pub fn resolve(&self, lights: &[&ProbeLight]) -> Result<ResolvedVolume, ProbeError> {
        if lights.len() != self.set_sizes.len() {
            return Err(GridError::LengthMismatch {
                field: "lights",
                expected: self.set_sizes.len(),
                found: lights.len(),
            }
            .into());
        }
        for (l, n) in lights.iter().zip(&self.set_sizes) {
            if l.probes().len() != *n {
                return Err(GridError::LengthMismatch {
                    field: "lights[..].probes",
                    expected: *n,
                    found: l.probes().len(),
                }
                .into());
            }
        }
        let mut cubes: Vec<AmbientCube> = (0..self.desc.point_count())
            .into_par_iter()
            .map(|i| {
                let mut e = [Vec3::ZERO; 6];
                for en in &self.entries[self.start[i] as usize..self.start[i + 1] as usize] {
                    let c = &lights[en.set as usize].probes()[en.probe as usize].0;
                    for (ek, ck) in e.iter_mut().zip(c) {
                        *ek += *ck * en.weight;
                    }
                }
                AmbientCube(e)
            })
            .collect();
        let covered: Vec<bool> = self.start.windows(2).map(|w| w[1] > w[0]).collect();
        let mut filled = covered.clone();
        let dims = self.desc.dims().as_ivec3();
        for _ in 0..2 {
            let grow: Vec<(usize, AmbientCube)> = (0..cubes.len())
                .into_par_iter()
                .filter(|i| !filled[*i])
                .filter_map(|i| {
                    let c = self.desc.coords(i).expect("in range").as_ivec3();
                    let (mut sum, mut n) = ([Vec3::ZERO; 6], 0);
                    for d in [
                        IVec3::X,
                        IVec3::NEG_X,
                        IVec3::Y,
                        IVec3::NEG_Y,
                        IVec3::Z,
                        IVec3::NEG_Z,
                    ] {
                        let q = c + d;
                        if q.cmplt(IVec3::ZERO).any() || q.cmpge(dims).any() {
                            continue;
                        }
                        let j = self.desc.index_unchecked(q.as_uvec3());
                        if filled[j] {
                            for (s, v) in sum.iter_mut().zip(&cubes[j].0) {
                                *s += *v;
                            }
                            n += 1;
                        }
                    }
                    (n > 0).then(|| (i, AmbientCube(sum.map(|s| s / n as f32))))
                })
                .collect();
            for (i, c) in grow {
                cubes[i] = c;
                filled[i] = true;
            }
        }
        Ok(ResolvedVolume {
            cubes: Grid::from_trusted(self.desc, cubes),
            filled: Grid::from_trusted(
                self.desc,
                filled.iter().map(|f| if *f { 1.0 } else { 0.0 }).collect(),
            ),
            covered,
        })
    }
}

/// One set's probes hashed in cells of their reach.
struct SetIndex<'s> {
    set: &'s ProbeSet,
    r: f32,
    cells: HashMap<IVec3, Vec<u32>>,
}

/// The probe shares of one point (see [`ProbeVolume`]).
fn point_entries(scene: &RayScene<'_>, index: &[SetIndex<'_>], p: Vec3) -> Vec<Entry> {
    let room: Vec<f32> = index
        .iter()
        .map(|x| x.set.interior().map_or(0.0, |b| b.weight(p)))
        .collect();
    let inside = room.iter().copied().fold(0.0f32, f32::max);
    let mut parts: Vec<(f32, Vec<Entry>)> = Vec::new();
    for (si, SetIndex { set, r, cells }) in index.iter().enumerate() {
        let share = if set.interior().is_some() {
            room[si]
        } else {
            1.0 - inside
        };
        if share <= 0.0 {
            continue;
        }
        let k = (p / *r).floor().as_ivec3();
        let mut found = Vec::new();
        let mut sum = 0.0f32;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(list) = cells.get(&(k + IVec3::new(dx, dy, dz))) else {
                        continue;
                    };
                    for &q in list {
                        let to = set.probes()[q as usize].position - p;
                        let d = to.length();
                        if d >= *r {
                            continue;
                        }
                        let clear = d < 1e-4 || scene.closest_hit(p, to / d, d, 0.5).is_none();
                        if clear {
                            let x = d / *r;
                            let w = (1.0 - x * x).powi(2);
                            sum += w;
                            found.push(Entry {
                                set: si as u32,
                                probe: q,
                                weight: w,
                            });
                        }
                    }
                }
            }
        }
        if sum > 0.0 {
            found.sort_by_key(|e| e.probe);
            for e in &mut found {
                e.weight /= sum;
            }
            parts.push((share, found));
        }
    }
    let total: f32 = parts.iter().map(|(s, _)| s).sum();
    parts
        .into_iter()
        .flat_map(|(s, es)| {
            es.into_iter().map(move |mut e| {
                e.weight *= s / total;
                e
            })
        })
        .collect()
}

/// One frame's probe light on a regular volume: an ambient cube a point, read
/// trilinearly. As a [`LightField`], its bins are the radiance `E(u) / π` the cube gives
/// each direction `u` the light comes from (exact for uniform light, blurred for
/// directional: renderers that need the irradiance take [`LightField::irradiance`],
/// which reads the cube itself). It keeps no sun apart (`sun_transmittance` is 0).
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedVolume {
    cubes: Grid<AmbientCube>,
    covered: Vec<bool>,
    /// 1 where covered or given its neighbours' mean, else 0.
    filled: Grid<f32>,
}

impl ResolvedVolume {
    /// The points.
    pub fn desc(&self) -> &GridDesc {
        self.cubes.desc()
    }

    /// The ambient cube of every point (x fastest, then z, then y).
    pub fn cubes(&self) -> &[AmbientCube] {
        self.cubes.data()
    }

    /// Whether each point saw a probe (uncovered points near covered ones hold their
    /// neighbours' mean; the rest are dark).
    pub fn covered(&self) -> &[bool] {
        &self.covered
    }

    /// How much of the trilinear lookup at `p` falls on points holding probe light
    /// (covered or filled from covered neighbours): 1 where the probes light `p` fully,
    /// 0 away from every probe. A renderer can fall back to another light by `1 - c`.
    pub fn coverage(&self, p: Vec3) -> Result<f32, GridError> {
        Ok(self.filled.sample(p)?.clamp(0.0, 1.0))
    }

    /// The ambient cube at `p`, trilinear, clamped at the volume's edges; errors on a
    /// non-finite `p`.
    pub fn cube_at(&self, p: Vec3) -> Result<AmbientCube, GridError> {
        self.cubes.sample(p)
    }

    /// The cube at `p`, or half a cell along the normal `n` (as light grids are read).
    fn cube_biased(&self, p: Vec3, n: Option<Vec3>) -> Result<AmbientCube, GridError> {
        match n {
            Some(n) => self.cubes.sample_biased(p, n),
            None => self.cubes.sample(p),
        }
    }
}

/// Bins from an ambient cube: bin `d` (light travelling along `t_d`, arriving from
/// `-t_d`) holds `E(-t_d) / π × ω_d`.
pub fn cube_to_bins(cube: &AmbientCube) -> BinLight {
    let omega = dirs::solid_angles();
    BinLight(std::array::from_fn(|d| {
        cube.irradiance(-dirs::dir_unit(d)) * (omega[d] / std::f32::consts::PI)
    }))
}

impl LightField for ResolvedVolume {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        Ok(cube_to_bins(&self.cube_biased(p, n)?))
    }

    /// The cube's own irradiance facing `n` (sharper than the bins').
    fn irradiance(&self, p: Vec3, n: Vec3) -> Result<Vec3, GridError> {
        Ok(self.cube_biased(p, Some(n))?.irradiance(n.normalize()))
    }
}
