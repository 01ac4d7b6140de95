//! Building a frame's nodes, a depth at a time, the nodes of one depth side by side.
//!
//! A node's boundaries read only coarser grids, so the nodes of one depth are
//! independent once the coarser depths are done. [`Hierarchy::update`] takes the wanted
//! nodes a depth at a time: it decides in the wanted order (nearest first) which nodes
//! are built and which sun responses computed within the budget, exactly as one node
//! after the other would, composes the new nodes' materials side by side, then sweeps
//! the chosen nodes side by side on forks of the sweeper ([`Sweeper::fork`]: the CPU
//! sweeper forks, each fork keeping its memory from frame to frame; a sweeper that
//! cannot fork, the GPU's, sweeps them one after the other). Beside those sweeps it
//! composes the materials of the frame's next depth to build, which read no light
//! ([`HierarchyParams::compose_ahead`](crate::HierarchyParams::compose_ahead)): a thread
//! that would wait on a depth's last node composes instead. The results are those of
//! the one-by-one order bit for bit: every node's sweep is deterministic and reads
//! nothing its siblings write.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use lightgrid_core::glam::Vec3;
use lightgrid_core::{BinLight, GridError, LightField, Sweeper};
use rayon::prelude::*;

use crate::shadow::Fresh;
use crate::{
    FrameStats, GridSun, Hierarchy, LodError, Node, NodeKey, NodeMaterial, StageTimes, timed,
};

/// A node's material, composed.
type Composed = Result<NodeMaterial, GridError>;

/// One node's work in a frame.
pub(crate) struct Job {
    pub(crate) key: NodeKey,
    /// A new node's material: its index among the depth's composed ones (`None`: a
    /// built node whose sun response is stale; its stored material is used).
    pub(crate) material: Option<usize>,
    /// Sweep the sky's light (a new node, or a ready one `refresh` rebuilds).
    pub(crate) sky: bool,
    /// The sky sweep's inputs, where made already (`refresh` hashes them first).
    pub(crate) inputs: Option<crate::apron::SkyInputs>,
    /// Compute the sun's responses.
    pub(crate) sun: bool,
    /// A new node whose sun responses wait for a later frame: march its transmittance
    /// now ([`Hierarchy::interim_sun`]).
    pub(crate) march: bool,
    /// With `march`: the sun's casters its rays cross are not all composed yet (the
    /// frame's time ran out): the march reads coarser material there, and the
    /// transmittance is marched again with them ([`GridSun`]'s `march_stale`).
    pub(crate) casters_missing: bool,
    /// A built node whose scattered sun is current but whose transmittance a moved
    /// sun's `set_sun` left for later ([`Hierarchy::march_suns`] under a time budget):
    /// march it alone.
    pub(crate) remarch: bool,
}

impl Job {
    /// A job for `key` that does nothing yet (set what it does).
    pub(crate) fn new(key: NodeKey) -> Self {
        Self {
            key,
            material: None,
            sky: false,
            inputs: None,
            sun: false,
            march: false,
            casters_missing: false,
            remarch: false,
        }
    }
}

/// What a job made.
struct Done {
    key: NodeKey,
    node: Option<Node>,
    sun: Option<GridSun>,
    /// A re-marched transmittance, for the sun shown.
    marched: Option<lightgrid_core::Grid<f32>>,
    /// The transmittance beyond the node's points for the direction it shows.
    ring: Option<crate::apron::SunRing>,
    times: StageTimes,
}

/// How a wanted node of a depth is served this frame.
enum Want {
    /// Built, its sun response stale.
    Stale(NodeKey),
    /// To build (its material is at this index of the composed ones).
    New(NodeKey, usize),
}

impl Hierarchy {
    /// Builds the wanted nodes of one depth (`keys`, nearest first; `wanted` all the
    /// frame's) within the budget.
    pub(crate) fn build_depth(
        &mut self,
        keys: &[NodeKey],
        next: &[NodeKey],
        wanted: &crate::order::Wanted,
        stats: &mut FrameStats,
    ) -> Result<(), LodError> {
        let mut order = Vec::new();
        let mut new = Vec::new();
        let mut provisional = Vec::new();
        for &key in keys {
            if self.nodes.contains_key(&key) {
                if self.sun.is_some() && !self.sun_current(key) {
                    order.push(Want::Stale(key));
                }
                continue;
            }
            if self.parent_blocks(key, stats) {
                continue;
            }
            if !self.composed.contains_key(&key) && self.out_of_time(stats.points_swept) {
                stats.pending += 1; // composed in a later frame
                continue;
            }
            if self.reads_unsettled(key, wanted) {
                provisional.push(key);
            }
            order.push(Want::New(key, new.len()));
            new.push(key);
        }
        // Materials first (they size the grids the budget counts), side by side: under a
        // time budget a batch of one a thread at a time while the budget allows
        // ([`Hierarchy::composition_waits`]), else all at once; those composed in an
        // earlier frame for nodes the budget left are kept.
        let missing: Vec<NodeKey> = new
            .iter()
            .copied()
            .filter(|k| !self.composed.contains_key(k))
            .collect();
        let per_batch = match self.params.budget_ms {
            Some(_) => rayon::current_num_threads().max(1),
            None => missing.len().max(1),
        };
        for batch in missing.chunks(per_batch) {
            if self.composition_waits(stats.composed) {
                break;
            }
            let composed = self.compose_nodes(batch);
            for (&key, (m, t)) in batch.iter().zip(composed) {
                stats.times.material += t;
                self.composed.insert(key, m?);
            }
            stats.composed += batch.len() as u32;
        }
        // New nodes whose material waits are left for a later frame.
        if new.iter().any(|k| !self.composed.contains_key(k)) {
            let waiting = new
                .iter()
                .filter(|k| !self.composed.contains_key(k))
                .count();
            stats.pending += waiting as u32;
            new.retain(|k| self.composed.contains_key(k));
            order = order
                .into_iter()
                .filter_map(|w| match w {
                    Want::New(key, _) => new
                        .iter()
                        .position(|k| *k == key)
                        .map(|i| Want::New(key, i)),
                    stale => Some(stale),
                })
                .collect();
        }
        let materials: Vec<NodeMaterial> = new
            .iter()
            .map(|k| self.composed.remove(k).expect("composed above or kept"))
            .collect();
        self.step_swept = stats.points_swept;
        let jobs = self.jobs(order, &materials, stats);
        let (selected, started) = (stats.points_swept - self.step_swept, Instant::now());
        let jobs = self.compose_jobs_casters(jobs, &new, &materials, stats)?;
        let ahead = self.ahead_of(next, &new, &materials);
        let (done, composed) =
            self.run_jobs_composing(jobs, &new, &materials, &mut stats.times, &ahead);
        self.step_swept = stats.points_swept;
        let secs = started.elapsed().as_secs_f64();
        if self.params.budget_ms.is_some() {
            self.steps_timed.0 += selected;
            self.steps_timed.1 += secs;
        }
        for (key, (m, t)) in ahead.into_iter().zip(composed) {
            stats.times.material += t;
            // (An error is met again, and returned, when the node's turn comes.)
            if let Ok(m) = m {
                self.composed.insert(key, m);
                stats.composed += 1;
            }
        }
        self.mark_provisional(provisional);
        // Nodes built earlier after these ones in the order their halos read
        // (`neighbours.rs`) read a coarser grid where these now are: swept again.
        let after: Vec<NodeKey> = new
            .iter()
            .filter(|k| self.nodes.contains_key(k))
            .flat_map(|k| self.after_neighbours(*k))
            .filter(|k| self.nodes.contains_key(k))
            .collect();
        self.mark_provisional(after);
        // The materials of nodes left for a later frame are kept for it.
        for (key, m) in new.into_iter().zip(materials) {
            if !self.nodes.contains_key(&key) {
                self.composed.insert(key, m);
            }
        }
        done
    }

    /// The materials of `keys` composed side by side (rayon), each with the time it
    /// took.
    pub(crate) fn compose_nodes(&self, keys: &[NodeKey]) -> Vec<(Composed, Duration)> {
        self.compose_each(keys, Self::node_material)
    }

    /// `compose(self, key)` of each of `keys` side by side (rayon), each with the time
    /// it took.
    pub(crate) fn compose_each(
        &self,
        keys: &[NodeKey],
        compose: impl Fn(&Self, NodeKey) -> Composed + Sync,
    ) -> Vec<(Composed, Duration)> {
        keys.par_iter()
            .map(|&key| {
                let mut t = Duration::ZERO;
                let m = timed(&mut t, || compose(self, key));
                (m, t)
            })
            .collect()
    }

    /// Composes the sun's casters ([`crate::casters`]) for the jobs that light nodes,
    /// first: all at once without a time budget; under one a job at a time and a
    /// job's a batch at a time, and a job whose casters are not all held once the frame
    /// has spent half its budget on composing loses its sun part to a later frame (its
    /// points are given back; the casters composed for it are kept).
    pub(crate) fn compose_jobs_casters(
        &mut self,
        jobs: Vec<Job>,
        new: &[NodeKey],
        materials: &[NodeMaterial],
        stats: &mut FrameStats,
    ) -> Result<Vec<Job>, LodError> {
        let dirs = self.sun_directions();
        // The grid a job's marches run on (their rays start in all of it).
        let grid = |this: &Self, j: &Job| {
            let m = match j.material {
                Some(i) => &materials[i],
                None => &this.nodes[&j.key].material,
            };
            (j.key, this.marched_extent(m))
        };
        if self.params.budget_ms.is_none() {
            let lit: Vec<_> = jobs
                .iter()
                .filter(|j| j.sun || j.march || j.remarch)
                .map(|j| grid(self, j))
                .collect();
            let (n, t) = self.compose_casters(&lit, &dirs, new)?;
            stats.casters += n;
            stats.times.material += t;
            return Ok(jobs);
        }
        // A batch (a caster a thread) at a time: a low sun's job may need tens of
        // casters (19 at once took a frame at 10° to 64-71 ms of a 30 ms budget). Those
        // composed before the frame's time ran out are kept for the job's next try.
        let per_batch = rayon::current_num_threads().max(1);
        let mut kept = Vec::with_capacity(jobs.len());
        for mut job in jobs {
            if job.sun || job.march || job.remarch {
                let g = grid(self, &job);
                let need = self.missing_casters(&[g], &dirs, new);
                let mut held = true;
                for batch in need.chunks(per_batch) {
                    if self.composition_waits(stats.composed + stats.casters) {
                        held = false;
                        break;
                    }
                    let (n, t) = self.compose_missing(batch.to_vec())?;
                    stats.casters += n;
                    stats.times.material += t;
                }
                if !held {
                    if job.march {
                        // The sky's job stays; its sun is the coarser grids' meanwhile,
                        // or with `HierarchyParams::march_before_casters` its march
                        // through the casters held and coarser material beyond, marched
                        // again once they all are.
                        if self.params.march_before_casters {
                            job.casters_missing = true;
                        } else {
                            job.march = false;
                        }
                        kept.push(job);
                        continue;
                    }
                    let m = match job.material {
                        Some(i) => &materials[i],
                        None => &self.nodes[&job.key].material,
                    };
                    stats.points_swept -= m.grid.desc().point_count() as u64;
                    stats.sun_built -= 1;
                    stats.pending += 1;
                    continue;
                }
            }
            kept.push(job);
        }
        Ok(kept)
    }

    /// Whether a new node waits (its parent not built: pending) or is skipped (bare
    /// ground above it with the skip on), counting it.
    fn parent_blocks(&self, key: NodeKey, stats: &mut FrameStats) -> bool {
        let Some(p) = Self::parent(key) else {
            return false;
        };
        let skip_bare = self.params.skip.bare_children;
        match self.nodes.get(&p) {
            Some(n) if n.material.has_objects || !skip_bare => false,
            Some(_) => {
                stats.skipped_bare += 1; // bare ground: no finer child needed
                true
            }
            // A missing parent under a bare ancestor will never be built: neither will
            // this node (not pending work).
            None if skip_bare && self.bare_ancestor(p) => {
                stats.skipped_bare += 1;
                true
            }
            None => {
                stats.pending += 1;
                true
            }
        }
    }

    /// The jobs for the wanted nodes of a depth (`order`, nearest first; `materials`
    /// the new ones' composed materials) within the budget, counted in `stats`: a new
    /// node's sky sweep, and its sun responses as a second job where they fit (else its
    /// transmittance marched with the sky's job); a built node's stale sun responses.
    fn jobs(
        &self,
        order: Vec<Want>,
        materials: &[NodeMaterial],
        stats: &mut FrameStats,
    ) -> Vec<Job> {
        let mut jobs = Vec::new();
        for w in order {
            match w {
                Want::Stale(key) => jobs.extend(self.stale_sun_job(key, stats)),
                Want::New(key, i) => {
                    let sky = Job {
                        material: Some(i),
                        sky: true,
                        ..Job::new(key)
                    };
                    self.budgeted_sky_jobs(sky, materials[i].grid.desc(), stats, &mut jobs);
                }
            }
        }
        jobs
    }

    /// The job for built node `key`'s stale sun responses within the budget, counted in
    /// `stats` (`None`: pending): its transmittance alone where its scattered sun is
    /// current, else its responses (the march alone where the finest depth reads the
    /// coarser grids' scattered sun).
    pub(crate) fn stale_sun_job(&self, key: NodeKey, stats: &mut FrameStats) -> Option<Job> {
        // Its sun responses are swept and marched over its sun's apron, if any.
        let points =
            crate::apron::sky_points(self.nodes[&key].light.desc(), self.params.sun_apron_cells());
        if self.scattered_sun_current(key) {
            // The transmittance alone (about a quarter of a sun response's work:
            // counted so in the budget).
            let cost = points / 4;
            if self.over_budget(stats.points_swept, cost) {
                stats.pending += 1;
                return None;
            }
            stats.points_swept += cost;
            stats.sun_built += 1;
            return Some(Job {
                remarch: true,
                ..Job::new(key)
            });
        }
        let (cost, job) = if self.sun_with_sky().is_some() {
            // Its sky sweep took another sun: the node is swept again (sky and sun in
            // one sweep), its march with it.
            let desc = *self.nodes[&key].light.desc();
            let job = Job {
                sky: true,
                march: true,
                ..Job::new(key)
            };
            (crate::apron::sky_points(&desc, self.params.apron), job)
        } else {
            // Where the finest depth reads the coarser grids' scattered sun, the march
            // alone (its scattered sun read once they are current).
            let read = self.reads_coarse_scattered_sun(key);
            let job = Job {
                sun: !read,
                march: read,
                ..Job::new(key)
            };
            (points, job)
        };
        // With the sun swept with the sky, once the coarser nodes its boundary reads
        // are built and settled (it reads their bins: else, swept over a coarser grid
        // where a wanted node is still to come, it would not be swept again once that
        // one is built). Not pending work of this frame: a frame builds those first,
        // and `sun_pending` counts the node meanwhile.
        if job.sky && self.reads_unsettled(key, &self.wanted_now) {
            return None;
        }
        // Once the coarser grids its boundary reads are current (coarse first).
        if !self.sun_parent_ready(key) || self.over_budget(stats.points_swept, cost) {
            stats.pending += 1;
            return None;
        }
        stats.points_swept += cost;
        stats.sun_built += 1;
        Some(job)
    }

    /// Adds `sky`, the sky job of a node on grid `desc`, and its sun's to `jobs` where its
    /// sky sweep fits the budget (else it is pending), counted in `stats`.
    pub(crate) fn budgeted_sky_jobs(
        &self,
        sky: Job,
        desc: &lightgrid_core::GridDesc,
        stats: &mut FrameStats,
        jobs: &mut Vec<Job>,
    ) {
        let sky_cost = crate::apron::sky_points(desc, self.params.apron);
        if self.over_budget(stats.points_swept, sky_cost) {
            stats.pending += 1;
            return;
        }
        self.counted_sky_jobs(sky, desc, stats, jobs);
    }

    /// Adds `sky`, the sky job of a node on grid `desc` that the budget allows (a new
    /// one, or one `refresh` rebuilds), and its sun's to `jobs`, its sky sweep's points
    /// counted in `stats`.
    pub(crate) fn counted_sky_jobs(
        &self,
        sky: Job,
        desc: &lightgrid_core::GridDesc,
        stats: &mut FrameStats,
        jobs: &mut Vec<Job>,
    ) {
        stats.points_swept += crate::apron::sky_points(desc, self.params.apron);
        stats.built += 1;
        let sun_cost = crate::apron::sky_points(desc, self.params.sun_apron_cells());
        self.sky_jobs(sky, sun_cost, stats, jobs);
    }

    /// Adds `sky`, a node's sky job (built new, or rebuilt by `refresh`; its points
    /// counted), to `jobs`, and its sun responses (`cost` points) as a second job where
    /// they fit the budget, counted in `stats`.
    fn sky_jobs(&self, sky: Job, cost: u64, stats: &mut FrameStats, jobs: &mut Vec<Job>) {
        let key = sky.key;
        let mut sun = false;
        if self.sun.is_some() && !self.reads_coarse_scattered_sun(key) {
            if !self.sun_parent_ready(key) || self.over_budget(stats.points_swept, cost) {
                stats.pending += 1;
            } else {
                stats.points_swept += cost;
                stats.sun_built += 1;
                sun = true;
            }
        }
        // The sky sweep and the sun responses as two jobs: they read only coarser grids
        // and the material, so they run side by side (a depth of three nodes keeps two
        // threads busy). The sky's job comes first: the results are stored in this
        // order, the node before its sun. A sun response left for a later frame: the
        // transmittance is marched with the sky's job meanwhile (the direct sun exact).
        let material = sky.material;
        jobs.push(Job {
            march: self.sun.is_some() && !sun,
            ..sky
        });
        if sun {
            jobs.push(Job {
                material,
                sun: true,
                ..Job::new(key)
            });
        }
    }

    /// Runs `jobs` (side by side on forks where the sweeper forks) and stores what they
    /// made. `new` are the depth's new nodes and `materials` theirs (composed, in that
    /// order): every job's sun march reads all of them. The first error is returned
    /// after every job has finished.
    pub(crate) fn run_jobs(
        &mut self,
        jobs: Vec<Job>,
        new: &[NodeKey],
        materials: &[NodeMaterial],
        times: &mut StageTimes,
    ) -> Result<(), LodError> {
        self.run_jobs_composing(jobs, new, materials, times, &[]).0
    }

    /// The nodes of `next` (the frame's next depth to build) whose materials are
    /// composed beside this depth's sweeps ([`Hierarchy::run_jobs_composing`]): those
    /// not built or composed whose parent is built or among this depth's `new` ones
    /// (`materials`), and holds objects where bare ground's children are skipped; at
    /// most [`HierarchyParams::compose_ahead`](crate::HierarchyParams::compose_ahead).
    /// None under a time budget, whose frames compose a batch at a time
    /// ([`Hierarchy::composition_waits`]).
    fn ahead_of(
        &self,
        next: &[NodeKey],
        new: &[NodeKey],
        materials: &[NodeMaterial],
    ) -> Vec<NodeKey> {
        if self.params.budget_ms.is_some() {
            return Vec::new();
        }
        let skip_bare = self.params.skip.bare_children;
        next.iter()
            .copied()
            .filter(|k| !self.nodes.contains_key(k) && !self.composed.contains_key(k))
            .filter(|&k| match Self::parent(k) {
                None => true,
                Some(p) => match (self.nodes.get(&p), new.iter().position(|n| *n == p)) {
                    (Some(n), _) => n.material.has_objects || !skip_bare,
                    (None, Some(i)) => materials[i].has_objects || !skip_bare,
                    (None, None) => false,
                },
            })
            .take(self.params.compose_ahead as usize)
            .collect()
    }

    /// [`Hierarchy::run_jobs`], composing the materials of `ahead` beside the jobs
    /// (rayon: a thread between jobs, or waiting on a lone job's last level, composes);
    /// the materials are returned with their times, in `ahead`'s order.
    pub(crate) fn run_jobs_composing(
        &mut self,
        jobs: Vec<Job>,
        new: &[NodeKey],
        materials: &[NodeMaterial],
        times: &mut StageTimes,
        ahead: &[NodeKey],
    ) -> (Result<(), LodError>, Vec<(Composed, Duration)>) {
        if jobs.is_empty() {
            return (Ok(()), self.compose_nodes(ahead));
        }
        let mut main = {
            let lent = crate::Lent(self.sweeper.carries_halo_paths());
            std::mem::replace(&mut self.sweeper, Box::new(lent))
        };
        let pool = Mutex::new(std::mem::take(&mut self.forks));
        let fresh: Fresh<'_> = new.iter().copied().zip(materials).collect();
        let (results, composed) = {
            let this = &*self;
            rayon::join(
                || this.sweep_jobs(jobs, &mut main, &pool, materials, &fresh),
                || this.compose_nodes(ahead),
            )
        };
        self.sweeper = main;
        self.forks = pool.into_inner().unwrap_or_else(|e| e.into_inner());
        let mut first_error = None;
        // Nodes whose scattered sun this batch swept anew (or made first): with the
        // sun swept with the sky, whose bins it swept again differently.
        let mut scattered = Vec::new();
        let with_sky = self.sun_with_sky().is_some();
        for r in results {
            match r {
                Ok(done) => {
                    add_times(times, &done.times);
                    if let Some(mut node) = done.node {
                        if done.sun.is_none() {
                            node.sun = self.kept_sun(done.key, &node);
                        }
                        let old = self.nodes.insert(done.key, node);
                        if with_sky
                            && old.is_some_and(|o| {
                                let n = &self.nodes[&done.key];
                                o.light != n.light || o.horizon != n.horizon
                            })
                        {
                            scattered.push(done.key);
                        }
                    }
                    if let (Some(sun), Some(n)) = (done.sun, self.nodes.get_mut(&done.key)) {
                        let same = n.sun.as_ref().is_some_and(|old| {
                            (old.scattered == sun.scattered && old.horizon == sun.horizon)
                                && old.to_sun == sun.to_sun
                        });
                        if !same && sun.with_sky.is_none() {
                            scattered.push(done.key);
                        }
                        n.sun = Some(sun);
                    }
                    let to_sun = self.sun.map(|s| s.to_sun);
                    if let (Some(t), Some(to_sun), Some(g)) = (
                        done.marched,
                        to_sun,
                        self.nodes.get_mut(&done.key).and_then(|n| n.sun.as_mut()),
                    ) {
                        g.transmittance = t;
                        g.marched_to = to_sun;
                        g.march_stale = false;
                    }
                    if let (Some(r), Some(g)) = (
                        done.ring,
                        self.nodes.get_mut(&done.key).and_then(|n| n.sun.as_mut()),
                    ) {
                        g.ring = (r.to_sun == g.marched_to).then_some(r);
                    }
                }
                Err(e) => {
                    first_error.get_or_insert(e);
                }
            }
        }
        self.mark_scattered_readers(&scattered);
        (first_error.map_or(Ok(()), Err), composed)
    }

    /// Marks the scattered sun of the nodes whose sun boundary reads one of `keys`'
    /// (finer nodes whose boundary's coarser grids include one of them,
    /// [`Hierarchy::halo_nodes`], and with [`crate::HierarchyParams::neighbour_halo`]
    /// the nodes of a key's depth after it) to be swept again, shown meanwhile: they
    /// were swept from its earlier scattered sun, or from a coarser grid's where it had
    /// none. With the sun swept with the sky, the scattered sun is in the bins: those
    /// nodes are swept again. (Else a refresh round or a provisional node's second
    /// sweep left them on it, and settled, a hierarchy was not the one a build in
    /// another order gives.)
    fn mark_scattered_readers(&mut self, keys: &[NodeKey]) {
        let Some(least) = keys.iter().map(|k| k.depth).min() else {
            return;
        };
        let neighbours = self.params.neighbour_halo;
        let readers: Vec<NodeKey> = (self.nodes.iter())
            .filter(|(k, n)| {
                k.depth >= least && n.sun.as_ref().is_some_and(|g| g.to_sun != Vec3::ZERO)
            })
            .map(|(k, _)| *k)
            .filter(|k| {
                self.halo_nodes(*k).any(|c| keys.contains(&c))
                    || (neighbours && keys.iter().any(|c| crate::neighbours::before(*c, *k)))
            })
            .collect();
        for k in readers {
            if let Some(g) = self.nodes.get_mut(&k).and_then(|n| n.sun.as_mut()) {
                g.mark_scattered_stale();
            }
        }
    }

    /// The sun node `key` shows, for `new` (its sky swept again over the same
    /// material: a provisional node's second sweep, a refresh) to show until its own
    /// comes. A sky job's march or its sun job may wait for a later frame (the sun's
    /// casters not composed in the frame's time, or the budget spent): the node then
    /// dropped the sun it showed, and its points read the coarser grids' (their 2–8 m
    /// shadows) until then. Kept where the material is the same, so that the
    /// transmittance is (`refresh` drops the sun of a node whose material changed);
    /// the scattered sun, swept from the boundary before, is marked to be swept again
    /// (the sky's, with the sun swept with the sky, is in `new`).
    fn kept_sun(&mut self, key: NodeKey, new: &Node) -> Option<GridSun> {
        let sun = self.sun?;
        let old = self.nodes.get_mut(&key).filter(|n| n.sun.is_some())?;
        // (The apron's cells too: the march runs over the widened grid.)
        if old.material.grid != new.material.grid || old.material.widened != new.material.widened {
            return None;
        }
        let g = old.sun.take()?;
        Some(match g.with_sky {
            Some(_) => GridSun {
                march_stale: g.march_stale,
                ring: g.ring,
                ..GridSun::marched(g.transmittance, self.sky_sun().unwrap_or(sun), g.marched_to)
            },
            None => GridSun {
                to_sun: Vec3::ZERO,
                ..g
            },
        })
    }

    /// Runs `jobs`: side by side on forks of `main` (taken from `pool`, and given back)
    /// where the sweeper forks, else one after the other on `main`.
    fn sweep_jobs(
        &self,
        jobs: Vec<Job>,
        main: &mut Box<dyn Sweeper + Send + Sync>,
        pool: &Mutex<Vec<Box<dyn Sweeper + Send + Sync>>>,
        materials: &[NodeMaterial],
        fresh: &Fresh<'_>,
    ) -> Vec<Result<Done, LodError>> {
        let side_by_side =
            jobs.len() > 1 && rayon::current_num_threads() > 1 && main.fork().is_some();
        if !side_by_side {
            return jobs
                .into_iter()
                .map(|job| self.run_job(job, materials, fresh, main.as_mut()))
                .collect();
        }
        let main = &*main;
        jobs.into_par_iter()
            .map(|job| {
                let taken = pool.lock().unwrap_or_else(|e| e.into_inner()).pop();
                let Some(mut s) = taken.or_else(|| main.fork()) else {
                    return Err(
                        GridError::invalid("sweeper", main.name(), "stopped giving forks").into(),
                    );
                };
                let r = self.run_job(job, materials, fresh, s.as_mut());
                pool.lock().unwrap_or_else(|e| e.into_inner()).push(s);
                r
            })
            .collect()
    }

    /// One node's sky sweep and sun responses, on `sweeper`.
    fn run_job(
        &self,
        job: Job,
        materials: &[NodeMaterial],
        fresh: &Fresh<'_>,
        sweeper: &mut dyn Sweeper,
    ) -> Result<Done, LodError> {
        let _node = tracing::trace_span!("node", key = ?job.key).entered();
        let mut times = StageTimes::default();
        let material = match job.material {
            Some(i) => &materials[i],
            None => &self.nodes[&job.key].material,
        };
        let node = if job.sky {
            Some(self.sky_node(
                job.key,
                material,
                job.inputs,
                (&mut *sweeper, fresh),
                &mut times,
            )?)
        } else {
            None
        };
        let sun = if job.sun {
            self.node_sun(job.key, material, sweeper, fresh, &mut times)?
        } else if job.march {
            let mut sun = self.interim_sun(job.key, material, sweeper, fresh, &mut times)?;
            if let Some(g) = sun.as_mut() {
                g.march_stale |= job.casters_missing;
            }
            sun
        } else {
            None
        };
        let marched = match (job.remarch, self.sun) {
            (true, Some(s)) => Some(timed(&mut times.sun_sweep, || {
                self.march_node(sweeper, job.key, material, s.to_sun, fresh)
            })?),
            _ => None,
        };
        // The transmittance beyond the node's points, for the direction it will show
        // (its sky's ring, read beside it, may still be to come: a new node's sun job
        // runs beside its sky's).
        let shown = match (&marched, self.sun) {
            (Some(_), Some(s)) => Some(s.to_sun),
            _ => sun.as_ref().map(|g| g.marched_to),
        };
        let ring = match shown {
            Some(to_sun) => timed(&mut times.sun_sweep, || {
                self.march_ring(sweeper, (job.key, fresh), material, to_sun)
            })?,
            None => None,
        };
        Ok(Done {
            key: job.key,
            node,
            sun,
            marched,
            ring,
            times,
        })
    }

    /// Whether node `key` sweeps no scattered sun of its own: its sky sweep holds it
    /// ([`crate::HierarchyParams::sun_with_sky`]), or it is the coarser grids' read at
    /// its points ([`crate::LodSkips::finest_scattered_sun`]: the finest depth's, when
    /// asked for). Either way its sun job is the march alone.
    pub(crate) fn reads_coarse_scattered_sun(&self, key: NodeKey) -> bool {
        self.params.sun_with_sky
            || (self.params.skip.finest_scattered_sun && key.depth == self.params.depths())
    }

    /// A new node's sun responses until its own are swept: the transmittance marched
    /// for the sun shown (exact, as the full responses' is), the scattered sun the
    /// coarser grids' at its points (what its points read without it). Marked not
    /// swept (`to_sun` zero), so the node's responses are computed in a later frame;
    /// meanwhile its direct sun is its own. On the 16-point flythrough at 30° the 6 %
    /// of the finest nodes' reads whose node's responses were still to come read a
    /// coarser grid's sun, 22 % RMSE off the 1 m sweep against 0.9 % for the others.
    ///
    /// Where the node's scattered sun is the coarser grids' for good
    /// ([`Hierarchy::reads_coarse_scattered_sun`]) and they are current
    /// ([`Hierarchy::sun_parent_ready`]), these are its responses: read from the current
    /// coarser grids and marked swept for the direction theirs are.
    pub(crate) fn interim_sun(
        &self,
        key: NodeKey,
        material: &NodeMaterial,
        sweeper: &mut dyn Sweeper,
        fresh: &Fresh<'_>,
        times: &mut StageTimes,
    ) -> Result<Option<GridSun>, LodError> {
        let _span = tracing::trace_span!("interim sun", ?key).entered();
        let Some(sun) = self.sun else {
            return Ok(None);
        };
        if self.params.sun_with_sky {
            // The scattered sun is in the node's sky bins: its responses for good. A
            // node swept again for a moved sun over its own material keeps the
            // transmittance `set_sun` marched for it (the same material, the same
            // grids beyond it: marched again, it is the same bit for bit), unless the
            // scene changed since (`refresh`).
            let kept = self
                .nodes
                .get(&key)
                .filter(|n| std::ptr::eq(&n.material, material));
            let kept = kept
                .and_then(|n| n.sun.as_ref())
                .filter(|g| g.marched_to == sun.to_sun && !g.march_stale)
                .map(|g| g.transmittance.clone());
            let transmittance = match kept {
                Some(t) => t,
                None => timed(&mut times.sun_sweep, || {
                    self.march_node(sweeper, key, material, sun.to_sun, fresh)
                })?,
            };
            let sky = self.sky_sun().unwrap_or(sun);
            return Ok(Some(GridSun::marched(transmittance, sky, sun.to_sun)));
        }
        let transmittance = timed(&mut times.sun_sweep, || {
            self.march_node(sweeper, key, material, sun.to_sun, fresh)
        })?;
        let for_good = self.reads_coarse_scattered_sun(key) && self.sun_parent_ready(key);
        let desc = *material.grid.desc();
        // The coarser grids' scattered sun at the node's points, and the downward
        // halves of its horizontal bins where the grids keep them (even where one
        // does not).
        let halves = self.params.sweep.outputs.horizon;
        let read: Vec<(BinLight, Option<lightgrid_core::HorizonLight>)> =
            timed(&mut times.sun_boundary, || {
                (0..desc.point_count())
                    .map(|i| {
                        let p = desc.position(desc.coords(i).expect("in range"));
                        let Some(g) = self.coarse_sun(p, key.depth, !for_good) else {
                            return Ok((BinLight::ZERO, halves.then(Default::default)));
                        };
                        let bins = match &g.scattered {
                            Some(sc) => sc.light(p, None)?,
                            None => BinLight::ZERO,
                        };
                        let down = match (&g.horizon, halves) {
                            (_, false) => None,
                            (Some(h), true) => Some(h.sample(p)?),
                            (None, true) => Some(lightgrid_core::HorizonLight::even(&bins)),
                        };
                        Ok((bins, down))
                    })
                    .collect::<Result<Vec<_>, GridError>>()
            })?;
        let horizon = halves.then(|| {
            lightgrid_core::Grid::from_trusted(
                desc,
                read.iter().map(|(_, d)| d.unwrap_or_default()).collect(),
            )
        });
        let scattered = read.into_iter().map(|(b, _)| b).collect();
        Ok(Some(GridSun {
            scattered: Some(lightgrid_core::Grid::from_trusted(desc, scattered)),
            horizon,
            resident: None,
            transmittance,
            to_sun: match self.scattered_to() {
                Some(to) if for_good => to,
                _ => Vec3::ZERO,
            },
            marched_to: sun.to_sun,
            with_sky: None,
            march_stale: false,
            ring: None,
        }))
    }

    /// A new node's grid: its boundary from the coarser grids (`prepared`: made already
    /// for `composed`), swept.
    pub(crate) fn sky_node(
        &self,
        key: NodeKey,
        composed: &NodeMaterial,
        prepared: Option<crate::apron::SkyInputs>,
        (sweeper, fresh): (&mut dyn Sweeper, &Fresh<'_>),
        times: &mut StageTimes,
    ) -> Result<Node, LodError> {
        let o = self.node_options(composed.has_objects);
        let material = (&composed.grid, composed.widened.as_ref());
        let ((out, ring, band), input_hash) = match prepared {
            Some(inputs) => (
                self.sweep_sky(&inputs, composed, &o, (&mut *sweeper, fresh), times)?,
                inputs.hash,
            ),
            None => {
                // The inputs' hash (a pass over the material and the boundary: some
                // 600 kB a 16-point node) taken on a worker the sweep leaves idle (a
                // lone node's levels keep the second thread only half busy), else
                // after it on this thread.
                let inputs = self.sky_boundary(key, composed, times);
                let mut hash = 0;
                let mut hash_time = Duration::ZERO;
                let out = rayon::in_place_scope(|s| {
                    s.spawn(|_| {
                        timed(&mut hash_time, || {
                            hash = self.sky_hash(material, &inputs.boundary, &o);
                        })
                    });
                    self.sweep_sky(&inputs, composed, &o, (&mut *sweeper, fresh), times)
                })?;
                times.boundary += hash_time;
                (out, hash)
            }
        };
        let light = out.bins.ok_or_else(|| {
            GridError::invalid("sweeper", sweeper.name(), "returned no bins, asked for")
        })?;
        Ok(Node {
            light,
            horizon: out.horizon,
            material: composed.clone(),
            sun: None,
            resident: out.resident,
            ring,
            band,
            input_hash,
            provisional: false,
        })
    }
}

/// `into += t`, stage by stage.
fn add_times(into: &mut StageTimes, t: &StageTimes) {
    into.material += t.material;
    into.boundary += t.boundary;
    into.sky_sweep += t.sky_sweep;
    into.sun_boundary += t.sun_boundary;
    into.sun_sweep += t.sun_sweep;
}
