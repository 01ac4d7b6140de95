//! A grid's sun responses: a node's computed ([`Hierarchy::node_sun`], the world
//! grid's by [`Hierarchy::sweep_world_sun`]), and which are current for the sun shown
//! (its direction, the direction the scattered sun is swept for, and with
//! [`HierarchyParams::sun_with_sky`](crate::HierarchyParams::sun_with_sky) the sun a
//! grid's sky sweep took).

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{Grid, Sweeper};

use crate::{
    GridSun, Hierarchy, LodError, Node, NodeKey, NodeMaterial, Response, StageTimes, SunBoundary,
    SunLight, apron, shadow, sun_move, timed, within_levels,
};

impl GridSun {
    /// Its [`apron::SunRing`]'s tile at `offset` from the node (x, z), where it keeps one
    /// marched for the direction its transmittance is.
    pub(crate) fn ring_tile(&self, offset: lightgrid_core::glam::IVec2) -> Option<&Grid<f32>> {
        self.ring
            .as_ref()
            .filter(|r| r.to_sun == self.marched_to)
            .and_then(|r| r.tile(offset))
    }

    /// Marks the scattered sun to be swept again, shown until then (`to_sun` zero; with
    /// the sun swept with the sky, the grid's sky sweep: `with_sky` none).
    pub(crate) fn mark_scattered_stale(&mut self) {
        match self.with_sky {
            Some(_) => self.with_sky = None,
            None => self.to_sun = Vec3::ZERO,
        }
    }

    /// The responses of a grid whose sky sweep holds `sky`'s scattered light
    /// ([`HierarchyParams::sun_with_sky`](crate::HierarchyParams::sun_with_sky)): the
    /// transmittance marched toward `marched_to` (the sun shown: `sky`'s but while a
    /// moved sun's world grid is swept on a thread), no scattered light of their own.
    pub(crate) fn marched(transmittance: Grid<f32>, sky: SunLight, marched_to: Vec3) -> Self {
        Self {
            scattered: None,
            horizon: None,
            resident: None,
            transmittance,
            to_sun: sky.to_sun,
            marched_to,
            with_sky: Some(sky.irradiance),
            march_stale: false,
            ring: None,
        }
    }
}

/// `hash` with the sun every grid sweeps with its sky ([`crate::HierarchyParams::sun_with_sky`]):
/// a node swept for another sun, or another irradiance, is stale.
pub(crate) fn hash_sun(hash: u64, sun: SunLight) -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = foldhash::quality::FixedState::with_seed(0x7375_6e5f_736b_7921).build_hasher();
    h.write_u64(hash);
    h.write(bytemuck::cast_slice(&sun.to_sun.to_array()));
    h.write(bytemuck::cast_slice(&sun.irradiance.to_array()));
    h.finish()
}

impl Hierarchy {
    /// The world grid's sun responses for the current sun.
    pub(crate) fn sweep_world_sun(&mut self) -> Result<(), LodError> {
        let Some(sun) = self.sun else {
            return Ok(());
        };
        let desc = *self.world.desc();
        let composed;
        let material = match &self.world_material {
            Some(m) if *m.desc() == desc => m,
            _ => {
                composed = self.compose(&desc)?;
                &composed
            }
        };
        let o = self.node_options(true);
        let r = if self.sun_with_sky().is_some() {
            // The scattered sun is in the sky's bins (`sweep_world`): the march alone.
            let t = sun_move::march(self.sweeper.as_mut(), material, sun.to_sun, &|_| 1.0)?;
            GridSun::marched(t, sun, sun.to_sun)
        } else {
            sun_move::world_grid_sun(self.sweeper.as_mut(), material, sun.to_sun, &o)?
        };
        self.world_sun = Some(r);
        Ok(())
    }

    /// Node `key`'s sun responses for the current sun on `sweeper`, its boundary from
    /// the coarser grids' sun responses (`None` without a sun kept apart).
    pub(crate) fn node_sun(
        &self,
        key: NodeKey,
        material: &NodeMaterial,
        sweeper: &mut dyn Sweeper,
        fresh: &shadow::Fresh<'_>,
        times: &mut StageTimes,
    ) -> Result<Option<GridSun>, LodError> {
        let _span = tracing::trace_span!("node sun", ?key).entered();
        let (Some(sun), Some(scattered_to)) = (self.sun, self.scattered_to()) else {
            return Ok(None);
        };
        if let Some(sky) = self.sky_sun() {
            // The scattered sun is in the sky's bins: the march alone.
            let t = timed(&mut times.sun_sweep, || {
                self.march_node(sweeper, key, material, sun.to_sun, fresh)
            })?;
            return Ok(Some(GridSun::marched(t, sky, sun.to_sun)));
        }
        // Swept over the widened grid where the sun has an apron (the scattered sun
        // entering the node's sides has crossed the apron's fine material), kept inside.
        let wide = self.sun_material(material);
        let swept = wide.as_ref().map_or(&material.grid, |w| &*w.0);
        let desc = *swept.desc();
        let o = self.node_options(material.has_objects);
        let scattered = timed(&mut times.sun_boundary, || {
            let mut b = self.node_boundary_of(
                &desc,
                key,
                Response::Sun,
                crate::boundary::HaloMaterial {
                    swept: Some(swept),
                    outer: material.outer.as_ref().or(material.widened.as_ref()),
                },
            );
            // Carried here, in place: the sweep then copies nothing.
            lightgrid_core::halo_carry::carry_halo(&mut b, desc.dims());
            b
        });
        // Swept for the direction the scattered sun is shown for (the old one while a
        // moved sun's world grid is swept on a thread), marched for the sun shown.
        let sky = crate::shadow::SkyMarch::new(self, key.depth, fresh);
        let outside = |p: Vec3| sky.to_sky(p, scattered_to);
        let r = timed(&mut times.sun_sweep, || {
            sweeper.sweep_sun(
                swept,
                &SunBoundary {
                    to_sun: scattered_to,
                    scattered,
                    outside: &outside,
                },
                &o,
            )
        })?;
        let r = match &wide {
            None => r,
            Some((w, k)) => apron::cropped_sun(r, w.desc(), material.grid.desc(), *k, sweeper),
        };
        let mut g = GridSun {
            scattered: Some(r.scattered),
            horizon: r.horizon,
            resident: r.resident,
            transmittance: r.transmittance,
            to_sun: scattered_to,
            marched_to: scattered_to,
            with_sky: None,
            march_stale: false,
            ring: None,
        };
        if sun.to_sun != scattered_to {
            g.transmittance = timed(&mut times.sun_sweep, || {
                self.march_node(sweeper, key, material, sun.to_sun, fresh)
            })?;
            g.marched_to = sun.to_sun;
        }
        Ok(Some(g))
    }

    /// The directions a node's sun responses march along: the sun's, and the one its
    /// scattered light is swept for if that differs ([`Hierarchy::scattered_to`]).
    pub(crate) fn sun_directions(&self) -> Vec<Vec3> {
        let mut v: Vec<Vec3> = self.sun.iter().map(|s| s.to_sun).collect();
        if let Some(d) = self.scattered_to().filter(|d| !v.contains(d)) {
            v.push(d);
        }
        v
    }

    /// The sun kept apart whose first collisions every grid sweeps with its sky
    /// ([`crate::HierarchyParams::sun_with_sky`]); `None` where the sky is swept alone.
    pub(crate) fn sun_with_sky(&self) -> Option<SunLight> {
        self.sun.filter(|_| self.params.sun_with_sky)
    }

    /// The sun the grids' sky sweeps take its first collisions from
    /// ([`crate::HierarchyParams::sun_with_sky`]): the world grid's sky sweep's, the
    /// sun's but while a moved sun's world grid is swept on a thread (a node swept
    /// meanwhile takes the world grid's, whose light its boundary reads, and is swept
    /// again once the new one is installed). `None` where the sky is swept alone.
    pub(crate) fn sky_sun(&self) -> Option<SunLight> {
        self.sun_with_sky()?;
        match self.world_sun.as_ref() {
            Some(w) => w.with_sky.map(|irradiance| SunLight {
                to_sun: w.to_sun,
                irradiance,
            }),
            None => self.sun,
        }
    }

    /// The direction the scattered sun is shown for: the world grid's (the sun's but
    /// while a moved sun's world grid is swept on a thread).
    pub(crate) fn scattered_to(&self) -> Option<Vec3> {
        self.world_sun.as_ref().map(|w| w.to_sun)
    }

    /// Whether node `key` has sun responses for the current sun: its transmittance
    /// marched for the sun shown, its scattered light swept for the direction the world
    /// grid's is.
    pub(crate) fn sun_current(&self, key: NodeKey) -> bool {
        match (self.sun, self.nodes.get(&key).and_then(|n| n.sun.as_ref())) {
            (Some(s), Some(g)) => {
                g.marched_to == s.to_sun && !g.march_stale && self.scattered_current(g)
            }
            _ => false,
        }
    }

    /// Whether `g`'s scattered sun is swept for the direction the world grid's is; with
    /// the sun swept with the sky, whether its grid's sky sweep took the current sun
    /// (direction and irradiance): else the grid is swept again.
    pub(crate) fn scattered_current(&self, g: &GridSun) -> bool {
        match (self.sky_sun(), g.with_sky) {
            (Some(s), Some(e)) => g.to_sun == s.to_sun && e == s.irradiance,
            (Some(_), None) => false,
            (None, _) => Some(g.to_sun) == self.scattered_to(),
        }
    }

    /// Whether node `key`'s scattered sun is current (swept for the direction the world
    /// grid's is) while its transmittance is not marched for the sun shown (a moved
    /// sun's `set_sun` left its march for later: [`Hierarchy::march_suns`]) or was
    /// marched through a scene since changed ([`Hierarchy::refresh`]).
    pub(crate) fn scattered_sun_current(&self, key: NodeKey) -> bool {
        match (self.sun, self.nodes.get(&key).and_then(|n| n.sun.as_ref())) {
            (Some(s), Some(g)) => {
                (g.marched_to != s.to_sun || g.march_stale) && self.scattered_current(g)
            }
            _ => false,
        }
    }

    /// Whether node `key`'s sun responses are shown: its transmittance is marched for
    /// the sun shown (its scattered light may still be an earlier direction's, until
    /// the budget sweeps it again: a moved sun re-marches the grids' transmittances at
    /// once, under a time budget those nearest the camera first).
    pub(crate) fn sun_shown(&self, key: NodeKey) -> bool {
        self.nodes.get(&key).is_some_and(|n| self.shows_sun(n))
    }

    /// [`Hierarchy::sun_shown`] of a node in hand (a read's: no second lookup).
    #[inline]
    pub(crate) fn shows_sun(&self, node: &Node) -> bool {
        match (self.sun, node.sun.as_ref()) {
            (Some(s), Some(g)) => g.marched_to == s.to_sun,
            _ => false,
        }
    }

    /// Whether the coarser grids a node's sun boundary reads are current: every built
    /// coarser node its boundary reads ([`Hierarchy::halo_rect`]: its parent and the
    /// neighbours its halo reaches; the world grid's, always current, where none is)
    /// that the camera wants. Else a node near the camera, swept before a neighbour of
    /// its parent's depth (`order.rs`), would take that neighbour's old sun and keep
    /// it. The same for the nodes of its depth before it whose scattered sun its halo
    /// reads ([`HierarchyParams::neighbour_halo`]). A built node the camera no longer
    /// wants keeps a stale sun (only wanted nodes' suns are swept again), which the
    /// boundary does not read ([`Hierarchy::coarse_sun`] takes current suns alone):
    /// waiting for it, a moved sun never settled (`tests/order.rs`); once it is wanted
    /// and current again, the nodes that read it are marked to be swept again
    /// (`mark_scattered_readers`).
    pub(crate) fn sun_parent_ready(&self, key: NodeKey) -> bool {
        let ready = |k: NodeKey| {
            !self.nodes.contains_key(&k) || !self.wanted_now.contains(&k) || self.sun_current(k)
        };
        self.halo_nodes(key).all(ready) && self.before_neighbours(key).all(ready)
    }

    /// The finest grid coarser than `depth` with a current sun response at `p` (the
    /// world grid's at worst); with `shown`, one whose sun is shown
    /// ([`Hierarchy::sun_shown`]: what is read), else one whose sun is current (what a
    /// node's boundary takes).
    pub(crate) fn coarse_sun(&self, p: Vec3, depth: u32, shown: bool) -> Option<&GridSun> {
        for d in (1..depth).rev() {
            let key = self.node_at(d, Vec2::new(p.x, p.z));
            if let Some(n) = self.nodes.get(&key)
                && within_levels(n.light.desc(), p)
                && (if shown {
                    self.shows_sun(n)
                } else {
                    self.sun_current(key)
                })
            {
                return n.sun.as_ref();
            }
        }
        self.world_sun.as_ref()
    }
}
