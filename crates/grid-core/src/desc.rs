//! Grid descriptor: where a grid sits, how fine it is, and how its points are laid out.

use glam::{UVec3, Vec3};

use crate::GridError;

/// Most points one grid may have (2^32): indices stay in `u32` on the GPU.
pub const MAX_POINTS: u64 = 1 << 32;

/// Smallest and largest cell sizes accepted, in metres. Outside this range positions lose
/// all precision in `f32` at world scales.
pub const CELL_SIZE_RANGE: (f32, f32) = (1e-4, 1e5);

/// Largest distance from the world origin of any grid point, metres. Beyond it `f32`
/// positions are coarser than 64 m and sampling is meaningless.
pub const WORLD_LIMIT: f32 = 1e9;

/// A regular grid: point `(i, j, k)` sits at `origin + h * (i, j, k)`.
///
/// Memory order is x fastest, then z, then y, so one horizontal **level** (fixed `j`) is
/// one contiguous run of `nx * nz` points:
///
/// ```text
/// index(i, j, k) = i + nx * (k + nz * j)
/// ```
///
/// The material cell of a point is the cube of side `h` centred on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridDesc {
    origin: Vec3,
    h: f32,
    dims: UVec3,
}

impl GridDesc {
    /// A validated descriptor.
    ///
    /// Errors name the field: `origin` must be finite, `h` finite and within
    /// [`CELL_SIZE_RANGE`], every entry of `dims` at least 1, the point count at most
    /// [`MAX_POINTS`], and the far corner finite.
    pub fn new(origin: Vec3, h: f32, dims: UVec3) -> Result<Self, GridError> {
        if !origin.is_finite() {
            return Err(GridError::invalid("origin", origin, "must be finite"));
        }
        if !(h.is_finite() && h >= CELL_SIZE_RANGE.0 && h <= CELL_SIZE_RANGE.1) {
            return Err(GridError::invalid(
                "h",
                h,
                "cell size must be finite and within [1e-4, 1e5] metres",
            ));
        }
        for (name, d) in [("dims.x", dims.x), ("dims.y", dims.y), ("dims.z", dims.z)] {
            if d == 0 {
                return Err(GridError::invalid(name, d, "must be at least 1"));
            }
        }
        // Checked: 2^22 points a side is 2^66 points, which wraps a plain u64 product.
        let count = (dims.x as u64)
            .checked_mul(dims.y as u64)
            .and_then(|c| c.checked_mul(dims.z as u64));
        if count.is_none_or(|c| c > MAX_POINTS) {
            return Err(GridError::invalid(
                "dims",
                dims,
                "more than 2^32 points in one grid",
            ));
        }
        if origin.abs().max_element() > WORLD_LIMIT {
            return Err(GridError::invalid(
                "origin",
                origin,
                "must lie within ±1e9 m",
            ));
        }
        let far = origin + h * (dims - UVec3::ONE).as_vec3();
        if far.abs().max_element() > WORLD_LIMIT {
            return Err(GridError::invalid(
                "dims",
                dims,
                "far corner lies beyond ±1e9 m",
            ));
        }
        Ok(Self { origin, h, dims })
    }

    /// World position of point (0, 0, 0).
    pub fn origin(&self) -> Vec3 {
        self.origin
    }
    /// Cell size (distance between neighbouring points), metres.
    pub fn h(&self) -> f32 {
        self.h
    }
    /// Points along x, y and z.
    pub fn dims(&self) -> UVec3 {
        self.dims
    }
    /// Number of points, `nx * ny * nz`.
    pub fn point_count(&self) -> usize {
        self.dims.x as usize * self.dims.y as usize * self.dims.z as usize
    }
    /// Points in one horizontal level, `nx * nz`.
    pub fn level_len(&self) -> usize {
        self.dims.x as usize * self.dims.z as usize
    }
    /// Number of levels, `ny`.
    pub fn levels(&self) -> u32 {
        self.dims.y
    }
    /// Linear index of point `(i, j, k)`; `None` outside the grid.
    pub fn index(&self, p: UVec3) -> Option<usize> {
        if p.cmplt(self.dims).all() {
            Some(self.index_unchecked(p))
        } else {
            None
        }
    }
    /// Linear index of point `p` without bounds checks (garbage, not UB, outside).
    #[inline]
    pub fn index_unchecked(&self, p: UVec3) -> usize {
        p.x as usize + self.dims.x as usize * (p.z as usize + self.dims.z as usize * p.y as usize)
    }
    /// Point coordinates of a linear index; `None` past the end.
    pub fn coords(&self, index: usize) -> Option<UVec3> {
        if index >= self.point_count() {
            return None;
        }
        let nx = self.dims.x as usize;
        let nz = self.dims.z as usize;
        let x = index % nx;
        let z = (index / nx) % nz;
        let y = index / (nx * nz);
        Some(UVec3::new(x as u32, y as u32, z as u32))
    }
    /// Range of linear indices of level `j`.
    pub fn level_range(&self, j: u32) -> std::ops::Range<usize> {
        let start = j as usize * self.level_len();
        start..start + self.level_len()
    }
    /// World position of point `p` (may lie outside the grid for `p` past `dims`).
    pub fn position(&self, p: UVec3) -> Vec3 {
        self.origin + self.h * p.as_vec3()
    }
    /// Continuous grid coordinates of a world position: point `(i, j, k)` maps to
    /// `(i, j, k)` exactly.
    pub fn to_grid(&self, world: Vec3) -> Vec3 {
        (world - self.origin) / self.h
    }
    /// World position of continuous grid coordinates.
    pub fn to_world(&self, grid: Vec3) -> Vec3 {
        self.origin + self.h * grid
    }
    /// World-space box spanned by the points (not the cells): `(min, max)`.
    pub fn point_bounds(&self) -> (Vec3, Vec3) {
        (self.origin, self.position(self.dims - UVec3::ONE))
    }
    /// World-space box covered by the material cells: point bounds grown by `h/2`.
    pub fn cell_bounds(&self) -> (Vec3, Vec3) {
        let (lo, hi) = self.point_bounds();
        (lo - self.h * 0.5, hi + self.h * 0.5)
    }
    /// True when `world` lies inside [`Self::point_bounds`] (inclusive).
    pub fn contains(&self, world: Vec3) -> bool {
        let (lo, hi) = self.point_bounds();
        world.cmpge(lo).all() && world.cmple(hi).all()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn desc() -> GridDesc {
        GridDesc::new(Vec3::new(1.0, -2.0, 3.0), 0.5, UVec3::new(4, 3, 5)).unwrap()
    }

    #[test]
    fn index_order_is_x_then_z_then_y() {
        let d = desc();
        assert_eq!(d.index(UVec3::new(1, 0, 0)), Some(1));
        assert_eq!(d.index(UVec3::new(0, 0, 1)), Some(4));
        assert_eq!(d.index(UVec3::new(0, 1, 0)), Some(20));
        assert_eq!(d.level_range(2), 40..60);
        assert_eq!(d.index(UVec3::new(4, 0, 0)), None);
        for i in 0..d.point_count() {
            assert_eq!(d.index(d.coords(i).unwrap()), Some(i));
        }
        assert_eq!(d.coords(d.point_count()), None);
    }

    #[test]
    fn point_count_products_cannot_wrap() {
        // 2^22 cubed = 2^66 points wraps a u64 product to 0: it must be refused.
        for dims in [
            UVec3::splat(1 << 22),
            UVec3::new(u32::MAX, u32::MAX, u32::MAX),
            UVec3::new(1 << 16, 1 << 16, 2),
            UVec3::new(u32::MAX, 2, 1),
        ] {
            let e = GridDesc::new(Vec3::ZERO, 1e-4, dims)
                .unwrap_err()
                .to_string();
            assert!(e.contains("dims"), "{dims}: {e}");
        }
        assert!(GridDesc::new(Vec3::ZERO, 1e-4, UVec3::new(1 << 16, 1 << 16, 1)).is_ok());
    }

    #[test]
    fn world_grid_round_trip() {
        let d = desc();
        let p = UVec3::new(3, 2, 4);
        assert_eq!(d.position(p), Vec3::new(2.5, -1.0, 5.0));
        assert_eq!(d.to_grid(d.position(p)), p.as_vec3());
        assert!(d.contains(d.position(p)));
        assert!(!d.contains(d.position(p) + Vec3::X * 0.01));
        let (lo, hi) = d.cell_bounds();
        assert_eq!(lo, Vec3::new(0.75, -2.25, 2.75));
        assert_eq!(hi, Vec3::new(2.75, -0.75, 5.25));
    }

    #[test]
    fn invalid_descriptors_name_the_field() {
        let e = |r: Result<GridDesc, GridError>| r.unwrap_err().to_string();
        assert!(e(GridDesc::new(Vec3::NAN, 1.0, UVec3::ONE)).contains("origin"));
        assert!(e(GridDesc::new(Vec3::ZERO, 0.0, UVec3::ONE)).starts_with("invalid h = 0.0"));
        assert!(e(GridDesc::new(Vec3::ZERO, f32::INFINITY, UVec3::ONE)).contains("h = inf"));
        assert!(e(GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(1, 0, 1))).contains("dims.y = 0"));
        assert!(e(GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(1 << 11))).contains("2^32"));
        assert!(e(GridDesc::new(Vec3::splat(3e38), 1.0, UVec3::ONE)).contains("origin"));
        assert!(GridDesc::new(Vec3::splat(-9.9e8), 1e5, UVec3::new(1000, 1, 1)).is_ok());
        assert!(
            e(GridDesc::new(
                Vec3::splat(9.9e8),
                1e5,
                UVec3::new(1000, 1, 1)
            ))
            .contains("far corner")
        );
        // The extremes of the stress list are accepted.
        assert!(GridDesc::new(Vec3::ZERO, 0.01, UVec3::new(1, 1024, 1)).is_ok());
        assert!(GridDesc::new(Vec3::ZERO, 1000.0, UVec3::ONE).is_ok());
    }
}
