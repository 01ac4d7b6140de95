//! Light volumes read from the hierarchy fast: every grid reduced once to the moments a
//! volume stores (total light, and the direction moment of [`BinLight::direction_moment`]),
//! with the sky scale and the sun's irradiance folded in, so a point reads 7 numbers a
//! corner instead of 26 bins of sky and 26 of scattered sun. Equal to reading the bins
//! (`LightField::light`) up to rounding: both moments are linear in the light, so they
//! interpolate as the bins do (tested against it).

use std::collections::HashMap;

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{Blend, Grid, GridError, LightGrid, VolumeSample};
use rayon::prelude::*;

use crate::{Hierarchy, NodeKey, within_levels};

/// A point's light reduced: `Σ L_d` (RGB) and the direction moment `(Σ Y_d t_d, Σ Y_d)`.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    total: Vec3,
    v: Vec3,
    s: f32,
}

impl Blend for Moments {
    fn zero() -> Self {
        Self::default()
    }
    fn add_scaled(&mut self, o: &Self, w: f32) {
        self.total += o.total * w;
        self.v += o.v * w;
        self.s += o.s * w;
    }
}

/// `g`'s light times `scale`, reduced point by point.
fn reduce(g: &LightGrid, scale: Vec3) -> Grid<Moments> {
    let data = g
        .data()
        .par_iter()
        .map(|b| {
            let b = *b * scale;
            let (v, s) = b.direction_moment();
            Moments {
                total: b.total(),
                v,
                s,
            }
        })
        .collect();
    Grid::from_trusted(*g.desc(), data)
}

/// The grids of the hierarchy reduced, by node (`None`: the world grid).
pub(crate) struct Reduced<'a> {
    h: &'a Hierarchy,
    sky: HashMap<Option<NodeKey>, Grid<Moments>>,
    sun: HashMap<Option<NodeKey>, (Grid<Moments>, &'a Grid<f32>)>,
}

impl<'a> Reduced<'a> {
    pub(crate) fn new(h: &'a Hierarchy) -> Self {
        let keys: Vec<Option<NodeKey>> = std::iter::once(None)
            .chain(h.ready_nodes().into_iter().map(Some))
            .collect();
        let sky = keys
            .par_iter()
            .map(|k| {
                let g = match k {
                    None => &h.world,
                    Some(k) => &h.nodes[k].light,
                };
                (*k, reduce(g, h.sky_scale))
            })
            .collect();
        let sun = match h.sun {
            None => HashMap::new(),
            Some(s) => keys
                .par_iter()
                .filter_map(|k| {
                    let g = match k {
                        None => h.world_sun.as_ref()?,
                        Some(k) if h.sun_current(*k) => h.nodes[k].sun.as_ref()?,
                        Some(_) => return None,
                    };
                    Some((*k, (reduce(&g.scattered, s.irradiance), &g.transmittance)))
                })
                .collect(),
        };
        Self { h, sky, sun }
    }

    /// The volume's sample at `p` (see [`crate::Hierarchy`]'s `LightField`: the finest
    /// ready grid's sky, the finest grid's with a current sun response scattered sun
    /// and transmittance).
    pub(crate) fn sample(&self, p: Vec3) -> Result<VolumeSample, GridError> {
        if !p.is_finite() {
            return Err(GridError::invalid("p", p, "must be finite"));
        }
        let xz = Vec2::new(p.x, p.z);
        let depths = self.h.params.depths();
        let finest = |ok: &dyn Fn(NodeKey) -> bool| {
            (1..=depths).rev().map(|d| self.h.node_at(d, xz)).find(|k| {
                self.h
                    .nodes
                    .get(k)
                    .is_some_and(|n| within_levels(n.light.desc(), p))
                    && ok(*k)
            })
        };
        let mut m = self.sky[&finest(&|_| true)].sample(p)?;
        let mut sun = 0.0;
        if self.h.sun.is_some() {
            let key = finest(&|k| self.h.sun_current(k));
            if let Some((g, t)) = self.sun.get(&key) {
                m.add_scaled(&g.sample(p)?, 1.0);
                sun = t.sample(p)?.clamp(0.0, 1.0);
            }
        }
        let r = m.v / m.s;
        let dominant = if m.s > 0.0 && r.is_finite() {
            r.clamp_length_max(1.0)
        } else {
            Vec3::ZERO
        };
        let average = m.total / (4.0 * std::f32::consts::PI);
        Ok(VolumeSample {
            average: if average.is_finite() {
                average
            } else {
                Vec3::ZERO
            },
            dominant,
            sun: if sun.is_finite() { sun } else { 0.0 },
        })
    }
}
