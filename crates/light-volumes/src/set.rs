//! A set of local lights over one grid: lights turn on and off and change colour and
//! intensity; the combined grid changes only inside the changed light's box (its
//! volume times the old factor is subtracted, times the new one added), and the box is
//! recorded as dirty for a sparse GPU upload.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, Grid, GridDesc, GridError, LightField, LightGrid};

use crate::volume::CompressedVolume;

/// Handle of a light in a [`LightSet`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct LightId(usize);

/// A box of points `[lo, hi]` (inclusive) of the combined grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// Lowest point.
    pub lo: UVec3,
    /// Highest point.
    pub hi: UVec3,
}

impl Region {
    /// Points inside.
    pub fn point_count(&self) -> usize {
        let d = self.hi - self.lo + UVec3::ONE;
        d.x as usize * d.y as usize * d.z as usize
    }
    fn union(self, o: Region) -> Region {
        Region {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
}

struct Entry {
    /// The white volume, decoded, on the combined grid's points of `region`.
    volume: Vec<BinLight>,
    region: Region,
    /// Colour × intensity while on; zero while off.
    factor: Vec3,
    colour: Vec3,
    intensity: f32,
    on: bool,
}

/// Local lights merged into one grid.
pub struct LightSet {
    combined: LightGrid,
    lights: Vec<Entry>,
    dirty: Option<Region>,
}

/// How far (in spacings) a volume's origin may lie from one of the set's points and be
/// snapped onto it by [`LightSet::add`].
pub const SNAP: f32 = 1e-3;

impl LightSet {
    /// An empty set over `desc` (every light's volume must lie on this grid's points).
    pub fn new(desc: GridDesc) -> Result<Self, GridError> {
        Ok(Self {
            combined: Grid::filled(desc, BinLight::ZERO)?,
            lights: Vec::new(),
            dirty: None,
        })
    }

    /// The combined light.
    pub fn grid(&self) -> &LightGrid {
        &self.combined
    }

    /// Adds a light (on) from its compressed white volume, with its colour and intensity.
    ///
    /// The volume must lie on the set's points: its spacing equal to the set's (to 1e-6
    /// of it) and its origin on a point, within [`SNAP`] of a spacing (it is snapped
    /// there), with the whole box inside the set's grid. Anything else is refused with
    /// [`GridError`] naming `volume.desc`.
    pub fn add(
        &mut self,
        volume: &CompressedVolume,
        colour: Vec3,
        intensity: f32,
    ) -> Result<LightId, GridError> {
        check_factor(colour, intensity)?;
        let d = *self.combined.desc();
        let (values, region) = match volume.decode() {
            Some(g) => {
                let vd = g.desc();
                let lo_f = (vd.origin() - d.origin()) / d.h();
                let lo = lo_f.round();
                if !lo_f.is_finite()
                    || (lo_f - lo).abs().max_element() > SNAP
                    || (vd.h() - d.h()).abs() > 1e-6 * d.h()
                    || lo.min_element() < 0.0
                {
                    return Err(GridError::invalid(
                        "volume.desc",
                        vd,
                        "must lie on the set's grid points",
                    ));
                }
                // In u64: a box far outside (an origin of 9e8 on 1e-4 m points) is
                // refused, not wrapped into the grid.
                let far = (0..3).any(|a| lo[a] as u64 + vd.dims()[a] as u64 > d.dims()[a] as u64);
                if lo.cmpge(d.dims().as_vec3()).any() || far {
                    return Err(GridError::invalid(
                        "volume.desc",
                        vd,
                        "reaches outside the set's grid",
                    ));
                }
                let lo = lo.as_uvec3();
                let hi = lo + vd.dims() - UVec3::ONE;
                (g.into_data(), Region { lo, hi })
            }
            None => (
                Vec::new(),
                Region {
                    lo: UVec3::ZERO,
                    hi: UVec3::ZERO,
                },
            ),
        };
        self.lights.push(Entry {
            volume: values,
            region,
            factor: Vec3::ZERO,
            colour,
            intensity,
            on: false,
        });
        let id = LightId(self.lights.len() - 1);
        self.set_on(id, true)?;
        Ok(id)
    }

    /// Turns a light on or off.
    pub fn set_on(&mut self, id: LightId, on: bool) -> Result<(), GridError> {
        let e = self.entry(id)?;
        let (c, i) = (e.colour, e.intensity);
        self.lights[id.0].on = on;
        self.apply(id, if on { c * i } else { Vec3::ZERO });
        Ok(())
    }

    /// Changes a light's colour and intensity (kept while it is off).
    pub fn set_colour(
        &mut self,
        id: LightId,
        colour: Vec3,
        intensity: f32,
    ) -> Result<(), GridError> {
        check_factor(colour, intensity)?;
        self.entry(id)?;
        let e = &mut self.lights[id.0];
        e.colour = colour;
        e.intensity = intensity;
        let on = e.on;
        if on {
            self.apply(id, colour * intensity);
        }
        Ok(())
    }

    /// Whether a light is on.
    pub fn is_on(&self, id: LightId) -> Result<bool, GridError> {
        Ok(self.entry(id)?.on)
    }

    /// The region changed since the last call (to upload), and clears it.
    pub fn take_dirty(&mut self) -> Option<Region> {
        self.dirty.take()
    }

    fn entry(&self, id: LightId) -> Result<&Entry, GridError> {
        self.lights
            .get(id.0)
            .ok_or_else(|| GridError::invalid("light", id.0, "no such light"))
    }

    /// Adds `(new − old factor) × volume` inside the light's region only.
    fn apply(&mut self, id: LightId, factor: Vec3) {
        let e = &mut self.lights[id.0];
        let delta = factor - e.factor;
        e.factor = factor;
        if delta == Vec3::ZERO || e.volume.is_empty() {
            return;
        }
        let r = e.region;
        let d = *self.combined.desc();
        let nx = (r.hi.x - r.lo.x + 1) as usize;
        let nz = (r.hi.z - r.lo.z + 1) as usize;
        let data = self.combined.data_mut();
        let mut k = 0;
        for y in r.lo.y..=r.hi.y {
            for z in r.lo.z..=r.hi.z {
                let row = d.index_unchecked(UVec3::new(r.lo.x, y, z));
                for x in 0..nx {
                    let dst = &mut data[row + x];
                    let src = &e.volume[k];
                    for b in 0..lightgrid_core::NUM_DIRS {
                        // Subtracting can leave -1e-9 where the sum was a light alone.
                        // Clamped to f32's range too: the sum of many bright lights must
                        // not become infinity (and NaN when it is subtracted again).
                        dst.0[b] =
                            (dst.0[b] + src.0[b] * delta).clamp(Vec3::ZERO, Vec3::splat(f32::MAX));
                    }
                    k += 1;
                }
            }
        }
        debug_assert_eq!(k, nx * nz * (r.hi.y - r.lo.y + 1) as usize);
        self.dirty = Some(self.dirty.map_or(r, |d| d.union(r)));
    }
}

/// Largest colour × intensity of one light.
pub const MAX_FACTOR: f32 = 1e30;

fn check_factor(colour: Vec3, intensity: f32) -> Result<(), GridError> {
    if !(colour.is_finite() && colour.cmpge(Vec3::ZERO).all()) {
        return Err(GridError::invalid(
            "colour",
            colour,
            "must be finite and >= 0",
        ));
    }
    if !(intensity.is_finite() && intensity >= 0.0) {
        return Err(GridError::invalid(
            "intensity",
            intensity,
            "must be finite and >= 0",
        ));
    }
    let product = colour * intensity;
    if !(product.is_finite() && product.max_element() <= MAX_FACTOR) {
        return Err(GridError::invalid(
            "colour x intensity",
            product,
            "must be at most 1e30",
        ));
    }
    Ok(())
}

impl LightField for LightSet {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        self.combined.light(p, n)
    }
}
