//! Diffusion synthetic acceleration of the passes ([`Acceleration::Diffusion`],
//! issue 13).
//!
//! The passes are source iteration: each emits what the passes before it scattered, so
//! in a thick medium of albedo near 1 the light still waiting falls slowly (a slab of
//! optical depth 100, albedo 0.99: 264 passes to 1e-4; albedo 0.999: over 1000).
//! Discrete-ordinates codes estimate every later generation of the scattering at once
//! by diffusion, and so does the sweep here, in five parts:
//!
//! 1. **When.** The passes run plain while they converge fast; from the first pair of
//!    passes after which the light waiting is more than [`SWITCH`] of what waited
//!    after the pair before, they run accelerated. Scenes that converge in a few
//!    passes (dark foliage, ground) never switch, and get the plain sweep's light bit
//!    for bit.
//! 2. **One generation per pair.** Accelerated, a medium cell emits in a pair of passes
//!    only what waited before it; what collides during the pair waits for the next
//!    (the plain passes emit half of it at once, which diffusion cannot model).
//! 3. **The estimate.** After each pair, the light waiting in media cell `c`, `q_c`
//!    (both directions' shares), is smoothed ([`SMOOTHING`] rounds of a 1-2-1 filter
//!    along each axis, over media cells) and its later generations solved for, per
//!    colour, by conjugate gradients over the media cells (`h` = 1, `τ_c = −ln p_c`):
//!
//!    ```text
//!    Σ_faces K_f (φ_c − φ_n) + Σ_open faces B_f φ_c + (1 − a_c e_c) τ_c φ_c = q_c
//!    δ_c = a_c e_c τ_c φ_c
//!    K_f = 2 D_c D_n / (D_c + D_n)                (along the face's axis)
//!    D_c = max(1 / (3 τ_c), τ_c a_c e_c s_axis)
//!    B_f = max(2 D / (1 + 4 D) with D = 1 / (3 τ_c), τ_c e_c s_f)
//!    ```
//!
//!    `e_c = G / (G + (1 − a) K)` is the part of a cell's emission that leaves it (the
//!    sweep scatters what the cell's own material stops again at once,
//!    [`crate::medium`]), and `s_f` the share of it leaving through face `f` in the
//!    sweep's own paths (top and bottom: vertical and diagonal channels; each side: a
//!    quarter of the horizontal ones). Thin cells diffuse (`D = 1/(3τ)`, Marshak's
//!    vacuum condition on faces to anything that is not medium); in cells thicker than
//!    about 1 the sweep's flat source moves light one cell per generation, faster than
//!    diffusion would, and the walk's coefficients take over. Surfaces, empty cells and
//!    the grid's open sides are vacuum to the estimate (periodic sides wrap).
//! 4. **Damping.** Of the light waiting, `ω` = [`DAMPING`] is emitted in the next pair
//!    with the estimate `δ`; the rest is held back a pair. Cell-to-cell alternating
//!    patterns, which a pair turns over (a thick cell's light lands in its
//!    neighbours), would otherwise decay slowly or, with the estimate's help, grow.
//! 5. **Taking back.** After the next pair has emitted `δ` it is taken back: what
//!    waits is then `N − δ`, with `N` what the pair's emission scattered. The sweep is
//!    linear, so whatever `δ` is the passes sum to the same converged light; a good `δ`
//!    leaves little for the passes after it. Light taken back can make a cell's waiting
//!    light negative: accelerated passes emit negative light as readily as positive (no
//!    clamping at 0 in them), the convergence test takes every cell's waiting light at
//!    its absolute value, and the final light is clamped at 0 (a point in the dark may
//!    be off by up to the tolerance).
//!
//! Measured (`cargo xtask exact`, tolerance 1e-4, cells of optical depth 1): passes
//! 8 / 18 / 20 / 26 at albedo 0.5 / 0.9 / 0.99 / 0.999 for slabs of optical depth 10
//! to 1000, where the plain passes take 8 / 33 / 264 / over 1000. Cost: a conjugate
//! gradient solve over the media cells per pair (a 7-point stencil; tens of
//! iterations), small against a pass over every point.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{Acceleration, MaterialGrid, MediumEmission, SweepOptions};

/// A sweep runs accelerated from the first pair of passes after which the light
/// waiting is more than this fraction of what waited after the pair before: plain
/// passes converge fast enough below it.
pub const SWITCH: f64 = 0.6;

/// The share of the diffusion estimate added (step 3): diffusion over a few cells of
/// optical depth about 1 (a small cloud) foresees up to 2.5 times the later
/// generations the passes then find, and a full estimate would overshoot there.
pub const GAIN: f32 = 0.7;

/// Share of the waiting light an accelerated pair emits (step 4 of the module docs).
pub const DAMPING: f32 = 0.7;

/// Rounds of the 1-2-1 filter over the waiting light before the diffusion estimate
/// (step 3): alternating patterns, which diffusion would overestimate, do not reach it.
pub const SMOOTHING: usize = 2;

/// How a flat source in a medium cell of `ln(pass)` `lnp` leaves it in the sweep's
/// paths ([`crate::medium`]), over both passes.
#[derive(Debug, Clone, Copy)]
struct Faces {
    /// What a unit source sends out of the cell's segments, `G`, and what the cell's
    /// own material stops of it, `K`.
    g: f32,
    k: f32,
    /// Shares of `G` leaving through the top, the bottom (vertical and diagonal
    /// channels, whose paths cross only their own cell's level) and each of the four
    /// sides (horizontal channels).
    up: f32,
    down: f32,
    side: f32,
}

fn faces(lnp: f32) -> Faces {
    let exps = crate::sweep::path_exponents();
    let omega = lightgrid_core::dirs::solid_angles();
    let (mut up, mut down, mut side, mut o) = (0f32, 0f32, 0f32, 0f32);
    for pass_up in [false, true] {
        for chn in crate::sweep::channels(pass_up) {
            let om = omega[chn.bin] * chn.share;
            o += om * -lnp;
            let g: f32 = chn
                .pow
                .iter()
                .map(|&e| chn.mu * om * (1.0 - (exps[e] * lnp).exp()))
                .sum();
            if chn.pow.len() > 1 {
                side += g;
            } else if pass_up {
                up += g;
            } else {
                down += g;
            }
        }
    }
    let g = up + down + side;
    let k = (o - g).max(0.0);
    let n = g.max(f32::MIN_POSITIVE);
    Faces {
        g,
        k,
        up: up / n,
        down: down / n,
        side: side / n / 4.0,
    }
}

/// The optical depth the estimate gives an empty cell beside media (its diffusion
/// coefficient `1 / (3 GAP_TAU)`: light crosses it all but freely).
const GAP_TAU: f32 = 0.1;

/// The six face neighbours' offsets, in the order of [`Diffusion`]'s neighbour slots
/// (face `f` lies on axis `f / 2`).
const FACES: [[i32; 3]; 6] = [
    [-1, 0, 0],
    [1, 0, 0],
    [0, -1, 0],
    [0, 1, 0],
    [0, 0, -1],
    [0, 0, 1],
];

/// No neighbour: the face is open (vacuum).
const OPEN: u32 = u32::MAX;

/// The diffusion problem of a material grid's media cells.
#[derive(Debug, Clone)]
pub struct Diffusion {
    /// Grid index of each cell of the estimate: the media cells, then the empty
    /// cells beside them.
    pub cells: Vec<u32>,
    /// How many of `cells` are media cells.
    pub media: usize,
    /// Per grid cell: its slot in `cells`, or `u32::MAX`.
    pub slot: Vec<u32>,
    /// Per media cell: its six neighbours' slots in `cells` (`OPEN` where the
    /// neighbour is no medium cell, or the face is a grid side that does not wrap).
    nb: Vec<[u32; 6]>,
    /// Per media cell: `K_f` to each neighbour (0 for open faces), per colour.
    k: Vec<[Vec3; 6]>,
    /// Per media cell: the diagonal `Σ K_f + Σ B_c + (1 − a) τ`, per colour.
    diag: Vec<Vec3>,
    /// Per media cell: `a τ` (what a unit of `φ` scatters), per colour.
    scatter: Vec<Vec3>,
    /// Relative residual the solve stops at.
    tolerance: f32,
}

/// What a correction did.
#[derive(Debug, Clone, Copy, Default)]
pub struct Correction {
    /// Conjugate-gradient iterations of the solve (the most of the three colours).
    pub iterations: u32,
}

impl Diffusion {
    /// The diffusion problem of `material`'s media cells under `options`, or `None` when
    /// acceleration is off, the medium rule is not [`MediumEmission::Source`], or the
    /// grid holds no scattering medium. `periodic`: the sides wrap.
    pub fn of(material: &MaterialGrid, periodic: bool, options: &SweepOptions) -> Option<Self> {
        if options.acceleration != Acceleration::Diffusion
            || options.medium != MediumEmission::Source
        {
            return None;
        }
        let desc = material.desc();
        let data = material.data();
        let is_medium = |m: &lightgrid_core::Material| {
            m.pass > 0.0 && m.pass < 1.0 && m.reflectance.max_element() > 0.0
        };
        let mut slot = vec![OPEN; data.len()];
        let mut cells = Vec::new();
        for (i, m) in data.iter().enumerate() {
            if is_medium(m) {
                slot[i] = cells.len() as u32;
                cells.push(i as u32);
            }
        }
        if cells.is_empty() {
            return None;
        }
        let media = cells.len();
        let dims = desc.dims().as_ivec3();
        let neighbour = |i: usize, off: [i32; 3]| -> Option<usize> {
            let mut q = desc.coords(i).expect("in range").as_ivec3()
                + lightgrid_core::glam::IVec3::from(off);
            if periodic {
                q.x = q.x.rem_euclid(dims.x);
                q.z = q.z.rem_euclid(dims.z);
            }
            let inside = q.cmpge(lightgrid_core::glam::IVec3::ZERO).all() && q.cmplt(dims).all();
            inside
                .then(|| desc.index(UVec3::new(q.x as u32, q.y as u32, q.z as u32)))
                .flatten()
                .filter(|&j| j != i)
        };
        // The empty cells beside media join them: light crosses a gap between media
        // cells (foliage, a broken cloud) and collides on the other side.
        for c in 0..media {
            for off in FACES {
                if let Some(j) = neighbour(cells[c] as usize, off)
                    && slot[j] == OPEN
                    && data[j].is_empty()
                {
                    slot[j] = cells.len() as u32;
                    cells.push(j as u32);
                }
            }
        }
        // Per cell: optical depth, the scattering the passes see per collision
        // `a e`, and the diffusion coefficient.
        let props: Vec<(f32, Vec3, Vec3, [Vec3; 3], Faces)> = cells
            .iter()
            .map(|&ci| {
                let m = &data[ci as usize];
                if m.is_empty() {
                    // Free flight: nothing collides, light crosses at once.
                    let d = Vec3::splat(1.0 / (3.0 * GAP_TAU));
                    let f = faces(-GAP_TAU);
                    return (GAP_TAU, Vec3::ZERO, Vec3::ZERO, [d; 3], f);
                }
                let lnp = m.pass.ln();
                let t = -lnp;
                let f = faces(lnp);
                let a = m.reflectance;
                // The sweep scatters what a cell's own material stops of its source
                // again at once ([`crate::medium`]), so of the waiting light a cell
                // emits, `e = G / (G + (1 − a) K)` leaves it: the later generations the
                // passes see scatter `a e` per collision, not `a`.
                let e = Vec3::splat(f.g) / (Vec3::splat(f.g) + (Vec3::ONE - a) * f.k);
                // Light leaving a thick cell collides in the next one: a walk of one
                // cell per generation, through the top and bottom (vertical and
                // diagonal channels) or the four sides (horizontal channels) in the
                // shares `f` of the sweep's own paths, which spreads faster than
                // diffusion (`D = 1 / 3τ`) once `τ` ≳ 1.
                let walk_d = |share: f32| Vec3::splat(1.0 / (3.0 * t)).max(t * a * e * share);
                let d = [
                    walk_d(f.side),
                    walk_d(0.5 * (f.up + f.down)),
                    walk_d(f.side),
                ];
                (t, a * e, e, d, f)
            })
            .collect();
        let mut nb = Vec::with_capacity(cells.len());
        let mut k = Vec::with_capacity(cells.len());
        let mut diag = Vec::with_capacity(cells.len());
        let mut scatter = Vec::with_capacity(cells.len());
        for (c, &ci) in cells.iter().enumerate() {
            let i = ci as usize;
            let (t, ae, e, dc, fc) = props[c];
            let mut n6 = [OPEN; 6];
            let mut k6 = [Vec3::ZERO; 6];
            let mut d = Vec3::ZERO;
            for (f, off) in FACES.into_iter().enumerate() {
                let j = neighbour(i, off).filter(|&j| slot[j] != OPEN);
                match j {
                    Some(j) => {
                        // The harmonic mean of the two cells' coefficients over the face.
                        let axis = f / 2;
                        let (dca, dn) = (dc[axis], props[slot[j] as usize].3[axis]);
                        let kf = 2.0 * dca * dn / (dca + dn);
                        n6[f] = slot[j];
                        k6[f] = kf;
                        d += kf;
                    }
                    None => {
                        // Marshak's vacuum condition, or the walk's share through the
                        // face for thick cells.
                        let dp = 1.0 / (3.0 * t);
                        let b = 2.0 * dp / (1.0 + 4.0 * dp);
                        let share = match f {
                            2 => fc.down,
                            3 => fc.up,
                            _ => fc.side,
                        };
                        d += Vec3::splat(b).max(t * e * share);
                    }
                }
            }
            nb.push(n6);
            k.push(k6);
            // An empty cell absorbs nothing and scatters nothing.
            let gap = c >= media;
            diag.push(if gap { d } else { d + (Vec3::ONE - ae) * t });
            scatter.push(if gap { Vec3::ZERO } else { ae * t });
        }
        Some(Self {
            cells,
            media,
            slot,
            nb,
            k,
            diag,
            scatter,
            tolerance: 1e-4,
        })
    }

    fn apply(&self, x: &[Vec3], out: &mut [Vec3]) {
        for (c, o) in out.iter_mut().enumerate() {
            let mut v = self.diag[c] * x[c];
            for f in 0..6 {
                let n = self.nb[c][f];
                if n != OPEN {
                    v -= self.k[c][f] * x[n as usize];
                }
            }
            *o = v;
        }
    }

    /// The later generations `δ` of waiting light `q` (per media cell, in the order of
    /// [`Diffusion::cells`]), written to `delta`. Linear in `q`; `q ≥ 0` gives `δ ≥ 0`.
    pub fn correct(&self, q: &[Vec3], delta: &mut [Vec3]) -> Correction {
        let n = self.cells.len();
        let mut sq = q.to_vec();
        let mut tmp = vec![Vec3::ZERO; n];
        for _ in 0..SMOOTHING {
            for axis in 0..3 {
                for c in 0..n {
                    let mut v = 2.0 * sq[c];
                    let mut w = 2.0;
                    for f in [2 * axis, 2 * axis + 1] {
                        let nb = self.nb[c][f];
                        if nb != OPEN {
                            v += sq[nb as usize];
                            w += 1.0;
                        }
                    }
                    tmp[c] = v / w;
                }
                std::mem::swap(&mut sq, &mut tmp);
            }
        }
        let q = &sq[..];
        // Jacobi-preconditioned conjugate gradients, the three colours side by side.
        let mut x = vec![Vec3::ZERO; n];
        let mut r = q.to_vec();
        let mut z: Vec<Vec3> = r.iter().zip(&self.diag).map(|(r, d)| *r / *d).collect();
        let mut p = z.clone();
        let mut ap = vec![Vec3::ZERO; n];
        let dot = |a: &[Vec3], b: &[Vec3]| -> Vec3 {
            a.iter()
                .zip(b)
                .map(|(a, b)| (*a * *b).as_dvec3())
                .sum::<lightgrid_core::glam::DVec3>()
                .as_vec3()
        };
        let norm0 = dot(&r, &r);
        let stop = norm0 * self.tolerance * self.tolerance;
        let mut rz = dot(&r, &z);
        let mut iterations = 0;
        let limit = 50 + 20 * n as u32;
        while iterations < limit.min(4000) {
            let rr = dot(&r, &r);
            if rr.cmple(stop).all() {
                break;
            }
            iterations += 1;
            self.apply(&p, &mut ap);
            let pap = dot(&p, &ap);
            let alpha = Vec3::select(pap.cmpgt(Vec3::ZERO), rz / pap, Vec3::ZERO);
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * ap[i];
                z[i] = r[i] / self.diag[i];
            }
            let rz_new = dot(&r, &z);
            let beta = Vec3::select(rz.cmpgt(Vec3::ZERO), rz_new / rz, Vec3::ZERO);
            rz = rz_new;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
        for i in 0..n {
            let d = self.scatter[i] * x[i];
            delta[i] = if d.is_finite() { d } else { Vec3::ZERO };
        }
        Correction { iterations }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::{GridDesc, Material};

    fn slab(a: f32, pass: f32, levels: u32) -> MaterialGrid {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, levels, 2)).expect("valid");
        MaterialGrid::filled(
            d,
            Material {
                reflectance: Vec3::splat(a),
                pass,
            },
        )
        .expect("valid")
    }

    fn on() -> SweepOptions {
        let mut o = SweepOptions::multi_bounce();
        o.acceleration = Acceleration::Diffusion;
        o
    }

    #[test]
    fn an_infinite_medium_gets_every_later_generation() {
        // Periodic sides and a thick slab: the middle is an infinite medium, where the
        // later generations the passes see of a uniform q are q (b + b² + ...) =
        // q b / (1 − b), b = a e (what leaves a cell of what it emits, scattered).
        let a = 0.9;
        let d = Diffusion::of(&slab(a, 0.5, 400), true, &on()).expect("media");
        let f = faces(0.5f32.ln());
        let b = a * f.g / (f.g + (1.0 - a) * f.k);
        assert!(b < a && b > 0.5 * a, "{b}");
        let q = vec![Vec3::ONE; d.cells.len()];
        let mut delta = vec![Vec3::ZERO; q.len()];
        d.correct(&q, &mut delta);
        let mid = delta[delta.len() / 2].x;
        let want = b / (1.0 - b);
        assert!((mid - want).abs() < 1e-3 * want, "{mid} against {want}");
        // Near the open top and bottom less comes back.
        assert!(delta[0].x < 0.7 * mid);
    }

    #[test]
    fn faces_share_what_leaves() {
        for lnp in [-0.05f32, -0.69, -3.0, -10.0] {
            let f = faces(lnp);
            assert!((f.up + f.down + 4.0 * f.side - 1.0).abs() < 1e-5, "{f:?}");
            assert!((f.up - f.down).abs() < 1e-5, "{f:?}");
            // A thin cell lets most of its source out, a thick one stops most.
            assert!(f.g > 0.0 && f.k >= 0.0);
        }
        assert!(faces(-0.05).k < 0.1 * faces(-0.05).g);
        assert!(faces(-10.0).k > 3.0 * faces(-10.0).g);
    }

    #[test]
    fn off_or_without_media_there_is_nothing_to_solve() {
        assert!(Diffusion::of(&slab(0.9, 0.5, 4), true, &SweepOptions::multi_bounce()).is_none());
        assert!(Diffusion::of(&slab(0.9, 1.0, 4), true, &on()).is_none());
        assert!(Diffusion::of(&slab(0.9, 0.0, 4), true, &on()).is_none());
        let mut escape = on();
        escape.medium = MediumEmission::Escape;
        assert!(Diffusion::of(&slab(0.9, 0.5, 4), true, &escape).is_none());
    }

    #[test]
    fn corrections_are_linear_and_positive() {
        let d = Diffusion::of(&slab(0.7, 0.3, 12), false, &on()).expect("media");
        let n = d.cells.len();
        let q1: Vec<Vec3> = (0..n).map(|i| Vec3::splat((i % 5) as f32)).collect();
        let q2: Vec<Vec3> = (0..n)
            .map(|i| Vec3::new(1.0, (i % 3) as f32, 0.5))
            .collect();
        let (mut d1, mut d2, mut d12) = (
            vec![Vec3::ZERO; n],
            vec![Vec3::ZERO; n],
            vec![Vec3::ZERO; n],
        );
        d.correct(&q1, &mut d1);
        d.correct(&q2, &mut d2);
        let q12: Vec<Vec3> = q1.iter().zip(&q2).map(|(a, b)| *a + 2.0 * *b).collect();
        d.correct(&q12, &mut d12);
        for i in 0..n {
            assert!(d1[i].min_element() >= 0.0 && d2[i].min_element() >= 0.0);
            let want = d1[i] + 2.0 * d2[i];
            assert!((d12[i] - want).abs().max_element() <= 1e-3 * want.max_element().max(1e-3));
        }
    }
}
