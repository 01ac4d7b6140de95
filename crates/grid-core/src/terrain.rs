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
        let cell = |v: f32, o: f32, n: u32| {
            let g = (v - o) / self.spacing;
            if g.is_nan() {
                0.0
            } else {
                g.clamp(0.0, (n - 1) as f32)
            }
        };
        let (gx, gz) = (
            cell(x, self.origin.x, self.width),
            cell(z, self.origin.y, self.depth),
        );
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
