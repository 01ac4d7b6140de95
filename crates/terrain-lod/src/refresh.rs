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
use crate::{
    FrameStats, Hierarchy, KeyHasher, LodError, NodeKey, NodeMaterial, StageTimes, apron, timed,
};

/// The nodes a round of [`Hierarchy::refresh`] calls has checked.
pub(crate) type Checked = HashSet<NodeKey, BuildHasherDefault<KeyHasher>>;

/// Materials of ready nodes composed in a round's frame whose budget then left them
/// for a later frame of the round (composed once a round).
pub(crate) type Recomposed = HashMap<NodeKey, NodeMaterial, BuildHasherDefault<KeyHasher>>;

impl Hierarchy {
    /// Rebuilds every ready node whose inputs changed (after the scene, the sky or the
    /// sun changed), within the budget; nodes whose inputs hash as before are counted
    /// as skipped.
    ///
    /// A round's first call composes the world grid's material again: where the scene
    /// changed it (anything its cells see), the world grid is swept again at once, and
    /// a node whose column the scene changed (an object now rises above its levels, or
    /// is gone) is built anew at its new height within the round
    /// ([`FrameStats::regrown`]), before the finer nodes that read it. Wherever a
    /// material changed, the nodes whose sun shines through it are marched again within
    /// the round (showing their sun meanwhile). Settled, the hierarchy is one built
    /// over the new scene.
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
    /// responses), and the nodes whose sun's march crosses the changed cells are marked
    /// to be marched again ([`Hierarchy::mark_suns_crossing`]; shown until the round's
    /// frames march them; their scattered sun follows the coarser grids' light, which
    /// changed, as their sky does).
    fn refresh_world(&mut self, stats: &mut FrameStats) -> Result<(), LodError> {
        let desc = *self.world.desc();
        let material = timed(&mut stats.times.material, || self.compose(&desc))?;
        let changed = match &self.world_material {
            Some(old) => changed_box(old, &material),
            None => Some(desc.cell_bounds()),
        };
        let Some(changed) = changed else {
            return Ok(());
        };
        let _span = tracing::debug_span!("world grid swept again: the scene changed").entered();
        // A moved sun's sweep under way crossed the old material: finished first.
        self.poll_sun_move(true)?;
        timed(&mut stats.times.sky_sweep, || {
            self.sweep_world_over(material)
        })?;
        timed(&mut stats.times.sun_sweep, || self.sweep_world_sun())?;
        self.mark_suns_crossing(changed, None);
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
        // Nodes whose column the scene changed, swept anew at their new height as
        // `update` builds a new node, and their materials (the jobs' indices).
        let (mut regrown, mut regrown_materials) = (Vec::new(), Vec::new());
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
            let n = &self.nodes[&key];
            let same_column = p.material.has_objects == n.material.has_objects
                && p.material.open_above == n.material.open_above;
            let Some(inputs) = p.inputs.filter(|_| same_column) else {
                // The scene changed its column (an object risen above its levels, or
                // gone): built anew at its new height in this round, as `update`
                // builds a new node (its finer nodes, checked again, then read it
                // once); the nodes whose sun shines through it are marked.
                let desc = *p.material.grid.desc();
                let sky_points = apron::sky_points(&desc, self.params.apron);
                if self.over_budget(stats.points_swept, sky_points) {
                    stats.pending += 1;
                    self.recomposed.insert(key, p.material);
                    continue;
                }
                let old = changed_box(&n.material.grid, &p.material.grid);
                self.nodes.remove(&key);
                stats.regrown += 1;
                if let Some(b) = old {
                    self.mark_suns_crossing(b, Some(key));
                }
                let sky = Job {
                    material: Some(regrown_materials.len()),
                    sky: true,
                    ..Job::new(key)
                };
                regrown.push(key);
                regrown_materials.push(p.material);
                self.counted_sky_jobs(sky, &desc, stats, &mut jobs);
                self.checked.insert(key);
                continue;
            };
            let unchanged =
                self.params.skip.unchanged && inputs.hash == self.nodes[&key].input_hash;
            if unchanged {
                stats.skipped_unchanged += 1;
                if sun && !self.sun_current(key) {
                    jobs.extend(self.stale_sun_job(key, stats));
                }
            } else {
                // Rebuilt as `update` builds a new node: its material may have changed,
                // so its sun responses too.
                rebuilt.push((key, p.material.grid, p.material.widened));
                let sky = Job {
                    sky: true,
                    inputs: Some(inputs),
                    ..Job::new(key)
                };
                self.counted_sky_jobs(sky, &desc, stats, &mut jobs);
            }
            self.checked.insert(key);
        }
        // Those the budget left: their materials for a later frame of the round.
        for (key, p) in prepared {
            self.recomposed.insert(key, p.material);
        }
        let column_changed = !regrown.is_empty();
        if !rebuilt.is_empty() || column_changed {
            // Finer nodes read these ones' light, and so do the nodes of this depth
            // after them where they read those (`neighbours.rs`): checked again.
            let depth = keys[0].depth;
            let on = self.params.neighbour_halo;
            self.checked.retain(|k| {
                k.depth < depth
                    || (k.depth == depth
                        && !(on
                            && (column_changed
                                || rebuilt
                                    .iter()
                                    .any(|(r, _, _)| crate::neighbours::before(*r, *k)))))
            });
        }
        let provisional: Vec<NodeKey> = (rebuilt.iter().map(|(k, _, _)| *k))
            .chain(regrown.iter().copied())
            .filter(|k| self.reads_unsettled(*k, wanted))
            .collect();
        self.keep_rebuilt_materials(rebuilt);
        let jobs = self.compose_jobs_casters(jobs, &regrown, &regrown_materials, stats)?;
        let done = self.run_jobs(jobs, &regrown, &regrown_materials, &mut stats.times);
        self.mark_provisional(provisional);
        done
    }

    /// Gives the nodes `refresh_depth` rebuilds on their grids their new materials
    /// (grid and widened), which their sweeps read. A node whose material changed
    /// drops its sun: its transmittance crossed the old one (else the node shows it
    /// until its sun is swept again: `kept_sun`). Other nodes whose march crosses a
    /// changed material are marked to be marched again (a finer node's march beyond
    /// its box crosses this one's material).
    fn keep_rebuilt_materials(
        &mut self,
        rebuilt: Vec<(NodeKey, MaterialGrid, Option<MaterialGrid>)>,
    ) {
        for (key, grid, widened) in rebuilt {
            let n = self.nodes.get_mut(&key).expect("ready node");
            let changed = match &n.material.widened {
                Some(old) => changed_box(old, widened.as_ref().unwrap_or(&grid)),
                None => changed_box(&n.material.grid, &grid),
            };
            if changed.is_some() {
                n.sun = None;
            }
            n.material.grid = grid;
            n.material.widened = widened;
            if let Some(b) = changed {
                self.mark_suns_crossing(b, Some(key));
            }
        }
    }

    /// The materials of ready nodes `keys` composed from the scene as `update` composes
    /// a new node's (where `kept` holds none: its column, which the scene may have made
    /// taller or shorter) and, where its grid is the node's, their sky sweeps' inputs
    /// made and hashed, side by side.
    fn prepare(
        &self,
        keys: &[NodeKey],
        kept: Vec<Option<NodeMaterial>>,
    ) -> Vec<Result<Prepared, LodError>> {
        keys.par_iter()
            .zip(kept)
            .map(|(key, kept)| {
                let n = &self.nodes[key];
                let mut times = StageTimes::default();
                let material = match kept {
                    Some(m) => m,
                    None => timed(&mut times.material, || self.node_material(*key))?,
                };
                let inputs = (material.grid.desc() == n.light.desc()).then(|| {
                    let o = self.node_options(material.has_objects);
                    self.sky_inputs(*key, &material, &o, &mut times)
                });
                Ok(Prepared {
                    material,
                    inputs,
                    times,
                })
            })
            .collect()
    }
}

/// A ready node's material composed again and its sky sweep's inputs (`None` where
/// its grid is no longer the node's).
struct Prepared {
    material: NodeMaterial,
    inputs: Option<apron::SkyInputs>,
    times: StageTimes,
}

/// A box, min and max corners.
type Aabb = (Vec3, Vec3);

/// The box of the cells where `new` differs from `old` (all of both where their grids
/// differ), `None` where they are the same.
fn changed_box(old: &MaterialGrid, new: &MaterialGrid) -> Option<Aabb> {
    let desc = *new.desc();
    if *old.desc() != desc {
        let (a, b) = (old.desc().cell_bounds(), desc.cell_bounds());
        return Some((a.0.min(b.0), a.1.max(b.1)));
    }
    let half = Vec3::splat(0.5 * desc.h());
    (old.data().iter().zip(new.data()).enumerate())
        .filter(|(_, (a, b))| a != b)
        .map(|(i, _)| desc.position(desc.coords(i).expect("in range")))
        .fold(None, |acc: Option<Aabb>, p| {
            let (lo, hi) = acc.unwrap_or((p, p));
            Some((lo.min(p), hi.max(p)))
        })
        .map(|(lo, hi)| (lo - half, hi + half))
}

/// Whether a ray from some point of `from` along `dir` meets `to`: the ray from the
/// origin through the box of their differences (slabs).
fn ray_meets(from: Aabb, to: Aabb, dir: Vec3) -> bool {
    let (lo, hi) = (to.0 - from.1, to.1 - from.0);
    let (mut enter, mut exit) = (0.0f32, f32::INFINITY);
    for i in 0..3 {
        if dir[i] == 0.0 {
            if lo[i] > 0.0 || hi[i] < 0.0 {
                return false;
            }
            continue;
        }
        let (a, b) = (lo[i] / dir[i], hi[i] / dir[i]);
        enter = enter.max(a.min(b));
        exit = exit.min(a.max(b));
    }
    enter <= exit
}

impl Hierarchy {
    /// Marks the sun of every node whose march toward the sun may cross `changed` to be
    /// marched again ([`crate::GridSun`]'s `march_stale`) and its scattered sun to be
    /// swept again (with the sun swept with the sky, the node's sky sweep: the beam's
    /// first collisions are the scattered sun's source), both shown until then. The
    /// march leaves a node's points (and its apron's) toward the sun, over its depth's
    /// materials and coarser ones, to the sky: where `changed` is node `from`'s
    /// material, neither that node nor the coarser ones read it.
    pub(crate) fn mark_suns_crossing(&mut self, changed: Aabb, from: Option<NodeKey>) {
        let Some(sun) = self.sun else {
            return;
        };
        let apron = self.params.apron.max(self.params.sun_apron_cells()) as f32 + 1.0;
        for (key, n) in &mut self.nodes {
            if from.is_some_and(|f| *key == f || key.depth < f.depth) {
                continue;
            }
            let Some(g) = n.sun.as_mut() else {
                continue;
            };
            let desc = n.light.desc();
            let (lo, hi) = desc.cell_bounds();
            let wide = Vec3::new(apron, 0.0, apron) * desc.h();
            if ray_meets((lo - wide, hi + wide), changed, sun.to_sun) {
                g.march_stale = true;
                // Its scattered sun too: the beam's first collisions are its source.
                g.mark_scattered_stale();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ray_meets_a_box_toward_it_and_not_one_behind_or_beside() {
        let from = (Vec3::ZERO, Vec3::ONE);
        let up = Vec3::new(0.0, 1.0, 0.0);
        assert!(ray_meets(
            from,
            (Vec3::new(0.0, 5.0, 0.0), Vec3::new(1.0, 6.0, 1.0)),
            up
        ));
        assert!(!ray_meets(
            from,
            (Vec3::new(0.0, -6.0, 0.0), Vec3::new(1.0, -5.0, 1.0)),
            up
        ));
        assert!(!ray_meets(
            from,
            (Vec3::new(3.0, 5.0, 0.0), Vec3::new(4.0, 6.0, 1.0)),
            up
        ));
        // A low sun toward +x: a box 10 m away and 2 m up is met, one 10 m up is not.
        let low = Vec3::new(1.0, 0.2, 0.0).normalize();
        assert!(ray_meets(
            from,
            (Vec3::new(10.0, 2.0, 0.0), Vec3::new(11.0, 3.0, 1.0)),
            low
        ));
        assert!(!ray_meets(
            from,
            (Vec3::new(10.0, 10.0, 0.0), Vec3::new(11.0, 11.0, 1.0)),
            low
        ));
        // Overlapping boxes meet.
        assert!(ray_meets(from, (Vec3::splat(0.5), Vec3::splat(2.0)), -up));
    }

    #[test]
    fn the_changed_box_holds_the_changed_cells_alone() {
        use lightgrid_core::{GridDesc, Material};
        let desc = GridDesc::new(Vec3::ZERO, 2.0, lightgrid_core::glam::UVec3::splat(4)).unwrap();
        let old = MaterialGrid::new(desc, vec![Material::EMPTY; 64]).unwrap();
        assert_eq!(changed_box(&old, &old), None);
        let mut new = old.clone();
        let i = desc
            .index(lightgrid_core::glam::UVec3::new(1, 2, 3))
            .unwrap();
        new.data_mut()[i] = Material::opaque(Vec3::splat(0.5));
        assert_eq!(
            changed_box(&old, &new),
            Some((Vec3::new(1.0, 3.0, 5.0), Vec3::new(3.0, 5.0, 7.0)))
        );
    }
}
