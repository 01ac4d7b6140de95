//! What a renderer reads from the hierarchy: its grids as layers ([`Hierarchy::layers`]),
//! the grid serving a point ([`Hierarchy::grid_at`]) and the hierarchy as a
//! [`LightField`] (bins, horizon halves, the sun's transmittance, the light volume's
//! moments).

use lightgrid_core::glam::{IVec2, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Blend, Grid, GridDesc, GridError, HorizonGrid, HorizonLight, LightField, LightGrid,
    Reading, trilinear_indices,
};

use crate::{
    GridSun, Hierarchy, Layer, LayerSun, Node, NodeKey, Owner, SunLight, volume, within_levels,
};
use lightgrid_core::seam::seam_shares;

impl Hierarchy {
    /// The grids for layered sampling: the world grid, then the ready nodes in
    /// [`Hierarchy::ready_nodes`]'s order (by depth, then index; see [`Layer`]).
    pub fn layers(&self) -> Vec<Layer<'_>> {
        fn layer_sun(g: &GridSun) -> LayerSun<'_> {
            LayerSun {
                scattered: g.scattered.as_ref(),
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
        match self.serving_node(p) {
            Some((_, n)) => (&n.light, n.horizon.as_ref()),
            None => (&self.world, self.world_horizon.as_ref()),
        }
    }

    /// The finest ready node containing `p` (`None`: the world grid serves it).
    fn serving_node(&self, p: Vec3) -> Option<(NodeKey, &Node)> {
        (1..=self.params.depths()).rev().find_map(|d| {
            let key = self.node_at(d, Vec2::new(p.x, p.z));
            self.nodes
                .get(&key)
                .filter(|n| within_levels(n.light.desc(), p))
                .map(|n| (key, n))
        })
    }

    /// The grids `p`'s read takes its light from, with their weights: the serving grid
    /// alone, or where the read (moved half a cell along `n`) falls between the serving
    /// node's points and a neighbour's, the nodes of its depth that hold the lookup's
    /// corners, each weighted by its share of them ([`lightgrid_core::seam`]); a node
    /// not built there read from the serving node's ring ([`crate::apron::Ring`]), its
    /// transmittance from its sun's ([`crate::apron::SunRing`]) where kept. The
    /// serving grid alone where such a node has no ring to stand for it, or a built one
    /// does not reach `p`'s height.
    fn shares(&self, p: Vec3, n: Option<Vec3>) -> ([Share<'_>; 4], usize) {
        let Some((key, node)) = self.serving_node(p) else {
            let world = Share {
                light: &self.world,
                halves: self.world_horizon.as_ref(),
                sun: self.sun_at(p),
                beyond: None,
                w: 1.0,
            };
            return ([world; 4], 1);
        };
        // The serving node's share: no finer node holds `p`, so its sun is the one
        // `sun_at` finds, without walking the finer depths again.
        let own = Share {
            light: &node.light,
            halves: node.horizon.as_ref(),
            sun: self.node_sun_at(key, node, p),
            beyond: None,
            w: 1.0,
        };
        let desc = node.light.desc();
        let q = match n.map(Vec3::try_normalize) {
            None => p,
            Some(Some(n)) => p + n * (0.5 * desc.h()),
            // (The grid's own read names the bad normal.)
            Some(None) => return ([own; 4], 1),
        };
        let (weights, count) = seam_shares(desc, q);
        if count == 1 && weights[0].0 == IVec2::ZERO {
            return ([own; 4], 1);
        }
        let mut out = [own; 4];
        for (slot, &(offset, w)) in out.iter_mut().zip(&weights[..count]) {
            let k = NodeKey {
                depth: key.depth,
                index: key.index + offset,
            };
            let Some(m) = self.nodes.get(&k) else {
                // A neighbour not built: its share is its tile's outermost points, the
                // ring's where the node keeps one (its scattered sun the node's own,
                // clamped; its transmittance the sun's ring where the node's own sun
                // keeps one), else the node's own read stands alone.
                match node.ring.as_ref().and_then(|r| r.tile(offset)) {
                    Some((light, halves)) if halves.is_some() == node.horizon.is_some() => {
                        *slot = Share {
                            light,
                            halves,
                            sun: own.sun,
                            beyond: own.sun.and_then(|(_, g)| g.ring_tile(offset)),
                            w,
                        };
                        continue;
                    }
                    _ => return ([own; 4], 1),
                }
            };
            if !within_levels(m.light.desc(), p) || m.horizon.is_some() != node.horizon.is_some() {
                return ([own; 4], 1);
            }
            *slot = Share {
                light: &m.light,
                halves: m.horizon.as_ref(),
                sun: if k == key {
                    own.sun
                } else {
                    self.node_sun_at(k, m, p)
                },
                beyond: None,
                w,
            };
        }
        (out, count)
    }

    /// `read` given [`Hierarchy::shares`] with each share's [`Lookup`] (the errors of a
    /// read with a bad normal or position). A read away from a seam (one share, nearly
    /// every read) builds no array of four: a share and its lookup are some 370 bytes,
    /// whose copies showed in the sampling's profile (`docs/measurements.md`).
    #[inline]
    fn looked_up<R>(
        &self,
        p: Vec3,
        n: Option<Vec3>,
        read: impl FnOnce(&[(Share<'_>, Lookup)]) -> Result<R, GridError>,
    ) -> Result<R, GridError> {
        let (shares, count) = self.shares(p, n);
        if count == 1 {
            let one = (shares[0], Lookup::of(&shares[0], p, n)?);
            return read(std::slice::from_ref(&one));
        }
        let first = Lookup::of(&shares[0], p, n)?;
        let mut out = [(shares[0], first); 4];
        for (slot, s) in out.iter_mut().zip(&shares[..count]).skip(1) {
            *slot = (*s, Lookup::of(s, p, n)?);
        }
        read(&out[..count])
    }

    /// Node `key`'s sun at `p` with the sun kept apart: its own responses where shown,
    /// else the finest coarser grid's with a shown sun (a stale node's points read
    /// those).
    fn node_sun_at<'a>(
        &'a self,
        key: NodeKey,
        node: &'a Node,
        p: Vec3,
    ) -> Option<(SunLight, &'a GridSun)> {
        let sun = self.sun?;
        match &node.sun {
            Some(g) if self.shows_sun(node) => Some((sun, g)),
            _ => self.coarse_sun(p, key.depth, true).map(|g| (sun, g)),
        }
    }
}

/// One grid's part in a read ([`Hierarchy::shares`]).
#[derive(Clone, Copy)]
struct Share<'a> {
    light: &'a LightGrid,
    halves: Option<&'a HorizonGrid>,
    sun: Option<(SunLight, &'a GridSun)>,
    /// The transmittance read instead of the sun's own: a ring tile's
    /// ([`crate::apron::SunRing`]), on `light`'s layout.
    beyond: Option<&'a Grid<f32>>,
    w: f32,
}

/// One share's trilinear lookup, found once and read from every grid of its layout
/// (the node's bins and halves, its sun's scattered light and transmittance): the
/// corners [`Grid::sample_biased`] (with a normal) or [`Grid::sample`] find, so a read
/// through it is theirs bit for bit. A grid of another layout (a sun marched over a
/// widened grid) is read as before.
#[derive(Clone, Copy)]
struct Lookup {
    desc: GridDesc,
    corners: Corners,
    /// The lookup in the share's sun's grids where they lie on another layout (a
    /// coarser grid's sun read while the node's own is still to come).
    sun: Option<(GridDesc, Corners)>,
}

/// A trilinear lookup's corners: indices and weights ([`trilinear_indices`]).
type Corners = ([usize; 8], [f32; 8]);

impl Lookup {
    /// The lookup at `p` (half a cell along `n` where given) in grids of `desc`, with
    /// [`Grid::sample_biased`]'s errors for a bad normal or position.
    fn new(desc: &GridDesc, p: Vec3, n: Option<Vec3>) -> Result<Self, GridError> {
        let q = match n {
            Some(n) => {
                let n = n.try_normalize().ok_or_else(|| {
                    GridError::invalid("n", n, "normal must be finite and non-zero")
                })?;
                p + n * (0.5 * desc.h())
            }
            None => p,
        };
        if !q.is_finite() {
            return Err(GridError::invalid("p", q, "sample position must be finite"));
        }
        Ok(Self {
            desc: *desc,
            corners: trilinear_indices(desc.dims(), desc.to_grid(q)),
            sun: None,
        })
    }

    /// The lookup of `share`'s grids: its light's layout, and its sun's where that is
    /// another (whose reads are then theirs bit for bit too).
    fn of(share: &Share<'_>, p: Vec3, n: Option<Vec3>) -> Result<Self, GridError> {
        let mut at = Self::new(share.light.desc(), p, n)?;
        if let Some((_, g)) = share.sun {
            let sun = g.transmittance.desc();
            if *sun != at.desc {
                let other = Self::new(sun, p, n)?;
                at.sun = Some((other.desc, other.corners));
            }
        }
        Ok(at)
    }

    /// `grid` read at the lookup's point.
    #[inline]
    fn read<T: Blend>(&self, grid: &Grid<T>, p: Vec3, n: Option<Vec3>) -> Result<T, GridError> {
        if *grid.desc() == self.desc {
            return Ok(grid.blend(self.corners));
        }
        if let Some((desc, corners)) = self.sun
            && *grid.desc() == desc
        {
            return Ok(grid.blend(corners));
        }
        match n {
            Some(n) => grid.sample_biased(p, n),
            None => grid.sample(p),
        }
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
    #[inline]
    fn bins_at(
        &self,
        share: &Share<'_>,
        at: &Lookup,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<BinLight, GridError> {
        let sky = at.read(share.light, p, n)? * self.sky_scale;
        Ok(match share.sun {
            // (None where the sky's bins hold the scattered sun.)
            Some((s, g)) => match &g.scattered {
                Some(sc) => sky + at.read(sc, p, n)? * s.irradiance,
                None => sky,
            },
            None => sky,
        })
    }

    /// The sky's `halves` times the sky scale, plus the sun's scattered light's (its
    /// bins split evenly where its grid keeps no halves) times the sun's irradiance.
    #[inline]
    fn halves_at(
        &self,
        halves: &HorizonGrid,
        sun: Option<(SunLight, &GridSun)>,
        at: &Lookup,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<HorizonLight, GridError> {
        let sky = at.read(halves, p, n)? * self.sky_scale;
        Ok(match sun {
            Some((s, g)) => {
                let scattered = match (&g.horizon, &g.scattered) {
                    (Some(h), _) => at.read(h, p, n)?,
                    (None, Some(sc)) => HorizonLight::even(&at.read(sc, p, n)?),
                    // (The sky's bins hold the scattered sun.)
                    (None, None) => return Ok(sky),
                };
                sky + scattered * s.irradiance
            }
            None => sky,
        })
    }

    /// The sun's transmittance at `p` in `[0, 1]` (0 without a sun): `beyond`'s where
    /// given (a ring tile's), else the sun's grid's.
    #[inline]
    fn transmittance_at(
        sun: Option<(SunLight, &GridSun)>,
        beyond: Option<&Grid<f32>>,
        at: &Lookup,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<f32, GridError> {
        let Some((_, g)) = sun else {
            return Ok(0.0);
        };
        let t = at.read(beyond.unwrap_or(&g.transmittance), p, n)?;
        // (Trilinear weights may sum to 1 + 1 ulp.)
        Ok(t.clamp(0.0, 1.0))
    }

    /// [`Hierarchy::bins_at`] of each share, weighted.
    fn bins_of(
        &self,
        shares: &[(Share<'_>, Lookup)],
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<BinLight, GridError> {
        if let [(one, at)] = shares {
            return self.bins_at(one, at, p, n);
        }
        let mut acc = BinLight::ZERO;
        for (s, at) in shares {
            acc.add_scaled(&self.bins_at(s, at, p, n)?, s.w);
        }
        Ok(acc)
    }

    /// [`Hierarchy::halves_at`] of each share, weighted; `None` where the grids keep no
    /// halves.
    fn halves_of(
        &self,
        shares: &[(Share<'_>, Lookup)],
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<Option<HorizonLight>, GridError> {
        let mut acc = HorizonLight::default();
        for (s, at) in shares {
            let Some(h) = s.halves else {
                return Ok(None);
            };
            let v = self.halves_at(h, s.sun, at, p, n)?;
            if shares.len() == 1 {
                return Ok(Some(v));
            }
            acc.add_scaled(&v, s.w);
        }
        Ok(Some(acc))
    }

    /// [`Hierarchy::transmittance_at`] of each share, weighted, in `[0, 1]`.
    fn transmittance_of(
        shares: &[(Share<'_>, Lookup)],
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<f32, GridError> {
        if let [(one, at)] = shares {
            return Self::transmittance_at(one.sun, one.beyond, at, p, n);
        }
        let mut t = 0.0;
        for (s, at) in shares {
            t += Self::transmittance_at(s.sun, s.beyond, at, p, n)? * s.w;
        }
        Ok(t.clamp(0.0, 1.0))
    }
}

/// The light of the finest ready grid at `p` ([`Hierarchy::grid_at`]) times the sky
/// scale; with the sun kept apart, plus the sun's scattered light of the finest grid at
/// `p` with a current sun response times the sun's irradiance, and the transmittance
/// of that grid. Where the read (with a normal, half a cell along it) falls between the
/// serving node's outermost points and a neighbour's, it is the sum of the reads of
/// the nodes of that depth holding the lookup's corners, weighted by their shares
/// ([`lightgrid_core::seam`]): one grid's trilinear read across the seam, not the
/// serving node's points clamped.
impl LightField for Hierarchy {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        self.looked_up(p, n, |shares| self.bins_of(shares, p, n))
    }
    /// The horizon halves of the finest ready grid at `p` times the sky scale, plus with
    /// the sun kept apart those of the sun's scattered light read as [`LightField::light`]
    /// reads it (its bins split evenly where that grid keeps no halves), times the
    /// sun's irradiance; `None` where the grid serving `p` keeps no halves
    /// (`HierarchyParams::sweep.outputs.horizon` off).
    fn horizon(&self, p: Vec3, n: Option<Vec3>) -> Result<Option<HorizonLight>, GridError> {
        self.looked_up(p, n, |shares| self.halves_of(shares, p, n))
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
        self.looked_up(p, n, |shares| {
            let horizon = match n {
                Some(_) => self.halves_of(shares, p, n)?,
                None => None,
            };
            Ok(Reading {
                light: self.bins_of(shares, p, n)?,
                horizon,
                sun: Self::transmittance_of(shares, p, n)?,
            })
        })
    }

    fn sun_transmittance(&self, p: Vec3, n: Option<Vec3>) -> Result<f32, GridError> {
        if !p.is_finite() {
            return Err(GridError::invalid("p", p, "must be finite"));
        }
        self.looked_up(p, n, |shares| Self::transmittance_of(shares, p, n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::glam::UVec3;
    use proptest::prelude::*;

    /// A grid of `desc` whose values differ point by point (every bin, every channel).
    fn grid(desc: GridDesc) -> LightGrid {
        let data = (0..desc.point_count())
            .map(|i| {
                BinLight(std::array::from_fn(|d| {
                    Vec3::new(
                        i as f32 + 0.25,
                        d as f32 * 0.5 + 1.0,
                        (i * 7 + d) as f32 * 0.1,
                    )
                }))
            })
            .collect();
        LightGrid::from_trusted(desc, data)
    }

    proptest! {
        /// A read through a shared lookup is the grid's own read bit for bit: with a
        /// normal (half a cell along it) and without, inside and outside the grid,
        /// for a grid of the sun's layout where the lookup keeps it, and for a grid of
        /// another layout (read as before).
        #[test]
        fn a_lookup_reads_as_the_grid_samples(
            p in (-3.0f32..9.0, -3.0f32..9.0, -3.0f32..9.0),
            n in (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
            with_normal in any::<bool>(),
        ) {
            let desc = GridDesc::new(Vec3::new(0.5, -1.0, 0.25), 0.75, UVec3::new(5, 4, 6)).unwrap();
            let other = GridDesc::new(Vec3::new(-0.5, -1.0, 0.25), 1.5, UVec3::new(4, 3, 4)).unwrap();
            let (a, b) = (grid(desc), grid(other));
            let p = Vec3::new(p.0, p.1, p.2);
            let n = Vec3::new(n.0, n.1, n.2);
            prop_assume!(n.length() > 1e-3);
            let n = with_normal.then_some(n);
            let at = Lookup::new(&desc, p, n).unwrap();
            // With the other layout's lookup kept too (a share whose sun lies on
            // another grid's layout), and with a third layout neither holds.
            let third = GridDesc::new(Vec3::new(0.0, 0.0, 0.0), 2.0, UVec3::new(3, 3, 3)).unwrap();
            let mut both = at;
            let o = Lookup::new(&other, p, n).unwrap();
            both.sun = Some((o.desc, o.corners));
            for at in [at, both] {
                for g in [&a, &b, &grid(third)] {
                    let want = match n {
                        Some(n) => g.sample_biased(p, n).unwrap(),
                        None => g.sample(p).unwrap(),
                    };
                    let got = at.read(g, p, n).unwrap();
                    for (x, y) in got.0.iter().zip(&want.0) {
                        prop_assert_eq!(x.to_array().map(f32::to_bits), y.to_array().map(f32::to_bits));
                    }
                }
            }
        }
    }

    /// A bad normal or position is named as the grid's own read names it.
    #[test]
    fn a_lookup_names_a_bad_normal_or_position() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(3)).unwrap();
        let g = grid(desc);
        for (p, n) in [
            (Vec3::ONE, Some(Vec3::ZERO)),
            (Vec3::ONE, Some(Vec3::NAN)),
            (Vec3::new(f32::INFINITY, 0.0, 0.0), None),
            (Vec3::new(f32::NAN, 0.0, 0.0), Some(Vec3::Y)),
        ] {
            let want = match n {
                Some(n) => g.sample_biased(p, n).unwrap_err(),
                None => g.sample(p).unwrap_err(),
            };
            let got = Lookup::new(&desc, p, n).err().expect("refused");
            assert_eq!(got.to_string(), want.to_string());
        }
    }
}
