//! The side halo from the same depth's nodes ([`HierarchyParams::neighbour_halo`]).
//!
//! A node's side halo takes the coarser grid's light by default: the light entering
//! its sides has crossed coarser material, and carries that grid's error inward (the
//! horizontal bins most: a bin's path climbs one level in four cells). With the option
//! on, halo points that lie among the points of a built node of the same depth *before*
//! it, and that the camera wants, read that node's light, sky and scattered sun. "Before" is a fixed order, the
//! sum of a node's indices `x + z` (its rank): a node reads its neighbours at
//! `(x − 1, z)`, `(x, z − 1)` and `(x − 1, z − 1)`, never one of equal or higher rank,
//! so no two nodes read each other and what a node holds does not depend on the order
//! frames built them in:
//!
//! - a node swept while one of its before-neighbours that the camera wants is not
//!   built, or is provisional, is provisional itself (`order.rs`) and swept again, and
//!   so is a built node once a before-neighbour of it is built (the camera came to
//!   want it later);
//! - the camera's surroundings, which a frame builds first, take in the nodes before
//!   them that the camera wants;
//! - a frame builds a depth's nodes in waves of equal rank (none of a wave reads
//!   another), each after the waves before it, and `refresh` and the second sweeps of
//!   provisional nodes go the same way.
//!
//! Settled, the hierarchy is then the one a build without a budget gives, bit for bit
//! (`tests/neighbours.rs`), as with the option off.
//!
//! [`HierarchyParams::neighbour_halo`]: crate::HierarchyParams::neighbour_halo

use lightgrid_core::glam::{IVec2, Vec2, Vec3};
use lightgrid_core::{HorizonGrid, LightGrid};

use crate::{Hierarchy, NodeKey, Response};

/// A node's rank: the order of [`before`] (lower first).
pub(crate) fn rank(key: NodeKey) -> i64 {
    key.index.x as i64 + key.index.y as i64
}

/// Where a node's before-neighbours lie from it: the nodes next to it (edge or corner)
/// of lower rank.
const BEFORE: [IVec2; 3] = [IVec2::new(-1, 0), IVec2::new(0, -1), IVec2::new(-1, -1)];

/// Whether node `a` is one of `b`'s before-neighbours ([`BEFORE`], the same depth).
pub(crate) fn before(a: NodeKey, b: NodeKey) -> bool {
    a.depth == b.depth && BEFORE.contains(&(a.index - b.index))
}

/// `keys` in waves of equal rank, lowest first, each in `keys`' order; with the option
/// off one wave, `keys` as they are.
pub(crate) fn waves(keys: &[NodeKey], on: bool) -> Vec<Vec<NodeKey>> {
    if !on {
        return vec![keys.to_vec()];
    }
    let mut ranks: Vec<i64> = keys.iter().map(|k| rank(*k)).collect();
    ranks.sort_unstable();
    ranks.dedup();
    ranks
        .into_iter()
        .map(|r| keys.iter().copied().filter(|k| rank(*k) == r).collect())
        .collect()
}

impl Hierarchy {
    /// Node `key`'s before-neighbours (built or not); none with the option off.
    pub(crate) fn before_neighbours(&self, key: NodeKey) -> impl Iterator<Item = NodeKey> {
        self.offset_neighbours(key, 1)
    }

    /// The nodes whose before-neighbours include `key` (built or not); none with the
    /// option off.
    pub(crate) fn after_neighbours(&self, key: NodeKey) -> impl Iterator<Item = NodeKey> {
        self.offset_neighbours(key, -1)
    }

    /// The nodes at `key` plus `sign` times each of [`BEFORE`]'s offsets, with the
    /// option on.
    fn offset_neighbours(&self, key: NodeKey, sign: i32) -> impl Iterator<Item = NodeKey> {
        let on = self.params.neighbour_halo;
        BEFORE
            .into_iter()
            .filter(move |_| on)
            .map(move |d| NodeKey {
                depth: key.depth,
                index: key.index + d * sign,
            })
    }

    /// The light node `key`'s halo takes at `p` from a built before-neighbour the camera
    /// wants whose points reach `p` (and its horizon halves, if kept): its sky light, or its
    /// scattered sun where that is current. `None`: the coarser grids' light.
    pub(crate) fn neighbour_light(
        &self,
        p: Vec3,
        key: NodeKey,
        which: Response,
    ) -> Option<(&LightGrid, Option<&HorizonGrid>)> {
        if !self.params.neighbour_halo || key.depth == 0 {
            return None;
        }
        let at = self.node_at(key.depth, Vec2::new(p.x, p.z));
        // One the camera wants: a built node it no longer wants is not read (a build
        // without a budget would not hold it).
        if !before(at, key) || !self.wanted_now.contains(&at) {
            return None;
        }
        let n = self.nodes.get(&at)?;
        let d = n.light.desc();
        let g = d.to_grid(p);
        let top = (d.dims() - 1).as_vec3();
        // On its points, not past them (the strip beyond a node's last points is the
        // coarser grid's, as it is to a reader).
        if !(g.cmpge(Vec3::ZERO).all() && g.cmple(top).all()) {
            return None;
        }
        match which {
            Response::Sky => Some((&n.light, n.horizon.as_ref())),
            Response::Sun => self
                .sun_current(at)
                .then(|| {
                    let s = n.sun.as_ref()?;
                    Some((s.scattered.as_ref()?, s.horizon.as_ref()))
                })
                .flatten(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(x: i32, z: i32) -> NodeKey {
        NodeKey {
            depth: 3,
            index: IVec2::new(x, z),
        }
    }

    /// The three neighbours of lower `x + z` beside a node and no other node.
    #[test]
    fn before_is_the_three_lower_neighbours() {
        let b = key(5, 7);
        let mut found = Vec::new();
        for x in 2..9 {
            for z in 4..11 {
                if before(key(x, z), b) {
                    found.push((x, z));
                }
            }
        }
        assert_eq!(found, vec![(4, 6), (4, 7), (5, 6)]);
        let other_depth = NodeKey {
            depth: 2,
            index: IVec2::new(4, 7),
        };
        assert!(!before(other_depth, b));
        // Never both ways.
        for x in 2..9 {
            for z in 4..11 {
                assert!(!(before(key(x, z), b) && before(b, key(x, z))));
            }
        }
    }

    /// Waves hold the keys of one rank each, lowest first, in the keys' order; off,
    /// one wave.
    #[test]
    fn waves_group_by_rank() {
        let keys = [key(1, 1), key(0, 0), key(2, 0), key(0, 1), key(1, 0)];
        let w = waves(&keys, true);
        assert_eq!(
            w,
            vec![
                vec![key(0, 0)],
                vec![key(0, 1), key(1, 0)],
                vec![key(1, 1), key(2, 0)],
            ]
        );
        assert_eq!(waves(&keys, false), vec![keys.to_vec()]);
        assert!(waves(&[], true).is_empty());
    }
}
