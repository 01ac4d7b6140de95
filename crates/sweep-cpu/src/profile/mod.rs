//! A medium cell's source as a **quadratic in height**: the segment integrals, the
//! per-cell tables and the source solve of [`lightgrid_core::MediumEmission::Profile`]
//! (issue 13's thick cells), **the default rule** for cells of optical depth at least
//! [`crate::medium::PROFILE_MIN_DEPTH`] (thinner ones, and every medium under the
//! option `MediumEmission::Source`, emit the flat source of [`crate::medium`]). It runs on the CPU sweeper (row kernels:
//! phases 2 and 3 gather the collisions' height moments over blocks of a row, phase 2
//! writes what each cell's `P_1`, `P_2` terms emit into each slot's segment for phase
//! 3's emission; with diffusion acceleration, [`crate::accel`]: its
//! corrections become flat sources, [`CellProfile::source_of_scattered`]) and on the GPU
//! (`sweep-gpu`, from [`table_floats`] and [`slot_geometry`]); see the crate docs,
//! "Against exact answers". Cost: the tables' nodes ship with the crate (`tables.bin`,
//! read on first use; computing one took about 0.15 ms on the 2-core VM, all 1025, as
//! the GPU's copy needs, 60 ms on two threads); a [`CellProfile`], 1.2 µs, computed once per distinct cell depth and pass
//! direction and kept across levels, passes, sweeps and sweepers (one set a process,
//! which every sweeper reads: a hierarchy's forks meet the same depths; up to
//! 65 536 of them, 77.5 MiB; a scene with more distinct depths computes the others once
//! per level that holds them).
//!
//! ## Why
//!
//! With a flat source, Chandrasekhar's half-space albedo comes out 15–23 % low in cells
//! of optical depth 3 and albedo ≤ 0.5: a beam entering a thick cell collides near the
//! face it entered by, and a flat source sends too little of that back out. The 1-D
//! study `cargo run --release -p lightgrid-measure --example do1d` solves the half-space with
//! the sweep's own channel cosines as ordinates and the cell's whole source expanded in
//! Legendre polynomials of height up to order 0, 1 or 2 (each coefficient the cell's
//! moment of its collisions, so the scheme stays **linear in the light** and exact in a
//! white furnace, where the moments above 0 vanish). At cell depth 3 (w 0.1 / 0.5 / 0.9 /
//! 0.99):
//!
//! | source in height | error |
//! |------------------|------:|
//! | flat (order 0) | −48 / −41 / −23 / −7.5 % |
//! | linear (order 1) | −7.5 / −3.5 / +0.9 / +0.3 % |
//! | quadratic (order 2) | +0.7 / +1.1 / +0.4 / −0.0 % |
//! | the channels' own angular error (fine mesh) | +1.7 / +1.1 / +0.2 / −0.1 % |
//!
//! So a quadratic source in height leaves no spatial error at depths 0.69 to 3: the
//! issue's 2 % is within reach with two more moments per cell and colour.
//!
//! ## The rule
//!
//! Height in a cell: `y ∈ [−1, 1]` (bottom to top). A medium cell's source radiance in a
//! pass is `j(y) = Σ_m J_m P_m(y)`, `m = 0..2` (Legendre polynomials, [`legendre`]).
//! A path segment through the cell (optical length `t`, height running linearly from
//! `y0` where the path enters to `y1` where it leaves, [`Segment`]):
//!
//! - **collides** light entering it with the height moments [`Segment::collided`]
//!   `C_n = ∫₀ᵗ P_n(y(s)) e^{−s} ds` (`C_0 = 1 − e^{−t}`, the removed fraction): the
//!   cell tallies `R_n = Σ μ_c × removed × C_n / C_0` over its segments in phases 2
//!   and 3;
//! - **emits** `ω_b σ_c Σ_m J_m E_m` into its path, [`Segment::emitted`] `E_m =
//!   ∫₀ᵗ P_m(y(s)) e^{−(t−s)} ds` (`E_0 = 1 − e^{−t}`, today's flat rule);
//! - **stops again** of its own emission the moments [`Segment::self_collided`] `K_nm`;
//! - gives the point whose own cell it is the mean light `L_in m + Σ_m J_m (U_m − E_m)
//!   / t`, with [`Segment::uniform`] `U_m = ∫₀ᵗ P_m(y(s)) ds`.
//!
//! Summed over a pass's segments through one cell (weights `μ_c ω_b σ_c`,
//! [`PassSums`]): the pass emits the moments `O J_n / (2n + 1)` (`O = τ Σ_c ω_b σ_c`:
//! each channel's segments through a cell cover its height evenly), sends `G·J` out of
//! the cell and stops `K J` again, of which it scatters `a` once more. With `E_n` the
//! scattered light's moments this pass emits (half of the cell's collisions' `a R_n`,
//! the source being isotropic), the source solves the 3 × 3 system ([`PassSums::solve`])
//!
//! ```text
//! O J_n / (2n + 1) − a Σ_m K_nm J_m = E_n,   n = 0, 1, 2.
//! ```
//!
//! Its `n = 0` row is today's `J = E / (G + (1 − a) K)` when `J_1 = J_2 = 0`, and flux
//! is conserved exactly (`K_0m = O δ_m0 − G_m`, by construction). In a white furnace the
//! collisions of light entering a segment and of the segment's own flat source add up
//! to an even density, `C_n + K_n0 = U_n`, whose moments above 0 vanish over a pass
//! ([`PassSums::furnace_moments`]): `J = (1, 0, 0)` exactly, as today. The up/down split
//! of [`crate::medium::split`] becomes unnecessary: a source heavy at the top sends
//! more out through the top by itself.
//!
//! ## How the sweep runs it
//!
//! Solving each pass's half separately (its own self-collisions only) was measured
//! worse, up to +3.0 % (`measure/examples/profile_slab.rs`, "per pass"): the source must be
//! isotropic. So each batch of collisions a cell tallies (phase 2's, and phase 3's from
//! its level-mates) is solved at once over **both** passes' segments
//! ([`CellProfile::source`], `O` and `K` of the full sphere): the pass that found it
//! emits its own segments' part at once, and the same coefficients wait, as Legendre
//! coefficients in the cell's pending light, for the other direction's next pass
//! (phase 3's collisions wait for both). Per level and pass, each medium cell's
//! [`CellProfile`] is interpolated from tables over `√τ` ([`TABLE`] nodes up to
//! [`TAU_MAX`]); `K_0m` and `K_n0` are rebuilt from the interpolated values so that flux
//! balances and a furnace stays flat to rounding. A quadratic is not positive
//! everywhere: where a point's light comes out below 0 the output clamps it (the light
//! before the clamp is linear in the boundary light).

use std::f64::consts::PI;

use lightgrid_core::Material;
use lightgrid_core::dirs;
use lightgrid_core::glam::{DVec3, Vec3};

use crate::sweep::{SLOTS, channels, path_exponents};

mod store;
pub(crate) use store::Profiles;

/// Legendre polynomials `P_0, P_1, P_2` at `y`.
#[inline]
pub fn legendre(y: f64) -> [f64; 3] {
    [1.0, y, 0.5 * (3.0 * y * y - 1.0)]
}

/// `∫₀ᵗ s^(k−1) e^{−s} ds` for `k` = 1, 2, 3 (the lower incomplete gamma function
/// `γ(k, t)`): a series below `t = 2` (no cancellation for small `t`), the closed form
/// above. 0 for `t ≤ 0` or NaN; `(k − 1)!` for `t = ∞`.
pub fn lower_gamma(k: u32, t: f64) -> f64 {
    assert!(
        (1..=3).contains(&k),
        "lower_gamma: k = {k} is not 1, 2 or 3"
    );
    if t.is_nan() || t <= 0.0 {
        return 0.0;
    }
    if t < 2.0 {
        // Σ_j (−t)^j / j! × t^k / (k + j)
        let mut term = t.powi(k as i32);
        let mut sum = 0.0;
        for j in 0..40 {
            sum += term / (k + j) as f64;
            term *= -t / (j + 1) as f64;
            if term.abs() < 1e-19 * sum.abs() {
                break;
            }
        }
        return sum;
    }
    let e = (-t).exp();
    if e == 0.0 {
        return [1.0, 1.0, 2.0][k as usize - 1];
    }
    match k {
        1 => 1.0 - e,
        2 => 1.0 - e * (1.0 + t),
        _ => 2.0 * (1.0 - e * (1.0 + t + 0.5 * t * t)),
    }
}

/// One path segment through a cell: optical length `t`, height `y0` where the path
/// enters the cell and `y1` where it leaves (`y ∈ [−1, 1]`, linear along the path).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Optical length along the path.
    pub t: f64,
    /// Height where the path enters.
    pub y0: f64,
    /// Height where the path leaves.
    pub y1: f64,
}

/// Quadrature points per segment for [`Segment::self_collided`]'s outer integral.
const SELF_POINTS: usize = 32;

impl Segment {
    /// `∫₀ᵗ P_n(y0 + δ s) e^{−s} ds`, `δ = (y1 − y0)/t`: the height moments of where
    /// light entering at `y0` collides (a beam decays as `e^{−s}`). (Inlined, with
    /// [`Segment::self_collided`], into the tables' node computation on the widest
    /// instruction set the CPU has.)
    #[inline(always)]
    fn decay_moments(t: f64, y0: f64, y1: f64) -> [f64; 3] {
        if t.is_nan() || t <= 0.0 {
            return [0.0; 3];
        }
        let d = (y1 - y0) / t;
        let (g1, g2, g3) = (lower_gamma(1, t), lower_gamma(2, t), lower_gamma(3, t));
        // P_2(y0 + δ s) = (3 y0² − 1)/2 + 3 y0 δ s + 3/2 δ² s²
        [
            g1,
            y0 * g1 + d * g2,
            0.5 * (3.0 * y0 * y0 - 1.0) * g1 + 3.0 * y0 * d * g2 + 1.5 * d * d * g3,
        ]
    }

    /// `C_n = ∫₀ᵗ P_n(y(s)) e^{−s} ds`: the height moments of the collisions of light
    /// entering the segment (per unit of it; `C_0 = 1 − e^{−t}`).
    #[inline(always)]
    pub fn collided(&self) -> [f64; 3] {
        Self::decay_moments(self.t, self.y0, self.y1)
    }

    /// `E_m = ∫₀ᵗ P_m(y(s)) e^{−(t−s)} ds`: what a source `P_m(y)` (per unit of
    /// radiance) along the segment sends out of its end (`E_0 = 1 − e^{−t}`).
    #[inline(always)]
    pub fn emitted(&self) -> [f64; 3] {
        Self::decay_moments(self.t, self.y1, self.y0)
    }

    /// `U_n = ∫₀ᵗ P_n(y(s)) ds`: the moments of an even density along the segment.
    #[inline(always)]
    pub fn uniform(&self) -> [f64; 3] {
        let (a, b) = (self.y0, self.y1);
        // Means of P_n over [a, b] (exact for polynomials up to degree 2 by Simpson).
        let (pa, pm, pb) = (legendre(a), legendre(0.5 * (a + b)), legendre(b));
        std::array::from_fn(|n| self.t * (pa[n] + 4.0 * pm[n] + pb[n]) / 6.0)
    }

    /// `K_nm = ∫₀ᵗ P_m(y(s')) ∫_{s'}^t P_n(y(s)) e^{−(s−s')} ds ds'`: the height
    /// moments `n` of where the segment's own source `P_m` collides further along it.
    /// `K_n0 = U_n − C_n` exactly; the other columns by Gauss–Legendre quadrature of
    /// the outer integral (each point a beam starting at `s'`).
    #[inline(always)]
    pub fn self_collided(&self) -> [[f64; 3]; 3] {
        let (u, c) = (self.uniform(), self.collided());
        let mut k = [[0.0; 3]; 3];
        for n in 0..3 {
            k[n][0] = u[n] - c[n];
        }
        if self.t.is_nan() || self.t <= 0.0 {
            return k;
        }
        let y = |s: f64| self.y0 + (self.y1 - self.y0) * s / self.t;
        for &(x, w) in gauss_nodes() {
            let s = x * self.t;
            let pm = legendre(y(s));
            let inner = Self::decay_moments(self.t - s, y(s), self.y1);
            for n in 0..3 {
                for m in 1..3 {
                    k[n][m] += w * self.t * pm[m] * inner[n];
                }
            }
        }
        k
    }
}

fn gauss_nodes() -> &'static [(f64, f64)] {
    static Q: std::sync::OnceLock<Vec<(f64, f64)>> = std::sync::OnceLock::new();
    Q.get_or_init(|| crate::quadrature::gauss_legendre_01(SELF_POINTS))
}

/// The segments of a pass through one cell of optical depth `tau` (per level), each
/// with its weight `μ_c ω_b σ_c`: for every channel of the pass, one segment a stencil
/// cell (the cell is crossed once by each, by the paths of different points).
pub fn pass_segments(up: bool, tau: f64) -> Vec<(f64, Segment)> {
    let exps = path_exponents();
    let omega = dirs::solid_angles();
    let mut out = Vec::new();
    for chn in channels(up).iter() {
        let w = (chn.mu * omega[chn.bin] * chn.share) as f64;
        let mut along = 0.0f64;
        for (k, &(_, _, f)) in chn.stencil.iter().enumerate() {
            // Height: downward paths run from the top (y = 1) to the bottom.
            let y = |a: f64| if up { 2.0 * a - 1.0 } else { 1.0 - 2.0 * a };
            let seg = Segment {
                t: exps[chn.pow[k]] as f64 * tau,
                y0: y(along),
                y1: y(along + f as f64),
            };
            along += f as f64;
            out.push((w, seg));
        }
    }
    out
}

/// A pass's sums over a cell's segments ([`pass_segments`]), weighted `μ_c ω_b σ_c`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassSums {
    /// `O = τ Σ_c ω_b σ_c`: the flux a unit flat source emits in the pass's directions.
    pub o: f64,
    /// `G_m = Σ w E_m`: what a source `P_m` sends out of the cell.
    pub g: [f64; 3],
    /// `K_nm = Σ w K_nm(segment)`, with `K_0m = O δ_m0 − G_m` set exactly (flux).
    pub k: [[f64; 3]; 3],
}

impl PassSums {
    /// The sums of the downward (`up = false`) or upward pass for a cell of optical
    /// depth `tau` per level.
    pub fn new(up: bool, tau: f64) -> Self {
        let mut g = [0.0; 3];
        let mut k = [[0.0; 3]; 3];
        let mut half = 0.0;
        for (w, seg) in pass_segments(up, tau) {
            let (e, kk) = (seg.emitted(), seg.self_collided());
            for n in 0..3 {
                g[n] += w * e[n];
                for m in 0..3 {
                    k[n][m] += w * kk[n][m];
                }
            }
            half += w * seg.t;
        }
        // Σ μ ω σ f ℓ τ = τ Σ ω σ: each channel's fractions sum to 1 and μ ℓ = 1.
        let o = half;
        for m in 0..3 {
            k[0][m] = if m == 0 { o } else { 0.0 } - g[m];
        }
        Self { o, g, k }
    }

    /// The moments `Σ w (C_n + K_n0)` of a white furnace's collisions in the pass (light
    /// 1 entering every segment and a flat source 1): `(O, 0, 0)` when the pass's
    /// segments cover the cell's height evenly.
    pub fn furnace_moments(up: bool, tau: f64) -> [f64; 3] {
        let mut v = [0.0; 3];
        for (w, seg) in pass_segments(up, tau) {
            let (c, k) = (seg.collided(), seg.self_collided());
            for n in 0..3 {
                v[n] += w * (c[n] + k[n][0]);
            }
        }
        v
    }

    /// The source `J` (Legendre coefficients in height) that emits the scattered
    /// moments `e` this pass, albedo `a`: `O J_n / (2n + 1) − a Σ_m K_nm J_m = e_n`.
    /// `None` where the system is singular (an empty cell, `O = 0`).
    pub fn solve(&self, a: f64, e: [f64; 3]) -> Option<[f64; 3]> {
        solve_balance(self.o, &self.k, a, e)
    }

    /// Flux the source `j` sends out of the cell (`G·J`) and the flux its own material
    /// absorbs of it (`(1 − a)(O J_0 − G·J)`).
    pub fn escaped_absorbed(&self, a: f64, j: [f64; 3]) -> (f64, f64) {
        let out: f64 = (0..3).map(|m| self.g[m] * j[m]).sum();
        (out, (1.0 - a) * (self.o * j[0] - out))
    }
}

/// Nodes of the tables behind [`CellProfile::new`]: optical depths `τ = TAU_MAX (i /
/// (TABLE − 1))²`, interpolated linearly in `√τ`.
pub const TABLE: usize = 1025;
/// Largest optical depth per level in the tables (thicker cells take its values).
pub const TAU_MAX: f64 = 64.0;

/// One table node: per pass and stencil slot `[C_1/C_0, C_2/C_0, E_1, E_2, M_1, M_2]`
/// (`M_m = (U_m − E_m)/t`, a source `P_m`'s share of the mean light over the segment),
/// and both passes' self-collisions `K_nm`, `n, m ∈ {1, 2}`.
struct Node {
    slot: [[[f32; 6]; SLOTS]; 2],
    k: [[f32; 2]; 2],
}

/// Node `i` of the tables, read on first use from the copy the crate ships
/// ([`SHIPPED`]; computing one took about 0.15 ms, and the world grid of a hierarchy
/// over a 1.6 km DEM met some 300 in its first sweep, 40–50 ms of a process's start),
/// or computed where that copy does not hold it (a file of another length). A scene
/// reads the nodes around its media's optical depths, a few of the [`TABLE`]. The
/// computation runs no rayon jobs, so a worker never waits in one node's initializer
/// while stealing work that needs the same node.
///
/// Each node is boxed when first read: a table of unboxed empty slots (2.4 MB) had every
/// one of its 600 pages faulted in by the slots' initialisation, a fifth of a small
/// process's page faults before its first sweep.
fn node(i: usize) -> &'static Node {
    type Slots = Vec<std::sync::OnceLock<Box<Node>>>;
    static T: std::sync::OnceLock<Slots> = std::sync::OnceLock::new();
    T.get_or_init(|| (0..TABLE).map(|_| std::sync::OnceLock::new()).collect())[i].get_or_init(
        || Box::new(shipped_node(i).unwrap_or_else(|| crate::isa::vectorised!(compute_node(i)))),
    )
}

/// The tables as [`table_floats`] lays them out, little-endian, computed by
/// [`compute_node`] (the test `shipped_tables_are_the_computed_ones` holds them to it
/// bit for bit, and writes them anew with `LIGHTGRID_WRITE_TABLES=1`).
static SHIPPED: &[u8] = include_bytes!("tables.bin");

/// Node `i` from [`SHIPPED`] (read as little-endian on any target; `None` if the file
/// does not hold the whole table).
fn shipped_node(i: usize) -> Option<Node> {
    if SHIPPED.len() != TABLE * NODE_FLOATS * 4 {
        return None;
    }
    let bytes = &SHIPPED[i * NODE_FLOATS * 4..][..NODE_FLOATS * 4];
    let mut v = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    let mut node = Node {
        slot: [[[0.0; 6]; SLOTS]; 2],
        k: [[0.0; 2]; 2],
    };
    for x in node
        .slot
        .iter_mut()
        .flatten()
        .flatten()
        .chain(node.k.iter_mut().flatten())
    {
        *x = v.next()?;
    }
    Some(node)
}

/// Node `i` of the tables, from the segments' integrals. (Inlined into [`node`]'s call
/// on the widest instruction set the CPU has, [`crate::isa`]: a quarter fewer
/// instructions for a process's first sweep, the same values bit for bit.)
#[inline(always)]
fn compute_node(i: usize) -> Node {
    let u = i as f64 / (TABLE - 1) as f64;
    // τ = 0 as a vanishing depth: the ratios' limits.
    let tau = (TAU_MAX * u * u).max(1e-9);
    let mut node = Node {
        slot: [[[0.0; 6]; SLOTS]; 2],
        k: [[0.0; 2]; 2],
    };
    let mut k = [[0.0f64; 2]; 2];
    // Channels of one kind (the four axis-aligned horizontal ones, say) cross a cell
    // by the same segments: each distinct segment's integrals are computed once (the
    // same values bit for bit; a node takes about a quarter of the time).
    type Integrals = ([f64; 3], [f64; 3], [f64; 3], [[f64; 3]; 3]);
    let mut seen: Vec<([u64; 3], Integrals)> = Vec::new();
    for (pass, up) in [false, true].into_iter().enumerate() {
        for (sl, (w, seg)) in pass_segments(up, tau).into_iter().enumerate() {
            let key = [seg.t.to_bits(), seg.y0.to_bits(), seg.y1.to_bits()];
            let (c, e, uu, kk) = match seen.iter().find(|(k, _)| *k == key) {
                Some(&(_, v)) => v,
                None => {
                    let v = (
                        seg.collided(),
                        seg.emitted(),
                        seg.uniform(),
                        seg.self_collided(),
                    );
                    seen.push((key, v));
                    v
                }
            };
            node.slot[pass][sl] = [
                (c[1] / c[0]) as f32,
                (c[2] / c[0]) as f32,
                e[1] as f32,
                e[2] as f32,
                ((uu[1] - e[1]) / seg.t) as f32,
                ((uu[2] - e[2]) / seg.t) as f32,
            ];
            for n in 0..2 {
                for m in 0..2 {
                    k[n][m] += w * kk[n + 1][m + 1];
                }
            }
        }
    }
    node.k = k.map(|r| r.map(|v| v as f32));
    node
}

/// Every node of the tables, computed (not read from [`SHIPPED`]), on two plain
/// threads.
#[cfg(test)]
fn computed_tables() -> Vec<Node> {
    let half = TABLE / 2;
    let compute = |i| crate::isa::vectorised!(compute_node(i));
    std::thread::scope(|s| {
        let upper = s.spawn(move || (half..TABLE).map(compute).collect::<Vec<_>>());
        let mut v: Vec<Node> = (0..half).map(compute).collect();
        v.extend(upper.join().expect("profile table thread"));
        v
    })
}

/// `(μ_c ω_b σ_c, e, [ū_1, ū_2])` of a stencil slot ([`slot_geometry`]).
pub type SlotGeometry = (f32, f32, [f32; 2]);

/// Floats of one table node in [`table_floats`]: per pass and slot six values, then
/// the four `K_nm` (`n, m ∈ {1, 2}`).
pub const NODE_FLOATS: usize = 2 * SLOTS * 6 + 4;

/// The tables behind [`CellProfile::new`], node by node ([`NODE_FLOATS`] each: per
/// pass (downward first) and slot `[C_1/C_0, C_2/C_0, E_1, E_2, M_1, M_2]`, then `K_11,
/// K_12, K_21, K_22`), for a GPU buffer.
pub fn table_floats() -> Vec<f32> {
    (0..TABLE).flat_map(|i| node_floats(node(i))).collect()
}

/// A node's [`NODE_FLOATS`] values in [`table_floats`]' order.
fn node_floats(n: &Node) -> impl Iterator<Item = f32> + '_ {
    let slots = n.slot.iter().flatten().flatten();
    slots.chain(n.k.iter().flatten()).copied()
}

/// Per stencil slot of a pass: `μ_c ω_b σ_c`, the path exponent `e` (the segment's
/// optical length is `e τ`) and the mean of `P_1`, `P_2` over its height range.
pub fn slot_geometry(up: bool) -> &'static [SlotGeometry; SLOTS] {
    static G: std::sync::OnceLock<[[SlotGeometry; SLOTS]; 2]> = std::sync::OnceLock::new();
    &G.get_or_init(|| {
        [false, true].map(|up| {
            let segs = pass_segments(up, 1.0);
            std::array::from_fn(|sl| {
                let (w, seg) = segs[sl];
                let u = seg.uniform();
                (
                    w as f32,
                    seg.t as f32,
                    [(u[1] / seg.t) as f32, (u[2] / seg.t) as f32],
                )
            })
        })
    })[up as usize]
}

/// A medium cell's profile values for one pass (interpolated from the tables at its
/// optical depth) and its full-sphere balance: what the sweep's source rule with a
/// quadratic source in height ([`lightgrid_core::MediumEmission::Profile`]) reads.
#[derive(Debug, Clone, Copy)]
pub struct CellProfile {
    /// Per slot of this pass: `C_1/C_0`, `C_2/C_0` (a collision's height moments per
    /// unit of the light it removed).
    pub coll: [[f32; 2]; SLOTS],
    /// Per slot of this pass: `E_1`, `E_2` (emission of sources `P_1`, `P_2`).
    pub emit: [[f32; 2]; SLOTS],
    /// Per slot of this pass: `M_1`, `M_2` (their share of the segment's mean light).
    pub mean: [[f32; 2]; SLOTS],
    /// `G_m` of this pass and of the other one.
    pub g: [[f32; 3]; 2],
    /// Both passes: `O` (a flat unit source's whole emission).
    pub o: f32,
    /// Both passes: `K_nm`, with `K_0m = O δ_m0 − G_m` and `K_n0 = Σ w (U_n − C_n)` from
    /// the same interpolated values the tallies use, so that flux is conserved and a
    /// white furnace stays flat to rounding.
    pub k: [[f32; 3]; 3],
}

impl CellProfile {
    /// The profile of a medium cell of `ln(pass)` `lnp` for the downward (`up = false`)
    /// or upward pass. Finite for any `lnp` (thicker than [`TAU_MAX`]: its values).
    pub fn new(up: bool, lnp: f32) -> Self {
        Self::of(up, lnp)
    }

    /// [`CellProfile::new`], for inlining into a call on the widest instruction set the
    /// CPU has ([`crate::isa`]; the same values bit for bit).
    #[inline(always)]
    fn of(up: bool, lnp: f32) -> Self {
        let tau = (-lnp as f64).clamp(0.0, f64::MAX);
        let u = (tau.min(TAU_MAX) / TAU_MAX).sqrt() * (TABLE - 1) as f64;
        let i = (u as usize).min(TABLE - 2);
        let t = [node(i), node(i + 1)];
        let f = (u - i as f64).clamp(0.0, 1.0) as f32;
        let lerp = |a: f32, b: f32| a + (b - a) * f;
        let mut out = CellProfile {
            coll: [[0.0; 2]; SLOTS],
            emit: [[0.0; 2]; SLOTS],
            mean: [[0.0; 2]; SLOTS],
            g: [[0.0; 3]; 2],
            o: 0.0,
            k: [[0.0; 3]; 3],
        };
        let tau32 = tau.min(f32::MAX as f64) as f32;
        // Sums in f64: in f32 a cell's 98 terms rounded its outflow 7e-7 away from what
        // its segments emit, and a bright medium's balance drifted by that every pass.
        let mut kn0 = [0.0f64; 2];
        let mut g = [[0.0f64; 3]; 2];
        let mut o = 0.0f64;
        for pass in 0..2 {
            let this = pass == up as usize;
            let geo = slot_geometry(pass == 1);
            let gi = if this { 0 } else { 1 };
            for sl in 0..SLOTS {
                let (a, b) = (&t[0].slot[pass][sl], &t[1].slot[pass][sl]);
                let v: [f32; 6] = std::array::from_fn(|q| lerp(a[q], b[q]));
                let (w, e, ubar) = geo[sl];
                // The segment's depth and the fraction it removes, as the sweep computes
                // its transmittance (`p^e = exp(e ln p)`), so that flux balances exactly.
                let seg_t = e * tau32;
                let c0 = 1.0 - (e * lnp.max(-f32::MAX)).exp();
                let w64 = w as f64;
                g[gi][0] += (w * c0) as f64;
                g[gi][1] += (w * v[2]) as f64;
                g[gi][2] += (w * v[3]) as f64;
                o += w64 * seg_t as f64;
                for n in 0..2 {
                    kn0[n] += w64 * (seg_t as f64 * ubar[n] as f64 - v[n] as f64 * c0 as f64);
                }
                if this {
                    out.coll[sl] = [v[0], v[1]];
                    out.emit[sl] = [v[2], v[3]];
                    out.mean[sl] = [v[4], v[5]];
                }
            }
        }
        out.o = o as f32;
        out.g = g.map(|r| r.map(|v| v as f32));
        for m in 0..3 {
            out.k[0][m] = (if m == 0 { o } else { 0.0 } - (g[0][m] + g[1][m])) as f32;
        }
        for n in 0..2 {
            out.k[n + 1][0] = kn0[n] as f32;
            for m in 0..2 {
                out.k[n + 1][m + 1] = lerp(t[0].k[n][m], t[1].k[n][m]);
            }
        }
        out
    }

    /// The isotropic source (Legendre coefficients in height) into which the cell
    /// scatters collisions of height moments `r` (flux, one colour), albedo `a`, and the
    /// flux its own material absorbs of it (the collisions' `1 − a` not included):
    /// `O J_n / (2n + 1) − a Σ_m K_nm J_m = a r_n`. Zero where `r_0 = 0`, `a = 0` or
    /// the balance is singular; finite always.
    pub fn source(&self, a: f32, r: [f32; 3]) -> ([f32; 3], f32) {
        let (j, absorbed) = self.sources(
            [a, 0.0, 0.0],
            [r[0], 0.0, 0.0],
            [r[1], 0.0, 0.0],
            [r[2], 0.0, 0.0],
        );
        ([j[0][0], j[1][0], j[2][0]], absorbed[0])
    }

    /// [`CellProfile::source`] for three albedos and collision moments at once (a
    /// cell's colours: `r_n` per colour), each colour's answer [`CellProfile::source`]'s
    /// bit for bit: [`balance_lane`] for every colour in one loop that compiles to
    /// vectors, the emission and absorbed flux in the same loop (their `f64`
    /// conversions and sums, one colour at a time, had cost more than the solve).
    #[inline(always)]
    fn sources(
        &self,
        a: [f32; 3],
        r0: [f32; 3],
        r1: [f32; 3],
        r2: [f32; 3],
    ) -> ([[f32; 3]; 3], [f32; 3]) {
        let ok: [bool; 3] = crate::isa::array_from(|c| {
            a[c] > 0.0
                && r0[c] != 0.0
                && r0[c].is_finite()
                && r1[c].is_finite()
                && r2[c].is_finite()
        });
        let mut j = [[0.0f32; 3]; 3];
        let mut absorbed = [0.0f32; 3];
        if !ok.contains(&true) {
            return (j, absorbed);
        }
        let k = crate::isa::array_map(self.k, |row| crate::isa::array_map(row, |v| v as f64));
        let o = self.o as f64;
        let gsum: [f64; 3] = crate::isa::array_from(|q| (self.g[0][q] + self.g[1][q]) as f64);
        // Lane by lane (the colours, and a spare lane of nothing so that the loop
        // compiles to four-wide vectors).
        let pad = |v: [f32; 3]| [v[0], v[1], v[2], 0.0];
        let (a4, r4) = (pad(a), [pad(r0), pad(r1), pad(r2)]);
        let take = [ok[0], ok[1], ok[2], false];
        let mut jl = [[0.0f32; 4]; 3];
        let mut al = [0.0f32; 4];
        let mut valid = [false; 4];
        for l in 0..4 {
            let alb = if take[l] { a4[l] as f64 } else { 0.0 };
            let r = |n: usize| if take[l] { alb * r4[n][l] as f64 } else { 0.0 };
            let e = [r(0), r(1), r(2)];
            let (d, j) = balance_lane(o, &k, alb, e);
            // The coefficients as the sweep will emit them (f32), and as absorbed
            // whatever of the scattered light they do not send out: flux balances to
            // rounding however the solve rounds (`(1 − a)(O J_0 − G·J)` in exact
            // arithmetic).
            let j32 = crate::isa::array_map(j, |v| v as f32);
            let out = gsum[0] * j32[0] as f64 + gsum[1] * j32[1] as f64 + gsum[2] * j32[2] as f64;
            valid[l] = take[l] && balance_ok(d, j);
            al[l] = (e[0] - out) as f32;
            for n in 0..3 {
                jl[n][l] = j32[n];
            }
        }
        for c in 0..3 {
            if valid[c] {
                absorbed[c] = al[c];
                for n in 0..3 {
                    j[n][c] = jl[n][c];
                }
            }
        }
        (j, absorbed)
    }

    /// The source that scatters flux `e0` in all (one colour, albedo `a`), flat in
    /// height: the solve of [`CellProfile::source`] with right side `(e0, 0, 0)`, of
    /// either sign (the accelerated sweep's diffusion correction, [`crate::accel`]).
    pub fn source_of_scattered(&self, a: f32, e0: f32) -> [f32; 3] {
        if !e0.is_finite() || e0 == 0.0 || a <= 0.0 {
            return [0.0; 3];
        }
        // `source` solves for `a r`: r = e0 / a.
        self.source(a, [e0 / a, 0.0, 0.0]).0
    }

    /// The scattered flux a source `j` stands for: `O J_0 − a Σ_m K_0m J_m` (its
    /// emission less what its own material scatters again), so that
    /// `scattered(source(a, r)) = a r_0`.
    pub fn scattered(&self, a: f32, j: [f32; 3]) -> f32 {
        let k0: f32 = (0..3).map(|m| self.k[0][m] * j[m]).sum();
        self.o * j[0] - a * k0
    }

    /// What the source `j` sends out of the cell through this pass's segments (`which`
    /// 0) or the other pass's (1).
    #[inline]
    pub fn flux_out(&self, which: usize, j: [f32; 3]) -> f32 {
        (0..3).map(|m| self.g[which][m] * j[m]).sum()
    }
}

/// [`CellProfile::source`] per colour: the source coefficients (`[J_0, J_1, J_2]`, RGB
/// each) for collisions of height moments `r` (RGB each), albedo `alb`; the flux the
/// cell's own material absorbs of it is added to `absorbed`. Inlined into the sweep's
/// row kernels, so that it runs on their vector path ([`crate::isa`]).
#[inline(always)]
pub fn source_rgb(pr: &CellProfile, alb: Vec3, r: [Vec3; 3], absorbed: &mut DVec3) -> [Vec3; 3] {
    let (j, ab) = pr.sources(
        alb.to_array(),
        r[0].to_array(),
        r[1].to_array(),
        r[2].to_array(),
    );
    for k in 0..3 {
        absorbed[k] += ab[k] as f64;
    }
    j.map(Vec3::from_array)
}

/// [`CellProfile::scattered`] per colour (albedo `alb`).
pub fn scattered_rgb(pr: &CellProfile, alb: Vec3, j: &[Vec3; 3]) -> Vec3 {
    Vec3::from_array(crate::isa::array_from(|k| {
        pr.scattered(alb[k], [j[0][k], j[1][k], j[2][k]])
    }))
}

/// [`CellProfile::flux_out`] per colour.
pub fn flux_rgb(pr: &CellProfile, which: usize, j: &[Vec3; 3]) -> Vec3 {
    Vec3::from_array(crate::isa::array_from(|k| {
        pr.flux_out(which, [j[0][k], j[1][k], j[2][k]])
    }))
}

/// The source of a medium cell's share of a beam's first collisions `r` (flux, RGB;
/// a `CellSource`), the beam travelling along `dir`: collisions with the height moments
/// `heights` (`[C₁/C₀, C₂/C₀]`, `CellSource::heights`) where known, otherwise those of
/// a beam entering through the top face (downward `dir`) or the bottom face, along
/// `dir`'s slant (flat for a horizontal beam). Returns the coefficients and the flux
/// the source's own re-collisions absorb (the collisions' `1 − a` not included).
pub fn beam_source(
    mat: &Material,
    dir: Vec3,
    r: Vec3,
    heights: Option<[f32; 2]>,
) -> ([Vec3; 3], Vec3) {
    let tau = -(mat.pass as f64).ln();
    let mu = dir.y.abs() as f64;
    let c = if let Some(h) = heights {
        h
    } else if mu > 1e-3 && tau > 0.0 {
        let down = dir.y < 0.0;
        let seg = Segment {
            t: (tau / mu).min(4.0 * TAU_MAX),
            y0: if down { 1.0 } else { -1.0 },
            y1: if down { -1.0 } else { 1.0 },
        };
        let c = seg.collided();
        [(c[1] / c[0]) as f32, (c[2] / c[0]) as f32]
    } else {
        [0.0; 2]
    };
    let mut absorbed = DVec3::ZERO;
    let j = with_profile(false, mat.pass.ln(), |pr| {
        source_rgb(pr, mat.reflectance, [r, r * c[0], r * c[1]], &mut absorbed)
    });
    (j, absorbed.as_vec3())
}

/// The source balance `O J_n / (2n + 1) − a Σ_m K_nm J_m = e_n` solved for `J`
/// ([`balance_lane`]); `None` where it is singular or the answer not finite.
fn solve_balance(o: f64, k: &[[f64; 3]; 3], a: f64, e: [f64; 3]) -> Option<[f64; 3]> {
    let (d, j) = balance_lane(o, k, a, e);
    balance_ok(d, j).then_some(j)
}

/// One system of the source balance, albedo `a`, right side `e`: Cramer's rule with
/// the cofactors shared, `J = adj(M) e / det M` (each of Cramer's determinants
/// expanded along its replaced column); `(det M, J)`. Inlined into loops over a
/// cell's colours, so that they run as one vector, each colour the same operations
/// in the same order as alone. (Four determinants per colour, one colour at a time,
/// took 6 % of a forest sweep.)
#[inline(always)]
fn balance_lane(o: f64, k: &[[f64; 3]; 3], a: f64, e: [f64; 3]) -> (f64, [f64; 3]) {
    let diag = [o, o / 3.0, o / 5.0];
    let m: [[f64; 3]; 3] = crate::isa::array_from(|n| {
        crate::isa::array_from(|c| (if n == c { diag[n] } else { 0.0 }) - a * k[n][c])
    });
    // cof[n][c]: the cofactor of m[n][c].
    let cof = [
        [
            m[1][1] * m[2][2] - m[1][2] * m[2][1],
            m[1][2] * m[2][0] - m[1][0] * m[2][2],
            m[1][0] * m[2][1] - m[1][1] * m[2][0],
        ],
        [
            m[0][2] * m[2][1] - m[0][1] * m[2][2],
            m[0][0] * m[2][2] - m[0][2] * m[2][0],
            m[0][1] * m[2][0] - m[0][0] * m[2][1],
        ],
        [
            m[0][1] * m[1][2] - m[0][2] * m[1][1],
            m[0][2] * m[1][0] - m[0][0] * m[1][2],
            m[0][0] * m[1][1] - m[0][1] * m[1][0],
        ],
    ];
    let d = m[0][0] * cof[0][0] + m[0][1] * cof[0][1] + m[0][2] * cof[0][2];
    let j =
        crate::isa::array_from(|c| (e[0] * cof[0][c] + e[1] * cof[1][c] + e[2] * cof[2][c]) / d);
    (d, j)
}

/// Whether [`balance_lane`]'s answer stands: the system not singular, the answer
/// finite.
#[inline(always)]
fn balance_ok(d: f64, j: [f64; 3]) -> bool {
    d.is_finite() && d.abs() > 1e-300 && j.iter().all(|v| v.is_finite())
}

/// `4π`: the flux both passes of a unit flat source emit per unit optical depth
/// (`O_down + O_up = 4π τ`).
pub const FULL_SPHERE: f64 = 4.0 * PI;

/// Profiles [`with_profile`] keeps per thread (1.2 KiB each).
const THREAD_KEEP: usize = 4096;

/// Runs `f` on [`CellProfile::new`]`(up, lnp)`, computed once per thread and kept (up
/// to [`THREAD_KEEP`] of them, then the cache starts afresh): for the serial code that
/// reads one cell's profile at a time (diffusion acceleration's corrections, a beam's
/// first collisions). The values are [`CellProfile::new`]'s, bit for bit.
pub(crate) fn with_profile<R>(up: bool, lnp: f32, f: impl FnOnce(&CellProfile) -> R) -> R {
    use std::cell::RefCell;
    use std::collections::HashMap;
    thread_local! {
        static CACHE: RefCell<HashMap<(bool, u32), Box<CellProfile>>> =
            RefCell::new(HashMap::new());
    }
    let key = (up, lnp.to_bits());
    // A copy (1.2 KiB): `f` may read another profile.
    let pr = CACHE.with(|c| c.borrow().get(&key).map(|p| **p));
    let pr = pr.unwrap_or_else(|| {
        let pr = CellProfile::new(up, lnp);
        CACHE.with(|c| {
            let mut c = c.borrow_mut();
            if c.len() >= THREAD_KEEP {
                c.clear();
            }
            c.insert(key, Box::new(pr));
        });
        pr
    });
    f(&pr)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Midpoint-rule reference for `∫₀ᵗ f(s) ds`.
    fn brute(t: f64, f: impl Fn(f64) -> f64) -> f64 {
        let n = 200_000;
        let h = t / n as f64;
        (0..n).map(|i| f((i as f64 + 0.5) * h) * h).sum()
    }

    fn segs() -> Vec<Segment> {
        let mut v = Vec::new();
        for t in [1e-7, 1e-3, 0.05, 0.69, 1.9, 2.1, 3.0, 12.0, 60.0] {
            for (y0, y1) in [
                (1.0, -1.0),
                (-1.0, 1.0),
                (1.0, 0.75),
                (0.25, -0.25),
                (-0.75, -1.0),
            ] {
                v.push(Segment { t, y0, y1 });
            }
        }
        v
    }

    /// The tables' nodes are computed on the widest instruction set the CPU has
    /// ([`node`]); the baseline path (this function's) gives them bit for bit.
    #[test]
    fn table_nodes_are_the_same_on_every_instruction_set() {
        let bits = |n: &Node| -> Vec<u32> {
            let slots = n.slot.iter().flatten().flatten();
            slots
                .chain(n.k.iter().flatten())
                .map(|v| v.to_bits())
                .collect()
        };
        for i in (0..TABLE).step_by(32).chain([TABLE - 2, TABLE - 1]) {
            let baseline = compute_node(i);
            let widest = crate::isa::vectorised!(compute_node(i));
            assert_eq!(bits(&baseline), bits(&widest), "node {i}");
            assert_eq!(bits(&baseline), bits(node(i)), "node {i}");
        }
    }

    /// The tables the crate ships are [`compute_node`]'s bit for bit, and [`node`]
    /// hands them out. `LIGHTGRID_WRITE_TABLES=1` writes them anew (after a change to
    /// the integrals) instead of checking.
    #[test]
    fn shipped_tables_are_the_computed_ones() {
        let computed = computed_tables();
        let bytes: Vec<u8> = computed
            .iter()
            .flat_map(node_floats)
            .flat_map(f32::to_le_bytes)
            .collect();
        if std::env::var_os("LIGHTGRID_WRITE_TABLES").is_some() {
            let path = concat!(env!("CARGO_MANIFEST_DIR"), "/src/profile/tables.bin");
            std::fs::write(path, &bytes).expect("writing the tables");
            return;
        }
        assert_eq!(SHIPPED.len(), bytes.len(), "tables.bin's length");
        let n = NODE_FLOATS * 4;
        let differs = (0..TABLE).find(|&i| SHIPPED[i * n..][..n] != bytes[i * n..][..n]);
        assert_eq!(
            differs, None,
            "tables.bin differs from the computed tables at this node: run this test \
             with LIGHTGRID_WRITE_TABLES=1 to write them anew"
        );
        let bits = |n: &Node| node_floats(n).map(f32::to_bits).collect::<Vec<_>>();
        for i in [0, 1, 2, 511, TABLE - 1] {
            assert_eq!(bits(node(i)), bits(&computed[i]), "node {i}");
            let shipped = shipped_node(i).expect("shipped");
            assert_eq!(bits(&shipped), bits(&computed[i]), "node {i}");
        }
    }

    #[test]
    fn lower_gamma_known_answers() {
        for t in [1e-9, 0.01, 0.5, 1.99, 2.0, 2.01, 7.0, 50.0] {
            for k in 1..=3u32 {
                let want = brute(t, |s| s.powi(k as i32 - 1) * (-s).exp());
                let got = lower_gamma(k, t);
                assert!(
                    (got - want).abs() <= 1e-8 * want.abs() + 1e-300,
                    "k {k} t {t}: {got} vs {want}"
                );
            }
        }
        assert_eq!(lower_gamma(3, f64::INFINITY), 2.0);
        assert_eq!(lower_gamma(2, -1.0), 0.0);
        assert_eq!(lower_gamma(1, f64::NAN), 0.0);
    }

    #[test]
    fn segment_integrals_against_brute_force() {
        for s in segs() {
            let y = |u: f64| s.y0 + (s.y1 - s.y0) * u / s.t;
            let (c, e, u) = (s.collided(), s.emitted(), s.uniform());
            for n in 0..3 {
                let bc = brute(s.t, |v| legendre(y(v))[n] * (-v).exp());
                let be = brute(s.t, |v| legendre(y(v))[n] * (-(s.t - v)).exp());
                let bu = brute(s.t, |v| legendre(y(v))[n]);
                let tol = |b: f64| 1e-7 * b.abs().max(s.t.min(1.0)) + 1e-15;
                assert!((c[n] - bc).abs() < tol(bc), "{s:?} C{n}: {} vs {bc}", c[n]);
                assert!((e[n] - be).abs() < tol(be), "{s:?} E{n}: {} vs {be}", e[n]);
                assert!((u[n] - bu).abs() < tol(bu), "{s:?} U{n}: {} vs {bu}", u[n]);
            }
            // A flat source's emission is today's 1 − e^{−t}, and so is a beam's removal.
            let removed = -(-s.t).exp_m1();
            assert!((c[0] - removed).abs() < 1e-12 && (e[0] - removed).abs() < 1e-12);
        }
    }

    #[test]
    fn self_collisions_against_brute_force() {
        for s in [
            Segment {
                t: 0.3,
                y0: 1.0,
                y1: -1.0,
            },
            Segment {
                t: 3.0,
                y0: 0.75,
                y1: 0.25,
            },
            Segment {
                t: 20.0,
                y0: -1.0,
                y1: 1.0,
            },
        ] {
            let y = |u: f64| s.y0 + (s.y1 - s.y0) * u / s.t;
            let k = s.self_collided();
            let n_pts = 2000;
            let h = s.t / n_pts as f64;
            for n in 0..3 {
                for m in 0..3 {
                    // Double midpoint sum over s' < s.
                    let mut b = 0.0;
                    for i in 0..n_pts {
                        let sp = (i as f64 + 0.5) * h;
                        let pm = legendre(y(sp))[m];
                        // Inner integral from s' to t, analytic in the decay.
                        let inner = Segment::decay_moments(s.t - sp, y(sp), s.y1)[n];
                        b += pm * inner * h;
                    }
                    assert!(
                        (k[n][m] - b).abs() < 1e-5 * b.abs().max(1e-3),
                        "{s:?} K{n}{m}: {} vs {b}",
                        k[n][m]
                    );
                }
            }
        }
    }

    /// Each channel's segments cover a cell's height evenly: a white furnace's
    /// collisions have no height moments, in either pass and at any depth.
    #[test]
    fn furnace_collisions_are_even_in_height() {
        for up in [false, true] {
            for tau in [1e-4, 0.05, 0.69, 3.0, 30.0] {
                let v = PassSums::furnace_moments(up, tau);
                let o = PassSums::new(up, tau).o;
                assert!((v[0] - o).abs() < 1e-9 * o, "{up} {tau}: {v:?} vs {o}");
                assert!(
                    v[1].abs() < 1e-9 * o && v[2].abs() < 1e-9 * o,
                    "{up} {tau}: {v:?}"
                );
                // O is τ times half the sphere's solid angle.
                assert!((o / tau - FULL_SPHERE / 2.0).abs() < 1e-4, "{}", o / tau);
            }
        }
    }

    /// A white furnace's source is flat and 1; flux is conserved for any albedo and
    /// any scattered moments; a source heavy at the top sends more out upward.
    #[test]
    fn solve_known_answers_and_energy() {
        for tau in [0.01, 0.69, 3.0, 10.0] {
            let down = PassSums::new(false, tau);
            let up = PassSums::new(true, tau);
            // Furnace: the scattered moments of light 1 entering every segment.
            let mut e = [0.0; 3];
            for (w, seg) in pass_segments(false, tau) {
                let c = seg.collided();
                for n in 0..3 {
                    e[n] += w * c[n];
                }
            }
            let j = down.solve(1.0, e).unwrap();
            assert!((j[0] - 1.0).abs() < 1e-9, "{tau}: {j:?}");
            assert!(j[1].abs() < 1e-9 && j[2].abs() < 1e-9, "{tau}: {j:?}");
            for a in [0.0, 0.3, 0.9, 1.0] {
                for e in [[1.0, 0.0, 0.0], [1.0, 0.3, -0.1], [2.0, -0.9, 0.4]] {
                    let j = down.solve(a, e).unwrap();
                    let (out, absorbed) = down.escaped_absorbed(a, j);
                    assert!(
                        (out + absorbed - e[0]).abs() < 1e-9 * e[0],
                        "tau {tau} a {a} e {e:?}: {out} + {absorbed}"
                    );
                }
            }
            // Top-heavy source (P_1 > 0): the upward pass's segments send out more.
            if tau > 0.5 {
                let j = [1.0, 0.5, 0.0];
                let (gu, gd) = (
                    up.escaped_absorbed(1.0, j).0,
                    down.escaped_absorbed(1.0, j).0,
                );
                assert!(gu > gd * 1.05, "tau {tau}: up {gu} down {gd}");
            }
        }
        assert_eq!(PassSums::new(false, 0.0).solve(0.5, [1.0, 0.0, 0.0]), None);
    }

    /// The shared-cofactor solve satisfies the balance it solves (residual against
    /// the matrix multiplied out) on random well-conditioned systems, and finds none
    /// where the matrix is singular.
    #[test]
    fn solve_balance_satisfies_the_balance() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..2000 {
            let o = 0.5 + 20.0 * next();
            let k: [[f64; 3]; 3] =
                std::array::from_fn(|_| std::array::from_fn(|_| o * (next() - 0.5) * 0.2));
            let a = next();
            let e = [next() * 3.0, next() - 0.5, next() - 0.5];
            let j = solve_balance(o, &k, a, e).expect("diagonally dominant");
            for n in 0..3 {
                let lhs: f64 = (0..3)
                    .map(|c| {
                        let diag = if n == c { o / (2 * n + 1) as f64 } else { 0.0 };
                        (diag - a * k[n][c]) * j[c]
                    })
                    .sum();
                assert!(
                    (lhs - e[n]).abs() < 1e-12 * (1.0 + e[n].abs()),
                    "{lhs} vs {}",
                    e[n]
                );
            }
        }
        // Three colours at once: each colour's answer the one-colour solve's, bit
        // for bit, and the cell's absorbed flux the sum of theirs.
        for (i, tau) in [0.05, 0.7, 3.0, 40.0].into_iter().enumerate() {
            let pr = CellProfile::new(i % 2 == 0, -(tau as f32));
            for _ in 0..200 {
                let alb = Vec3::new(next() as f32, next() as f32, 0.5 + 0.5 * next() as f32);
                let r: [Vec3; 3] = std::array::from_fn(|n| {
                    Vec3::from_array(std::array::from_fn(|_| {
                        (if n == 0 { 3.0 * next() } else { next() - 0.5 }) as f32
                    }))
                });
                let mut absorbed = DVec3::ZERO;
                let j = source_rgb(&pr, alb, r, &mut absorbed);
                for c in 0..3 {
                    let (jc, ab) = pr.source(alb[c], [r[0][c], r[1][c], r[2][c]]);
                    for n in 0..3 {
                        assert_eq!(j[n][c].to_bits(), jc[n].to_bits(), "tau {tau} colour {c}");
                    }
                    assert_eq!(absorbed[c], ab as f64);
                }
            }
        }
        // O = 0, a = 0: the zero matrix.
        assert_eq!(
            solve_balance(0.0, &[[1.0; 3]; 3], 0.0, [1.0, 0.0, 0.0]),
            None
        );
        // Two equal rows.
        let k = [[0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]];
        assert_eq!(solve_balance(0.0, &k, 1.0, [1.0, 0.0, 0.0]), None);
    }
}
