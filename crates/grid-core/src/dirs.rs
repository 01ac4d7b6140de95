//! The 26 directions, their solid-angle bins, and the 17 sweep directions.
//!
//! # Canonical order
//!
//! Direction `d` is a vector `(dx, dy, dz)` in `{-1, 0, 1}^3 \ 0`. Its index follows the
//! grid's memory order (x fastest, then z, then y), skipping the zero vector:
//!
//! ```text
//! c = (dx + 1) + 3 (dz + 1) + 9 (dy + 1)      (0..27, c = 13 is the zero vector)
//! index = c - (c > 13)
//! ```
//!
//! so bins `0..9` point down (`dy = -1`, [`DOWN`] = 4 is straight down), `9..17` are
//! horizontal (`dy = 0`) and `17..26` point up ([`UP`] = 21 is straight up).
//!
//! # Bins
//!
//! Bin `d` is the part of the unit sphere nearer (by angle) to `d`'s unit vector than to
//! any other of the 26: a convex spherical polygon bounded by great circles. Its solid
//! angle `omega_d` is computed exactly (the polygon is clipped in the gnomonic projection,
//! where great circles are straight lines, then split into triangles whose solid angles
//! have a closed form). The 26 weights sum to `4 pi`; by symmetry there are three distinct
//! values (6 axis, 12 edge, 8 corner bins). The first moment `∫ ω dω` and the clipped
//! cosine integral `∫ max(0, n·ω) dω` of each bin are exact too (Lambert's formula for
//! polygons), which makes irradiance from 26 bins exact for light that is constant
//! within each bin.

use std::sync::OnceLock;

use glam::{DVec3, IVec3, Vec3};

/// Number of directions (bins).
pub const NUM_DIRS: usize = 26;
/// Index of straight down, `(0, -1, 0)`.
pub const DOWN: usize = 4;
/// Index of straight up, `(0, 1, 0)`.
pub const UP: usize = 21;
/// Number of directions the downward sweep gathers from.
pub const NUM_SWEEP_DIRS: usize = 17;
/// Index of the first horizontal bin (`dy = 0`): bins `9..17` are horizontal.
pub const FIRST_HORIZONTAL: usize = 9;
/// Number of horizontal bins.
pub const HORIZONTAL_BINS: usize = 8;
/// How many points a near-horizontal sweep path moves sideways per level.
pub const HORIZONTAL_STEP: i32 = 4;

/// The integer vector of direction `d` (`d < 26`).
pub const fn dir_ivec(d: usize) -> IVec3 {
    let c = if d < 13 { d } else { d + 1 } as i32;
    IVec3::new(c % 3 - 1, c / 9 - 1, (c / 3) % 3 - 1)
}

/// The index of integer direction `v` (each component in -1..=1, not all zero).
pub const fn dir_index(v: IVec3) -> Option<usize> {
    if v.x < -1 || v.x > 1 || v.y < -1 || v.y > 1 || v.z < -1 || v.z > 1 {
        return None;
    }
    let c = ((v.x + 1) + 3 * (v.z + 1) + 9 * (v.y + 1)) as usize;
    if c == 13 {
        None
    } else if c > 13 {
        Some(c - 1)
    } else {
        Some(c)
    }
}

/// Index of the opposite direction `-d`.
pub const fn opposite(d: usize) -> usize {
    NUM_DIRS - 1 - d
}

/// Unit vector of direction `d` (`d < 26`).
#[inline]
pub fn dir_unit(d: usize) -> Vec3 {
    units()[d]
}

/// The 26 unit vectors in canonical order.
pub fn units() -> &'static [Vec3; NUM_DIRS] {
    static U: OnceLock<[Vec3; NUM_DIRS]> = OnceLock::new();
    U.get_or_init(|| std::array::from_fn(|d| dir_ivec(d).as_vec3().normalize()))
}

/// One of the 17 directions the downward sweep gathers from.
///
/// A point on level `j` receives the light that left point `p - step` on level `j + 1`
/// travelling along `step`, and accounts it in bin `bin`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepDir {
    /// The bin this light is accounted in (`0..17`, the 9 downward and 8 horizontal bins).
    pub bin: usize,
    /// Offset from the source point to the receiving point, in points: `y = -1` always;
    /// `(dx, -1, dz)` for the 9 downward bins, `(4 dx, -1, 4 dz)` for the 8 horizontal ones.
    pub step: IVec3,
    /// Path length of one step in units of `h`: `|step|` (1, √2, √3, √17 or √33).
    /// Its inverse is `|cos|` of the path to the vertical, which converts light a bin holds
    /// into flux through a level.
    pub length: f32,
}

/// The 17 sweep directions, in bin order (`SWEEP_DIRS[i].bin == i`).
pub fn sweep_dirs() -> &'static [SweepDir; NUM_SWEEP_DIRS] {
    static T: OnceLock<[SweepDir; NUM_SWEEP_DIRS]> = OnceLock::new();
    T.get_or_init(|| {
        std::array::from_fn(|bin| {
            let v = dir_ivec(bin);
            let step = if v.y == 0 {
                IVec3::new(v.x * HORIZONTAL_STEP, -1, v.z * HORIZONTAL_STEP)
            } else {
                v
            };
            SweepDir {
                bin,
                step,
                length: step.as_vec3().length(),
            }
        })
    })
}

/// Exact geometry of the 26 bins, computed once in `f64`.
#[derive(Debug)]
pub struct BinGeometry {
    /// Vertices of each bin's spherical polygon (unit vectors, counter-clockwise seen from
    /// outside the sphere).
    pub polygons: [Vec<DVec3>; NUM_DIRS],
    /// Solid angle of each bin, steradians. Sums to `4 pi`.
    pub omega: [f64; NUM_DIRS],
    /// First moment `∫_bin ω dω` of each bin.
    pub moment: [DVec3; NUM_DIRS],
}

/// The bin geometry (computed on first use, about a millisecond).
pub fn bins() -> &'static BinGeometry {
    static G: OnceLock<BinGeometry> = OnceLock::new();
    G.get_or_init(|| {
        let polygons: [Vec<DVec3>; NUM_DIRS] = std::array::from_fn(bin_polygon);
        let omega = std::array::from_fn(|d| polygon_solid_angle(&polygons[d]));
        let moment = std::array::from_fn(|d| polygon_moment(&polygons[d]));
        BinGeometry {
            polygons,
            omega,
            moment,
        }
    })
}

/// Solid-angle weights of the 26 bins as `f32` (sum to `4 pi` within `f32` rounding).
pub fn solid_angles() -> &'static [f32; NUM_DIRS] {
    static W: OnceLock<[f32; NUM_DIRS]> = OnceLock::new();
    W.get_or_init(|| bins().omega.map(|w| w as f32))
}

/// `∫_{bin d} max(0, n·ω) dω` for unit `n`: the cosine-weighted solid angle of the part of
/// bin `d` facing `n`. Exact (clip against the hemisphere, then Lambert's formula).
pub fn clipped_cosine(d: usize, n: DVec3) -> f64 {
    let g = bins();
    let poly = &g.polygons[d];
    let mut any_in = false;
    let mut any_out = false;
    for v in poly {
        let s = n.dot(*v);
        any_in |= s > 0.0;
        any_out |= s < 0.0;
    }
    if !any_in {
        return 0.0;
    }
    if !any_out {
        return n.dot(g.moment[d]);
    }
    let clipped = clip(poly, n);
    n.dot(polygon_moment(&clipped)).max(0.0)
}

/// Solid angle and first moment `∫ ω dω` of the part of bin `d` on the positive side of
/// every plane in `planes` (each a normal through the origin): for example the
/// downward-travelling half of a horizontal bin (`planes = [-Y]`), or the part of it that
/// enters a face with inward normal `n` (`[-Y, n]`).
pub fn bin_region(d: usize, planes: &[DVec3]) -> (f64, DVec3) {
    let mut poly = bins().polygons[d].clone();
    for p in planes {
        if poly.len() < 3 {
            break;
        }
        poly = clip(&poly, *p);
    }
    if poly.len() < 3 {
        return (0.0, DVec3::ZERO);
    }
    (polygon_solid_angle(&poly), polygon_moment(&poly))
}

/// The nearest of the 26 directions to `v` (any non-zero vector): the bin containing it.
pub fn nearest_dir(v: Vec3) -> usize {
    let u = units();
    let mut best = 0;
    let mut best_dot = f32::NEG_INFINITY;
    for d in 0..NUM_DIRS {
        let dot = u[d].dot(v);
        if dot > best_dot {
            best_dot = dot;
            best = d;
        }
    }
    best
}

fn dunit(d: usize) -> DVec3 {
    dir_ivec(d).as_dvec3().normalize()
}

/// Sutherland–Hodgman clip of a convex polygon (points on any rays from the origin) to the
/// half-space `plane · x >= 0`.
fn clip(poly: &[DVec3], plane: DVec3) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let p = poly[i];
        let q = poly[(i + 1) % poly.len()];
        let fp = plane.dot(p);
        let fq = plane.dot(q);
        if fp >= 0.0 {
            out.push(p);
        }
        if (fp >= 0.0) != (fq >= 0.0) {
            let t = fp / (fp - fq);
            out.push(p + (q - p) * t);
        }
    }
    // Normalise and drop repeated vertices (clips through a vertex produce them).
    let mut res: Vec<DVec3> = Vec::with_capacity(out.len());
    for v in out {
        let v = v.normalize();
        if res.last().is_none_or(|l| l.distance(v) > 1e-12) {
            res.push(v);
        }
    }
    while res.len() > 1 && res[0].distance(*res.last().unwrap()) <= 1e-12 {
        res.pop();
    }
    res
}

fn bin_polygon(d: usize) -> Vec<DVec3> {
    let a = dunit(d);
    let t1 = a.any_orthonormal_vector();
    let t2 = a.cross(t1); // (t1, t2, a) right-handed: counter-clockwise seen from outside.
    // A square on the tangent plane that contains the whole bin (every bin lies within 45°
    // of its centre; the square reaches at least 63°).
    let mut poly: Vec<DVec3> = [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)]
        .iter()
        .map(|&(u, v)| a + t1 * u + t2 * v)
        .collect();
    for b in 0..NUM_DIRS {
        if b != d {
            poly = clip(&poly, a - dunit(b));
        }
    }
    poly
}

/// Solid angle of a convex spherical polygon (fan of Van Oosterom–Strackee triangles).
fn polygon_solid_angle(poly: &[DVec3]) -> f64 {
    let mut sum = 0.0;
    for i in 1..poly.len().saturating_sub(1) {
        sum += triangle_solid_angle(poly[0], poly[i], poly[i + 1]);
    }
    sum
}

/// Signed solid angle of the spherical triangle of unit vectors `a, b, c`.
pub(crate) fn triangle_solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let num = a.dot(b.cross(c));
    let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    2.0 * num.atan2(den)
}

/// `∫_P ω dω` over a spherical polygon (Lambert): `1/2 Σ θ_i (v_i × v_{i+1}) / |v_i × v_{i+1}|`.
fn polygon_moment(poly: &[DVec3]) -> DVec3 {
    let mut sum = DVec3::ZERO;
    for i in 0..poly.len() {
        let p = poly[i];
        let q = poly[(i + 1) % poly.len()];
        let cross = p.cross(q);
        let len = cross.length();
        if len > 0.0 {
            sum += cross / len * len.atan2(p.dot(q));
        }
    }
    0.5 * sum
}

/// The cells a channel of direction `v` (a bin's integer vector, [`dir_ivec`]) crosses
/// within one level, in travel order: `(dx, dz, fraction)` of each, its offset from
/// the receiving point's own cell and its share of the channel's path length per level
/// ([`channel_length`]). A horizontal channel crosses five cells along its direction
/// (an eighth, three quarters and an eighth of its length: the point's own cell holds
/// a quarter); any other crosses its own cell alone. The sweeps' stencils and the
/// carry of a halo through its cells ([`crate::halo_carry`]) read it.
pub fn level_stencil(v: IVec3) -> Vec<(i32, i32, f32)> {
    if v.y == 0 {
        let (dx, dz) = (v.x, v.z);
        vec![
            (-2 * dx, -2 * dz, 0.125),
            (-dx, -dz, 0.25),
            (0, 0, 0.25),
            (dx, dz, 0.25),
            (2 * dx, 2 * dz, 0.125),
        ]
    } else {
        vec![(0, 0, 1.0)]
    }
}

/// [`channel_length`] of any bin: an upward bin's is its downward mirror's, as the
/// upward pass mirrors the downward one.
pub fn bin_channel_length(bin: usize) -> f32 {
    let mut v = dir_ivec(bin.min(NUM_DIRS - 1));
    v.y = -v.y.abs();
    channel_length(dir_index(v).expect("a direction mirrored is one"))
}

/// Path length per level (in `h`) of the channels of bin `bin` (a downward or
/// horizontal bin; the upward pass mirrors them): `1 / μ̄`, where `μ̄` is the bin's mean
/// `|cos|` to the vertical over its solid angle (a horizontal bin's downward half). A
/// channel's flux per unit of light, `μ_c = 1 / ℓ_c`, is then the exact flux of light
/// constant within the bin, and its transmittance through a thin layer is the bin's
/// mean. (The step vector's own length, `ℓ = |s_c|`, overstates `μ` by 5 % on the
/// vertical bin and 30 % on the horizontal ones: the half-space albedo came out 5.5 %
/// too high with thin cells, `w = 0.5`; measured in issue 13 with `lightgrid-measure`'s `examples/do1d.rs`.)
pub fn channel_length(bin: usize) -> f32 {
    static L: OnceLock<[f32; NUM_SWEEP_DIRS]> = OnceLock::new();
    L.get_or_init(|| {
        let g = bins();
        std::array::from_fn(|b| {
            let omega = if dir_unit(b).y == 0.0 {
                0.5 * g.omega[b]
            } else {
                g.omega[b]
            };
            (omega / clipped_cosine(b, -DVec3::Y)) as f32
        })
    })[bin]
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// `n` nearly uniform unit vectors (Fibonacci lattice), each standing for `4 pi / n`
    /// steradians: an integration rule independent of the bin polygons.
    pub(crate) fn fibonacci_sphere(n: usize) -> impl Iterator<Item = Vec3> {
        let golden = PI * (3.0 - 5f64.sqrt());
        (0..n).map(move |i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).sqrt();
            let phi = golden * i as f64;
            Vec3::new((r * phi.cos()) as f32, y as f32, (r * phi.sin()) as f32)
        })
    }

    #[test]
    fn order_and_index_round_trip() {
        for d in 0..NUM_DIRS {
            let v = dir_ivec(d);
            assert_ne!(v, IVec3::ZERO);
            assert_eq!(dir_index(v), Some(d));
            assert_eq!(dir_ivec(opposite(d)), -v);
        }
        assert_eq!(dir_ivec(DOWN), IVec3::NEG_Y);
        assert_eq!(dir_ivec(UP), IVec3::Y);
        assert_eq!(dir_index(IVec3::ZERO), None);
        assert_eq!(dir_index(IVec3::new(2, 0, 0)), None);
        assert!((0..9).all(|d| dir_ivec(d).y == -1));
        assert!((9..17).all(|d| dir_ivec(d).y == 0));
        assert!((17..26).all(|d| dir_ivec(d).y == 1));
    }

    /// Independent check: a Fibonacci lattice of 4 million points over the sphere, each
    /// assigned to the nearest direction by brute force.
    #[test]
    fn solid_angles_match_independent_sphere_integration() {
        let n = 4_000_000usize;
        let mut counts = [0usize; NUM_DIRS];
        for v in fibonacci_sphere(n) {
            counts[nearest_dir(v)] += 1;
        }
        let g = bins();
        for d in 0..NUM_DIRS {
            let mc = counts[d] as f64 / n as f64 * 4.0 * PI;
            assert!(
                (mc - g.omega[d]).abs() < 2e-4,
                "bin {d}: exact {} vs lattice {mc}",
                g.omega[d]
            );
        }
        let total: f64 = g.omega.iter().sum();
        assert!((total - 4.0 * PI).abs() < 1e-12, "sum {total}");
        let total32: f32 = solid_angles().iter().sum();
        assert!((total32 - 4.0 * std::f32::consts::PI).abs() < 1e-5);
    }

    #[test]
    fn three_symmetry_classes() {
        let g = bins();
        let class = |d: usize| dir_ivec(d).abs().element_sum();
        for a in 0..NUM_DIRS {
            for b in 0..NUM_DIRS {
                if class(a) == class(b) {
                    assert!((g.omega[a] - g.omega[b]).abs() < 1e-12);
                }
            }
        }
        // Axis bins are the largest, corner bins the smallest.
        assert!(g.omega[DOWN] > g.omega[dir_index(IVec3::new(1, -1, 0)).unwrap()]);
        assert!(g.omega[0] < g.omega[dir_index(IVec3::new(1, -1, 0)).unwrap()]);
    }

    #[test]
    fn moments_point_at_their_direction_and_cancel() {
        let g = bins();
        let mut sum = DVec3::ZERO;
        for d in 0..NUM_DIRS {
            let m = g.moment[d];
            sum += m;
            // Mean cosine inside the bin: below 1, above cos(45°).
            let mean_cos = m.length() / g.omega[d];
            assert!(mean_cos < 1.0 && mean_cos > 0.7, "bin {d}: {mean_cos}");
            assert!(m.normalize().dot(dunit(d)) > 1.0 - 1e-12);
        }
        assert!(sum.length() < 1e-12);
    }

    #[test]
    fn clipped_cosine_sums_to_pi_for_any_normal() {
        for n in [
            DVec3::Y,
            DVec3::NEG_X,
            DVec3::new(0.3, -0.5, 0.8).normalize(),
            DVec3::new(1.0, 1.0, 1e-9).normalize(),
        ] {
            let s: f64 = (0..NUM_DIRS).map(|d| clipped_cosine(d, n)).sum();
            assert!((s - PI).abs() < 1e-12, "n {n}: {s}");
        }
        // A bin fully behind the normal contributes nothing; fully in front, n·moment.
        assert_eq!(clipped_cosine(DOWN, DVec3::Y), 0.0);
        assert!((clipped_cosine(UP, DVec3::Y) - bins().moment[UP].y).abs() < 1e-15);
    }

    #[test]
    fn bin_regions_split_exactly() {
        let g = bins();
        for d in 0..NUM_DIRS {
            let (lo, _) = bin_region(d, &[DVec3::NEG_Y]);
            let (hi, _) = bin_region(d, &[DVec3::Y]);
            assert!((lo + hi - g.omega[d]).abs() < 1e-12, "bin {d}");
            match dir_ivec(d).y {
                -1 => assert!((lo - g.omega[d]).abs() < 1e-12),
                1 => assert!(lo.abs() < 1e-12),
                _ => assert!((lo - hi).abs() < 1e-12), // symmetric about the horizon
            }
            let (w, m) = bin_region(d, &[]);
            assert!((w - g.omega[d]).abs() < 1e-12 && (m - g.moment[d]).length() < 1e-12);
        }
    }

    #[test]
    fn sweep_dirs_map_onto_the_first_17_bins() {
        let s = sweep_dirs();
        assert_eq!(s[DOWN].step, IVec3::NEG_Y);
        for (i, sd) in s.iter().enumerate() {
            assert_eq!(sd.bin, i);
            assert_eq!(sd.step.y, -1);
            // Each path's direction lies in the bin it is accounted in.
            assert_eq!(nearest_dir(sd.step.as_vec3()), sd.bin);
            assert!((sd.length - sd.step.as_vec3().length()).abs() < 1e-6);
        }
        assert_eq!(
            s[dir_index(IVec3::new(1, 0, 1)).unwrap()].step,
            IVec3::new(4, -1, 4)
        );
    }
}
