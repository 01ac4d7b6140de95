//! Relighting, once a frame (the CPU specification): surfels from the sun and last
//! frame's probes, bricks from their surfels, probes from their bricks and the sky.

use lightgrid_core::glam::Vec3;
use lightgrid_core::light::AmbientCube;
use lightgrid_core::{BinLight, GridError, NUM_DIRS};
use rayon::prelude::*;

use crate::{ProbeError, ProbeSet};

/// The light of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// What a ray leaving the scene sees, all round: full-sphere bins (radiance × bin
    /// solid angle, light travelling along each bin's direction), as
    /// `BinLight::uniform(L)` for a uniform sky of radiance `L`.
    pub sky: BinLight,
    /// The sun: direction toward it and its irradiance on a surface facing it, or none.
    pub sun: Option<(Vec3, Vec3)>,
}

impl Lighting {
    fn validate(&self) -> Result<(), GridError> {
        if !self.sky.is_valid() {
            return Err(GridError::invalid(
                "sky",
                self.sky,
                "light must be finite and >= 0",
            ));
        }
        if let Some((s, e)) = self.sun {
            lightgrid_core::light::check_sun(s, e)?;
        }
        Ok(())
    }
}

/// The relit state: every probe's irradiance (ambient cube) and every surfel's
/// radiance, carried from frame to frame (each frame adds one bounce).
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeLight {
    probes: Vec<AmbientCube>,
    surfels: Vec<Vec3>,
    bricks: Vec<Vec3>,
    frames: u32,
}

impl ProbeLight {
    /// Dark: no frame yet.
    pub fn new(set: &ProbeSet) -> Self {
        Self {
            probes: vec![AmbientCube::default(); set.probes().len()],
            surfels: vec![Vec3::ZERO; set.surfels().len()],
            bricks: vec![Vec3::ZERO; set.brick_count()],
            frames: 0,
        }
    }

    /// One frame:
    ///
    /// 1. each surfel's irradiance is the sun's, `E V max(0, n · s)` with its visibility
    ///    `V` ([`ProbeSet::sun_visibility`]), plus last frame's probes that saw it
    ///    evaluated on its normal (ambient cube, weights by inverse squared distance):
    ///    sky and bounce light; its radiance is `albedo × E / π`;
    /// 2. each brick's radiance is the hit-weighted mean of its surfels';
    /// 3. each probe's irradiance on axis `k` is `Σ_bricks w_k L_brick` plus
    ///    `Σ_bins sky[k][b] × sky_b`.
    ///
    /// The direct sun is not in the probes (renderers shade it with their own shadows).
    /// An interior set ([`ProbeSet::bake_interior`]) needs [`ProbeLight::frame_interior`].
    pub fn frame(
        &mut self,
        set: &ProbeSet,
        lighting: &Lighting,
        sun_visibility: &[f32],
    ) -> Result<(), ProbeError> {
        if set.interior().is_some() {
            return Err(GridError::invalid(
                "set",
                "interior set",
                "its outside surfels need the exterior's light: relight it with frame_interior",
            )
            .into());
        }
        self.frame_with(set, lighting, sun_visibility, None)
    }

    /// One frame of an interior set ([`ProbeSet::bake_interior`]): as
    /// [`ProbeLight::frame`], but the surfels outside the room's box (seen through its
    /// openings) take their probe light from `exterior`, the exterior set's light (relit
    /// first this frame).
    pub fn frame_interior(
        &mut self,
        set: &ProbeSet,
        lighting: &Lighting,
        sun_visibility: &[f32],
        exterior: &ProbeLight,
    ) -> Result<(), ProbeError> {
        if exterior.probes.len() != set.exterior_probes() || set.interior().is_none() {
            return Err(GridError::LengthMismatch {
                field: "exterior",
                expected: set.exterior_probes(),
                found: exterior.probes.len(),
            }
            .into());
        }
        self.frame_with(set, lighting, sun_visibility, Some(exterior))
    }

    fn frame_with(
        &mut self,
        set: &ProbeSet,
        lighting: &Lighting,
        sun_visibility: &[f32],
        exterior: Option<&ProbeLight>,
    ) -> Result<(), ProbeError> {
        lighting.validate()?;
        if sun_visibility.len() != set.surfels().len() {
            return Err(GridError::LengthMismatch {
                field: "sun_visibility",
                expected: set.surfels().len(),
                found: sun_visibility.len(),
            }
            .into());
        }
        if self.probes.len() != set.probes().len() || self.surfels.len() != set.surfels().len() {
            return Err(GridError::invalid(
                "set",
                set.probes().len(),
                "is not the probe set this light was made for",
            )
            .into());
        }
        let sun = lighting
            .sun
            .map(|(s, e)| (s.normalize(), e))
            .filter(|(s, _)| s.is_finite());
        let last = &self.probes;
        self.surfels.par_iter_mut().enumerate().for_each(|(i, l)| {
            let sf = &set.surfels()[i];
            let mut e = Vec3::ZERO;
            let probes = match exterior {
                Some(ext) if set.surfel_outside(i) => &ext.probes,
                _ => last,
            };
            for &(p, w) in set.surfel_links(i) {
                e += probes[p as usize].irradiance(sf.normal) * w;
            }
            if let Some((s, irr)) = sun {
                e += irr * (sun_visibility[i].clamp(0.0, 1.0) * sf.normal.dot(s).max(0.0));
            }
            *l = sf.albedo * e / std::f32::consts::PI;
        });
        let surfels = &self.surfels;
        self.bricks.par_iter_mut().enumerate().for_each(|(b, l)| {
            let (mut sum, mut hits) = (Vec3::ZERO, 0u32);
            for &s in set.brick(b) {
                let h = set.surfels()[s as usize].hits;
                sum += surfels[s as usize] * h as f32;
                hits += h;
            }
            *l = if hits > 0 {
                sum / hits as f32
            } else {
                Vec3::ZERO
            };
        });
        let bricks = &self.bricks;
        let sky = &lighting.sky;
        self.probes
            .par_iter_mut()
            .zip(set.probes())
            .for_each(|(cube, probe)| {
                let mut e = [Vec3::ZERO; 6];
                for f in &set.factors()[probe.factors.start as usize..probe.factors.end as usize] {
                    let l = bricks[f.brick as usize];
                    for (k, w) in f.weights.iter().enumerate() {
                        e[k] += l * *w;
                    }
                }
                for (k, ek) in e.iter_mut().enumerate() {
                    for b in 0..NUM_DIRS {
                        *ek += sky.0[b] * probe.sky[k][b];
                    }
                }
                *cube = AmbientCube(e);
            });
        self.frames += 1;
        Ok(())
    }

    /// Probe `i`'s irradiance on the six axes.
    pub fn probe(&self, i: usize) -> Option<&AmbientCube> {
        self.probes.get(i)
    }

    /// All probes' irradiance.
    pub fn probes(&self) -> &[AmbientCube] {
        &self.probes
    }

    /// Surfel radiances (what the probes saw this frame).
    pub fn surfels(&self) -> &[Vec3] {
        &self.surfels
    }

    /// Frames run.
    pub fn frames(&self) -> u32 {
        self.frames
    }
}
