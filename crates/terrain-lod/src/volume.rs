//! Light volumes read from the hierarchy fast: every grid reduced once to the moments a
//! volume stores (total light and the direction moment of
//! [`lightgrid_core::BinLight::direction_moment`]), with the sky scale and the sun's
//! irradiance folded in and the sun's transmittance beside them, so a point finds its
//! grid through a table per depth (no hashing) and reads 8 numbers a corner instead of
//! 26 bins of sky, 26 of scattered sun and the transmittance. Equal to reading the bins
//! (`LightField::light`) up to rounding where a lookup's eight corners lie outside
//! geometry: the moments are linear in the light, so they interpolate as the bins do
//! (tested against it). Grid points inside geometry (opaque cells) take their valid
//! neighbours' moments first (`lightgrid_core::validity`, the rule the Bevy export
//! follows), so a surface reads the light just above it rather than half of it.

use lightgrid_core::glam::{IVec2, Vec2, Vec3};
use lightgrid_core::{Blend, Grid, GridError, LightGrid, VolumeSample};
use rayon::prelude::*;

use crate::{GridSun, Hierarchy, NodeKey};
use lightgrid_core::seam::seam_shares;

/// A point's light reduced: `Σ L_d` (RGB), the direction moment `(Σ Y_d t_d, Σ Y_d)`
/// and the sun's transmittance.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    total: Vec3,
    v: Vec3,
    s: f32,
    t: f32,
}

impl std::ops::Add for Moments {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self.add_scaled(&o, 1.0);
        self
    }
}

impl std::ops::Mul<f32> for Moments {
    type Output = Self;
    fn mul(self, w: f32) -> Self {
        let mut m = Self::zero();
        m.add_scaled(&self, w);
        m
    }
}

impl Blend for Moments {
    fn zero() -> Self {
        Self::default()
    }
    fn add_scaled(&mut self, o: &Self, w: f32) {
        self.total += o.total * w;
        self.v += o.v * w;
        self.s += o.s * w;
        self.t += o.t * w;
    }
}

/// `sky × scale` (and `sun`'s scattered light × `e` with its transmittance), reduced
/// point by point; points inside geometry (`valid` false) then take their valid
/// neighbours' values (`lightgrid_core::validity`, the rule exports follow), so that a
/// lookup on a surface reads the light above it, not half of it.
fn reduce(
    sky: Option<&LightGrid>,
    scale: Vec3,
    sun: Option<(SunParts<'_>, Vec3)>,
    valid: Option<&[bool]>,
) -> Grid<Moments> {
    let desc = match (sky, sun) {
        (Some(g), _) => *g.desc(),
        (None, Some((s, _))) => *s.transmittance.desc(),
        (None, None) => unreachable!("a sky or a sun to reduce"),
    };
    let data = (0..desc.point_count())
        .into_par_iter()
        .map(|i| {
            let mut b = sky.map_or(lightgrid_core::BinLight::ZERO, |g| g.data()[i] * scale);
            let mut t = 0.0;
            if let Some((s, e)) = sun {
                // (None where the sky's bins hold the scattered sun.)
                if let Some(sc) = &s.scattered {
                    b += sc.data()[i] * e;
                }
                t = s.transmittance.data()[i];
            }
            let (v, s) = b.direction_moment();
            Moments {
                total: b.total(),
                v,
                s,
                t,
            }
        })
        .collect();
    let mut g = Grid::from_trusted(desc, data);
    if let Some(valid) = valid.filter(|v| v.len() == desc.point_count()) {
        // (Lengths match: the mask is of the grid's own material.)
        let _ = lightgrid_core::validity::fill_invalid(
            &mut g,
            valid,
            lightgrid_core::validity::DEFAULT_ROUNDS,
        );
    }
    g
}

/// A sun response's grids on one layout: its scattered light (`None` where the sky's
/// bins hold it) and its transmittance.
#[derive(Clone, Copy)]
struct SunParts<'a> {
    scattered: Option<&'a LightGrid>,
    transmittance: &'a Grid<f32>,
}

impl<'a> From<&'a GridSun> for SunParts<'a> {
    fn from(s: &'a GridSun) -> Self {
        Self {
            scattered: s.scattered.as_ref(),
            transmittance: &s.transmittance,
        }
    }
}

/// One grid reduced.
struct Layer {
    /// The node it is (`None`: the world grid).
    key: Option<NodeKey>,
    /// Sky (times the sky scale) and, where `sun_folded`, the scattered sun (times its
    /// irradiance) and transmittance.
    light: Grid<Moments>,
    /// Lowest and highest level's heights (a node serves its column between them).
    levels: (f32, f32),
    /// The grid's sun response is current and folded into `light`.
    sun_folded: bool,
    /// Its sun response alone (kept where a finer grid's is stale and reads this one's).
    sun: Option<Grid<Moments>>,
    /// Its ring's tiles reduced ([`crate::apron::Ring`]), each with the scattered sun of
    /// the node's points beside it (the node's clamped read) and the transmittance of
    /// its sun's ring ([`crate::apron::SunRing`]; without one, the node's points'); in
    /// the ring's order.
    ring: Option<Vec<Grid<Moments>>>,
}

/// The ready nodes of one depth as a dense table over their lattice indices.
struct DepthTable {
    depth: u32,
    lo: IVec2,
    size: IVec2,
    /// Index into the layers, `u32::MAX` where no node is ready.
    layer: Vec<u32>,
}

/// The grids of the hierarchy reduced.
pub(crate) struct Reduced<'a> {
    h: &'a Hierarchy,
    /// The world grid first.
    layers: Vec<Layer>,
    /// Depth `d`'s table at `d - 1`.
    depths: Vec<DepthTable>,
}

impl<'a> Reduced<'a> {
    pub(crate) fn new(h: &'a Hierarchy) -> Self {
        let keys: Vec<Option<NodeKey>> = std::iter::once(None)
            .chain(h.ready_nodes().into_iter().map(Some))
            .collect();
        let sun = h.sun.map(|s| s.irradiance);
        // A stale node takes the sun from coarser grids, which then keep theirs apart.
        let any_stale = sun.is_some() && keys.iter().flatten().any(|k| !h.sun_shown(*k));
        let layers = keys
            .par_iter()
            .map(|k| {
                let (grid, own_sun, material) = match k {
                    None => (&h.world, h.world_sun.as_ref(), h.world_material.as_ref()),
                    Some(k) => (
                        &h.nodes[k].light,
                        h.nodes[k].sun.as_ref().filter(|_| h.sun_shown(*k)),
                        Some(&h.nodes[k].material.grid),
                    ),
                };
                let own_sun = sun.and_then(|e| own_sun.map(|s| (s, e)));
                let sun_ring = own_sun.map(|(s, _)| s);
                let valid = material
                    .filter(|m| m.desc() == grid.desc())
                    .map(lightgrid_core::validity::valid_points);
                let valid = valid.as_deref();
                let (lo, hi) = grid.desc().point_bounds();
                let own_sun = own_sun.map(|(s, e)| (SunParts::from(s), e));
                let ring = k.and_then(|k| h.nodes[&k].ring.as_ref()).map(|r| {
                    r.tiles()
                        .map(|(offset, tile)| {
                            // The node's sun at its points beside the tile; the
                            // transmittance its sun's ring holds there, where kept.
                            let beyond = sun_ring.and_then(|g| g.ring_tile(offset));
                            let edge = own_sun.map(|(s, e)| {
                                let d = tile.desc();
                                (
                                    s.scattered.map(|g| crate::apron::edge_of(g, offset, d)),
                                    match beyond {
                                        Some(t) => std::borrow::Cow::Borrowed(t),
                                        None => std::borrow::Cow::Owned(crate::apron::edge_of(
                                            s.transmittance,
                                            offset,
                                            d,
                                        )),
                                    },
                                    e,
                                )
                            });
                            let sun = edge.as_ref().map(|(sc, t, e)| {
                                (
                                    SunParts {
                                        scattered: sc.as_ref(),
                                        transmittance: t,
                                    },
                                    *e,
                                )
                            });
                            reduce(Some(tile), h.sky_scale, sun, None)
                        })
                        .collect()
                });
                Layer {
                    key: *k,
                    light: reduce(Some(grid), h.sky_scale, own_sun, valid),
                    levels: (lo.y, hi.y),
                    sun_folded: own_sun.is_some(),
                    sun: own_sun
                        .filter(|_| any_stale)
                        .map(|s| reduce(None, Vec3::ZERO, Some(s), valid)),
                    ring,
                }
            })
            .collect();
        let depths = (1..=h.params.depths())
            .map(|d| {
                let at: Vec<(IVec2, u32)> = keys
                    .iter()
                    .enumerate()
                    .filter_map(|(i, k)| k.filter(|k| k.depth == d).map(|k| (k.index, i as u32)))
                    .collect();
                let lo = at.iter().map(|a| a.0).fold(IVec2::MAX, IVec2::min);
                let hi = at.iter().map(|a| a.0).fold(IVec2::MIN, IVec2::max);
                let size = if at.is_empty() {
                    IVec2::ZERO
                } else {
                    hi - lo + IVec2::ONE
                };
                let mut layer = vec![u32::MAX; (size.x * size.y) as usize];
                for (idx, i) in at {
                    let c = idx - lo;
                    layer[(c.x + size.x * c.y) as usize] = i;
                }
                DepthTable {
                    depth: d,
                    lo,
                    size,
                    layer,
                }
            })
            .collect();
        Self { h, layers, depths }
    }

    /// The layers holding `p`, finest first (the world grid last).
    fn holding(&self, p: Vec3) -> impl Iterator<Item = &Layer> {
        self.depths
            .iter()
            .rev()
            .filter_map(move |t| self.held_by(t, p))
            .chain(std::iter::once(&self.layers[0]))
    }

    /// The first of [`Reduced::holding`], without the iterator (a volume's every point
    /// asks it).
    #[inline]
    fn finest_holding(&self, p: Vec3) -> &Layer {
        for t in self.depths.iter().rev() {
            if let Some(l) = self.held_by(t, p) {
                return l;
            }
        }
        &self.layers[0]
    }

    /// The ready node of table `t`'s depth holding `p`, if any.
    #[inline]
    fn held_by(&self, t: &DepthTable, p: Vec3) -> Option<&Layer> {
        let c = self.h.node_at(t.depth, Vec2::new(p.x, p.z)).index - t.lo;
        if c.cmplt(IVec2::ZERO).any() || c.cmpge(t.size).any() {
            return None;
        }
        let l = self
            .layers
            .get(t.layer[(c.x + t.size.x * c.y) as usize] as usize)?;
        (p.y >= l.levels.0 && p.y <= l.levels.1).then_some(l)
    }

    /// `layer`'s moments at `p` on `light`, its own grid or one of its ring's tiles (a
    /// stale sun response's taken from the finest coarser grid with a current one).
    fn read_on(&self, layer: &Layer, light: &Grid<Moments>, p: Vec3) -> Result<Moments, GridError> {
        let mut m = light.sample(p)?;
        self.add_stale_sun(layer, p, &mut m)?;
        Ok(m)
    }

    /// Where `layer`'s sun response is not folded into its light (stale, or none),
    /// the finest coarser grid's with a current one, added to `m`.
    #[inline]
    fn add_stale_sun(&self, layer: &Layer, p: Vec3, m: &mut Moments) -> Result<(), GridError> {
        if self.h.sun.is_some() && !layer.sun_folded {
            let depth = layer.key.map_or(0, |k| k.depth);
            let coarser = self
                .holding(p)
                .filter(|l| l.key.map_or(0, |k| k.depth) < depth);
            if let Some(s) = coarser.filter_map(|l| l.sun.as_ref()).next() {
                m.add_scaled(&s.sample(p)?, 1.0);
            }
        }
        Ok(())
    }

    /// Where `p` lies between the points of the node `first` and a neighbour's, the
    /// read across the seam (`lightgrid_core::seam`, as `LightField` reads it): the reads of the
    /// nodes of its depth holding the lookup's corners, weighted. `None` where `p` lies
    /// within the node's points, or one of those nodes is not ready or does not reach
    /// `p`'s height (the node's own read stands).
    fn across_seam(&self, first: &Layer, p: Vec3) -> Option<Result<Moments, GridError>> {
        let key = first.key?;
        let (weights, count) = seam_shares(first.light.desc(), p);
        if count == 1 && weights[0].0 == IVec2::ZERO {
            return None;
        }
        let table = &self.depths[key.depth as usize - 1];
        let mut parts = [(first, &first.light, 0.0f32); 4];
        for (slot, &(offset, w)) in parts.iter_mut().zip(&weights[..count]) {
            let c = key.index + offset - table.lo;
            let built = (c.cmpge(IVec2::ZERO).all() && c.cmplt(table.size).all())
                .then(|| table.layer[(c.x + table.size.x * c.y) as usize])
                .and_then(|i| self.layers.get(i as usize));
            let Some(l) = built else {
                // Not built: the ring's tile, as `LightField` reads it.
                let tile = first.ring.as_ref().zip(crate::apron::Ring::index(offset));
                *slot = (first, tile.map(|(r, k)| &r[k])?, w);
                continue;
            };
            if !(p.y >= l.levels.0 && p.y <= l.levels.1) {
                return None;
            }
            *slot = (l, &l.light, w);
        }
        let mut m = Moments::zero();
        for &(l, g, w) in &parts[..count] {
            match self.read_on(l, g, p) {
                Ok(v) => m.add_scaled(&v, w),
                Err(e) => return Some(Err(e)),
            }
        }
        Some(Ok(m))
    }

    /// The volume's sample at `p`, as the hierarchy's `LightField` reads it: the finest
    /// ready grid's sky; the finest grid's with a current sun response scattered sun and
    /// transmittance.
    pub(crate) fn sample(&self, p: Vec3) -> Result<VolumeSample, GridError> {
        if !p.is_finite() {
            return Err(GridError::invalid("p", p, "must be finite"));
        }
        let first = self.finest_holding(p);
        // Within the node's points (most of a volume's points) its own trilinear read,
        // the grid coordinates found once; beside them the read across the seam.
        let desc = first.light.desc();
        let g = desc.to_grid(p);
        let last = desc.dims().as_vec3() - 1.0;
        // (`seam_shares`' own test: no neighbour's share on either axis.)
        let inside = g.x >= 0.0 && g.x <= last.x && g.z >= 0.0 && g.z <= last.z;
        // (The world grid has no seam: it clamps.)
        let m = if inside || first.key.is_none() {
            let mut m = first
                .light
                .blend(lightgrid_core::trilinear_indices(desc.dims(), g));
            self.add_stale_sun(first, p, &mut m)?;
            m
        } else {
            match self.across_seam(first, p) {
                Some(m) => m?,
                None => self.read_on(first, &first.light, p)?,
            }
        };
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
            sun: if m.t.is_finite() {
                m.t.clamp(0.0, 1.0)
            } else {
                0.0
            },
        })
    }
}
