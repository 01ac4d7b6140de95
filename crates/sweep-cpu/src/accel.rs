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
//!    after the pair before, they run accelerated (the estimate's operator is built
//!    then). Scenes that converge in a few passes (dark foliage, ground) never switch,
//!    and get the plain sweep's light bit for bit; if two accelerated pairs in a row
//!    leave more waiting, the passes go back to plain ones.
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
//!    of which [`GAIN`] is added (diffusion over a few cells of optical depth about 1
//!    foresees more than the passes then find). `e_c = G / (G + (1 − a) K)` is the part of a cell's emission that leaves it (the
//!    sweep scatters what the cell's own material stops again at once,
//!    [`crate::medium`]), and `s_f` the share of it leaving through face `f` in the
//!    sweep's own paths (top and bottom: vertical and diagonal channels; each side: a
//!    quarter of the horizontal ones). Thin cells diffuse (`D = 1/(3τ)`, Marshak's
//!    vacuum condition on faces to anything that is not medium); in cells thicker than
//!    about 1 the sweep's flat source moves light one cell per generation, faster than
//!    diffusion would, and the walk's coefficients take over. Empty cells beside
//!    media join the estimate as free flight (`D = 1 / (3 × 0.1)`, no collisions), so
//!    light crosses a gap and collides on the other side; surfaces, the empty space
//!    beyond and the grid's open sides are vacuum to it (periodic sides wrap). The
//!    solve is preconditioned by the vertical lines of cells (solved exactly) plus a
//!    coarse problem of one unknown per level: a few iterations, where point-by-point
//!    preconditioning took hundreds in a thin layer.
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
//! Under [`MediumEmission::Profile`] (a quadratic source in height, [`crate::profile`])
//! the waiting light is source coefficients: `q_c` is the scattered flux they stand for
//! ([`crate::profile::CellProfile::scattered`]), the correction `δ` becomes a flat source
//! that scatters it ([`crate::profile::CellProfile::source_of_scattered`]) in both
//! directions' waiting light, and the convergence test counts what the waiting sources
//! will send out of their cells. The operator is the flat rule's.
//!
//! Measured (`cargo xtask exact`, tolerance 1e-4, slabs of cells of optical depth 1):
//! passes 8 / 30 / 26 / 24 at albedo 0.5 / 0.9 / 0.99 / 0.999 for a slab of optical
//! depth 100 or 1000, where the plain passes take 8 / 33 / 264 / over 1024 (albedo 0.5
//! and 0.9 converge fast enough not to switch). Each estimate costs a few
//! conjugate-gradient iterations over the media cells, small against a pass.

use lightgrid_core::glam::{DVec3, UVec3, Vec3};
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

/// Most conjugate-gradient iterations of one estimate (it needs no more than a rough
/// answer: what it misses, the passes after it find).
const MAX_ITERATIONS: u32 = 500;

/// The optical depth the estimate gives an empty cell beside media (its diffusion
/// coefficient `1 / (3 GAP_TAU)`: light crosses it all but freely).
const GAP_TAU: f32 = 0.1;

/// Whether `options` ask for acceleration that applies: [`Acceleration::Diffusion`]
/// under the source rule (the only medium rule it models).
pub fn wanted(options: &SweepOptions) -> bool {
    options.acceleration == Acceleration::Diffusion
        && matches!(
            options.medium,
            MediumEmission::Source | MediumEmission::Profile
        )
}

/// Relative residual at which the estimate's solve stops (a rough answer does: what
/// it misses, the passes after it find).
const SOLVE_TOLERANCE: f64 = 1e-3;

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
    /// The preconditioner's vertical lines (slots bottom to top, one line after
    /// another), where each starts, and its tridiagonal factors per slot.
    lines: Vec<u32>,
    line_start: Vec<u32>,
    denom: Vec<DVec3>,
    upper: Vec<DVec3>,
    /// The coarse problem of the preconditioner: the operator summed over each level
    /// (`Pᵀ A P`, `P` the level's cells alike), as tridiagonal factors per level, and
    /// each slot's level.
    level: Vec<u32>,
    coarse_denom: Vec<DVec3>,
    coarse_upper: Vec<DVec3>,
    coarse_lower: Vec<DVec3>,
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
        if !wanted(options) {
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
        Some(
            Self {
                cells,
                media,
                slot,
                nb,
                k,
                diag,
                scatter,
                lines: Vec::new(),
                line_start: Vec::new(),
                denom: Vec::new(),
                upper: Vec::new(),
                level: Vec::new(),
                coarse_denom: Vec::new(),
                coarse_upper: Vec::new(),
                coarse_lower: Vec::new(),
            }
            .with_lines()
            .with_levels(desc.level_len(), desc.levels() as usize),
        )
    }

    /// The vertical lines of the preconditioner: runs of cells joined bottom to top,
    /// and the tridiagonal (Thomas) factors of each along it.
    fn with_lines(mut self) -> Self {
        let n = self.cells.len();
        let (mut lines, mut start) = (Vec::with_capacity(n), Vec::new());
        let (mut denom, mut upper) = (vec![DVec3::ONE; n], vec![DVec3::ZERO; n]);
        for c in 0..n {
            if self.nb[c][2] != OPEN {
                continue;
            }
            start.push(lines.len() as u32);
            let mut i = c;
            let mut up_prev = DVec3::ZERO;
            loop {
                lines.push(i as u32);
                // b_i − a_i c'_{i−1}, with a_i = −k_down, c'_{i−1} = −k_up(prev) / denom.
                let below_k = self.k[i][2].as_dvec3();
                let d = self.diag[i].as_dvec3() - below_k * up_prev;
                denom[i] = d;
                let up = self.nb[i][3];
                let ku = self.k[i][3].as_dvec3();
                upper[i] = ku / d;
                up_prev = upper[i];
                if up == OPEN {
                    break;
                }
                i = up as usize;
            }
        }
        start.push(lines.len() as u32);
        self.lines = lines;
        self.line_start = start;
        self.denom = denom;
        self.upper = upper;
        self
    }

    /// The coarse problem: one unknown per level.
    fn with_levels(mut self, level_len: usize, levels: usize) -> Self {
        self.level = self
            .cells
            .iter()
            .map(|&i| (i as usize / level_len) as u32)
            .collect();
        let (mut diag, mut lower, mut upper) = (
            vec![DVec3::ZERO; levels],
            vec![DVec3::ZERO; levels],
            vec![DVec3::ZERO; levels],
        );
        for c in 0..self.cells.len() {
            let j = self.level[c] as usize;
            let mut d = self.diag[c].as_dvec3();
            for f in [0, 1, 4, 5] {
                if self.nb[c][f] != OPEN {
                    d -= self.k[c][f].as_dvec3();
                }
            }
            diag[j] += d;
            if self.nb[c][2] != OPEN {
                lower[j] += self.k[c][2].as_dvec3();
            }
            if self.nb[c][3] != OPEN {
                upper[j] += self.k[c][3].as_dvec3();
            }
        }
        // Thomas factors; a level without cells is left out (identity).
        let (mut den, mut up) = (vec![DVec3::ONE; levels], vec![DVec3::ZERO; levels]);
        let mut up_prev = DVec3::ZERO;
        for j in 0..levels {
            if diag[j] == DVec3::ZERO {
                up_prev = DVec3::ZERO;
                continue;
            }
            den[j] = diag[j] - lower[j] * up_prev;
            up[j] = upper[j] / den[j];
            up_prev = up[j];
        }
        self.coarse_denom = den;
        self.coarse_upper = up;
        self.coarse_lower = lower;
        self
    }

    /// `z += P A_c⁻¹ Pᵀ r`: the coarse problem's answer spread over each level.
    fn coarse(&self, r: &[DVec3], z: &mut [DVec3]) {
        let levels = self.coarse_denom.len();
        let mut rc = vec![DVec3::ZERO; levels];
        for (c, v) in r.iter().enumerate() {
            rc[self.level[c] as usize] += *v;
        }
        let mut prev = DVec3::ZERO;
        for j in 0..levels {
            prev = (rc[j] + self.coarse_lower[j] * prev) / self.coarse_denom[j];
            rc[j] = prev;
        }
        let mut next = DVec3::ZERO;
        for j in (0..levels).rev() {
            next = rc[j] + self.coarse_upper[j] * next;
            rc[j] = next;
        }
        for (c, v) in z.iter_mut().enumerate() {
            *v += rc[self.level[c] as usize];
        }
    }

    /// `z = M⁻¹ r`: the operator's vertical lines solved exactly, plus the coarse
    /// problem's answer (a two-level additive preconditioner). A layer of thin media
    /// couples over many levels and, laterally, over whole levels: point by point,
    /// conjugate gradients took hundreds of iterations there; with both, a few.
    fn precondition(&self, r: &[DVec3], z: &mut [DVec3]) {
        for w in self.line_start.windows(2) {
            let line = &self.lines[w[0] as usize..w[1] as usize];
            let mut prev = DVec3::ZERO;
            for (j, &c) in line.iter().enumerate() {
                let c = c as usize;
                // d'_i = (d_i − a_i d'_{i−1}) / denom_i, a_i = −k_down.
                let below = if j > 0 {
                    self.k[c][2].as_dvec3() * prev
                } else {
                    DVec3::ZERO
                };
                prev = (r[c] + below) / self.denom[c];
                z[c] = prev;
            }
            let mut next = DVec3::ZERO;
            for &c in line.iter().rev() {
                let c = c as usize;
                // x_i = d'_i − c'_i x_{i+1}, c'_i = −k_up / denom.
                next = z[c] + self.upper[c] * next;
                z[c] = next;
            }
        }
        self.coarse(r, z);
    }

    fn apply(&self, x: &[DVec3], out: &mut [DVec3]) {
        for (c, o) in out.iter_mut().enumerate() {
            let mut v = self.diag[c].as_dvec3() * x[c];
            for f in 0..6 {
                let n = self.nb[c][f];
                if n != OPEN {
                    v -= self.k[c][f].as_dvec3() * x[n as usize];
                }
            }
            *o = v;
        }
    }

    /// The later generations `δ` of waiting light `q` (per cell of the estimate, in
    /// the order of [`Diffusion::cells`]; 0 for the empty ones), written to `delta`.
    /// Linear in `q` up to the solver's tolerance; `q ≥ 0` gives `δ ≥ 0`.
    pub fn correct(&self, q: &[Vec3], delta: &mut [Vec3]) -> Correction {
        let (x, iterations) = self.solve(&self.smooth(q));
        for ((d, s), x) in delta.iter_mut().zip(&self.scatter).zip(&x) {
            let v = *s * x.as_vec3();
            *d = if v.is_finite() { v } else { Vec3::ZERO };
        }
        Correction { iterations }
    }

    /// `q` through [`SMOOTHING`] rounds of the 1-2-1 filter along each axis, over the
    /// estimate's cells.
    fn smooth(&self, q: &[Vec3]) -> Vec<DVec3> {
        let n = self.cells.len();
        let mut sq: Vec<DVec3> = q.iter().map(|v| v.as_dvec3()).collect();
        let mut tmp = vec![DVec3::ZERO; n];
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
        sq
    }

    /// `A⁻¹ b` by conjugate gradients preconditioned by [`Diffusion::precondition`],
    /// the three colours side by side, in f64 (a thin medium's operator is
    /// ill-conditioned for f32); and the iterations it took.
    fn solve(&self, b: &[DVec3]) -> (Vec<DVec3>, u32) {
        let n = self.cells.len();
        let mut x = vec![DVec3::ZERO; n];
        let mut r = b.to_vec();
        let mut z = vec![DVec3::ZERO; n];
        self.precondition(&r, &mut z);
        let mut p = z.clone();
        let mut ap = vec![DVec3::ZERO; n];
        let dot =
            |a: &[DVec3], b: &[DVec3]| -> DVec3 { a.iter().zip(b).map(|(a, b)| *a * *b).sum() };
        let stop = dot(&r, &r) * SOLVE_TOLERANCE * SOLVE_TOLERANCE;
        let mut rz = dot(&r, &z);
        let mut iterations = 0;
        while iterations < MAX_ITERATIONS {
            if dot(&r, &r).cmple(stop).all() {
                break;
            }
            iterations += 1;
            self.apply(&p, &mut ap);
            let pap = dot(&p, &ap);
            let alpha = DVec3::select(pap.cmpgt(DVec3::ZERO), rz / pap, DVec3::ZERO);
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * ap[i];
            }
            self.precondition(&r, &mut z);
            let rz_new = dot(&r, &z);
            let beta = DVec3::select(rz.cmpgt(DVec3::ZERO), rz_new / rz, DVec3::ZERO);
            rz = rz_new;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
        (x, iterations)
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
    fn the_solve_equals_a_dense_elimination() {
        // A heterogeneous grid: media of every optical depth, gaps, surfaces, open
        // sides; the conjugate-gradient answer against Gaussian elimination of the
        // same operator, per colour.
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(5, 6, 4)).expect("valid");
        let mut rng = fastrand::Rng::with_seed(3);
        let cells = (0..d.point_count())
            .map(|_| match rng.u32(0..8) {
                0 => Material::EMPTY,
                1 => Material::opaque(Vec3::splat(0.7)),
                _ => Material {
                    reflectance: Vec3::new(0.99, 0.9, 0.5 + 0.5 * rng.f32()),
                    pass: 0.01 + 0.98 * rng.f32(),
                },
            })
            .collect();
        let m = MaterialGrid::new(d, cells).expect("valid");
        for periodic in [false, true] {
            let s = Diffusion::of(&m, periodic, &on()).expect("media");
            assert!(s.cells.len() > s.media, "gap cells join the estimate");
            let n = s.cells.len();
            let b: Vec<DVec3> = (0..n)
                .map(|i| DVec3::new(1.0 + (i % 3) as f64, 0.5, (i % 7) as f64))
                .collect();
            let (x, iterations) = s.solve(&b);
            assert!(iterations < 40, "{iterations}");
            for colour in 0..3 {
                let mut a = vec![vec![0f64; n + 1]; n];
                for c in 0..n {
                    a[c][c] = s.diag[c][colour] as f64;
                    for f in 0..6 {
                        if s.nb[c][f] != OPEN {
                            a[c][s.nb[c][f] as usize] -= s.k[c][f][colour] as f64;
                        }
                    }
                    a[c][n] = b[c][colour];
                }
                for col in 0..n {
                    let piv = (col..n)
                        .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
                        .expect("rows");
                    a.swap(col, piv);
                    for row in 0..n {
                        if row != col {
                            let f = a[row][col] / a[col][col];
                            for k in col..=n {
                                a[row][k] -= f * a[col][k];
                            }
                        }
                    }
                }
                for c in 0..n {
                    let want = a[c][n] / a[c][c];
                    assert!(
                        (x[c][colour] - want).abs() <= 1e-2 * want.abs() + 1e-6,
                        "{} against {want}",
                        x[c][colour]
                    );
                }
            }
        }
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
