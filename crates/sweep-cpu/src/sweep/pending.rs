//! Light waiting in the media for the next pass (`Pending`), per level.

use super::*;

/// Scattered light a cell holds for emission: total flux `s` (RGB) and its first moment
/// `m[axis]` (RGB) over the incoming directions.
///
/// Under [`MediumEmission::Profile`] a medium cell holds instead the source still to be
/// emitted through the segments of this direction's passes, as Legendre coefficients in
/// height ([`crate::profile`]): `J_0` in `s`, `J_1` and `J_2` in `m[0]` and `m[1]`
/// ([`Pending::coeffs`]), so that the pending light keeps its size under every rule.
#[derive(Clone, Copy, Default, bytemuck::Zeroable)]
pub(crate) struct Pending {
    pub(crate) s: Vec3,
    pub(crate) m: [Vec3; 3],
}

impl Pending {
    pub(crate) fn add(&self, o: &Pending) -> Pending {
        Pending {
            s: self.s + o.s,
            m: [self.m[0] + o.m[0], self.m[1] + o.m[1], self.m[2] + o.m[2]],
        }
    }
    pub(crate) fn scaled(&self, a: Vec3) -> Pending {
        Pending {
            s: self.s * a,
            m: crate::isa::array_map(self.m, |v| v * a),
        }
    }
    /// [`MediumEmission::Profile`]: the source coefficients `[J_0, J_1, J_2]` held.
    pub(crate) fn coeffs(&self) -> [Vec3; 3] {
        [self.s, self.m[0], self.m[1]]
    }
    /// [`MediumEmission::Profile`]: pending light holding the coefficients `j`.
    pub(crate) fn of_coeffs(j: [Vec3; 3]) -> Pending {
        Pending {
            s: j[0],
            m: [j[1], j[2], Vec3::ZERO],
        }
    }
}

/// Scattered light waiting in one direction ([`Pending`] per grid point), level by
/// level: a level's records are allocated (zeroed) when one of them is first written,
/// and a level never written holds none and reads as zero. Only levels with material
/// hold scattered light, so a sweep over mostly empty space (the 64³ canopy: ground and
/// leaves in 4 of 64 levels) neither allocates nor clears records for the rest. (One
/// vector of all points cost fresh work at 64³ 25–38 MB, which the allocator, serving
/// freed blocks of that size from its heap, zeroed in full.)
#[derive(Clone, Default)]
pub(crate) struct PendingLevels {
    pub(crate) level_len: usize,
    pub(crate) levels: Vec<Vec<Pending>>,
}

impl PendingLevels {
    pub(crate) const ZERO: Pending = Pending {
        s: Vec3::ZERO,
        m: [Vec3::ZERO; 3],
    };
    pub(crate) fn new(level_len: usize, levels: usize) -> Self {
        Self {
            level_len,
            levels: vec![Vec::new(); levels],
        }
    }
    /// Points in all.
    pub(crate) fn len(&self) -> usize {
        self.level_len * self.levels.len()
    }
    /// Level `j`'s records, allocated if it had none.
    pub(crate) fn level_mut(&mut self, j: usize) -> &mut [Pending] {
        let l = &mut self.levels[j];
        if l.is_empty() {
            *l = vec![Pending::default(); self.level_len];
        }
        l
    }
    /// Level `j`'s records set to zero (kept allocated for the next sweep).
    pub(crate) fn clear_level(&mut self, j: usize) {
        self.levels[j].fill(Pending::default());
    }
}

impl std::ops::Index<usize> for PendingLevels {
    type Output = Pending;
    fn index(&self, i: usize) -> &Pending {
        self.levels[i / self.level_len]
            .get(i % self.level_len)
            .unwrap_or(&Self::ZERO)
    }
}

impl std::ops::IndexMut<usize> for PendingLevels {
    fn index_mut(&mut self, i: usize) -> &mut Pending {
        let len = self.level_len;
        &mut self.level_mut(i / len)[i % len]
    }
}
