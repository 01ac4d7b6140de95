//! Sun transmittance: how much of the sun's uncollided beam reaches each grid point,
//! along the sun's **exact** direction (not the nearest of the 26 bins).
//!
//! The first step of the first-collision split (issue 14): the beam is attenuated
//! exactly, and only what it loses is scattered into the bins. Two ways to compute it:
//!
//! - [`SunTransmittance::march`] — the specification: from every point, an exact DDA
//!   walk ([`lightgrid_core::dda::walk_segment`], the walk the Monte Carlo reference
//!   uses) toward the sun to the grid's box, `T = Π p_c^ℓ_c` (pass-through `p` per cell
//!   length, `ℓ` the length inside cell `c` in cells), times what the light had already
//!   lost where the ray leaves the box (`outside`: 1 for open sky; a coarser grid's
//!   transmittance for a fine grid of the hierarchy).
//! - [`SunTransmittance::sheared`] — the cheap form a sweep can do level by level: a
//!   point's transmittance is that of the level above, read bilinearly where the ray
//!   crosses it, times its own cell's and the upper cell's pass-through over the half
//!   steps between. Exact for media uniform along each level; it blurs shadows by the
//!   bilinear read (measured against the march in the tests and in
//!   `cargo run --release -p lightgrid-measure --example sun`).
//!
//! Both return one scalar per point in grid order; a sun at or below the horizon gives
//! zero everywhere (no direct sun).
//!
//! What the beam loses cell by cell (its first collisions, scattered by the sweep) is
//! traced apart, by parallel rays that conserve the beam: [`crate::beam`].
//!
//! Measured (`cargo run --release -p lightgrid-measure --example sun`, 64³, 2-core VM): the
//! march takes 94–118 ms, the sheared form 8–23 ms. The sheared form's mean absolute
//! error is 0.003–0.011 over all points, but in half-shadow (0.05 < T < 0.95 by the
//! march) it is 0.015–0.064 on the canopy and 0.06–0.61 beside the dense block, worst
//! for low suns: every level's bilinear read widens a shadow edge by up to a cell, so a
//! block's sharp shadow is smeared over the levels below it. The march is the
//! reference; the sheared form is a candidate only for soft media.
//!
//! **The split against the sun in the bins**, both against the Monte Carlo reference
//! with a collimated sun along its exact direction (`reference::trace_with_sun`, its
//! uncollided light kept apart), sun light only, azimuth 20° (between bins), 16³ cells,
//! 2 M reference paths (`cargo run --release -p lightgrid-measure --example sun_split`; medium
//! emission by a slab's escape, issue 13): relative RMSE of average light / of
//! irradiance on the six axes.
//!
//! | scene | elevation | bins | split | reference noise |
//! |-------|----------:|-----:|------:|----------------:|
//! | canopy | 10° | 0.064 / 0.288 | 0.036 / 0.037 | 0.013 |
//! | canopy | 25° | 0.223 / 0.428 | 0.014 / 0.015 | 0.012 |
//! | canopy | 40° | 0.048 / 0.206 | 0.010 / 0.012 | 0.011 |
//! | canopy | 60° | 0.218 / 0.376 | 0.010 / 0.011 | 0.011 |
//! | canopy | 80° | 0.027 / 0.146 | 0.010 / 0.012 | 0.011 |
//! | dense block | 10° | 0.301 / 0.407 | 0.066 / 0.068 | 0.012 |
//! | dense block | 25° | 0.232 / 0.433 | 0.042 / 0.046 | 0.011 |
//! | dense block | 40° | 0.083 / 0.209 | 0.035 / 0.040 | 0.011 |
//! | dense block | 60° | 0.206 / 0.382 | 0.037 / 0.043 | 0.011 |
//! | dense block | 80° | 0.053 / 0.153 | 0.034 / 0.040 | 0.011 |
//!
//! The split's first collisions are traced rays ([`crate::beam`]); with the earlier
//! rule, which counted only what crosses a cell's top and bottom, the split's average
//! light was 0.037 / 0.017 / 0.012 / 0.013 / 0.015 on the canopy and 0.073 / 0.049 /
//! 0.041 / 0.042 / 0.036 on the dense block at the same elevations.
//!
//! Irradiance improves 4–20× everywhere (the bins move the sun along the nearest bin);
//! average light improves in every case, to the reference's own noise on the canopy
//! from 40° up.
//!
//! The shadow of a dense 2 × 6 × 2 block on a periodic ground (same example): the
//! azimuth of the centroid of the missing ground irradiance, against the exact one
//! (away from the sun). Sun at 40°/30°, 30°/20°, 55°/67°, 25°/112° (elevation/azimuth):
//! the bins are off by 15°, 12°, 23°, 23° (the sun moves along the nearest bin); the
//! split by 0.7°, 0.2°, 1.8°, 0.4°.

use lightgrid_core::glam::{IVec3, Vec3};
use lightgrid_core::{GridDesc, GridError, MaterialGrid};
use rayon::prelude::*;

pub use crate::beam::{
    BeamBudget, BeamOptions, FirstCollisions, first_collision, first_collisions,
};

/// Cell steps per cell of `nx + ny + nz` after which a periodic march stops.
pub const MAX_STEPS_PER_CELL: u32 = 64;

/// The sun's transmittance at every point of a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct SunTransmittance {
    desc: GridDesc,
    values: Vec<f32>,
}

/// The unit direction toward the sun, or `None` at or below the horizon; errors on a
/// zero or non-finite vector (the GPU march takes its direction from here).
pub fn sun_direction(to_sun: Vec3) -> Result<Option<Vec3>, GridError> {
    if !to_sun.is_finite() || to_sun.length_squared() == 0.0 {
        return Err(GridError::invalid(
            "to_sun",
            to_sun,
            "must be a finite, non-zero direction",
        ));
    }
    let d = to_sun.normalize();
    Ok((d.y > 0.0).then_some(d))
}

impl SunTransmittance {
    /// The exact march (see the module docs). With `periodic` sides a ray leaving
    /// through a side comes back through the opposite one (the world repeats, as the
    /// sweep's periodic sides say) until it leaves through the top; otherwise it leaves
    /// at the side. `outside(world)` is the transmittance already lost where the ray
    /// leaves the grid's box (1 for open sky); its values are clamped to `[0, 1]` (NaN
    /// counts as 0). A periodic ray is followed for at most [`MAX_STEPS_PER_CELL`] ×
    /// (nx + ny + nz) cell steps (suns within a fraction of a degree of the horizon),
    /// then `outside` is read where it stopped; a ray darker than `e^-60` stops as 0.
    pub fn march(
        material: &MaterialGrid,
        to_sun: Vec3,
        periodic: bool,
        outside: &(dyn Fn(Vec3) -> f32 + Sync),
    ) -> Result<Self, GridError> {
        let desc = *material.desc();
        let Some(dir) = sun_direction(to_sun)? else {
            return Ok(Self::zero(desc));
        };
        let dims = desc.dims().as_ivec3();
        let cells = material.data();
        let max_steps = MAX_STEPS_PER_CELL * (dims.x + dims.y + dims.z) as u32;
        let clamp01 = |o: f32| if o.is_nan() { 0.0 } else { o.clamp(0.0, 1.0) };
        let values = (0..desc.point_count())
            .into_par_iter()
            .map(|i| {
                let mut cell = desc.coords(i).expect("in range").as_ivec3();
                let mut pos = cell.as_vec3();
                // Where the walk is in the unwrapped world (for `outside`).
                let mut shift = Vec3::ZERO;
                let mut log_t = 0.0f32;
                for _ in 0..max_steps {
                    let p = cells[desc.index_unchecked(cell.as_uvec3())].pass;
                    let (s, axis) = lightgrid_core::dda::exit(cell, pos, dir);
                    if s > 0.0 {
                        if p <= 0.0 {
                            return 0.0;
                        }
                        log_t += s * p.ln();
                        if log_t < -60.0 {
                            return 0.0;
                        }
                    }
                    pos += dir * s;
                    let step = lightgrid_core::dda::cross(&mut cell, &mut pos, axis, dir);
                    if cell[axis] >= 0 && cell[axis] < dims[axis] {
                        continue;
                    }
                    if axis == 1 || !periodic {
                        let exit = desc.origin() + (pos + shift) * desc.h();
                        return log_t.exp() * clamp01(outside(exit));
                    }
                    // Wrap to the opposite side.
                    let n = dims[axis];
                    cell[axis] = cell[axis].rem_euclid(n);
                    let back = if step > 0 { -(n as f32) } else { n as f32 };
                    pos[axis] += back;
                    shift[axis] -= back;
                }
                let stop = desc.origin() + (pos + shift) * desc.h();
                log_t.exp() * clamp01(outside(stop))
            })
            .collect();
        Ok(Self { desc, values })
    }

    /// The sheared level-by-level form (see the module docs); `outside` as for
    /// [`SunTransmittance::march`], read where a step's ray leaves the grid.
    pub fn sheared(
        material: &MaterialGrid,
        to_sun: Vec3,
        outside: &(dyn Fn(Vec3) -> f32 + Sync),
    ) -> Result<Self, GridError> {
        let desc = *material.desc();
        let Some(dir) = sun_direction(to_sun)? else {
            return Ok(Self::zero(desc));
        };
        let d = desc.dims();
        let (nx, ny, nz) = (d.x as usize, d.y as usize, d.z as usize);
        let level = nx * nz;
        let cells = material.data();
        // Horizontal shift per level climbed, and the half-step exponent (cells of path
        // per half level).
        let shift = (dir.x / dir.y, dir.z / dir.y);
        let half = 0.5 / dir.y;
        let pass = |j: usize, x: f32, z: f32| -> f32 {
            // Nearest cell of level j, or open sky beside the grid.
            let (ix, iz) = (x.round(), z.round());
            if ix < 0.0 || iz < 0.0 || ix >= nx as f32 || iz >= nz as f32 {
                return 1.0;
            }
            cells[j * level + ix as usize + nx * iz as usize].pass
        };
        let clamp01 = |o: f32| if o.is_nan() { 0.0 } else { o.clamp(0.0, 1.0) };
        let mut values = vec![0.0f32; desc.point_count()];
        // Top level: through the upper half of its own cell to the box's top face.
        let top = ny - 1;
        for z in 0..nz {
            for x in 0..nx {
                let (qx, qz) = (x as f32 + 0.5 * shift.0, z as f32 + 0.5 * shift.1);
                let exit = desc.origin() + Vec3::new(qx, top as f32 + 0.5, qz) * desc.h();
                let p = cells[top * level + x + nx * z].pass;
                values[top * level + x + nx * z] = p.powf(half) * clamp01(outside(exit));
            }
        }
        for j in (0..top).rev() {
            let (below, above) = values.split_at_mut((j + 1) * level);
            let above = &above[..level];
            below[j * level..]
                .par_chunks_mut(nx)
                .enumerate()
                .for_each(|(z, row)| {
                    for (x, out) in row.iter_mut().enumerate() {
                        let (fx, fz) = (x as f32, z as f32);
                        // Where the ray meets level j + 1.
                        let (qx, qz) = (fx + shift.0, fz + shift.1);
                        let up =
                            if qx < 0.0 || qz < 0.0 || qx > (nx - 1) as f32 || qz > (nz - 1) as f32
                            {
                                let w =
                                    desc.origin() + Vec3::new(qx, (j + 1) as f32, qz) * desc.h();
                                clamp01(outside(w))
                            } else {
                                bilinear(above, nx, nz, qx, qz)
                            };
                        let lower = pass(j, fx + 0.25 * shift.0, fz + 0.25 * shift.1);
                        let upper = pass(j + 1, fx + 0.75 * shift.0, fz + 0.75 * shift.1);
                        *out = (lower * upper).powf(half) * up;
                    }
                });
        }
        Ok(Self { desc, values })
    }

    /// Values computed elsewhere (the GPU march): one per point of `desc`, each finite
    /// and in `[0, 1]`.
    pub fn from_values(desc: GridDesc, values: Vec<f32>) -> Result<Self, GridError> {
        if values.len() != desc.point_count() {
            return Err(GridError::LengthMismatch {
                field: "values",
                expected: desc.point_count(),
                found: values.len(),
            });
        }
        if let Some(i) = values.iter().position(|v| !(0.0..=1.0).contains(v)) {
            return Err(GridError::invalid(
                format!("values[{i}]"),
                values[i],
                "must be in [0, 1]",
            ));
        }
        Ok(Self { desc, values })
    }

    /// Zero everywhere (the sun below the horizon).
    pub fn zero(desc: GridDesc) -> Self {
        Self {
            desc,
            values: vec![0.0; desc.point_count()],
        }
    }

    /// Where the points are.
    pub fn desc(&self) -> &GridDesc {
        &self.desc
    }

    /// One value per point, grid order, each in `[0, 1]`.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Trilinear value at world position `p`, clamped at the grid's edges; errors on a
    /// non-finite `p`.
    pub fn sample(&self, p: Vec3) -> Result<f32, GridError> {
        if !p.is_finite() {
            return Err(GridError::invalid("p", p, "must be finite"));
        }
        let g = self.desc.to_grid(p);
        Ok(lightgrid_core::trilinear_corners(self.desc.dims(), g)
            .iter()
            .map(|(c, w)| self.values[self.desc.index_unchecked(*c)] * w)
            .sum())
    }

    /// The value at a point.
    pub fn get(&self, c: IVec3) -> Option<f32> {
        let d = self.desc.dims().as_ivec3();
        (c.cmpge(IVec3::ZERO).all() && c.cmplt(d).all())
            .then(|| self.values[self.desc.index_unchecked(c.as_uvec3())])
    }
}

/// The sun and the sky kept apart, three responses (issue 14): the sky's light (26
/// bins, for the sky boundary as given), the sun's scattered light (26 bins, for a sun
/// of irradiance 1) and the sun's transmittance along its exact direction. Sky and sun
/// colours then change by a multiply; a new sun direction recomputes the sun's two
/// responses only ([`SunSplit::resun`]). The direct sun is never in the bins: its
/// irradiance on a normal is `E T max(0, n · s)` with the exact direction.
#[derive(Debug, Clone)]
pub struct SunSplit {
    /// Sky light (26 bins).
    pub sky: lightgrid_core::LightGrid,
    /// The sun's light after at least one scattering, for unit irradiance (26 bins).
    pub sun_scattered: lightgrid_core::LightGrid,
    /// The sun's transmittance at every point.
    pub transmittance: SunTransmittance,
    /// Unit direction toward the sun.
    pub to_sun: Vec3,
}

impl SunSplit {
    /// Sweeps the sky (`sky`: its top light and sides) and the sun toward `to_sun` (at
    /// or below the horizon: no sun) with any sweeper that takes cell sources.
    pub fn compute(
        sweeper: &mut dyn lightgrid_core::Sweeper,
        material: &MaterialGrid,
        sky: &lightgrid_core::Boundary,
        to_sun: Vec3,
        options: &lightgrid_core::SweepOptions,
    ) -> Result<Self, lightgrid_core::SweepError> {
        // The split keeps bins alone: average and dominant direction are not computed.
        let mut o = *options;
        o.outputs = lightgrid_core::Outputs {
            bins: true,
            average: false,
            dominant: false,
            horizon: false,
        };
        let sky_light = sweeper
            .sweep(material, sky, &o)?
            .bins
            .expect("bins asked for");
        let mut split = Self {
            sky: sky_light,
            sun_scattered: lightgrid_core::LightGrid::filled(
                *material.desc(),
                lightgrid_core::BinLight::ZERO,
            )?,
            transmittance: SunTransmittance::zero(*material.desc()),
            to_sun: Vec3::Y,
        };
        split.resun(sweeper, material, &sky.sides, to_sun, &o)?;
        Ok(split)
    }

    /// Moves the sun: the transmittance and the sun's scattered light are computed again
    /// (open or periodic sides as the sky's; a given halo is taken as dark, since it holds
    /// sky light: a hierarchy will pass its coarser grid's sun response instead), the
    /// sky's light is kept.
    pub fn resun(
        &mut self,
        sweeper: &mut dyn lightgrid_core::Sweeper,
        material: &MaterialGrid,
        sides: &lightgrid_core::SideBoundary,
        to_sun: Vec3,
        options: &lightgrid_core::SweepOptions,
    ) -> Result<(), lightgrid_core::SweepError> {
        // Only the first collisions bring light: no boundary light at all.
        let dark = lightgrid_core::Boundary {
            sides: match sides {
                lightgrid_core::SideBoundary::Given(h)
                | lightgrid_core::SideBoundary::GivenHalves { light: h, .. } => {
                    lightgrid_core::SideBoundary::Given(vec![
                        lightgrid_core::BinLight::ZERO;
                        h.len()
                    ])
                }
                other => other.clone(),
            },
            ..lightgrid_core::Boundary::open_sky(lightgrid_core::BinLight::ZERO)
        };
        let sun = lightgrid_core::SunBoundary {
            to_sun,
            scattered: dark,
            outside: &|_| 1.0,
        };
        let r = sweep_sun(sweeper, material, &sun, options)?;
        self.sun_scattered = r.scattered;
        self.transmittance =
            SunTransmittance::from_values(*material.desc(), r.transmittance.into_data())?;
        self.to_sun = sun_direction(to_sun)?.unwrap_or(Vec3::Y);
        Ok(())
    }

    /// The 26 bins of sky and scattered sun light for a sky of colour `sky` and a sun
    /// of irradiance `sun` (what exports and bin-based renderers take; the direct sun is
    /// [`SunSplit::direct`]).
    pub fn bins(&self, sky: Vec3, sun: Vec3) -> lightgrid_core::LightGrid {
        let data = self
            .sky
            .data()
            .iter()
            .zip(self.sun_scattered.data())
            .map(|(a, b)| *a * sky + *b * sun)
            .collect();
        lightgrid_core::Grid::from_trusted(*self.sky.desc(), data)
    }

    /// The direct sun's irradiance on a surface at `p` facing `n`: `E T(p) max(0, n·s)`.
    pub fn direct(&self, p: Vec3, n: Vec3, sun: Vec3) -> Result<Vec3, GridError> {
        Ok(sun * (self.transmittance.sample(p)? * n.dot(self.to_sun).max(0.0)))
    }

    /// All light on a surface at `p` facing unit `n`: sky and scattered sun from the
    /// bins (read with the normal bias) plus the direct sun.
    pub fn irradiance(&self, p: Vec3, n: Vec3, sky: Vec3, sun: Vec3) -> Result<Vec3, GridError> {
        use lightgrid_core::LightField;
        let bins = self.sky.irradiance(p, n)? * sky + self.sun_scattered.irradiance(p, n)? * sun;
        Ok(bins + self.direct(p, n, sun)?)
    }
}

/// The sun's two responses in one grid ([`lightgrid_core::Sweeper::sweep_sun`]; the
/// implementation the CPU and GPU sweepers share): the exact march
/// ([`SunTransmittance::march`], wrapping when `sun.scattered` has periodic sides,
/// `sun.outside` beyond the box), the first collisions ([`first_collision`]: traced
/// rays, unit irradiance) and one sweep of them with `sweeper` into the bins, `sun.scattered` the
/// boundary light. A sun at or below the horizon has no beam: transmittance 0, and the
/// bins hold only what `sun.scattered` brings. The horizon halves of the scattered
/// light come with it where `options.outputs.horizon` asks for them. The first
/// scatterings are gathered where `options.gather.for_sun(sun.to_sun)` says.
pub fn sweep_sun(
    sweeper: &mut dyn lightgrid_core::Sweeper,
    material: &MaterialGrid,
    sun: &lightgrid_core::SunBoundary<'_>,
    options: &lightgrid_core::SweepOptions,
) -> Result<lightgrid_core::SunResponse, lightgrid_core::SweepError> {
    let periodic = matches!(sun.scattered.sides, lightgrid_core::SideBoundary::Periodic);
    let t = transmittance(material, sun)?;
    // The scattered sun is kept as bins (and the horizon halves where asked for):
    // average and dominant direction, which the response does not hold, are not
    // computed.
    let mut o = *options;
    o.outputs = lightgrid_core::Outputs {
        bins: true,
        average: false,
        dominant: false,
        horizon: options.outputs.horizon,
    };
    o.gather = options.gather.for_sun(sun.to_sun);
    let out = if sun_direction(sun.to_sun)?.is_some() {
        let src = first_collision(material, sun.to_sun, Vec3::ONE, periodic, sun.outside)?;
        sweeper.sweep_with_source(material, &sun.scattered, &src, &o)?
    } else {
        sweeper.sweep(material, &sun.scattered, &o)?
    };
    Ok(lightgrid_core::SunResponse {
        scattered: out.bins.expect("bins asked for"),
        horizon: out.horizon,
        transmittance: t,
        stats: out.stats,
        resident: out.resident,
    })
}

/// A grid's light and a sun beam's first collisions in one sweep
/// ([`lightgrid_core::Sweeper::sweep_with_sun`]; the implementation the CPU and GPU
/// sweepers share): the beam traced as in [`sweep_sun`] ([`first_collision`] with
/// `sun.irradiance`, wrapping on periodic sides of `boundary`, `sun.outside` beyond the
/// box) and swept with `boundary`'s light (its first scatterings gathered where
/// `options.gather.for_sun(sun.to_sun)` says). A sun at or below the horizon adds
/// nothing: the plain sweep of `boundary`.
pub fn sweep_with_sun(
    sweeper: &mut dyn lightgrid_core::Sweeper,
    material: &MaterialGrid,
    boundary: &lightgrid_core::Boundary,
    sun: &lightgrid_core::SunBeam<'_>,
    options: &lightgrid_core::SweepOptions,
) -> Result<lightgrid_core::SweepOutput, lightgrid_core::SweepError> {
    if sun_direction(sun.to_sun)?.is_none() {
        return sweeper.sweep(material, boundary, options);
    }
    let periodic = matches!(boundary.sides, lightgrid_core::SideBoundary::Periodic);
    let src = first_collision(material, sun.to_sun, sun.irradiance, periodic, sun.outside)?;
    let mut o = *options;
    o.gather = options.gather.for_sun(sun.to_sun);
    sweeper.sweep_with_source(material, boundary, &src, &o)
}

/// The transmittance part of [`sweep_sun`] alone
/// ([`lightgrid_core::Sweeper::sun_transmittance`] of the CPU and GPU sweepers): the
/// exact march, wrapping when `sun.scattered` has periodic sides, `sun.outside` beyond
/// the box.
pub fn transmittance(
    material: &MaterialGrid,
    sun: &lightgrid_core::SunBoundary<'_>,
) -> Result<lightgrid_core::Grid<f32>, GridError> {
    let periodic = matches!(sun.scattered.sides, lightgrid_core::SideBoundary::Periodic);
    let t = SunTransmittance::march(material, sun.to_sun, periodic, sun.outside)?;
    Ok(lightgrid_core::Grid::from_trusted(t.desc, t.values))
}

/// Bilinear read of a level (`nx × nz`, x fastest) at `(x, z)` inside its point range.
fn bilinear(level: &[f32], nx: usize, nz: usize, x: f32, z: f32) -> f32 {
    let (x0, z0) = (
        (x.floor() as usize).min(nx.saturating_sub(2)),
        (z.floor() as usize).min(nz.saturating_sub(2)),
    );
    let (x1, z1) = ((x0 + 1).min(nx - 1), (z0 + 1).min(nz - 1));
    let (fx, fz) = (
        (x - x0 as f32).clamp(0.0, 1.0),
        (z - z0 as f32).clamp(0.0, 1.0),
    );
    let at = |x: usize, z: usize| level[x + nx * z];
    let a = at(x0, z0) + (at(x1, z0) - at(x0, z0)) * fx;
    let b = at(x0, z1) + (at(x1, z1) - at(x0, z1)) * fx;
    a + (b - a) * fz
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::glam::UVec3;
    use lightgrid_core::{Grid, Material};
    use proptest::prelude::*;

    fn grid(dims: UVec3, pass: impl Fn(UVec3) -> f32) -> MaterialGrid {
        let desc = GridDesc::new(Vec3::new(-3.0, 1.0, 2.0), 0.5, dims).unwrap();
        let data = (0..desc.point_count())
            .map(|i| Material {
                reflectance: Vec3::splat(0.5),
                pass: pass(desc.coords(i).unwrap()),
            })
            .collect();
        Grid::new(desc, data).unwrap()
    }

    const OPEN: &(dyn Fn(Vec3) -> f32 + Sync) = &|_| 1.0;

    /// The sky and a sun swept together are the sky swept alone plus the irradiance
    /// times the sun's scattered response (the sweep is linear), bin for bin, with a
    /// side given (a node's halo) and with periodic sides; a sun below the horizon
    /// adds nothing.
    #[test]
    fn a_sun_swept_with_the_sky_is_their_sum() {
        use lightgrid_core::{
            BinLight, Boundary, HaloLayout, SideBoundary, SunBeam, SunBoundary, Sweeper,
        };
        let m = grid(UVec3::new(6, 5, 7), |c| match c.y {
            0 => 0.0,
            1 | 2 if (c.x + c.z) % 3 != 0 => 0.4,
            _ => 1.0,
        });
        let sky = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0))
            .split_vertical()
            .0;
        let halo = (0..HaloLayout::new(m.desc().dims()).len())
            .map(|i| sky.scaled(0.3 + (i % 5) as f32 / 10.0))
            .collect();
        let mut o = lightgrid_core::SweepOptions::multi_bounce();
        o.max_passes = 4;
        o.tolerance = 0.0;
        let e = Vec3::new(2.0, 3.0, 4.0);
        let outside = |p: Vec3| 0.5 + 0.4 * (p.x * 1.3).sin();
        for (sides, to_sun) in [
            (SideBoundary::Given(halo), Vec3::new(0.7, 0.4, -0.3)),
            (SideBoundary::Periodic, Vec3::new(-0.2, 0.9, 0.4)),
            (SideBoundary::Periodic, Vec3::new(0.3, -0.1, 0.2)),
        ] {
            let b = Boundary {
                sides: sides.clone(),
                ..Boundary::open_sky(sky)
            };
            let mut s = crate::CpuSweeper::new();
            let beam = SunBeam {
                to_sun,
                irradiance: e,
                outside: &outside,
            };
            let both = s.sweep_with_sun(&m, &b, &beam, &o).unwrap().bins.unwrap();
            let alone = s.sweep(&m, &b, &o).unwrap().bins.unwrap();
            let sun = SunBoundary {
                to_sun,
                // The same sides, dark: a given side's ground goes on beyond it
                // (`sweep::exposure`), an open side's would not.
                scattered: Boundary {
                    sides: match &sides {
                        SideBoundary::Given(h) => {
                            SideBoundary::Given(vec![BinLight::ZERO; h.len()])
                        }
                        other => other.clone(),
                    },
                    ..Boundary::open_sky(BinLight::ZERO)
                },
                outside: &outside,
            };
            let scattered = sweep_sun(&mut s, &m, &sun, &o).unwrap().scattered;
            let top = both
                .data()
                .iter()
                .flat_map(|b| b.0)
                .map(|c| c.max_element());
            let top = top.fold(0.0, f32::max);
            assert!(top > 0.0);
            for ((x, y), z) in both.data().iter().zip(alone.data()).zip(scattered.data()) {
                for k in 0..26 {
                    let want = y.0[k] + z.0[k] * e;
                    let d = (x.0[k] - want).abs().max_element();
                    assert!(d <= 1e-5 * top, "bin {k}: {} against {want}", x.0[k]);
                }
            }
        }
    }

    /// Distance along unit `dir` from `a` (inside the box) to where it leaves the box
    /// `[-0.5, dims - 0.5]` (grid coordinates).
    fn exit_distance(a: Vec3, dir: Vec3, dims: Vec3) -> f32 {
        let mut t = f32::INFINITY;
        for k in 0..3 {
            let face = if dir[k] > 0.0 {
                dims[k] - 0.5
            } else if dir[k] < 0.0 {
                -0.5
            } else {
                continue;
            };
            t = t.min(((face - a[k]) / dir[k]).max(0.0));
        }
        t
    }

    fn march_open(
        m: &MaterialGrid,
        to_sun: Vec3,
        outside: &(dyn Fn(Vec3) -> f32 + Sync),
    ) -> Result<SunTransmittance, GridError> {
        SunTransmittance::march(m, to_sun, false, outside)
    }

    /// A uniform medium: `p` to the power of the path length to the box, for every point
    /// whose ray leaves through the top (the march exactly; the sheared form too where
    /// every level crossing stays over the grid).
    #[test]
    fn uniform_medium_known_answer() {
        let p = 0.7f32;
        let m = grid(UVec3::new(40, 8, 36), |_| p);
        let to_sun = Vec3::new(0.3, 0.8, -0.2);
        let dir = to_sun.normalize();
        let march = SunTransmittance::march(&m, to_sun, false, OPEN).unwrap();
        let sheared = SunTransmittance::sheared(&m, to_sun, OPEN).unwrap();
        let dims = m.desc().dims().as_vec3();
        let (mut n_march, mut n_sheared) = (0, 0);
        for i in 0..m.desc().point_count() {
            let c = m.desc().coords(i).unwrap().as_vec3();
            let len = exit_distance(c, dir, dims);
            let exit = c + dir * len;
            if (exit.y - (dims.y - 0.5)).abs() > 1e-4 {
                continue; // leaves through a side
            }
            let want = p.powf(len);
            let got = march.values()[i];
            assert!(
                (got - want).abs() <= 1e-5 * want.max(1e-3),
                "{c}: {got} vs {want}"
            );
            n_march += 1;
            // The sheared form reads the level above bilinearly, so a point depends on a
            // cone widening by one point per level: compare where that cone stays over
            // the grid at every level.
            let levels = dims.y - 1.0 - c.y;
            let last = c + dir * (levels / dir.y);
            let inside = |q: Vec3| {
                q.x - levels >= 0.0
                    && q.x + levels <= dims.x - 1.0
                    && q.z - levels >= 0.0
                    && q.z + levels <= dims.z - 1.0
            };
            if inside(c) && inside(last) {
                let s = sheared.values()[i];
                assert!(
                    (s - want).abs() <= 1e-5 * want.max(1e-3),
                    "{c}: sheared {s} vs {want}"
                );
                n_sheared += 1;
            }
        }
        assert!(n_march > 5000 && n_sheared > 1000, "{n_march} {n_sheared}");
    }

    /// With periodic sides the medium repeats: in a uniform medium every point's ray
    /// wraps until it leaves through the top, `T = p^((ny - 1/2 - y) / cos θ)` exactly,
    /// even for a low sun that crosses the grid's width many times.
    #[test]
    fn periodic_uniform_medium_known_answer() {
        let p = 0.93f32;
        let m = grid(UVec3::new(5, 6, 4), |_| p);
        for to_sun in [Vec3::new(0.3, 0.8, -0.2), Vec3::new(-0.9, 0.12, 0.35)] {
            let dir = to_sun.normalize();
            let t = SunTransmittance::march(&m, to_sun, true, OPEN).unwrap();
            for i in 0..m.desc().point_count() {
                let y = m.desc().coords(i).unwrap().y as f32;
                let want = p.powf((6.0 - 0.5 - y) / dir.y);
                let got = t.values()[i];
                assert!(
                    (got - want).abs() <= 1e-4 * want,
                    "{to_sun} point {i}: {got} vs {want}"
                );
            }
        }
    }

    /// One opaque cell under a sun along a body diagonal shadows exactly the points
    /// behind it along that diagonal, and nothing else.
    #[test]
    fn opaque_cell_casts_its_shadow_along_the_exact_direction() {
        let blocker = UVec3::new(6, 7, 5);
        let m = grid(
            UVec3::new(12, 10, 12),
            |c| if c == blocker { 0.0 } else { 1.0 },
        );
        let t = SunTransmittance::march(&m, Vec3::new(1.0, 1.0, -1.0), false, OPEN).unwrap();
        for i in 0..m.desc().point_count() {
            let c = m.desc().coords(i).unwrap().as_ivec3();
            let d = blocker.as_ivec3() - c;
            // Behind the blocker along (1, 1, -1): d = k (1, 1, -1), k >= 0.
            let behind = d.x >= 0 && d.x == d.y && d.z == -d.x;
            assert_eq!(t.values()[i], if behind { 0.0 } else { 1.0 }, "{c}");
        }
    }

    #[test]
    fn sun_below_the_horizon_and_bad_directions() {
        let m = grid(UVec3::new(4, 3, 4), |_| 1.0);
        for f in [march_open, SunTransmittance::sheared] {
            let t = f(&m, Vec3::new(1.0, -0.1, 0.0), OPEN).unwrap();
            assert!(t.values().iter().all(|&v| v == 0.0));
            let e = f(&m, Vec3::ZERO, OPEN).unwrap_err().to_string();
            assert!(e.contains("to_sun"), "{e}");
            let e = f(&m, Vec3::new(f32::NAN, 1.0, 0.0), OPEN)
                .unwrap_err()
                .to_string();
            assert!(e.contains("to_sun"), "{e}");
            // What arrives from outside is clamped: NaN and negative count as 0, > 1 as 1.
            for (o, want) in [(f32::NAN, 0.0), (-2.0, 0.0), (7.0, 1.0)] {
                let t = f(&m, Vec3::Y, &move |_| o).unwrap();
                assert!(t.values().iter().all(|&v| v == want), "{o}");
            }
        }
    }

    fn random_grid() -> impl Strategy<Value = MaterialGrid> {
        (2u32..7, 2u32..6, 2u32..7, any::<u64>()).prop_map(|(x, y, z, seed)| {
            let mut r = fastrand::Rng::with_seed(seed);
            let v: Vec<f32> = (0..x * y * z)
                .map(|_| match r.u32(0..4) {
                    0 => 0.0,
                    1 => 1.0,
                    _ => r.f32(),
                })
                .collect();
            let dims = UVec3::new(x, y, z);
            grid(dims, |c| v[(c.x + x * (c.z + z * c.y)) as usize])
        })
    }

    proptest! {
        /// Under a zenith sun the two forms are the same product of half and whole
        /// cells, whatever the medium.
        #[test]
        fn zenith_sun_sheared_equals_march(m in random_grid(), o in 0.0f32..=1.0) {
            let outside = move |_: Vec3| o;
            let a = SunTransmittance::march(&m, Vec3::Y, false, &outside).unwrap();
            let b = SunTransmittance::sheared(&m, Vec3::Y, &outside).unwrap();
            for (x, y) in a.values().iter().zip(b.values()) {
                prop_assert!((x - y).abs() <= 1e-5, "{x} vs {y}");
            }
        }

        /// The transmittance alone (`Sweeper::sun_transmittance`: the CPU sweeper's
        /// march, and the trait's default, which runs the whole `sweep_sun`) is
        /// `sweep_sun`'s, bit for bit, with open and periodic sides and light outside.
        #[test]
        fn transmittance_alone_is_sweep_suns(
            m in random_grid(),
            sun in (-1.0f32..1.0, -0.3f32..1.0, -1.0f32..1.0),
            periodic in any::<bool>(),
            o in 0.0f32..=1.0,
        ) {
            use lightgrid_core::{BinLight, Boundary, SideBoundary, SunBoundary, SweepOptions, Sweeper};
            let to_sun = Vec3::new(sun.0, sun.1, sun.2);
            prop_assume!(to_sun.length() > 1e-3);
            let mut scattered = Boundary::open_sky(BinLight::ZERO);
            if periodic {
                scattered.sides = SideBoundary::Periodic;
            }
            let outside = move |p: Vec3| o * (0.5 + 0.5 * (p.x * 0.7).sin().abs());
            let b = SunBoundary { to_sun, scattered, outside: &outside };
            let mut cpu = crate::CpuSweeper::new();
            let whole = cpu.sweep_sun(&m, &b, &SweepOptions::single_pass()).unwrap();
            prop_assert!(cpu.sun_transmittance(&m, &b).unwrap() == whole.transmittance);
            /// A sweeper with `sweep_sun` only: the trait's default.
            struct Plain(crate::CpuSweeper);
            impl Sweeper for Plain {
                fn name(&self) -> &'static str {
                    "plain"
                }
                fn sweep(
                    &mut self,
                    m: &MaterialGrid,
                    b: &Boundary,
                    o: &SweepOptions,
                ) -> Result<lightgrid_core::SweepOutput, lightgrid_core::SweepError> {
                    self.0.sweep(m, b, o)
                }
                fn sweep_with_source(
                    &mut self,
                    m: &MaterialGrid,
                    b: &Boundary,
                    s: &lightgrid_core::CellSource,
                    o: &SweepOptions,
                ) -> Result<lightgrid_core::SweepOutput, lightgrid_core::SweepError> {
                    self.0.sweep_with_source(m, b, s, o)
                }
                fn sweep_sun(
                    &mut self,
                    m: &MaterialGrid,
                    s: &SunBoundary<'_>,
                    o: &SweepOptions,
                ) -> Result<lightgrid_core::SunResponse, lightgrid_core::SweepError> {
                    super::sweep_sun(self, m, s, o)
                }
            }
            let plain = Plain(crate::CpuSweeper::new()).sun_transmittance(&m, &b).unwrap();
            prop_assert!(plain == whole.transmittance);
        }

        /// Values lie in [0, 1], scale with what arrives from outside (linearity), and
        /// never grow when any cell gets denser (monotonicity).
        #[test]
        fn bounded_linear_and_monotone(
            m in random_grid(),
            sun in (-1.0f32..1.0, 0.05f32..1.0, -1.0f32..1.0),
            which in any::<prop::sample::Index>(),
            o in 0.0f32..=1.0,
        ) {
            let to_sun = Vec3::new(sun.0, sun.1, sun.2);
            for f in [march_open, SunTransmittance::sheared] {
                let full = f(&m, to_sun, OPEN).unwrap();
                let scaled = f(&m, to_sun, &move |_| o).unwrap();
                let mut denser = m.clone();
                let k = which.index(m.data().len());
                let mut cell = denser.data()[k];
                cell.pass *= 0.5;
                denser.set(m.desc().coords(k).unwrap(), cell).unwrap();
                let dense = f(&denser, to_sun, OPEN).unwrap();
                for i in 0..full.values().len() {
                    let (v, s, d) = (full.values()[i], scaled.values()[i], dense.values()[i]);
                    prop_assert!((0.0..=1.0).contains(&v));
                    prop_assert!((s - o * v).abs() <= 1e-5, "{s} vs {o} x {v}");
                    prop_assert!(d <= v + 1e-6, "{d} > {v}");
                }
            }
        }
    }
}
