//! [`ProbeParams`]: how densely probes and surfels sample a scene.

use lightgrid_core::GridError;

/// How a probe set is baked. Start from a preset and change fields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeParams {
    /// Horizontal spacing of the automatic probe grid, metres (The Division: 4 m).
    pub spacing: f32,
    /// Height of an automatic probe above the first surface below it, metres.
    pub height: f32,
    /// Rays cast from each probe (a Fibonacci sphere: deterministic, near-uniform).
    pub rays: u32,
    /// Longest ray, metres: a surface farther away counts as sky.
    pub max_distance: f32,
    /// Side of a surfel cell, metres (The Division: 1 m). All hits of the probes' rays
    /// in one cell, on faces turned the same way, average into one surfel.
    pub cell: f32,
    /// Surfel cells per brick side (The Division: 4). A probe reads bricks, not surfels:
    /// a brick's light is the hit-weighted mean of its surfels'. 1: every surfel is its
    /// own brick (exact, more factors per probe).
    pub brick: u32,
    /// Probes that light each surfel from their last frame (the nearest that saw it).
    pub probes_per_surfel: u32,
    /// Distance of the extra probes along walls from the wall, metres (The Division's
    /// second placement rule, against flat-looking walls; [`crate::place_walls`]).
    /// 0: no wall probes.
    pub wall_offset: f32,
}

impl ProbeParams {
    /// Coarse and quick: 8 m spacing, 256 rays, 2 m cells, bricks of 2 cells, no wall
    /// probes.
    pub const fn preview() -> Self {
        Self {
            spacing: 8.0,
            height: 2.0,
            rays: 256,
            max_distance: 200.0,
            cell: 2.0,
            brick: 2,
            probes_per_surfel: 2,
            wall_offset: 0.0,
        }
    }

    /// The Division's figures: 4 m spacing, 1 m cells, 4³-cell bricks; 1024 rays; wall
    /// probes 1 m from walls.
    pub const fn standard() -> Self {
        Self {
            spacing: 4.0,
            height: 2.0,
            rays: 1024,
            max_distance: 300.0,
            cell: 1.0,
            brick: 4,
            probes_per_surfel: 4,
            wall_offset: 1.0,
        }
    }

    /// Dense: 2 m spacing, 4096 rays, 0.5 m cells, every surfel its own brick; wall
    /// probes 0.75 m from walls.
    pub const fn fine() -> Self {
        Self {
            spacing: 2.0,
            height: 1.5,
            rays: 4096,
            max_distance: 400.0,
            cell: 0.5,
            brick: 1,
            probes_per_surfel: 4,
            wall_offset: 0.75,
        }
    }

    /// Checks every field; errors name it.
    pub fn validate(&self) -> Result<(), GridError> {
        for (name, v) in [
            ("spacing", self.spacing),
            ("max_distance", self.max_distance),
            ("cell", self.cell),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GridError::invalid(name, v, "must be finite and > 0"));
            }
        }
        for (name, v) in [("height", self.height), ("wall_offset", self.wall_offset)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(GridError::invalid(name, v, "must be finite and >= 0"));
            }
        }
        if !(16..=1 << 20).contains(&self.rays) {
            return Err(GridError::invalid(
                "rays",
                self.rays,
                "must be in 16..=1048576",
            ));
        }
        if !(1..=64).contains(&self.brick) {
            return Err(GridError::invalid("brick", self.brick, "must be in 1..=64"));
        }
        if !(1..=8).contains(&self.probes_per_surfel) {
            return Err(GridError::invalid(
                "probes_per_surfel",
                self.probes_per_surfel,
                "must be in 1..=8",
            ));
        }
        Ok(())
    }
}

impl Default for ProbeParams {
    fn default() -> Self {
        Self::standard()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_bad_fields_are_named() {
        for p in [
            ProbeParams::preview(),
            ProbeParams::standard(),
            ProbeParams::fine(),
        ] {
            p.validate().unwrap();
        }
        let mut p = ProbeParams::standard();
        p.cell = f32::NAN;
        assert!(p.validate().unwrap_err().to_string().contains("cell"));
        let mut p = ProbeParams::standard();
        p.rays = 3;
        assert!(p.validate().unwrap_err().to_string().contains("rays"));
        let mut p = ProbeParams::standard();
        p.brick = 0;
        assert!(p.validate().unwrap_err().to_string().contains("brick"));
        let mut p = ProbeParams::standard();
        p.wall_offset = -1.0;
        assert!(
            p.validate()
                .unwrap_err()
                .to_string()
                .contains("wall_offset")
        );
    }
}
