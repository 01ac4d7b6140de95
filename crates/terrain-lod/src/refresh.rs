//! [`Hierarchy::refresh`]: the ready nodes swept again where their inputs changed (the
//! sky, the sun, the scene), a round of frames at a time: each frame checks, coarse and
//! near first within the budget, the nodes the round has not checked yet, so that a
//! round's later frames do not compose and hash again the nodes its first frames found
//! unchanged or rebuilt.

use std::collections::HashSet;
use std::hash::BuildHasherDefault;

use lightgrid_core::glam::Vec3;

use crate::{FrameStats, Hierarchy, KeyHasher, Lent, LodError, NodeKey, apron, timed};

/// The nodes a round of [`Hierarchy::refresh`] calls has checked.
pub(crate) type Checked = HashSet<NodeKey, BuildHasherDefault<KeyHasher>>;

impl Hierarchy {
    /// Rebuilds every ready node whose inputs changed (after the scene, the sky or the
    /// sun changed), within the budget; nodes whose inputs hash as before are counted
    /// as skipped.
    ///
    /// Call it frame after frame until it returns `pending == 0`: such a round of
    /// calls checks each ready node once (a node its first frames checked is not
    /// composed and hashed again in its later ones; sun responses the budget left wait
    /// for a later frame of the round), those nodes finer than a node it rebuilt again
    /// (their boundaries changed). The call after a round that ended, or
    /// after [`Hierarchy::update`], [`Hierarchy::set_sky`], [`Hierarchy::set_sun`] or
    /// [`Hierarchy::set_sweeper`], starts a new round: it checks every ready node.
    pub fn refresh(&mut self, camera: Vec3) -> Result<FrameStats, LodError> {
        let _span = tracing::debug_span!("refresh", camera = %camera).entered();
        let mut stats = self.begin_frame(camera)?;
        if self.checked.is_empty() {
            // A new round: the scene may have changed since the materials kept for
            // later frames and the sun's casters were composed.
            self.composed.clear();
            self.casters.clear();
        }
        let mut keys = self.ready_nodes();
        keys.sort_by(|a, b| {
            a.depth.cmp(&b.depth).then(
                self.distance(*a, camera)
                    .total_cmp(&self.distance(*b, camera)),
            )
        });
        for key in keys {
            if self.checked.contains(&key) {
                // Checked this round: its sun responses alone, where the budget left
                // them for this frame (from the material it keeps).
                if self.sun.is_some() && !self.sun_current(key) {
                    self.update_sun(key, None, &mut stats)?;
                }
                continue;
            }
            let desc = *self.nodes[&key].light.desc();
            if self.over_budget(
                stats.points_swept,
                apron::sky_points(&desc, self.params.apron),
            ) {
                stats.pending += 1;
                continue;
            }
            let material = timed(&mut stats.times.material, || self.compose(&desc))?;
            let o = self.node_options(self.nodes[&key].material.has_objects);
            let inputs = self.sky_inputs(key.depth, &material, &o, &mut stats.times)?;
            let hash = inputs.hash;
            // (The node keeps its size; a changed scene may need a new size: evict it.)
            if self.params.skip.unchanged && hash == self.nodes[&key].input_hash {
                stats.skipped_unchanged += 1;
            } else {
                let mut sweeper = std::mem::replace(&mut self.sweeper, Box::new(Lent));
                let out =
                    self.sweep_sky(&inputs, &material, &o, sweeper.as_mut(), &mut stats.times);
                self.sweeper = sweeper;
                let out = out?;
                stats.points_swept += apron::sky_points(&desc, self.params.apron);
                stats.built += 1;
                let n = self.nodes.get_mut(&key).expect("ready node");
                n.light = out.bins.expect("bins asked for");
                n.horizon = out.horizon;
                n.resident = out.resident;
                n.input_hash = hash;
                n.material.grid = material.clone();
                // The material may have changed: the sun's responses too.
                n.sun = None;
                // Finer nodes read this one's light: checked again.
                self.checked.retain(|k| k.depth <= key.depth);
            }
            if self.sun.is_some() && !self.sun_current(key) {
                self.update_sun(key, Some(&material), &mut stats)?;
            }
            self.checked.insert(key);
        }
        stats.sun_pending = self.sun_pending();
        if stats.pending == 0 {
            // The round is over: the next call checks every node again.
            self.checked.clear();
        }
        self.casters.end_frame();
        stats.caster_bytes = self.casters.bytes();
        self.last_frame_swept = stats.points_swept > 0;
        Ok(stats)
    }
}
