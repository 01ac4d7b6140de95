//! The order a frame builds the wanted nodes in ([`Hierarchy::update`]), each part a
//! depth at a time, coarse to fine, nearest first within a depth:
//!
//! 1. the nodes within the finest depth's reach of the camera (`lod_factor` times a
//!    finest node's size), at every depth: the camera's surroundings, down to the
//!    finest; and, for their new nodes, the coarser nodes not built yet that those
//!    read, where that spares a second sweep ([`Hierarchy::pull_reads`], below);
//! 2. the coarser nodes the boundaries of those read ([`Hierarchy::halo_rect`]), and
//!    of those, and so on; then the nodes of part 1 swept before one of these was built
//!    are swept again ([`Hierarchy::rebuild_provisional`]);
//! 3. the rest (the coarse depths' far nodes).
//!
//! Where every wanted node not built yet fits the frame's budget, and in
//! [`Hierarchy::settle`]'s frames, the frame builds them all coarse to fine instead:
//! none is swept twice.
//!
//! Coarse to fine over all wanted nodes spent a cold start's point budget on the coarse
//! depths' far nodes (a depth-1 node is 256 m across at the defaults) while the camera's
//! surroundings waited frames for their finest nodes. On the frame bench's path
//! (`cargo xtask frame --node-points 32 --mc-probes 0`, 24 frames from a cold start)
//! the finest depth now serves 333,594 of the probes around the camera instead of
//! 246,452, and the path's sky and sun together are 5.9 % RMSE against one 1 m sweep
//! instead of 10.6 % at 15° (5.1 against 9.5 % at 40°).
//!
//! The price: a node of part 1 may be swept before a coarser neighbour its boundary
//! reads (its halo reads a coarser grid there): it is marked provisional, and so is
//! every node swept over a provisional one, until the frame that sweeps it again once
//! those are all built and final. Under the budget that frame may come late: along the
//! bench's path the nesting alone (each depth against one sweep at its own cell) is
//! 1.3 / 1.7 / 2.3 / 2.6 % RMSE for the sky at depths 1–4 at 15° where it was 1.0 /
//! 1.0 / 1.8 / 1.9. Settled, the hierarchy is the one a build without a budget gives,
//! bit for bit (`tests/order.rs`). A node's sun waits for every coarser node its
//! boundary reads to have a current sun ([`Hierarchy::sun_parent_ready`]).
//!
//! Once the camera has its surroundings (half of part 1's points built), what is new
//! in them each frame is an edge, and the coarser nodes its boundaries read are few:
//! part 1 then takes them in ([`Hierarchy::pull_reads`]) and builds them first in its
//! depth order, so a new node is swept once. In a cold start or after a jump part 1
//! takes in only those that cost no more than the node they spare a second sweep;
//! the rest is as above. Along the fly-through (16-point nodes, a frame budget it
//! meets about every frame) the points swept fell from 663,552 to 558,848 and a
//! frame from 33–36 to 29–30 ms; on the frame bench the path's error is unchanged
//! with 16-point nodes (sky and sun 7.7 / 6.2 / 5.4 % RMSE at 10° / 30° / 60°
//! against 7.6 / 6.1 / 5.4), 6.7 / 5.6 % against 6.0 / 5.2 at 15° / 40° with 32-point
//! nodes, whose finest depth's sky nests closer (2.3 / 2.1 % RMSE against 2.6 /
//! 2.3; `docs/measurements.md`, "New nodes after what they read").

use std::collections::HashSet;
use std::hash::BuildHasherDefault;

use lightgrid_core::glam::{IVec2, Vec2, Vec3};

use crate::build::Job;
use crate::{FrameStats, Hierarchy, KeyHasher, LodError, NodeKey};

/// The wanted nodes of a frame.
pub(crate) type Wanted = HashSet<NodeKey, BuildHasherDefault<KeyHasher>>;

impl Hierarchy {
    /// The rectangle over which node `key`'s boundaries read the coarser grids: its
    /// own, widened by its apron, the halo's points a cell beyond, and the coarser
    /// grid's lookup around them (half a coarser cell, and the seam a read may cross).
    pub(crate) fn halo_rect(&self, key: NodeKey) -> (Vec2, Vec2) {
        let (lo, hi) = self.node_rect(key);
        let p = &self.params;
        let w = (p.apron + 2) as f32 * p.cell(key.depth) + p.cell(key.depth.saturating_sub(1));
        (lo - Vec2::splat(w), hi + Vec2::splat(w))
    }

    /// `wanted` (coarse first, nearest first within a depth) split in the order a frame
    /// builds them: those within the finest depth's reach of `camera` (the finest
    /// depth's nodes there and the coarser ones under them); the coarser nodes the
    /// boundaries of those read, and of those, and so on; then the rest. Each keeps
    /// `wanted`'s order.
    pub(crate) fn build_order(&self, wanted: &[NodeKey], camera: Vec3) -> [Vec<NodeKey>; 3] {
        let r = self.params.lod_factor * self.params.node_size(self.params.depths());
        let mut near: Wanted = wanted
            .iter()
            .filter(|k| self.distance(**k, camera) <= r)
            .copied()
            .collect();
        // With the same depth's nodes read in halos (`neighbours.rs`), the wanted nodes
        // before those, and before them: else a node near the camera would be swept
        // before one it reads, and again after it.
        if self.params.neighbour_halo {
            let all: Wanted = wanted.iter().copied().collect();
            let mut todo: Vec<NodeKey> = near.iter().copied().collect();
            while let Some(k) = todo.pop() {
                for b in self.before_neighbours(k) {
                    if all.contains(&b) && near.insert(b) {
                        todo.push(b);
                    }
                }
            }
        }
        self.pull_reads(wanted, &mut near);
        let mut read = near.clone();
        for d in (1..self.params.depths()).rev() {
            let halos: Vec<(Vec2, Vec2)> = read
                .iter()
                .filter(|k| k.depth > d)
                .map(|k| self.halo_rect(*k))
                .collect();
            for k in wanted.iter().filter(|k| k.depth == d) {
                let (lo, hi) = self.node_rect(*k);
                if halos
                    .iter()
                    .any(|(a, b)| lo.cmplt(*b).all() && hi.cmpgt(*a).all())
                {
                    read.insert(*k);
                }
            }
        }
        let mut out = [Vec::new(), Vec::new(), Vec::new()];
        for k in wanted {
            let part = if near.contains(k) {
                0
            } else if read.contains(k) {
                1
            } else {
                2
            };
            out[part].push(*k);
        }
        out
    }

    /// Adds to `near` (the camera's surroundings, which a frame builds first) the
    /// coarser nodes not built yet that the boundaries of its new nodes read, and the
    /// ones those read ([`Hierarchy::missing_reads`]), where that spares a second sweep
    /// of the node for no more than it costs: once half of `near`'s points (by cost)
    /// are built, for every new node (the camera has its surroundings, and what is new
    /// about them is an edge, whose coarser nodes then come first in the frame's depth
    /// order); before that (a cold start, a jump) only where they cost no more than the
    /// node, else the node is swept at once, provisional (the module docs).
    fn pull_reads(&self, wanted: &[NodeKey], near: &mut Wanted) {
        let near_keys: Vec<NodeKey> = wanted
            .iter()
            .filter(|k| near.contains(k))
            .copied()
            .collect();
        // (A near node that cannot be laid out counts as nothing; missing reads that
        // cannot are never pulled in.)
        let costs: Vec<u64> = near_keys
            .iter()
            .map(|k| self.sweep_cost(*k).unwrap_or(0))
            .collect();
        let (built, total) = near_keys
            .iter()
            .zip(&costs)
            .fold((0, 0), |(b, t), (k, &c)| {
                (b + if self.nodes.contains_key(k) { c } else { 0 }, t + c)
            });
        let caught_up = 2 * built >= total;
        let all: Wanted = wanted.iter().copied().collect();
        for (k, cost) in near_keys.into_iter().zip(costs) {
            if self.nodes.contains_key(&k) {
                continue;
            }
            let missing = self.missing_reads(k, &all, near);
            let extra: Option<u64> = missing.iter().map(|m| self.sweep_cost(*m)).sum();
            match extra {
                Some(extra) if !missing.is_empty() && (caught_up || extra <= cost) => {
                    near.extend(missing);
                }
                _ => {}
            }
        }
    }

    /// The wanted coarser nodes, not built and not in `near`, that node `key`'s
    /// boundary reads ([`Hierarchy::halo_nodes`]), and that theirs read, and so on
    /// (none under bare ground with the bare-ground skip on: they are never built).
    fn missing_reads(&self, key: NodeKey, wanted: &Wanted, near: &Wanted) -> Wanted {
        let never = |c: NodeKey| self.params.skip.bare_children && self.bare_ancestor(c);
        let mut missing = Wanted::default();
        let mut todo = vec![key];
        while let Some(n) = todo.pop() {
            for c in self.halo_nodes(n) {
                let to_come = wanted.contains(&c) && !self.nodes.contains_key(&c) && !never(c);
                if to_come && !near.contains(&c) && missing.insert(c) {
                    todo.push(c);
                }
            }
        }
        missing
    }

    /// Points a build of node `key` sweeps: its sky sweep, and its sun response where
    /// the sun is kept apart, at their aprons (`None`: the node cannot be laid out).
    fn sweep_cost(&self, key: NodeKey) -> Option<u64> {
        let desc = self.node_desc(key).ok()?;
        let mut cost = crate::apron::sky_points(&desc, self.params.apron);
        if self.sun.is_some() {
            cost += crate::apron::sky_points(&desc, self.params.sun_apron_cells());
        }
        Some(cost)
    }

    /// Whether every wanted node not built yet fits this frame's point budget (sky and
    /// sun sweeps at their node's size), with no time budget: then building them coarse
    /// to fine sweeps each once, where the camera's surroundings first would sweep some
    /// twice within the frame for the same grids.
    pub(crate) fn all_fit(&self, wanted: &[NodeKey]) -> bool {
        if self.params.budget_ms.is_some() {
            return false;
        }
        let mut cost = 0u64;
        for k in wanted.iter().filter(|k| !self.nodes.contains_key(k)) {
            let Some(c) = self.sweep_cost(*k) else {
                return false;
            };
            cost += c;
            if cost > self.frame_budget {
                return false;
            }
        }
        true
    }

    /// Whether node `key`, swept now, would be provisional: a coarser node its boundary
    /// reads, or a node of its depth before it whose light it reads
    /// (`neighbours.rs`), is still to come ([`Hierarchy::halo_waits`]) or provisional
    /// itself.
    pub(crate) fn reads_unsettled(&self, key: NodeKey, wanted: &Wanted) -> bool {
        self.halo_waits(key, wanted) || self.halo_provisional(key)
    }

    /// Marks the ready nodes among `keys` provisional.
    pub(crate) fn mark_provisional(&mut self, keys: impl IntoIterator<Item = NodeKey>) {
        for key in keys {
            if let Some(n) = self.nodes.get_mut(&key) {
                n.provisional = true;
            }
        }
    }

    /// Whether a built node that node `key`'s boundary reads (coarser, or of its depth
    /// before it and wanted) is provisional.
    pub(crate) fn halo_provisional(&self, key: NodeKey) -> bool {
        let provisional = |k: &NodeKey| self.nodes.get(k).is_some_and(|n| n.provisional);
        self.halo_nodes(key).any(|k| provisional(&k))
            || self
                .before_neighbours(key)
                .any(|k| self.wanted_now.contains(&k) && provisional(&k))
    }

    /// The coarser nodes (built or not) whose rectangles meet node `key`'s
    /// [`Hierarchy::halo_rect`].
    pub(crate) fn halo_nodes(&self, key: NodeKey) -> impl Iterator<Item = NodeKey> + '_ {
        let (lo, hi) = self.halo_rect(key);
        (1..key.depth).flat_map(move |d| {
            let a = self.node_at(d, lo).index;
            let b = self.node_at(d, hi - Vec2::splat(1e-3)).index;
            (a.y..=b.y).flat_map(move |iz| {
                (a.x..=b.x).map(move |ix| NodeKey {
                    depth: d,
                    index: IVec2::new(ix, iz),
                })
            })
        })
    }

    /// Whether node `key` waits for a wanted coarser node its boundary reads
    /// ([`Hierarchy::halo_rect`]) that is not built yet (and will be: not under bare
    /// ground with the bare-ground skip on).
    pub(crate) fn halo_waits(&self, key: NodeKey, wanted: &Wanted) -> bool {
        let skip_bare = self.params.skip.bare_children;
        self.halo_nodes(key)
            .chain(self.before_neighbours(key))
            .any(|k| {
                wanted.contains(&k)
                    && !self.nodes.contains_key(&k)
                    && !(skip_bare && self.bare_ancestor(k))
            })
    }

    /// Sweeps again, within the budget and coarse to fine, the provisional nodes still
    /// wanted whose boundaries' coarser nodes are now all built and final (their
    /// materials kept: sky and sun, as new nodes are built); those still waiting count
    /// as pending.
    pub(crate) fn rebuild_provisional(
        &mut self,
        camera: Vec3,
        wanted: &Wanted,
        stats: &mut FrameStats,
    ) -> Result<(), LodError> {
        for d in 1..=self.params.depths() {
            let mut keys: Vec<NodeKey> = self
                .nodes
                .iter()
                .filter(|(k, n)| k.depth == d && n.provisional && wanted.contains(k))
                .map(|(k, _)| *k)
                .collect();
            if keys.is_empty() {
                continue;
            }
            keys.sort_by(|a, b| {
                self.distance(*a, camera)
                    .total_cmp(&self.distance(*b, camera))
                    .then(a.cmp(b))
            });
            // In waves (`neighbours.rs`): a node after those of its depth it reads.
            for wave in crate::neighbours::waves(&keys, self.params.neighbour_halo) {
                let mut jobs = Vec::new();
                for key in wave {
                    if self.reads_unsettled(key, wanted) {
                        stats.pending += 1;
                        continue;
                    }
                    let desc = *self.nodes[&key].light.desc();
                    let sky = Job {
                        sky: true,
                        ..Job::new(key)
                    };
                    self.budgeted_sky_jobs(sky, &desc, stats, &mut jobs);
                }
                let jobs = self.compose_jobs_casters(jobs, &[], &[], stats)?;
                self.run_jobs(jobs, &[], &[], &mut stats.times)?;
            }
        }
        Ok(())
    }
}
