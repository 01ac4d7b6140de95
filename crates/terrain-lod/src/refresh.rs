//! [`Hierarchy::refresh`]: the ready nodes swept again where their inputs changed (the
//! sky, the sun, the scene), a round of frames at a time: each frame checks, coarse and
//! near first within the budget, the nodes the round has not checked yet, so that a
//! round's later frames do not compose and hash again the nodes its first frames found
//! unchanged or rebuilt. A depth at a time, its nodes side by side, as
//! [`Hierarchy::update`] builds one (`build.rs`).

use std::collections::{HashMap, HashSet};
use std::hash::BuildHasherDefault;

use lightgrid_core::MaterialGrid;
use lightgrid_core::glam::Vec3;
use rayon::prelude::*;

use crate::build::Job;
use crate::{FrameStats, Hierarchy, KeyHasher, LodError, NodeKey, StageTimes, apron, timed};

/// The nodes a round of [`Hierarchy::refresh`] calls has checked.
pub(crate) type Checked = HashSet<NodeKey, BuildHasherDefault<KeyHasher>>;

/// Materials of ready nodes composed in a round's frame whose budget then left them
/// for a later frame of the round (composed once a round).
/// (Each with its widened material where the hierarchy has an apron.)
pub(crate) type Recomposed =
    HashMap<NodeKey, (MaterialGrid, Option<MaterialGrid>), BuildHasherDefault<KeyHasher>>;

impl Hierarchy {
    /// Rebuilds every ready node whose inputs changed (after the scene, the sky or the
    /// sun changed), within the budget; nodes whose inputs hash as before are counted
    /// as skipped.
    ///
    /// A round's first call composes the world grid's material again: where the scene
    /// changed it (anything its cells see), the world grid is swept again at once,
    /// every node's sun is swept again within the round, and the nodes an object now
    /// rises above are evicted ([`FrameStats::evicted`]): [`Hierarchy::update`] builds
    /// them anew, taller. Settled, the hierarchy is one built over the new scene.
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
            self.recomposed.clear();
            self.casters.clear();
            self.refresh_world(&mut stats)?;
        }
        let mut keys = self.ready_nodes();
        keys.sort_by(|a, b| {
            a.depth.cmp(&b.depth).then(
                self.distance(*a, camera)
                    .total_cmp(&self.distance(*b, camera)),
            )
        });
        let wanted: crate::order::Wanted = self.wanted(camera).into_iter().collect();
        self.wanted_now = wanted.clone();
        for depth in keys.chunk_by(|a, b| a.depth == b.depth) {
            // In waves where a node reads the nodes of its depth before it
            // (`neighbours.rs`): each wave reads the waves before it as rebuilt.
            for wave in crate::neighbours::waves(depth, self.params.neighbour_halo) {
                self.refresh_depth(&wave, &wanted, &mut stats)?;
            }
        }
        stats.sun_pending = self.sun_pending();
        stats.provisional = self.provisional_count();
        if stats.pending == 0 {
            // The round is over: the next call checks every node again.
            self.checked.clear();
            self.recomposed.clear();
        }
        self.casters.end_frame();
        stats.caster_bytes = self.casters.bytes();
        self.last_frame_swept = stats.points_swept > 0;
        Ok(stats)
    }

    /// A round's first step: the world grid's material composed again. Where the
    /// scene changed it, the world grid is swept again at once (its sky, and the sun's
    /// responses), every node's sun is dropped (its march beyond the node crossed the
    /// world grid's old material: the round's frames sweep it again), and the nodes
    /// whose column the new material no longer fits (an object rising above a node's
    /// levels: [`Hierarchy::node_desc`]) are evicted, for [`Hierarchy::update`] to
    /// build anew at their new height.
    fn refresh_world(&mut self, stats: &mut FrameStats) -> Result<(), LodError> {
        let desc = *self.world.desc();
        let material = timed(&mut stats.times.material, || self.compose(&desc))?;
        if self.world_material.as_ref() == Some(&material) {
            return Ok(());
        }
        let _span = tracing::debug_span!("world grid swept again: the scene changed").entered();
        // A moved sun's sweep under way crossed the old material: finished first.
        self.poll_sun_move(true)?;
        timed(&mut stats.times.sky_sweep, || {
            self.sweep_world_over(material)
        })?;
        timed(&mut stats.times.sun_sweep, || self.sweep_world_sun())?;
        self.drop_node_suns();
        let mut resized = Vec::new();
        for (key, n) in &self.nodes {
            if self.node_desc(*key)? != *n.light.desc() {
                resized.push(*key);
            }
        }
        for key in resized {
            self.nodes.remove(&key);
            stats.evicted += 1;
        }
        Ok(())
    }

    /// One depth of a refresh frame (`keys`, nearest first): the same choices as
    /// checking one node after the other within the budget, made first; then the
    /// materials composed and inputs hashed side by side, a batch (one a thread) at a
    /// time as the walk reaches them, and the sweeps run side by side on forks of the
    /// sweeper ([`Hierarchy::run_jobs`]), as [`Hierarchy::update`] builds a depth.
    /// A rebuilt node whose boundary reads a coarser node still to come (`wanted`, not
    /// built) or a provisional one stays provisional, as `update` marks a new one.
    fn refresh_depth(
        &mut self,
        keys: &[NodeKey],
        wanted: &crate::order::Wanted,
        stats: &mut FrameStats,
    ) -> Result<(), LodError> {
        let mut prepared: HashMap<NodeKey, Prepared, BuildHasherDefault<KeyHasher>> =
            HashMap::default();
        let mut jobs = Vec::new();
        let mut rebuilt = Vec::new();
        let sun = self.sun.is_some();
        for (i, &key) in keys.iter().enumerate() {
            if self.checked.contains(&key) {
                // Checked this round: its sun responses alone, where the budget left
                // them for this frame (from the material it keeps).
                if sun && !self.sun_current(key) {
                    jobs.extend(self.stale_sun_job(key, stats));
                }
                continue;
            }
            let desc = *self.nodes[&key].light.desc();
            let sky_points = apron::sky_points(&desc, self.params.apron);
            if self.over_budget(stats.points_swept, sky_points) {
                stats.pending += 1;
                continue;
            }
            if !prepared.contains_key(&key) {
                // This node and the next unchecked ones the budget may still allow.
                let batch: Vec<NodeKey> = (keys[i..].iter().copied())
                    .filter(|k| !self.checked.contains(k) && !prepared.contains_key(k))
                    .filter(|k| {
                        let d = self.nodes[k].light.desc();
                        !self.over_budget(
                            stats.points_swept,
                            apron::sky_points(d, self.params.apron),
                        )
                    })
                    .take(rayon::current_num_threads().max(1))
                    .collect();
                let kept: Vec<_> = batch.iter().map(|k| self.recomposed.remove(k)).collect();
                for (k, p) in batch.iter().zip(self.prepare(&batch, kept)) {
                    let p = p?;
                    stats.times.material += p.times.material;
                    stats.times.boundary += p.times.boundary;
                    prepared.insert(*k, p);
                }
            }
            let p = prepared.remove(&key).expect("prepared above");
            // (The node keeps its size; a changed scene may need a new size: evict it.)
            let unchanged =
                self.params.skip.unchanged && p.inputs.hash == self.nodes[&key].input_hash;
            if unchanged {
                stats.skipped_unchanged += 1;
                if sun && !self.sun_current(key) {
                    jobs.extend(self.stale_sun_job(key, stats));
                }
            } else {
                // Rebuilt as `update` builds a new node: its material may have changed,
                // so its sun responses too.
                stats.points_swept += sky_points;
                stats.built += 1;
                rebuilt.push((key, p.material, p.widened));
                let sky = Job {
                    sky: true,
                    inputs: Some(p.inputs),
                    ..Job::new(key)
                };
                let sun_points = apron::sky_points(&desc, self.params.sun_apron);
                self.sky_jobs(sky, sun_points, stats, &mut jobs);
            }
            self.checked.insert(key);
        }
        // Those the budget left: their materials for a later frame of the round.
        for (key, p) in prepared {
            self.recomposed.insert(key, (p.material, p.widened));
        }
        if !rebuilt.is_empty() {
            // Finer nodes read these ones' light, and so do the nodes of this depth
            // after them where they read those (`neighbours.rs`): checked again.
            let depth = keys[0].depth;
            let on = self.params.neighbour_halo;
            self.checked.retain(|k| {
                k.depth < depth
                    || (k.depth == depth
                        && !(on
                            && rebuilt
                                .iter()
                                .any(|(r, _, _)| crate::neighbours::before(*r, *k))))
            });
        }
        let provisional: Vec<NodeKey> = (rebuilt.iter().map(|(k, _, _)| *k))
            .filter(|k| self.reads_unsettled(*k, wanted))
            .collect();
        // The sweeps read the rebuilt nodes' new materials where they keep theirs. A
        // node whose material changed drops its sun: its transmittance crossed the old
        // one (else the node shows it until its sun is swept again: `kept_sun`).
        for (key, grid, widened) in rebuilt {
            let n = self.nodes.get_mut(&key).expect("ready node");
            if n.material.grid != grid || n.material.widened != widened {
                n.sun = None;
            }
            n.material.grid = grid;
            n.material.widened = widened;
        }
        let jobs = self.compose_jobs_casters(jobs, &[], &[], stats)?;
        let done = self.run_jobs(jobs, &[], &[], &mut stats.times);
        self.mark_provisional(provisional);
        done
    }

    /// The materials of ready nodes `keys` composed from the scene (where `kept` holds
    /// none) and their sky sweeps' inputs made and hashed, side by side.
    fn prepare(
        &self,
        keys: &[NodeKey],
        kept: Vec<Option<(MaterialGrid, Option<MaterialGrid>)>>,
    ) -> Vec<Result<Prepared, LodError>> {
        keys.par_iter()
            .zip(kept)
            .map(|(key, kept)| {
                let n = &self.nodes[key];
                let mut times = StageTimes::default();
                let (material, widened) = match kept {
                    Some(m) => m,
                    None => timed(&mut times.material, || self.compose_node(n.light.desc()))?,
                };
                let o = self.node_options(n.material.has_objects);
                let inputs = self.sky_inputs(*key, (&material, widened.as_ref()), &o, &mut times);
                Ok(Prepared {
                    material,
                    widened,
                    inputs,
                    times,
                })
            })
            .collect()
    }
}

/// A ready node's material composed again and its sky sweep's inputs.
struct Prepared {
    material: MaterialGrid,
    /// `material` widened by the apron, if any.
    widened: Option<MaterialGrid>,
    inputs: apron::SkyInputs,
    times: StageTimes,
}
