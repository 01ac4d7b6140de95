//! Sampling a grid at any world position: trilinear, clamped at the edges, and
//! normal-biased against light leaking through walls.

use glam::{UVec3, Vec3};

use crate::GridError;
use crate::grid::{AverageLight, DominantDir, Grid, Material};
use crate::light::BinLight;

/// Values that can be blended linearly (weights sum to 1 in trilinear sampling).
pub trait Blend: Copy {
    /// The additive identity.
    fn zero() -> Self;
    /// `self += other * w`.
    fn add_scaled(&mut self, other: &Self, w: f32);
}

impl Blend for f32 {
    fn zero() -> Self {
        0.0
    }
    #[inline]
    fn add_scaled(&mut self, other: &Self, w: f32) {
        *self += *other * w;
    }
}

impl Blend for Vec3 {
    fn zero() -> Self {
        Vec3::ZERO
    }
    #[inline]
    fn add_scaled(&mut self, other: &Self, w: f32) {
        *self += *other * w;
    }
}

impl Blend for crate::HorizonLight {
    fn zero() -> Self {
        Self::default()
    }
    #[inline]
    fn add_scaled(&mut self, other: &Self, w: f32) {
        // By reference, as floats in a row: the loop took a copy of `other` and ran 8
        // three-float steps.
        add_scaled_floats(&mut self.0, &other.0, w);
    }
}

impl Blend for BinLight {
    fn zero() -> Self {
        BinLight::ZERO
    }
    #[inline]
    fn add_scaled(&mut self, other: &Self, w: f32) {
        add_scaled_floats(&mut self.0, &other.0, w);
    }
}

/// `a += b · w` over the colours' floats in a row (the same sums, element by element):
/// the loop runs on the vector unit instead of one three-float step a colour. (With
/// `w` = 1 the product is exact: plain sums.)
#[inline]
pub(crate) fn add_scaled_floats(a: &mut [Vec3], b: &[Vec3], w: f32) {
    let a: &mut [f32] = bytemuck::cast_slice_mut(a);
    let b: &[f32] = bytemuck::cast_slice(b);
    for (x, y) in a.iter_mut().zip(b) {
        *x += *y * w;
    }
}

impl Blend for AverageLight {
    fn zero() -> Self {
        AverageLight(Vec3::ZERO)
    }
    #[inline]
    fn add_scaled(&mut self, other: &Self, w: f32) {
        self.0 += other.0 * w;
    }
}

impl Blend for DominantDir {
    fn zero() -> Self {
        DominantDir(Vec3::ZERO)
    }
    #[inline]
    fn add_scaled(&mut self, other: &Self, w: f32) {
        self.0 += other.0 * w;
    }
}

impl Blend for crate::AmbientCube {
    fn zero() -> Self {
        crate::AmbientCube::default()
    }
    #[inline]
    fn add_scaled(&mut self, other: &Self, w: f32) {
        for (a, b) in self.0.iter_mut().zip(&other.0) {
            *a += *b * w;
        }
    }
}

impl Blend for Material {
    fn zero() -> Self {
        Material {
            reflectance: Vec3::ZERO,
            pass: 0.0,
        }
    }
    #[inline]
    fn add_scaled(&mut self, other: &Self, w: f32) {
        self.reflectance += other.reflectance * w;
        self.pass += other.pass * w;
    }
}

/// A trilinear lookup at continuous grid coordinates `g` in a grid of `dims`: its base
/// point, the point one step up each axis (both clamped into the grid; a zero
/// dimension read as one point) and the fractions toward the second. The corners and
/// weights of [`trilinear_indices`] and [`trilinear_corners`] are made from these (a
/// caller that reads many points of one column can blend each level's four corners
/// once: weight `(1 - f.x)·(1 - f.z)` and so on, which at `f.y = 0` are the trilinear
/// weights bit for bit).
#[inline]
pub fn trilinear_frame(dims: UVec3, g: Vec3) -> (UVec3, UVec3, Vec3) {
    let dims = dims.max(UVec3::ONE);
    let maxf = (dims - UVec3::ONE).as_vec3();
    let g = g.clamp(Vec3::ZERO, maxf);
    // (`g` is clamped at 0: truncation is its floor, without a libm call a coordinate.)
    let base = g.as_uvec3().min(dims.saturating_sub(UVec3::splat(2)));
    let f = (g - base.as_vec3()).clamp(Vec3::ZERO, Vec3::ONE);
    let hi = (base + UVec3::ONE).min(dims - UVec3::ONE);
    (base, hi, f)
}

/// The base point (lowest corner) of the trilinear lookup at continuous grid coordinates
/// `g` ([`trilinear_indices`]' first index is this point's), clamped into the grid:
/// monotonic in `g` on every axis.
pub fn trilinear_base(dims: UVec3, g: Vec3) -> UVec3 {
    trilinear_frame(dims, g).0
}

/// The 8 corners and weights of a trilinear lookup at continuous grid coordinates `g`,
/// clamped into the grid (a point outside reads the nearest face/edge/corner value).
/// Along an axis with one point, that point has weight 1; a zero dimension is read as
/// one point (index 0), as no grid has one.
pub fn trilinear_corners(dims: UVec3, g: Vec3) -> [(UVec3, f32); 8] {
    let (base, hi, f) = trilinear_frame(dims, g);
    std::array::from_fn(|c| {
        let (bx, by, bz) = (c & 1 != 0, c & 2 != 0, c & 4 != 0);
        let p = UVec3::new(
            if bx { hi.x } else { base.x },
            if by { hi.y } else { base.y },
            if bz { hi.z } else { base.z },
        );
        let w = (if bx { f.x } else { 1.0 - f.x })
            * (if by { f.y } else { 1.0 - f.y })
            * (if bz { f.z } else { 1.0 - f.z });
        (p, w)
    })
}

/// [`trilinear_corners`] as linear indices into a grid of `dims` (x fastest, then z,
/// then y: [`crate::GridDesc::index_unchecked`]) and weights, corner by corner in the
/// same order and with the same arithmetic, without building the corners (the hot
/// path of [`Grid::sample`]: composing materials, boundaries, light volumes). The
/// first index is the lookup's base point: the corners are it and the points one step
/// up each axis, clamped into the grid.
#[inline]
pub fn trilinear_indices(dims: UVec3, g: Vec3) -> ([usize; 8], [f32; 8]) {
    let (base, hi, f) = trilinear_frame(dims, g);
    let (nx, nz) = (dims.x as usize, dims.z as usize);
    let xs = [base.x as usize, hi.x as usize];
    let ys = [base.y as usize, hi.y as usize];
    let zs = [base.z as usize, hi.z as usize];
    let (wx, wy, wz) = ([1.0 - f.x, f.x], [1.0 - f.y, f.y], [1.0 - f.z, f.z]);
    let mut index = [0; 8];
    let mut weight = [0.0; 8];
    for c in 0..8 {
        let (bx, by, bz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
        index[c] = xs[bx] + nx * (zs[bz] + nz * ys[by]);
        weight[c] = wx[bx] * wy[by] * wz[bz];
    }
    (index, weight)
}

impl<T: Blend> Grid<T> {
    /// Trilinear interpolation at world position `p`, clamped at the grid's edges.
    /// `p` must be finite (a typed error names it otherwise).
    pub fn sample(&self, p: Vec3) -> Result<T, GridError> {
        if !p.is_finite() {
            return Err(GridError::invalid("p", p, "sample position must be finite"));
        }
        let g = self.desc().to_grid(p);
        Ok(self.blend(trilinear_indices(self.desc().dims(), g)))
    }

    /// The values at `index` weighted by `weight` and summed in that order, zero
    /// weights skipped: [`Grid::sample`] of a lookup from [`trilinear_indices`]. Panics
    /// on an index past the grid (those of `trilinear_indices` of its dims never are).
    #[inline]
    pub fn blend(&self, (index, weight): ([usize; 8], [f32; 8])) -> T {
        let data = self.data();
        let mut acc = T::zero();
        for (i, w) in index.into_iter().zip(weight) {
            if w != 0.0 {
                acc.add_scaled(&data[i], w);
            }
        }
        acc
    }

    /// Samples at `p + n * h / 2` (half a cell along the unit normal `n`), as 3DWorld
    /// does, so a surface reads the light on its own side of a wall rather than a blend
    /// with the dark inside. `n` must be finite and non-zero.
    pub fn sample_biased(&self, p: Vec3, n: Vec3) -> Result<T, GridError> {
        let n = n
            .try_normalize()
            .ok_or_else(|| GridError::invalid("n", n, "normal must be finite and non-zero"))?;
        self.sample(p + n * (0.5 * self.desc().h()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridDesc;
    use proptest::prelude::*;

    proptest! {
        /// `Grid::sample` adds the corners of [`trilinear_corners`] at their indices,
        /// in their order, skipping zero weights: the same value bit for bit, inside
        /// the grid, outside it (clamped) and on grids one point thin.
        #[test]
        fn sample_is_the_corners_sum_bit_for_bit(
            dims in (1u32..6, 1u32..6, 1u32..6),
            g in (-2.0f32..8.0, -2.0f32..8.0, -2.0f32..8.0),
            seed in 1u64..u64::MAX,
        ) {
            let d = GridDesc::new(Vec3::new(0.5, -1.0, 2.0), 0.75, UVec3::new(dims.0, dims.1, dims.2)).unwrap();
            let mut s = seed;
            let data: Vec<Material> = (0..d.point_count())
                .map(|_| {
                    let mut r = || {
                        s ^= s << 13;
                        s ^= s >> 7;
                        s ^= s << 17;
                        (s >> 40) as f32 / (1u64 << 24) as f32
                    };
                    Material { reflectance: Vec3::new(r(), r(), r()), pass: r() }
                })
                .collect();
            let grid = Grid::from_trusted(d, data);
            let p = d.origin() + Vec3::new(g.0, g.1, g.2) * d.h();
            let mut want = Material::zero();
            for (c, w) in trilinear_corners(d.dims(), d.to_grid(p)) {
                if w != 0.0 {
                    want.add_scaled(&grid.data()[d.index_unchecked(c)], w);
                }
            }
            let got = grid.sample(p).unwrap();
            prop_assert_eq!(got.pass.to_bits(), want.pass.to_bits());
            for k in 0..3 {
                prop_assert_eq!(got.reflectance[k].to_bits(), want.reflectance[k].to_bits());
            }
        }
    }

    #[test]
    fn a_zero_dimension_reads_as_one_point() {
        for dims in [UVec3::ZERO, UVec3::new(0, 3, 2), UVec3::new(4, 0, 0)] {
            let c = trilinear_corners(dims, Vec3::new(1.3, 0.4, 7.0));
            let sum: f32 = c.iter().map(|(_, w)| w).sum();
            assert!((sum - 1.0).abs() < 1e-6, "{dims}: {sum}");
            for (p, _) in c {
                assert!(p.cmplt(dims.max(UVec3::ONE)).all(), "{dims}: {p}");
            }
        }
    }

    /// A grid whose value is a linear function of position: trilinear reproduces it
    /// exactly inside the grid.
    fn linear_grid() -> Grid<Vec3> {
        let d = GridDesc::new(Vec3::new(-1.0, 2.0, 0.5), 0.5, UVec3::new(4, 3, 5)).unwrap();
        let data = (0..d.point_count())
            .map(|i| {
                let p = d.position(d.coords(i).unwrap());
                Vec3::new(p.x * 2.0 + p.y, p.z - p.y, 3.0)
            })
            .collect();
        Grid::from_trusted(d, data)
    }

    fn f(p: Vec3) -> Vec3 {
        Vec3::new(p.x * 2.0 + p.y, p.z - p.y, 3.0)
    }

    #[test]
    fn reproduces_linear_fields_and_grid_points() {
        let g = linear_grid();
        for i in 0..g.desc().point_count() {
            let p = g.desc().position(g.desc().coords(i).unwrap());
            assert!((g.sample(p).unwrap() - g.data()[i]).length() < 1e-5);
        }
        let p = Vec3::new(-0.3, 2.7, 1.9);
        assert!((g.sample(p).unwrap() - f(p)).length() < 1e-5);
    }

    #[test]
    fn clamps_outside() {
        let g = linear_grid();
        let (lo, hi) = g.desc().point_bounds();
        assert!((g.sample(lo - Vec3::splat(10.0)).unwrap() - f(lo)).length() < 1e-5);
        assert!((g.sample(hi + Vec3::splat(10.0)).unwrap() - f(hi)).length() < 1e-5);
        assert!(g.sample(Vec3::new(f32::NAN, 0.0, 0.0)).is_err());
    }

    #[test]
    fn normal_bias_moves_half_a_cell() {
        let g = linear_grid();
        let p = Vec3::new(0.0, 3.0, 1.0);
        let b = g.sample_biased(p, Vec3::new(0.0, 0.0, 7.0)).unwrap();
        assert!((b - f(p + Vec3::Z * 0.25)).length() < 1e-5);
        assert!(g.sample_biased(p, Vec3::ZERO).is_err());
        assert!(g.sample_biased(p, Vec3::NAN).is_err());
    }

    #[test]
    fn one_point_wide_axes() {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(1, 4, 1)).unwrap();
        let g = Grid::from_trusted(d, (0..4).map(|j| Vec3::splat(j as f32)).collect());
        assert!((g.sample(Vec3::new(5.0, 1.5, -3.0)).unwrap() - Vec3::splat(1.5)).length() < 1e-6);
        let one = Grid::from_trusted(
            GridDesc::new(Vec3::ZERO, 1.0, UVec3::ONE).unwrap(),
            vec![Vec3::ONE],
        );
        assert_eq!(one.sample(Vec3::splat(0.3)).unwrap(), Vec3::ONE);
    }

    proptest! {
        /// Continuity across cell borders: the values just either side of a border agree.
        #[test]
        fn continuous_across_cell_borders(
            seed in prop::collection::vec(0f32..10.0, 60),
            x in 0u32..3, y in 0f32..2.0, z in 0f32..4.0,
        ) {
            let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 3, 5)).unwrap();
            let g = Grid::from_trusted(d, seed.iter().map(|&v| Vec3::splat(v)).collect());
            let border = Vec3::new(x as f32 + 1.0, y, z);
            let eps = Vec3::X * 1e-4;
            let a = g.sample(border - eps).unwrap();
            let b = g.sample(border + eps).unwrap();
            prop_assert!((a - b).abs().max_element() < 1e-2);
        }

        /// Weights are a partition of unity and never negative.
        #[test]
        fn weights_partition_unity(gx in -5f32..10.0, gy in -5f32..10.0, gz in -5f32..10.0, nx in 1u32..5, ny in 1u32..5, nz in 1u32..5) {
            let c = trilinear_corners(UVec3::new(nx, ny, nz), Vec3::new(gx, gy, gz));
            let s: f32 = c.iter().map(|(_, w)| w).sum();
            prop_assert!((s - 1.0).abs() < 1e-5);
            prop_assert!(c.iter().all(|(p, w)| *w >= 0.0 && p.x < nx && p.y < ny && p.z < nz));
        }
    }
}
