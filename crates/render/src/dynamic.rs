//! Many small dynamic lights (3DWorld's "grid bag"): point, spot and line lights with a
//! finite range, culled through a world-space grid whose cells hold ranges into one
//! light-index array, built on the CPU each frame and read in the shaders.
//!
//! The shading functions here are the specification; `shaders/dynamic.wgsl` implements
//! them. A light contributes exactly zero beyond its range, and every cell lists (in
//! ascending order) every light whose range reaches into it, so shading through the
//! grid gives the same sum as a loop over all lights (tested).

use std::f32::consts::PI;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{GridError, LightKind};

/// A dynamic light: shape, colour × intensity (irradiance at 1 m) and range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicLight {
    /// Shape: a point, a spot or a line (`lightgrid_core::LightKind`, the type the baked
    /// light volumes use too); area lights are baked only and refused here.
    pub kind: LightKind,
    /// Linear RGB irradiance on a surface facing it 1 m away.
    pub colour: Vec3,
    /// Distance beyond which it contributes nothing, metres.
    pub range: f32,
}

/// `ε` of the falloff `1 / (d² + ε)` (no singularity at the light).
pub const FALLOFF_EPSILON: f32 = 0.01;

impl DynamicLight {
    /// The point the light shines from, for a shaded point `p`.
    pub fn source(&self, p: Vec3) -> Vec3 {
        match self.kind {
            LightKind::Point { position } | LightKind::Spot { position, .. } => position,
            LightKind::Area { centre, .. } => centre,
            LightKind::Line { a, b } => {
                let ab = b - a;
                let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
                a + ab * t
            }
        }
    }

    /// Bounding box of the lit region (the range around the source).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let r = Vec3::splat(self.range);
        match self.kind {
            LightKind::Point { position } | LightKind::Spot { position, .. } => {
                (position - r, position + r)
            }
            LightKind::Area { centre, u, v } => {
                let e = u.abs() + v.abs();
                (centre - e - r, centre + e + r)
            }
            LightKind::Line { a, b } => (a.min(b) - r, a.max(b) + r),
        }
    }

    /// Checks the light at index `i`; errors name the field as `lights[i].field`.
    fn validate(&self, i: usize) -> Result<(), GridError> {
        let field = |f: &str| format!("lights[{i}].{f}");
        if !(self.range.is_finite() && self.range > 0.0) {
            return Err(GridError::invalid(
                field("range"),
                self.range,
                "must be finite and > 0",
            ));
        }
        if !(self.colour.is_finite() && self.colour.cmpge(Vec3::ZERO).all()) {
            return Err(GridError::invalid(
                field("colour"),
                self.colour,
                "must be finite and >= 0",
            ));
        }
        let (lo, hi) = self.bounds();
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(GridError::invalid(field("position"), lo, "must be finite"));
        }
        self.kind.validate().map_err(|e| match e {
            GridError::InvalidField {
                field: f,
                value,
                reason,
            } => GridError::InvalidField {
                field: field(&format!("kind.{f}")),
                value,
                reason,
            },
            other => other,
        })?;
        if let LightKind::Area { centre, .. } = self.kind {
            return Err(GridError::invalid(
                field("kind"),
                centre,
                "area lights are baked (light-volumes), not drawn as dynamic lights",
            ));
        }
        Ok(())
    }
}

/// Diffuse irradiance and specular radiance from dynamic lights at a point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DynamicShade {
    /// Irradiance (multiply by albedo / π).
    pub diffuse: Vec3,
    /// Specular radiance (Blinn-Phong, normalised).
    pub specular: Vec3,
}

/// One light's contribution at `p` (normal `n`, unit vector to the eye `v`).
pub fn shade_one(light: &DynamicLight, p: Vec3, n: Vec3, v: Vec3, shininess: f32) -> DynamicShade {
    let to = light.source(p) - p;
    let d2 = to.length_squared();
    let d = d2.sqrt();
    if d >= light.range {
        return DynamicShade::default();
    }
    let l = if d > 0.0 { to / d } else { n };
    let ndl = n.dot(l);
    if ndl <= 0.0 {
        return DynamicShade::default();
    }
    let x = d / light.range;
    let window = (1.0 - x * x * x * x).max(0.0);
    let mut f = window * window / (d2 + FALLOFF_EPSILON);
    if let Some((axis, cos_inner, cos_outer)) = light.kind.spot_cone() {
        f *= lightgrid_core::lights::spot_falloff((-l).dot(axis), cos_inner, cos_outer);
    }
    let e = light.colour * (f * ndl);
    let h = (l + v).normalize_or_zero();
    let spec = n.dot(h).max(0.0).powf(shininess) * (shininess + 8.0) / (8.0 * PI);
    DynamicShade {
        diffuse: e,
        specular: e * spec,
    }
}

/// The lights of a frame and their culling grid.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicLights {
    /// All lights.
    pub lights: Vec<DynamicLight>,
    /// World position of cell (0, 0, 0)'s lower corner.
    pub origin: Vec3,
    /// Cell size, metres.
    pub cell: f32,
    /// Cells along x, y, z.
    pub dims: UVec3,
    /// Per cell (x fastest, then z, then y): offset and count into `indices`.
    pub cells: Vec<[u32; 2]>,
    /// Light indices, ascending within each cell.
    pub indices: Vec<u32>,
}

/// Most cells along one axis of the culling grid.
pub const MAX_CELLS_PER_AXIS: u32 = 64;

impl DynamicLights {
    /// Builds the grid bag: cells of `cell` metres (grown if the lights span more than
    /// [`MAX_CELLS_PER_AXIS`] cells) over the lights' bounds.
    pub fn build(lights: Vec<DynamicLight>, cell: f32) -> Result<Self, GridError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(GridError::invalid("cell", cell, "must be finite and > 0"));
        }
        for (i, l) in lights.iter().enumerate() {
            l.validate(i)?;
        }
        if lights.is_empty() {
            return Ok(Self {
                lights,
                origin: Vec3::ZERO,
                cell,
                dims: UVec3::ONE,
                cells: vec![[0, 0]],
                indices: Vec::new(),
            });
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for l in &lights {
            let (a, b) = l.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        let span = hi - lo;
        let cell = cell.max(span.max_element() / MAX_CELLS_PER_AXIS as f32);
        let dims = (span / cell).ceil().as_uvec3().max(UVec3::ONE);
        let count = (dims.x * dims.y * dims.z) as usize;
        let index = |c: UVec3| (c.x + dims.x * (c.z + dims.z * c.y)) as usize;
        let mut per_cell: Vec<Vec<u32>> = vec![Vec::new(); count];
        for (i, l) in lights.iter().enumerate() {
            let (a, b) = l.bounds();
            let c0 = ((a - lo) / cell)
                .floor()
                .max(Vec3::ZERO)
                .as_uvec3()
                .min(dims - 1);
            let c1 = ((b - lo) / cell)
                .floor()
                .max(Vec3::ZERO)
                .as_uvec3()
                .min(dims - 1);
            for y in c0.y..=c1.y {
                for z in c0.z..=c1.z {
                    for x in c0.x..=c1.x {
                        per_cell[index(UVec3::new(x, y, z))].push(i as u32);
                    }
                }
            }
        }
        let mut cells = Vec::with_capacity(count);
        let mut indices = Vec::new();
        for c in per_cell {
            cells.push([indices.len() as u32, c.len() as u32]);
            indices.extend(c);
        }
        Ok(Self {
            lights,
            origin: lo,
            cell,
            dims,
            cells,
            indices,
        })
    }

    /// The lights whose range may reach `p` (ascending indices), through the grid.
    pub fn candidates(&self, p: Vec3) -> &[u32] {
        let g = (p - self.origin) / self.cell;
        if !(g.cmpge(Vec3::ZERO).all() && g.is_finite()) {
            return &[];
        }
        let c = g.floor().as_uvec3();
        if c.cmpge(self.dims).any() {
            return &[];
        }
        let [o, n] = self.cells[(c.x + self.dims.x * (c.z + self.dims.z * c.y)) as usize];
        &self.indices[o as usize..(o + n) as usize]
    }

    /// Shading at `p` through the grid.
    pub fn shade(&self, p: Vec3, n: Vec3, v: Vec3, shininess: f32) -> DynamicShade {
        let mut s = DynamicShade::default();
        for &i in self.candidates(p) {
            let c = shade_one(&self.lights[i as usize], p, n, v, shininess);
            s.diffuse += c.diffuse;
            s.specular += c.specular;
        }
        s
    }

    /// Shading at `p` by brute force over every light (the reference).
    pub fn shade_brute_force(&self, p: Vec3, n: Vec3, v: Vec3, shininess: f32) -> DynamicShade {
        let mut s = DynamicShade::default();
        for l in &self.lights {
            let c = shade_one(l, p, n, v, shininess);
            s.diffuse += c.diffuse;
            s.specular += c.specular;
        }
        s
    }
}

/// `n` random lights in the box `lo ..= hi` (points, spots aimed down, short lines in
/// turn; ranges 1–6 m; colours up to 5): for demos, tests and benchmarks.
/// Deterministic for a seed.
pub fn scatter(n: usize, seed: u64, lo: Vec3, hi: Vec3) -> Vec<DynamicLight> {
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut r = move || rng.f32();
    (0..n)
        .map(|i| {
            let p = lo + (hi - lo) * Vec3::new(r(), r(), r());
            let kind = match i % 3 {
                0 => LightKind::Point { position: p },
                1 => LightKind::Spot {
                    position: p,
                    direction: Vec3::new(r() - 0.5, -1.0, r() - 0.5).normalize(),
                    inner: 0.9f32.acos(),
                    outer: 0.65f32.acos(),
                },
                _ => LightKind::Line {
                    a: p,
                    b: p + Vec3::new(r() * 4.0, r() * 0.5, r() * 4.0),
                },
            };
            DynamicLight {
                kind,
                colour: Vec3::new(r(), r(), r()) * 5.0,
                range: 1.0 + r() * 5.0,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lights(n: usize, seed: u64) -> Vec<DynamicLight> {
        scatter(
            n,
            seed,
            Vec3::new(-20.0, 0.0, -20.0),
            Vec3::new(20.0, 6.0, 20.0),
        )
    }

    #[test]
    fn grid_shading_equals_brute_force() {
        for (n, cell) in [(1, 2.0), (50, 1.0), (2000, 2.5), (300, 0.01)] {
            let d = DynamicLights::build(lights(n, n as u64), cell).unwrap();
            assert!(d.dims.max_element() <= MAX_CELLS_PER_AXIS);
            let mut rng = fastrand::Rng::with_seed(7);
            let mut r = move || rng.f32();
            let mut lit = 0;
            for _ in 0..3000 {
                let p = Vec3::new(r() * 50.0 - 25.0, r() * 10.0 - 2.0, r() * 50.0 - 25.0);
                let nrm = Vec3::new(r() - 0.5, 1.0, r() - 0.5).normalize();
                let v = Vec3::new(r() - 0.5, 0.5, r() - 0.5).normalize();
                let a = d.shade(p, nrm, v, 32.0);
                let b = d.shade_brute_force(p, nrm, v, 32.0);
                assert_eq!(a, b, "{n} lights at {p}");
                lit += (a.diffuse != Vec3::ZERO) as u32;
            }
            assert!(
                lit > 0,
                "{n} lights: nothing lit, the test would prove nothing"
            );
        }
    }

    #[test]
    fn point_light_known_answer_and_range() {
        let l = DynamicLight {
            kind: LightKind::Point {
                position: Vec3::new(0.0, 2.0, 0.0),
            },
            colour: Vec3::ONE,
            range: 10.0,
        };
        let s = shade_one(&l, Vec3::ZERO, Vec3::Y, Vec3::Y, 16.0);
        let w = 1.0 - (0.2f32).powi(4);
        let expect = w * w / (4.0 + FALLOFF_EPSILON);
        assert!((s.diffuse.x - expect).abs() < 1e-6, "{}", s.diffuse);
        assert_eq!(
            shade_one(&l, Vec3::new(0.0, 12.5, 0.0), Vec3::NEG_Y, Vec3::Y, 16.0),
            DynamicShade::default()
        );
        assert_eq!(
            shade_one(&l, Vec3::ZERO, Vec3::NEG_Y, Vec3::Y, 16.0),
            DynamicShade::default()
        );
    }

    #[test]
    fn bad_lights_are_typed_errors() {
        let mut l = lights(1, 3);
        l[0].range = f32::NAN;
        assert!(
            DynamicLights::build(l, 1.0)
                .unwrap_err()
                .to_string()
                .contains("lights[0].range")
        );
        assert!(
            DynamicLights::build(Vec::new(), 0.0)
                .unwrap_err()
                .to_string()
                .contains("cell")
        );
        // The shared light type: its own checks name the field under `kind`, and area
        // lights (baked only) are refused.
        let mut l = lights(2, 3);
        l[1].kind = LightKind::Spot {
            position: Vec3::ZERO,
            direction: Vec3::Y,
            inner: 0.8,
            outer: 0.4,
        };
        let e = DynamicLights::build(l, 1.0).unwrap_err().to_string();
        assert!(e.contains("lights[1].kind.outer"), "{e}");
        let mut l = lights(1, 3);
        l[0].kind = LightKind::Area {
            centre: Vec3::ZERO,
            u: Vec3::X,
            v: Vec3::Z,
        };
        let e = DynamicLights::build(l, 1.0).unwrap_err().to_string();
        assert!(e.contains("area lights are baked"), "{e}");
    }
}
