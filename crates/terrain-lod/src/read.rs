//! What a renderer reads from the hierarchy: its grids as layers ([`Hierarchy::layers`]),
//! the grid serving a point ([`Hierarchy::grid_at`]) and the hierarchy as a
//! [`LightField`] (bins, horizon halves, the sun's transmittance, the light volume's
//! moments).

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{
    BinLight, GridError, HorizonGrid, HorizonLight, LightField, LightGrid, Reading,
};

use crate::{GridSun, Hierarchy, Layer, LayerSun, Owner, SunLight, volume, within_levels};

impl Hierarchy {
    /// The grids for layered sampling: the world grid, then the ready nodes by depth
    /// (see [`Layer`]).
    pub fn layers(&self) -> Vec<Layer<'_>> {
        fn layer_sun(g: &GridSun) -> LayerSun<'_> {
            LayerSun {
                scattered: &g.scattered,
                horizon: g.horizon.as_ref(),
                transmittance: &g.transmittance,
                resident: g.resident.as_ref(),
            }
        }
        let mut v = vec![Layer {
            grid: &self.world,
            resident: self.world_resident.as_ref(),
            horizon: self.world_horizon.as_ref(),
            owner: None,
            sun: self.world_sun.as_ref().map(layer_sun),
        }];
        for key in self.ready_nodes() {
            let n = &self.nodes[&key];
            v.push(Layer {
                grid: &n.light,
                resident: n.resident.as_ref(),
                horizon: n.horizon.as_ref(),
                sun: if self.sun_shown(key) {
                    n.sun.as_ref().map(layer_sun)
                } else {
                    None
                },
                owner: Some(Owner {
                    origin: self.heightmap_lo,
                    size: self.params.node_size(key.depth),
                    index: key.index,
                }),
            });
        }
        v
    }

    /// The finest ready grid containing `p` (the world grid if none).
    pub fn grid_at(&self, p: Vec3) -> &LightGrid {
        self.serving(p).0
    }

    /// The finest ready grid containing `p` and its horizon halves, if kept.
    fn serving(&self, p: Vec3) -> (&LightGrid, Option<&HorizonGrid>) {
        for d in (1..=self.params.depths()).rev() {
            let key = self.node_at(d, Vec2::new(p.x, p.z));
            if let Some(n) = self.nodes.get(&key)
                && within_levels(n.light.desc(), p)
            {
                return (&n.light, n.horizon.as_ref());
            }
        }
        (&self.world, self.world_horizon.as_ref())
    }
}

/// What one point reads, from the grid serving it and the grid holding its sun: the
/// three reads of [`LightField`] and [`LightField::reading`] are made of these, so that
/// they agree bit for bit.
impl Hierarchy {
    /// With the sun kept apart, the sun and the finest grid at `p` with a current sun
    /// response.
    fn sun_at(&self, p: Vec3) -> Option<(SunLight, &GridSun)> {
        let sun = self.sun?;
        Some((sun, self.coarse_sun(p, self.params.depths() + 1, true)?))
    }

    /// The sky's bins of `grid` times the sky scale, plus the sun's scattered light.
    fn bins_at(
        &self,
        grid: &LightGrid,
        sun: Option<(SunLight, &GridSun)>,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<BinLight, GridError> {
        let sky = grid.light(p, n)? * self.sky_scale;
        Ok(match sun {
            Some((s, g)) => sky + g.scattered.light(p, n)? * s.irradiance,
            None => sky,
        })
    }

    /// The sky's `halves` times the sky scale, plus the sun's scattered light's (its
    /// bins split evenly where its grid keeps no halves) times the sun's irradiance.
    fn halves_at(
        &self,
        halves: &HorizonGrid,
        sun: Option<(SunLight, &GridSun)>,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<HorizonLight, GridError> {
        let read = |h: &HorizonGrid| match n {
            Some(n) => h.sample_biased(p, n),
            None => h.sample(p),
        };
        let sky = read(halves)? * self.sky_scale;
        Ok(match sun {
            Some((s, g)) => {
                let scattered = match &g.horizon {
                    Some(h) => read(h)?,
                    None => HorizonLight::even(&g.scattered.light(p, n)?),
                };
                sky + scattered * s.irradiance
            }
            None => sky,
        })
    }

    /// The sun's transmittance at `p` in `[0, 1]` (0 without a sun).
    fn transmittance_at(
        sun: Option<(SunLight, &GridSun)>,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<f32, GridError> {
        let Some((_, g)) = sun else {
            return Ok(0.0);
        };
        let t = match n {
            Some(n) => g.transmittance.sample_biased(p, n)?,
            None => g.transmittance.sample(p)?,
        };
        // (Trilinear weights may sum to 1 + 1 ulp.)
        Ok(t.clamp(0.0, 1.0))
    }
}

/// The light of the finest ready grid at `p` ([`Hierarchy::grid_at`]) times the sky
/// scale; with the sun kept apart, plus the sun's scattered light of the finest grid at
/// `p` with a current sun response times the sun's irradiance, and the transmittance
/// of that grid.
impl LightField for Hierarchy {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        self.bins_at(self.grid_at(p), self.sun_at(p), p, n)
    }
    /// The horizon halves of the finest ready grid at `p` times the sky scale, plus with
    /// the sun kept apart those of the sun's scattered light read as [`LightField::light`]
    /// reads it (its bins split evenly where that grid keeps no halves), times the
    /// sun's irradiance; `None` where the grid serving `p` keeps no halves
    /// (`HierarchyParams::sweep.outputs.horizon` off).
    fn horizon(&self, p: Vec3, n: Option<Vec3>) -> Result<Option<HorizonLight>, GridError> {
        let Some(halves) = self.serving(p).1 else {
            return Ok(None);
        };
        self.halves_at(halves, self.sun_at(p), p, n).map(Some)
    }
    /// Every grid reduced once to the moments a light volume stores (the sky scale and
    /// the sun's irradiance folded in): 7 numbers a corner instead of 52 bins.
    fn volume_sampler(
        &self,
    ) -> Option<Box<dyn Fn(Vec3) -> Result<lightgrid_core::VolumeSample, GridError> + Sync + '_>>
    {
        let r = volume::Reduced::new(self);
        Some(Box::new(move |p| r.sample(p)))
    }

    /// The three reads with the serving grid and the sun's grid found once.
    fn reading(&self, p: Vec3, n: Option<Vec3>) -> Result<Reading, GridError> {
        if !p.is_finite() {
            return Err(GridError::invalid("p", p, "must be finite"));
        }
        let (grid, halves) = self.serving(p);
        let sun = self.sun_at(p);
        let horizon = match (n, halves) {
            (Some(_), Some(h)) => Some(self.halves_at(h, sun, p, n)?),
            _ => None,
        };
        Ok(Reading {
            light: self.bins_at(grid, sun, p, n)?,
            horizon,
            sun: Self::transmittance_at(sun, p, n)?,
        })
    }

    fn sun_transmittance(&self, p: Vec3, n: Option<Vec3>) -> Result<f32, GridError> {
        if !p.is_finite() {
            return Err(GridError::invalid("p", p, "must be finite"));
        }
        Self::transmittance_at(self.sun_at(p), p, n)
    }
}
