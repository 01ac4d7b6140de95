//! Terrain heights: the [`Heightmap`] that the area composer grounds material in and
//! that `terrain-lod` reads node height ranges from. File loading (16-bit PNG) lives
//! with the image decoder in `material-voxelizer` (`compose::load_heightmap_png`).

use glam::Vec2;

use crate::GridError;

/// Largest height a [`Heightmap`] accepts, metres either way: differences of heights
/// stay far inside `f32` (3e38 made bilinear reads NaN).
pub const MAX_HEIGHT: f32 = 1e7;

/// A heightmap: heights (metres, world Y) on a regular `(x, z)` lattice.
#[derive(Debug, Clone, PartialEq)]
pub struct Heightmap {
    /// World `(x, z)` of sample `(0, 0)`.
    pub origin: Vec2,
    /// Metres between neighbouring samples.
    pub spacing: f32,
    /// Samples along x.
    pub width: u32,
    /// Samples along z.
    pub depth: u32,
    /// Heights, x fastest.
    pub heights: Vec<f32>,
}

/// Most samples of one heightmap (2^30: 4 GiB of heights).
pub const MAX_HEIGHTMAP_SAMPLES: u64 = 1 << 30;

/// `width × depth` if it is at most [`MAX_HEIGHTMAP_SAMPLES`].
fn check_samples(width: u32, depth: u32) -> Result<u64, GridError> {
    crate::limits::checked_count("width x depth", width, depth, MAX_HEIGHTMAP_SAMPLES)
}

impl Heightmap {
    /// A heightmap from a function of world `(x, z)`.
    pub fn from_fn(
        origin: Vec2,
        spacing: f32,
        width: u32,
        depth: u32,
        f: impl Fn(f32, f32) -> f32,
    ) -> Result<Self, GridError> {
        let count = check_samples(width, depth)?;
        crate::limits::check_memory(&format!("a {width} x {depth} heightmap"), count * 4)?;
        let mut heights = Vec::with_capacity(count as usize);
        for k in 0..depth {
            for i in 0..width {
                heights.push(f(
                    origin.x + i as f32 * spacing,
                    origin.y + k as f32 * spacing,
                ));
            }
        }
        Self::new(origin, spacing, width, depth, heights)
    }

    /// A validated heightmap (finite heights, `spacing > 0`, at least 2 × 2 samples).
    pub fn new(
        origin: Vec2,
        spacing: f32,
        width: u32,
        depth: u32,
        heights: Vec<f32>,
    ) -> Result<Self, GridError> {
        if !origin.is_finite() {
            return Err(GridError::invalid("origin", origin, "must be finite"));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(GridError::invalid(
                "spacing",
                spacing,
                "must be finite and > 0",
            ));
        }
        if width < 2 || depth < 2 {
            return Err(GridError::invalid(
                "width x depth",
                (width, depth),
                "needs at least 2 x 2 samples",
            ));
        }
        let count = check_samples(width, depth)?;
        if heights.len() as u64 != count {
            return Err(GridError::LengthMismatch {
                field: "heights",
                expected: count as usize,
                found: heights.len(),
            });
        }
        if let Some(i) = heights
            .iter()
            .position(|h| !(h.is_finite() && h.abs() <= MAX_HEIGHT))
        {
            return Err(GridError::invalid(
                format!("heights[{i}]"),
                heights[i],
                "must be finite and within ±1e7 m",
            ));
        }
        Ok(Self {
            origin,
            spacing,
            width,
            depth,
            heights,
        })
    }

    /// Bilinear height at world `(x, z)`, clamped at the edges (a NaN coordinate reads
    /// the first row or column: the result is always finite).
    pub fn height_at(&self, x: f32, z: f32) -> f32 {
        let (gx, gz) = self.grid_coords(x, z);
        let (i0, k0) = (
            (gx as u32).min(self.width - 2),
            (gz as u32).min(self.depth - 2),
        );
        let (fx, fz) = (gx - i0 as f32, gz - k0 as f32);
        let at = |i: u32, k: u32| self.heights[(k * self.width + i) as usize];
        let a = at(i0, k0) + (at(i0 + 1, k0) - at(i0, k0)) * fx;
        let b = at(i0, k0 + 1) + (at(i0 + 1, k0 + 1) - at(i0, k0 + 1)) * fx;
        a + (b - a) * fz
    }

    /// Lowest and highest height over the rectangle between world corners `a` and `b`
    /// (`(x, z)`, either order), exactly as [`Heightmap::height_at`] reads it there:
    /// along any line of constant `x` or `z` inside one sample cell the bilinear height
    /// is linear, so its extremes over the rectangle lie at the samples inside it, at
    /// the sample lines' crossings of its edges, or at its corners, and those are all
    /// it reads. A non-finite corner reads as `height_at` reads it (clamped).
    pub fn range_within(&self, a: Vec2, b: Vec2) -> (f32, f32) {
        let (p, q) = (self.grid_coords(a.x, a.y), self.grid_coords(b.x, b.y));
        let (gx0, gx1) = (p.0.min(q.0), p.0.max(q.0));
        let (gz0, gz1) = (p.1.min(q.1), p.1.max(q.1));
        // Sample columns and rows strictly inside the rectangle.
        let inner = |g0: f32, g1: f32| {
            let start = g0.floor() as u32 + 1;
            start..(g1.ceil() as u32).max(start)
        };
        let (xs, zs) = (inner(gx0, gx1), inner(gz0, gz1));
        let world_x = |gx: f32| self.origin.x + gx * self.spacing;
        let world_z = |gz: f32| self.origin.y + gz * self.spacing;
        let (x0, x1, z0, z1) = (world_x(gx0), world_x(gx1), world_z(gz0), world_z(gz1));
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        let mut take = |h: f32| {
            lo = lo.min(h);
            hi = hi.max(h);
        };
        for (x, z) in [(x0, z0), (x1, z0), (x0, z1), (x1, z1)] {
            take(self.height_at(x, z));
        }
        for i in xs.clone() {
            let x = world_x(i as f32);
            take(self.height_at(x, z0));
            take(self.height_at(x, z1));
        }
        for k in zs {
            let z = world_z(k as f32);
            take(self.height_at(x0, z));
            take(self.height_at(x1, z));
            let row = &self.heights[(k * self.width) as usize..][..self.width as usize];
            for &h in &row[xs.start as usize..xs.end as usize] {
                take(h);
            }
        }
        (lo, hi)
    }

    /// World `(x, z)` in sample units from the first sample, clamped to the samples (a
    /// NaN coordinate: the first row or column), as [`Heightmap::height_at`] reads them.
    fn grid_coords(&self, x: f32, z: f32) -> (f32, f32) {
        let along = |v: f32, o: f32, n: u32| {
            let g = (v - o) / self.spacing;
            if g.is_nan() {
                0.0
            } else {
                g.clamp(0.0, (n - 1) as f32)
            }
        };
        (
            along(x, self.origin.x, self.width),
            along(z, self.origin.y, self.depth),
        )
    }

    /// Lowest and highest height.
    pub fn range(&self) -> (f32, f32) {
        self.heights
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                (lo.min(h), hi.max(h))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heights_out_of_range_are_refused_and_reads_stay_finite() {
        let e = Heightmap::new(Vec2::ZERO, 1.0, 2, 2, vec![0.0, 3e38, -3e38, 0.0]).unwrap_err();
        assert!(e.to_string().contains("heights[1]"), "{e}");
        let hm = Heightmap::new(Vec2::ZERO, 1.0, 2, 2, vec![1e7, -1e7, 0.0, 5.0]).unwrap();
        for (x, z) in [
            (0.5, 0.5),
            (f32::NAN, 0.5),
            (0.5, f32::NAN),
            (f32::INFINITY, -1e30),
        ] {
            assert!(hm.height_at(x, z).is_finite(), "{x}, {z}");
        }
        assert_eq!(hm.height_at(f32::NAN, f32::NAN), 1e7);
    }

    /// `range_within` against brute force: over random heightmaps and rectangles (inside,
    /// straddling the edges, thinner than a sample cell), every height read on a fine
    /// lattice of the rectangle lies within the range, and the range's ends are heights
    /// read there (the lattice holds the sample lines' crossings, where they lie).
    #[test]
    fn range_within_is_the_exact_range_of_the_reads() {
        let mut rng = crate::rng::SeededRng::new(11);
        for case in 0..300 {
            let (w, d) = (2 + (rng.f32() * 9.0) as u32, 2 + (rng.f32() * 9.0) as u32);
            let spacing = 0.25 + 2.0 * rng.f32();
            let origin = Vec2::new(rng.f32() * 10.0 - 5.0, rng.f32() * 10.0 - 5.0);
            let heights = (0..w * d).map(|_| rng.f32() * 20.0 - 10.0).collect();
            let hm = Heightmap::new(origin, spacing, w, d, heights).unwrap();
            let size = Vec2::new(w as f32, d as f32) * spacing;
            let mut corner = || origin - 0.3 * size + Vec2::new(rng.f32(), rng.f32()) * 1.6 * size;
            let (a, b) = (corner(), corner());
            let (lo, hi) = hm.range_within(a, b);
            assert!(lo.is_finite() && hi.is_finite() && lo <= hi, "case {case}");
            // Reads on a fine lattice of the rectangle, plus every sample line's
            // crossing of it.
            let (min, max) = (a.min(b), a.max(b));
            let mut xs: Vec<f32> = (0..=64)
                .map(|t| min.x + (max.x - min.x) * t as f32 / 64.0)
                .collect();
            let mut zs: Vec<f32> = (0..=64)
                .map(|t| min.y + (max.y - min.y) * t as f32 / 64.0)
                .collect();
            xs.extend(
                (0..w)
                    .map(|i| origin.x + i as f32 * spacing)
                    .filter(|x| (min.x..=max.x).contains(x)),
            );
            zs.extend(
                (0..d)
                    .map(|k| origin.y + k as f32 * spacing)
                    .filter(|z| (min.y..=max.y).contains(z)),
            );
            let (mut blo, mut bhi) = (f32::INFINITY, f32::NEG_INFINITY);
            for &x in &xs {
                for &z in &zs {
                    let h = hm.height_at(x, z);
                    assert!(
                        h >= lo - 1e-4 && h <= hi + 1e-4,
                        "case {case}: {h} outside {lo}..{hi}"
                    );
                    (blo, bhi) = (blo.min(h), bhi.max(h));
                }
            }
            assert!(
                (blo - lo).abs() <= 1e-4 && (bhi - hi).abs() <= 1e-4,
                "case {case}: {blo}..{bhi} against {lo}..{hi}"
            );
        }
    }

    #[test]
    fn bilinear_and_clamped() {
        let hm =
            Heightmap::from_fn(Vec2::new(-1.0, 2.0), 0.5, 5, 4, |x, z| 2.0 * x + 3.0 * z).unwrap();
        // A plane is reproduced exactly between samples...
        for (x, z) in [(-1.0, 2.0), (-0.3, 2.7), (0.9, 3.4)] {
            assert!(
                (hm.height_at(x, z) - (2.0 * x + 3.0 * z)).abs() < 1e-5,
                "{x} {z}"
            );
        }
        // ...and clamped to the edge outside.
        assert_eq!(hm.height_at(-10.0, 2.0), hm.height_at(-1.0, 2.0));
        assert_eq!(hm.range(), (hm.heights[0], *hm.heights.last().unwrap()));
    }

    #[test]
    fn bad_input_names_the_field() {
        let e = Heightmap::new(Vec2::ZERO, 0.0, 2, 2, vec![0.0; 4]).unwrap_err();
        assert!(e.to_string().contains("spacing"), "{e}");
        let e = Heightmap::new(Vec2::ZERO, 1.0, 2, 2, vec![0.0, 1.0, f32::NAN, 0.0]).unwrap_err();
        assert!(e.to_string().contains("heights[2]"), "{e}");
        let e = Heightmap::new(Vec2::ZERO, 1.0, 1, 2, vec![0.0; 2]).unwrap_err();
        assert!(e.to_string().contains("width x depth"), "{e}");
    }
}
