//! The sweep itself. The semantics are in the crate docs; this file follows them step by
//! step (the step names in comments refer to them).

use std::f32::consts::PI;
use std::sync::OnceLock;

use lightgrid_core::dirs::{self, NUM_DIRS, NUM_SWEEP_DIRS};
use lightgrid_core::glam::{DVec3, IVec3, UVec3, Vec3};
use lightgrid_core::light::luminance;
use lightgrid_core::{
    AverageLight, BinLight, Boundary, CellSource, DominantDir, Grid, GridError, MaterialGrid,
    MediumEmission, SideBoundary, SweepError, SweepOptions, SweepOutput, SweepStats, TopBoundary,
};
use rayon::prelude::*;

use crate::isa::vectorised;

use crate::medium;

/// Number of transport channels of one pass (9 vertical-ish bins + 8 horizontal halves).
pub const CHANNELS: usize = NUM_SWEEP_DIRS;
/// Largest boundary light value accepted: leaves room for path-length factors (≤ √33) and
/// sums over a grid without overflowing `f32`.
pub const MAX_LIGHT: f32 = 1e30;

/// Cells a channel's path crosses inside its slab, as horizontal offsets from the
/// receiving point, in travel order, with the fraction of the path in each.
#[derive(Debug, Clone)]
pub struct Channel {
    /// Bin the channel's light is accounted in.
    pub bin: usize,
    /// Offset from source point to receiving point (y = -1 downward, +1 upward).
    pub step: IVec3,
    /// Path length per level in units of `h` ([`channel_length`]).
    pub length: f32,
    /// `1 / length`: `|cos|` of the path to the vertical, light to flux.
    pub mu: f32,
    /// Unit vector of the bin (direction of travel).
    pub unit: Vec3,
    /// `(dx, dz, fraction)` of each cell crossed, in travel order.
    pub stencil: Vec<(i32, i32, f32)>,
    /// For each stencil cell, the index in [`path_exponents`] of `fraction × length`.
    pub pow: Vec<usize>,
    /// Path fraction from the slab's entry to the receiving point's centre (always 1/2).
    pub first_slot: usize,
    /// Share of the bin's isotropic emission this channel carries: 1, or 1/2 for a
    /// horizontal bin (the other half travels in the opposite pass).
    pub share: f32,
}

impl Channel {
    /// 0 for a channel of the downward pass, 1 for the upward pass.
    #[inline]
    pub fn pass(&self) -> usize {
        (self.step.y > 0) as usize
    }
}

/// The distinct path lengths through one cell (in `h`) that the channels use, and the
/// halves of the centre cells': each cell's transmittance `p^e` is computed once per
/// exponent `e` and level, not once per path.
pub fn path_exponents() -> &'static [f32] {
    static E: OnceLock<Vec<f32>> = OnceLock::new();
    E.get_or_init(|| {
        let mut e: Vec<f32> = Vec::new();
        for sd in dirs::sweep_dirs() {
            let horizontal = sd.step.x.abs() > 1 || sd.step.z.abs() > 1;
            let fracs: &[f32] = if horizontal {
                &[0.125, 0.25]
            } else {
                &[1.0, 0.5]
            };
            for f in fracs {
                let v = f * channel_length(sd.bin);
                if !e.iter().any(|x| (x - v).abs() < 1e-6) {
                    e.push(v);
                }
            }
        }
        e
    })
}

/// Path length per level (in `h`) of the channels of bin `bin` (a downward or
/// horizontal bin; the upward pass mirrors them): `1 / μ̄`, where `μ̄` is the bin's mean
/// `|cos|` to the vertical over its solid angle (a horizontal bin's downward half). A
/// channel's flux per unit of light, `μ_c = 1 / ℓ_c`, is then the exact flux of light
/// constant within the bin, and its transmittance through a thin layer is the bin's
/// mean. (The step vector's own length, `ℓ = |s_c|`, overstates `μ` by 5 % on the
/// vertical bin and 30 % on the horizontal ones: the half-space albedo came out 5.5 %
/// too high with thin cells, `w = 0.5`; measured in issue 13, `examples/do1d.rs`.)
pub fn channel_length(bin: usize) -> f32 {
    static L: OnceLock<[f32; NUM_SWEEP_DIRS]> = OnceLock::new();
    L.get_or_init(|| {
        let g = dirs::bins();
        std::array::from_fn(|b| {
            let omega = if dirs::dir_unit(b).y == 0.0 {
                0.5 * g.omega[b]
            } else {
                g.omega[b]
            };
            (omega / dirs::clipped_cosine(b, -DVec3::Y)) as f32
        })
    })[bin]
}

/// Fewest points one parallel task of a level's fast phases handles: a 16 × 16 level
/// runs as two tasks, one a core (the bench forest, 16³, 4 passes: 6.8 ms at 512 points,
/// one task a level, 4.4 ms at 128; below 64, rayon's per-task cost shows).
pub const MIN_POINTS_PER_TASK: usize = 128;

/// Most points one parallel task of phases 2 and 3 handles: their rows differ in cost
/// with the material they hold, so the level is cut into many small tasks that the
/// threads take as they free up (two tasks of 128 points left one thread waiting on
/// the other: the bench forest, 16³, two passes, 2.63–2.67 ms before, 2.51–2.55 ms
/// after). Phase 1 keeps [`MIN_POINTS_PER_TASK`]: each thread then gathers from the
/// rows it wrote a level before (small tasks there, which move rows between cores,
/// gained nothing).
pub const MAX_POINTS_PER_UNEVEN_TASK: usize = 32;

/// Levels of more points than this fetch each block's cell profiles ahead of the
/// profile rule's loops over the stencil slots, which read each profile one value at a
/// time: 512 cells' profiles take 635 KB, and a level's that outgrow the 1 MB L2 came
/// from farther out (the crate docs, "Tenth round").
pub const FETCH_PROFILES_ABOVE: usize = 512;

/// Most distinct exponents (see [`path_exponents`]).
pub const MAX_EXPONENTS: usize = 10;

fn exponent_index(v: f32) -> usize {
    path_exponents()
        .iter()
        .position(|x| (x - v).abs() < 1e-6)
        .expect("exponent in the table")
}

/// Channels of the downward (`up = false`) or upward pass.
pub fn channels(up: bool) -> &'static [Channel; CHANNELS] {
    static DOWN: OnceLock<[Channel; CHANNELS]> = OnceLock::new();
    static UP: OnceLock<[Channel; CHANNELS]> = OnceLock::new();
    let make = |up: bool| {
        let mut slot = 0;
        std::array::from_fn(|c| {
            let sd = dirs::sweep_dirs()[c];
            let mut step = sd.step;
            let mut v = dirs::dir_ivec(sd.bin);
            if up {
                step.y = 1;
                v.y = -v.y;
            }
            let bin = dirs::dir_index(v).expect("mirrored direction");
            let horizontal = v.y == 0;
            let stencil = if horizontal {
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
            };
            let first_slot = slot;
            slot += stencil.len();
            let length = channel_length(sd.bin);
            let pow = stencil
                .iter()
                .map(|&(_, _, f)| exponent_index(f * length))
                .collect();
            Channel {
                bin,
                step,
                length,
                mu: 1.0 / length,
                unit: dirs::dir_unit(bin),
                pow,
                stencil,
                first_slot,
                share: if horizontal { 0.5 } else { 1.0 },
            }
        })
    };
    if up {
        UP.get_or_init(|| make(true))
    } else {
        DOWN.get_or_init(|| make(false))
    }
}

/// Rounds of re-emission, within one pass, of the light a cell's own material stops
/// (step 6); what remains waits for the next pass in this direction.
pub const LOCAL_ROUNDS: usize = 4;

/// Total stencil slots over the channels of a pass.
pub const SLOTS: usize = 9 + 8 * 5;

/// Flux balance of a sweep, per RGB channel, in units of light × `h²` per point
/// (multiply by `h²` for power). Every term is non-negative; `input()` equals
/// `absorbed + escaped() + pending` to float rounding.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EnergyBalance {
    /// Entered through the top face.
    pub top_in: DVec3,
    /// Entered through the bottom face.
    pub bottom_in: DVec3,
    /// Entered through the side faces.
    pub side_in: DVec3,
    /// Left through the top face.
    pub top_out: DVec3,
    /// Left through the bottom face.
    pub bottom_out: DVec3,
    /// Left through the side faces.
    pub side_out: DVec3,
    /// Absorbed by material.
    pub absorbed: DVec3,
    /// Scattered light not yet transported when the passes stopped.
    pub pending: DVec3,
    /// Taken from a beam inside the grid by a [`CellSource`] (the sun's first
    /// collisions): absorbed or scattered into the bins.
    pub source_in: DVec3,
}

impl EnergyBalance {
    /// Everything that entered.
    pub fn input(&self) -> DVec3 {
        self.top_in + self.bottom_in + self.side_in + self.source_in
    }
    /// Everything that left.
    pub fn escaped(&self) -> DVec3 {
        self.top_out + self.bottom_out + self.side_out
    }
    /// `|input - absorbed - escaped - pending| / input`, worst RGB channel (0 for no input).
    pub fn relative_error(&self) -> f64 {
        let diff = (self.input() - self.absorbed - self.escaped() - self.pending).abs();
        let inp = self.input();
        (0..3)
            .map(|i| {
                if inp[i] > 0.0 {
                    diff[i] / inp[i]
                } else {
                    diff[i]
                }
            })
            .fold(0.0, f64::max)
    }
}

/// A sweep's outputs and its energy balance.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// What the [`lightgrid_core::Sweeper`] trait returns.
    pub output: SweepOutput,
    /// The flux balance.
    pub balance: EnergyBalance,
}

/// Scattered light a cell holds for emission: total flux `s` (RGB) and its first moment
/// `m[axis]` (RGB) over the incoming directions.
///
/// Under [`MediumEmission::Profile`] a medium cell holds instead the source still to be
/// emitted through the segments of this direction's passes, as Legendre coefficients in
/// height ([`crate::profile`]): `J_0` in `s`, `J_1` and `J_2` in `m[0]` and `m[1]`
/// ([`Pending::coeffs`]), so that the pending light keeps its size under every rule.
#[derive(Clone, Copy, Default, bytemuck::Zeroable)]
struct Pending {
    s: Vec3,
    m: [Vec3; 3],
}

impl Pending {
    fn add(&self, o: &Pending) -> Pending {
        Pending {
            s: self.s + o.s,
            m: [self.m[0] + o.m[0], self.m[1] + o.m[1], self.m[2] + o.m[2]],
        }
    }
    fn scaled(&self, a: Vec3) -> Pending {
        Pending {
            s: self.s * a,
            m: self.m.map(|v| v * a),
        }
    }
    /// [`MediumEmission::Profile`]: the source coefficients `[J_0, J_1, J_2]` held.
    fn coeffs(&self) -> [Vec3; 3] {
        [self.s, self.m[0], self.m[1]]
    }
    /// [`MediumEmission::Profile`]: pending light holding the coefficients `j`.
    fn of_coeffs(j: [Vec3; 3]) -> Pending {
        Pending {
            s: j[0],
            m: [j[1], j[2], Vec3::ZERO],
        }
    }
}

/// Scattered light waiting in one direction ([`Pending`] per grid point), level by
/// level: a level's records are allocated (zeroed) when one of them is first written,
/// and a level never written holds none and reads as zero. Only levels with material
/// hold scattered light, so a sweep over mostly empty space (the 64³ canopy: ground and
/// leaves in 4 of 64 levels) neither allocates nor clears records for the rest. (One
/// vector of all points cost fresh work at 64³ 25–38 MB, which the allocator, serving
/// freed blocks of that size from its heap, zeroed in full.)
#[derive(Clone, Default)]
struct PendingLevels {
    level_len: usize,
    levels: Vec<Vec<Pending>>,
}

impl PendingLevels {
    const ZERO: Pending = Pending {
        s: Vec3::ZERO,
        m: [Vec3::ZERO; 3],
    };
    fn new(level_len: usize, levels: usize) -> Self {
        Self {
            level_len,
            levels: vec![Vec::new(); levels],
        }
    }
    /// Points in all.
    fn len(&self) -> usize {
        self.level_len * self.levels.len()
    }
    /// Level `j`'s records, allocated if it had none.
    fn level_mut(&mut self, j: usize) -> &mut [Pending] {
        let l = &mut self.levels[j];
        if l.is_empty() {
            *l = vec![Pending::default(); self.level_len];
        }
        l
    }
    /// Level `j`'s records set to zero (kept allocated for the next sweep).
    fn clear_level(&mut self, j: usize) {
        self.levels[j].fill(Pending::default());
    }
}

impl std::ops::Index<usize> for PendingLevels {
    type Output = Pending;
    fn index(&self, i: usize) -> &Pending {
        self.levels[i / self.level_len]
            .get(i % self.level_len)
            .unwrap_or(&Self::ZERO)
    }
}

impl std::ops::IndexMut<usize> for PendingLevels {
    fn index_mut(&mut self, i: usize) -> &mut Pending {
        let len = self.level_len;
        &mut self.level_mut(i / len)[i % len]
    }
}

/// Phase 2's outputs for the source rules, per cell of a level (or row): the flat
/// source `J_0`, whether the cell emits, the `P_1`, `P_2` coefficients of a quadratic
/// source in height (empty unless [`MediumEmission::Profile`]), the cells' profiles, and
/// what the `P_1`, `P_2` terms emit into each slot's segment (phase 3's [`Planes::ex`];
/// empty unless the profile rule on the fast path).
type EmitRows<'a> = (
    &'a mut [Vec3],
    &'a mut [bool],
    &'a mut [[Vec3; 2]],
    &'a crate::profile::Profiles,
    &'a mut [f32],
);

/// [`MediumEmission::Profile`] in phase 3's row kernel: the level's `P_1`, `P_2` source
/// coefficients, its cells' profiles, and which cells emit.
type ProfileRows<'a> = (&'a [[Vec3; 2]], &'a crate::profile::Profiles, &'a [bool]);

/// How a cell distributes scattered light `(S, M)` over the bins (step 5).
enum Emission {
    /// A medium (`p > 0`): `omega_b / 4pi * (A S - B u_b · M)` with `(A, B)` of
    /// [`medium_emission`]; the rest of each bin's isotropic share is stopped in the cell.
    Medium { a: f32, b: f32 },
    /// An opaque cell (`p = 0`): diffuse (Lambertian) faces where it borders a
    /// non-opaque cell, with fixed weights per channel (see [`surface_weights`]).
    Surface { w: &'static SurfaceWeights },
}

/// How an opaque cell with a given set of exposed faces emits: per channel
/// (`[pass][bin]`, pass 0 the downward channels, 1 the upward ones) the share of its
/// scattered light, and the part of that share that leaves the cell's level at once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceWeights {
    /// Share of the scattered flux sent into each channel (all channels sum to 1).
    pub w: [[f32; NUM_DIRS]; 2],
    /// The part of `w` emitted by a top or bottom face into a horizontal bin: it starts
    /// on the face, above (below) the cell's level, so the cell's level-mates on the
    /// channel's path (`T_after`) do not stop it.
    pub free: [[f32; NUM_DIRS]; 2],
}

/// Emission weights of an opaque cell by the mask of its exposed faces (bit `f` for
/// the face with normal `FACE_NORMALS[f]`).
///
/// Each exposed face is a Lambertian surface: it sends into bin `b` the exact fraction
/// `∫_b max(0, u · n) dω / π` of what it emits ([`dirs::clipped_cosine`]; the fractions
/// over all bins sum to 1). A downward bin belongs to the downward pass, an upward one
/// to the upward pass; a horizontal bin spans both halves of the sphere, and its share
/// goes to the half on the face's side (a top face emits upward, a bottom face downward,
/// a side face half into each). A top or bottom face's horizontal light starts on the
/// face, outside the cell's level, so it is `free` of the level's `T_after`. The weights
/// are the mean over the exposed faces. They do not depend on the light, so the sweep
/// stays linear. An enclosed cell (mask 0, unreachable by light) scatters isotropically
/// (`ω_b / 4π`, horizontal bins halved).
///
/// (The seed's rule weighted each bin by `ω_b max(0, u_b · n)` at its centre direction,
/// which gives horizontal bins nothing: ground light above a Lambertian surface came out
/// 7 % too bright looking down, measured in `tests/exact.rs`.)
pub fn surface_weights(mask: u8) -> &'static SurfaceWeights {
    static T: OnceLock<Vec<SurfaceWeights>> = OnceLock::new();
    let t = T.get_or_init(|| {
        let omega = dirs::solid_angles();
        (0..64u8)
            .map(|m| {
                let faces: Vec<Vec3> = (0..6)
                    .filter(|f| m & (1 << f) != 0)
                    .map(|f| FACE_NORMALS[f])
                    .collect();
                let mut w = [[0f64; NUM_DIRS]; 2];
                let mut free = [[0f64; NUM_DIRS]; 2];
                // `into(b, side, v)`: v into bin b from a source whose normal has y
                // component `side` (horizontal bins go to that half, or both for 0).
                let mut into = |b: usize, side: f32, v: f64| {
                    let dy = dirs::dir_unit(b).y;
                    if dy < 0.0 {
                        w[0][b] += v;
                    } else if dy > 0.0 {
                        w[1][b] += v;
                    } else if side == 0.0 {
                        w[0][b] += v * 0.5;
                        w[1][b] += v * 0.5;
                    } else {
                        let h = (side > 0.0) as usize;
                        w[h][b] += v;
                        free[h][b] += v;
                    }
                };
                if faces.is_empty() {
                    for b in 0..NUM_DIRS {
                        into(b, 0.0, omega[b] as f64 / (4.0 * std::f64::consts::PI));
                    }
                }
                for n in &faces {
                    for b in 0..NUM_DIRS {
                        let c = dirs::clipped_cosine(b, n.as_dvec3()) / std::f64::consts::PI;
                        into(b, n.y, c / faces.len() as f64);
                    }
                }
                SurfaceWeights {
                    w: w.map(|h| h.map(|v| v as f32)),
                    free: free.map(|h| h.map(|v| v as f32)),
                }
            })
            .collect()
    });
    &t[mask as usize & 63]
}

/// Outward normals of a cell's six faces, in exposure-mask bit order (the ambient
/// cube's axis order).
pub const FACE_NORMALS: [Vec3; 6] = lightgrid_core::light::AMBIENT_AXES;

/// The medium emission weights `(A, B)` of step 5 for a cell of pass-through `p`
/// (`0 < p < 1`; optical depth `τ = −ln p` over one level): a slab's exact escape
/// probabilities for light scattered out of a vertical beam, whose collisions fall
/// `∝ e^{−τ z}` with depth `z` into the cell: out of the far face (forward) `s = τ p /
/// (1 − p)`, out of the entry face (back) `o = (1 + p) / 2`; `A = (s + o) / 2`, `B = (o −
/// s) / 2`, so that `A − B u·M / S` is `s` straight on and `o` straight back. Clear
/// cells (`p → 1`) tend to `(1, 0)`; very dense ones to `(1/4, 1/4)`.
///
/// (The seed's rule, `A = (1 + p)/2`, `B = (1 − p)/2`, lets everything out straight back
/// and `p` straight on: dense media reflected far too much, Chandrasekhar's half-space
/// albedo +26 % at cells of optical depth 0.69 and +59 % at 3 for `w = 0.5`, against
/// +9 % and −4 % with this rule; `lightgrid_sweep_cpu::exact`.)
pub fn medium_emission(pass: f32) -> (f32, f32) {
    if !(pass > 0.0 && pass < 1.0) {
        return (1.0, 0.0);
    }
    let forward = -pass.ln() * pass / (1.0 - pass);
    let back = (1.0 + pass) * 0.5;
    ((forward + back) * 0.5, (back - forward) * 0.5)
}

impl Emission {
    fn new(pass: f32, exposed: u8, rule: MediumEmission) -> Self {
        if pass > 0.0 {
            let (a, b) = match rule {
                MediumEmission::Escape => medium_emission(pass),
                // Emitted by `crate::medium` in phase 3; isotropic budget here.
                MediumEmission::Source | MediumEmission::Profile => (1.0, 0.0),
            };
            Emission::Medium { a, b }
        } else {
            Emission::Surface {
                w: surface_weights(exposed),
            }
        }
    }

    /// The cell's weights for every channel of a pass as lanes: a medium sends `ω_b/4π ×
    /// share × (A S − B u·M)` (clamped at 0), all of it through `T_after`; a surface its
    /// fixed weight `w S`, the `free` part of it past `T_after`.
    fn lanes(
        &self,
        l: &PassLanes,
        ch: &[Channel; CHANNELS],
        t_after: &[f32; CHANNELS],
    ) -> CellLanes {
        let mut cl = CellLanes {
            fa: [0.0; LANES],
            fb: [0.0; LANES],
            free: [0.0; LANES],
            full: [0.0; LANES],
            t_after: [0.0; LANES],
        };
        cl.t_after[..CHANNELS].copy_from_slice(t_after);
        match self {
            Emission::Medium { a, b } => {
                for c in 0..CHANNELS {
                    cl.fa[c] = a * l.iso[c];
                    cl.fb[c] = b * l.iso[c];
                    cl.full[c] = l.iso[c];
                }
            }
            Emission::Surface { w } => {
                for (c, chn) in ch.iter().enumerate() {
                    cl.fa[c] = w.w[chn.pass()][chn.bin];
                    cl.full[c] = cl.fa[c];
                    cl.free[c] = w.free[chn.pass()][chn.bin];
                }
            }
        }
        cl
    }

    /// Channel `chn`'s share of the scattered flux before anything stops it.
    #[inline]
    fn full(&self, p: &Pending, chn: &Channel) -> Vec3 {
        match self {
            Emission::Medium { .. } => {
                p.s * (dirs::solid_angles()[chn.bin] / (4.0 * PI) * chn.share)
            }
            Emission::Surface { w } => p.s * w.w[chn.pass()][chn.bin],
        }
    }

    /// The share of `p` that the pass with channels `ch` will emit (half, for a medium).
    fn budget(&self, p: &Pending, ch: &[Channel; CHANNELS]) -> Vec3 {
        if p.s == Vec3::ZERO {
            return Vec3::ZERO;
        }
        match self {
            Emission::Medium { .. } => p.s * 0.5,
            Emission::Surface { .. } => ch.iter().map(|c| self.full(p, c)).sum(),
        }
    }
}

/// Channels of a pass as lanes of phase 2's per-cell loops (structure of arrays, padded
/// with zeros to a multiple of 4 so that the loops vectorise).
const LANES: usize = CHANNELS.next_multiple_of(4);

/// The channels of one pass as [`LANES`]: unit vectors, isotropic shares (`ω_b / 4π`
/// times the channel's share), path lengths and half of them.
struct PassLanes {
    u: [[f32; LANES]; 3],
    iso: [f32; LANES],
    length: [f32; LANES],
    half_length: [f32; LANES],
}

fn pass_lanes(up: bool) -> &'static PassLanes {
    static L: OnceLock<[PassLanes; 2]> = OnceLock::new();
    let make = |up: bool| {
        let ch = channels(up);
        let mut l = PassLanes {
            u: [[0.0; LANES]; 3],
            iso: [0.0; LANES],
            length: [0.0; LANES],
            half_length: [0.0; LANES],
        };
        for (c, chn) in ch.iter().enumerate() {
            for a in 0..3 {
                l.u[a][c] = chn.unit[a];
            }
            l.iso[c] = dirs::solid_angles()[chn.bin] / (4.0 * PI) * chn.share;
            l.length[c] = chn.length;
            l.half_length[c] = 0.5 * chn.length;
        }
        l
    };
    &L.get_or_init(|| [make(false), make(true)])[up as usize]
}

/// One cell's emission weights as lanes (see [`Emission::lanes`]).
struct CellLanes {
    /// Flux into a channel: `max(0, S·fa − (u·M)·fb)`.
    fa: [f32; LANES],
    fb: [f32; LANES],
    /// The part of that flux that leaves free of `T_after` (a top or bottom face's
    /// horizontal light): `S·free`.
    free: [f32; LANES],
    /// The channel's share before anything stops it: `S·full`.
    full: [f32; LANES],
    /// `T_after` of each channel.
    t_after: [f32; LANES],
}

impl CellLanes {
    /// One round of step 6 for one colour (scattered flux `s`, moment `m`): adds what
    /// leaves the level to `leave` and what is emitted to `emit`, returns what the
    /// cell's own material stops, per channel.
    #[inline]
    fn round(
        &self,
        l: &PassLanes,
        s: f32,
        m: [f32; 3],
        (leave, emit): (&mut [f32; LANES], &mut [f32; LANES]),
        signed: bool,
    ) -> [f32; LANES] {
        let mut lost = [0f32; LANES];
        // Clamping at 0 only for light of one sign (see `Ctx::signed`).
        let floor = if signed { f32::NEG_INFINITY } else { 0.0 };
        for c in 0..LANES {
            let um = m[0] * l.u[0][c] + m[1] * l.u[1][c] + m[2] * l.u[2][c];
            let f = (s * self.fa[c] - um * self.fb[c]).max(floor);
            let fr = s * self.free[c];
            let leaving = (f - fr) * self.t_after[c] + fr;
            lost[c] = (s * self.full[c] - leaving).max(floor);
            leave[c] += leaving;
            emit[c] += f;
        }
        lost
    }
}

#[inline]
fn lanes_sum(v: &[f32; LANES]) -> f32 {
    let mut a = [0f32; 4];
    for ch in v.chunks_exact(4) {
        for i in 0..4 {
            a[i] += ch[i];
        }
    }
    (a[0] + a[1]) + (a[2] + a[3])
}

#[inline]
fn lanes_dot(v: &[f32; LANES], w: &[f32; LANES]) -> f32 {
    let mut a = [0f32; 4];
    for (x, y) in v.chunks_exact(4).zip(w.chunks_exact(4)) {
        for i in 0..4 {
            a[i] += x[i] * y[i];
        }
    }
    (a[0] + a[1]) + (a[2] + a[3])
}

fn up_pass(ch: &[Channel; CHANNELS]) -> bool {
    ch[0].step.y > 0
}

/// Where the final light of a point goes: all 26 bins, or only what the average and the
/// dominant direction need.
trait Sink: Copy + Default + Send + Sync + bytemuck::Pod {
    /// The sink holds every bin (so [`resolve_planes`] computes what its `resolve`
    /// would, from the level's planes, where a point's bins hold exactly one pass's
    /// channel light).
    const ALL_BINS: bool = false;
    fn add(&mut self, bin: usize, unit: Vec3, g: Vec3);
    /// [`Sink::add`] of every channel of a pass, in channel order: `light(c)` into
    /// channel `c`'s bin.
    #[inline]
    fn add_channels(&mut self, ch: &[Channel; CHANNELS], light: impl Fn(usize) -> Vec3) {
        for (c, chn) in ch.iter().enumerate() {
            self.add(chn.bin, chn.unit, light(c));
        }
    }
    /// The point's final values: every value finite and `>= 0`, the average, and the
    /// dominant direction (if `dominant`; zero otherwise).
    fn resolve(&self, dominant: bool) -> (bool, Vec3, Vec3);
    /// Light below 0 set to 0 (after accelerated passes, [`crate::accel`]).
    fn clamp(&mut self);
    /// [`Sink::resolve`] for every point of `g` into `avg` and `dom`; `false` if any
    /// value is negative, NaN or infinite.
    #[inline(always)]
    fn resolve_all(
        g: &[Self],
        avg: &mut [AverageLight],
        dom: &mut [DominantDir],
        dominant: bool,
    ) -> bool {
        resolve_each(g, avg, dom, dominant)
    }
}

/// [`Sink::resolve`] point by point (what [`Sink::resolve_all`] does unless a sink
/// does better).
fn resolve_each<S: Sink>(
    g: &[S],
    avg: &mut [AverageLight],
    dom: &mut [DominantDir],
    dominant: bool,
) -> bool {
    let mut ok = true;
    for ((g, a), d) in g.iter().zip(avg).zip(dom) {
        let (v, av, dv) = g.resolve(dominant);
        ok &= v & av.is_finite() & dv.is_finite();
        a.0 = av;
        d.0 = dv;
    }
    ok
}

impl Sink for BinLight {
    const ALL_BINS: bool = true;
    #[inline]
    fn add(&mut self, bin: usize, _unit: Vec3, g: Vec3) {
        self.0[bin] += g;
    }
    /// `Vec3::max(ZERO)` on every bin, as flat floats (the same comparison, `v > 0 ?
    /// v : 0`, so NaN and -0 become +0 as there; as `Vec3`s it did not vectorise).
    #[inline]
    fn clamp(&mut self) {
        let f: &mut [f32] = bytemuck::cast_slice_mut(std::slice::from_mut(self));
        for v in f {
            *v = if *v > 0.0 { *v } else { 0.0 };
        }
    }
    /// `BinLight::average` and `dominant` in one loop over the bins (each computed
    /// the total on its own), bit for bit as they compute.
    #[inline]
    fn resolve(&self, dominant: bool) -> (bool, Vec3, Vec3) {
        let mut total = Vec3::ZERO;
        let mut v = Vec3::ZERO;
        let mut sum = 0.0;
        for (light, unit) in self.0.iter().zip(dirs::units()) {
            total += *light;
            if dominant {
                let l = luminance(*light);
                v += *unit * l;
                sum += l;
            }
        }
        let (av, d) = resolved(total, v, sum);
        (valid_bins(self), av, d)
    }
    /// [`BinLight::resolve`] four points at a time (the same operations in the same
    /// order for each point, so bit for bit its values): one point's sums are chains of
    /// 26 dependent adds, four points' chains overlap.
    #[inline(always)]
    fn resolve_all(
        g: &[Self],
        avg: &mut [AverageLight],
        dom: &mut [DominantDir],
        dominant: bool,
    ) -> bool {
        const N: usize = 4;
        let mut ok = true;
        let (g4, g_rest) = g.as_chunks::<N>();
        let (a4, a_rest) = avg.as_chunks_mut::<N>();
        let (d4, d_rest) = dom.as_chunks_mut::<N>();
        let [wr, wg, wb] = lightgrid_core::light::LUMA;
        for ((g, a), d) in g4.iter().zip(a4).zip(d4) {
            // Lane j is point j; each sum is the `Vec3` operations of `resolve`
            // written out per component, in its order.
            let (mut tr, mut tg, mut tb) = ([0f32; N], [0f32; N], [0f32; N]);
            let (mut vx, mut vy, mut vz, mut sum) = ([0f32; N], [0f32; N], [0f32; N], [0f32; N]);
            let units = dirs::units();
            if dominant {
                for (b, u) in units.iter().enumerate() {
                    let r: [f32; N] = std::array::from_fn(|j| g[j].0[b].x);
                    let gg: [f32; N] = std::array::from_fn(|j| g[j].0[b].y);
                    let bb: [f32; N] = std::array::from_fn(|j| g[j].0[b].z);
                    for j in 0..N {
                        tr[j] += r[j];
                        tg[j] += gg[j];
                        tb[j] += bb[j];
                        let l = r[j] * wr + gg[j] * wg + bb[j] * wb;
                        vx[j] += u.x * l;
                        vy[j] += u.y * l;
                        vz[j] += u.z * l;
                        sum[j] += l;
                    }
                }
            } else {
                for b in 0..NUM_DIRS {
                    for j in 0..N {
                        tr[j] += g[j].0[b].x;
                        tg[j] += g[j].0[b].y;
                        tb[j] += g[j].0[b].z;
                    }
                }
            }
            for j in 0..N {
                let (av, dv) = resolved(
                    Vec3::new(tr[j], tg[j], tb[j]),
                    Vec3::new(vx[j], vy[j], vz[j]),
                    sum[j],
                );
                ok &= valid_bins(&g[j]) & av.is_finite() & dv.is_finite();
                a[j].0 = av;
                d[j].0 = dv;
            }
        }
        ok & resolve_each(g_rest, a_rest, d_rest, dominant)
    }
}

/// The average and the dominant direction from a point's sums over its bins: the
/// total, and the luminance-weighted sum of the bins' directions `v` and of their
/// luminances `sum` (`BinLight::average` and `dominant`'s last steps; zero where no
/// light has a direction).
#[inline]
fn resolved(total: Vec3, v: Vec3, sum: f32) -> (Vec3, Vec3) {
    let d = if sum > 0.0 && sum.is_finite() {
        (v / sum).clamp_length_max(1.0)
    } else {
        Vec3::ZERO
    };
    (total / (4.0 * PI), d)
}

/// `BinLight::is_valid` without early exit (every value finite and >= 0; NaN fails
/// `v >= 0`), so that it vectorises.
#[inline]
fn valid_bins(b: &BinLight) -> bool {
    let f: &[f32] = bytemuck::cast_slice(std::slice::from_ref(b));
    // Lanes of the least and greatest value and of "any NaN" (NaN fails every
    // comparison, so it moves neither bound): branch-free, so that it vectorises
    // (`fold` with `Range::contains`, whose `&&` branches, ran 2.5 times slower).
    let (chunks, rest) = f.as_chunks::<4>();
    let (mut lo, mut hi, mut nan) = ([0f32; 4], [0f32; 4], [false; 4]);
    for c in chunks {
        for j in 0..4 {
            let v = c[j];
            lo[j] = if v < lo[j] { v } else { lo[j] };
            hi[j] = if v > hi[j] { v } else { hi[j] };
            nan[j] |= v.is_nan();
        }
    }
    // (The two values after the last four: `contains` is as good there.)
    let ok = |v: f32| (0.0..f32::INFINITY).contains(&v);
    (0..4).fold(true, |a, j| {
        a & (lo[j] >= 0.0) & (hi[j] < f32::INFINITY) & !nan[j]
    }) & rest.iter().fold(true, |a, &v| a & ok(v))
}

/// [`BinLight`]'s `resolve` (after its `clamp` if `clamp`) of every point of a row
/// whose bins hold exactly the light of pass channels `ch` (zero in the other bins),
/// computed from the row's planes (`cur_row`, pitch `p`: [`LevelLight`]'s layout) as
/// lanes along the row: the same operations, per point, in the same order (bins in
/// order; a zero bin adds `+0`, which leaves a sum that starts at `+0` as it is), so
/// bit for bit its values. `false` if a value is negative, NaN or infinite. A level's
/// point after the first pass's gather is such a point: this is the one-pass sweep's
/// resolve without reading its bins (one point's bins at a time, as `BinLight`s, the
/// sums do not vectorise).
#[inline(always)]
fn resolve_planes(
    ch: &[Channel; CHANNELS],
    cur_row: &[f32],
    p: usize,
    (clamp, dominant): (bool, bool),
    avg: &mut [AverageLight],
    dom: &mut [DominantDir],
) -> bool {
    match (clamp, dominant) {
        (false, false) => resolve_planes_as::<false, false>(ch, cur_row, p, avg, dom),
        (false, true) => resolve_planes_as::<false, true>(ch, cur_row, p, avg, dom),
        (true, false) => resolve_planes_as::<true, false>(ch, cur_row, p, avg, dom),
        (true, true) => resolve_planes_as::<true, true>(ch, cur_row, p, avg, dom),
    }
}

#[inline(always)]
fn resolve_planes_as<const CLAMP: bool, const DOMINANT: bool>(
    ch: &[Channel; CHANNELS],
    cur_row: &[f32],
    p: usize,
    avg: &mut [AverageLight],
    dom: &mut [DominantDir],
) -> bool {
    const B: usize = GATHER_BLOCK;
    let nx = avg.len();
    let mut of_bin = [None; NUM_DIRS];
    for (c, chn) in ch.iter().enumerate() {
        of_bin[chn.bin] = Some(c);
    }
    let units = dirs::units();
    let [wr, wg, wb] = lightgrid_core::light::LUMA;
    let mut ok = true;
    let mut x0 = 0;
    while x0 < nx {
        let b = B.min(nx - x0);
        with_width(
            b,
            #[inline(always)]
            |b| {
                let (mut tr, mut tg, mut tb) = ([0f32; B], [0f32; B], [0f32; B]);
                let (mut vx, mut vy, mut vz, mut sum) =
                    ([0f32; B], [0f32; B], [0f32; B], [0f32; B]);
                // Lanes of the least and greatest value and of "any NaN" ([`valid_bins`]).
                let (mut lo, mut hi, mut nan) = ([0f32; B], [0f32; B], [false; B]);
                for (bin, c) in of_bin.iter().enumerate() {
                    let Some(c) = *c else { continue };
                    let u = units[bin];
                    let plane = |k: usize| &cur_row[(c * 3 + k) * p + PAD + x0..][..b];
                    let (pr, pg, pb) = (plane(0), plane(1), plane(2));
                    for i in 0..b {
                        let cl = |v: f32| if !CLAMP || v > 0.0 { v } else { 0.0 };
                        let (r, g, bl) = (cl(pr[i]), cl(pg[i]), cl(pb[i]));
                        tr[i] += r;
                        tg[i] += g;
                        tb[i] += bl;
                        for v in [r, g, bl] {
                            lo[i] = if v < lo[i] { v } else { lo[i] };
                            hi[i] = if v > hi[i] { v } else { hi[i] };
                            nan[i] |= v.is_nan();
                        }
                        if DOMINANT {
                            let l = r * wr + g * wg + bl * wb;
                            vx[i] += u.x * l;
                            vy[i] += u.y * l;
                            vz[i] += u.z * l;
                            sum[i] += l;
                        }
                    }
                }
                for i in 0..b {
                    let (av, dv) = resolved(
                        Vec3::new(tr[i], tg[i], tb[i]),
                        Vec3::new(vx[i], vy[i], vz[i]),
                        sum[i],
                    );
                    let valid = (lo[i] >= 0.0) & (hi[i] < f32::INFINITY) & !nan[i];
                    ok &= valid & av.is_finite() & dv.is_finite();
                    avg[x0 + i].0 = av;
                    dom[x0 + i].0 = dv;
                }
            },
        );
        x0 += b;
    }
    ok
}

/// Running sums for the average (`sum`) and dominant direction (`num / den`).
#[derive(Clone, Copy, Default, bytemuck::Zeroable, bytemuck::Pod)]
#[repr(C)]
struct AvgAcc {
    sum: Vec3,
    num: Vec3,
    den: f32,
}

impl Sink for AvgAcc {
    #[inline]
    fn add(&mut self, _bin: usize, unit: Vec3, g: Vec3) {
        self.sum += g;
        let l = luminance(g);
        self.num += unit * l;
        self.den += l;
    }
    /// The sums in a local: adding in place made each channel's add wait on the
    /// store of the one before (one chain through memory per point).
    #[inline]
    fn add_channels(&mut self, ch: &[Channel; CHANNELS], light: impl Fn(usize) -> Vec3) {
        let mut acc = *self;
        for (c, chn) in ch.iter().enumerate() {
            acc.add(chn.bin, chn.unit, light(c));
        }
        *self = acc;
    }
    #[inline]
    fn clamp(&mut self) {
        self.sum = self.sum.max(Vec3::ZERO);
        self.den = self.den.max(0.0);
    }
    fn resolve(&self, dominant: bool) -> (bool, Vec3, Vec3) {
        let avg = self.sum / (4.0 * PI);
        let d = if dominant && self.den > 0.0 && self.den.is_finite() {
            (self.num / self.den).clamp_length_max(1.0)
        } else {
            Vec3::ZERO
        };
        (avg.is_finite() && d.is_finite(), avg, d)
    }
}

/// Points per task of [`resolve`].
const RESOLVE_CHUNK: usize = 512;

/// Every point's final values into `avg` and `dom` (the grids `LightGrid::average_grid`
/// and `dominant_grid` would give, for all 26 bins), on every core; `false` if any value
/// is negative, NaN or infinite.
fn resolve<S: Sink>(
    g: &[S],
    avg: &mut [AverageLight],
    dom: &mut [DominantDir],
    dominant: bool,
) -> bool {
    g.par_chunks(RESOLVE_CHUNK)
        .zip(avg.par_chunks_mut(RESOLVE_CHUNK))
        .zip(dom.par_chunks_mut(RESOLVE_CHUNK))
        .map(|((g, a), d)| vectorised!(S::resolve_all(g, a, d, dominant)))
        .reduce(|| true, |a, b| a & b)
}

/// Per-row flux sums, reduced in row order (deterministic for any thread count).
#[derive(Clone, Copy, Default)]
struct RowFlux {
    inside: DVec3,
    outside: DVec3,
    absorbed: DVec3,
    pending: DVec3,
    /// Flux the row's final light sends on to the next level (or out of the grid).
    sent: DVec3,
    /// Flux emitted into the paths of points beyond an open or given side (phase 3):
    /// it leaves through the side.
    side_out: DVec3,
    /// A resolved value was negative, NaN or infinite.
    bad: bool,
    /// `sent` is already set (a row that passed its light on unchanged: what it
    /// gathered, summed in the same order); [`Ctx::finish_row`] leaves it.
    sent_known: bool,
}

impl std::ops::Add for RowFlux {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            inside: self.inside + o.inside,
            outside: self.outside + o.outside,
            absorbed: self.absorbed + o.absorbed,
            pending: self.pending + o.pending,
            sent: self.sent + o.sent,
            side_out: self.side_out + o.side_out,
            bad: self.bad | o.bad,
            sent_known: false,
        }
    }
}

/// What the last phase of a level does for each of its rows once the row's light is
/// final ([`Ctx::finish_row`]): sum the flux it sends on and, in the last pass, resolve
/// the row's output into these rows of the average and dominant grids.
struct Finish<'a> {
    /// The level's rows of the average and dominant grids.
    avg: &'a mut [AverageLight],
    dom: &'a mut [DominantDir],
    /// This phase is the level's last: sum `sent`, and resolve if `resolve`.
    last_phase: bool,
    /// `Some(dominant)`: resolve (the last pass).
    resolve: Option<bool>,
    /// Light below 0 set to 0 before it is resolved (light of either sign flows).
    clamp: bool,
    /// Each point's output holds exactly this pass's channel light, the level's
    /// final light (the first pass's phase 1 of a level without material): resolve
    /// from the level's planes ([`resolve_planes`]).
    from_planes: bool,
    /// Write each row's ring columns ([`wrap_columns`], periodic sides) as the row
    /// ends, while it is in cache: for a next level without material, which would
    /// otherwise wrap them on one thread while the other waits. (A level with material
    /// wraps them beside its transmittances, [`LevelLight::wrap_ring`].)
    wrap_columns: bool,
}

fn sum_rows(v: &[RowFlux]) -> RowFlux {
    v.iter().fold(RowFlux::default(), |a, b| a + *b)
}

type Level = [Vec3; CHANNELS];

/// Columns (and rows) of the ring around a [`LevelLight`]: a tap of step 1 lies at most
/// four columns (a horizontal channel's step) and one (the smoothing tap) beyond a point.
const PAD: usize = 5;

/// One level's channel light (step 1's `O'`, and the level being built), row by row in
/// planes, with a ring of [`PAD`] columns and rows around the grid: channel `c`, colour
/// `k` of column `(x, z)` (`-PAD <= x < nx + PAD`, the same for `z`) is at
/// `((z + PAD)·CHANNELS·3 + c·3 + k)·pitch + x + PAD`, `pitch = nx + 2·PAD`. One
/// channel's colour along a row is contiguous, so the fast path's gather over a row is
/// a loop over slices that the compiler vectorises; a row is one contiguous chunk
/// (`row_len`) for the parallel tasks. The ring holds the light of the columns a tap
/// beyond the sides reads *from inside the grid*: the wrapped columns on periodic sides
/// ([`LevelLight::wrap_ring`], or row by row as a level ends, [`Finish::wrap_columns`]),
/// zero otherwise; light from outside (open sides, a given
/// halo) comes from a second `LevelLight` whose inside is zero and whose ring holds it.
#[derive(Clone)]
struct LevelLight {
    v: Vec<f32>,
    nx: usize,
    nz: usize,
}

impl LevelLight {
    fn new(nx: usize, nz: usize) -> Self {
        Self {
            v: vec![0.0; CHANNELS * 3 * (nx + 2 * PAD) * (nz + 2 * PAD)],
            nx,
            nz,
        }
    }
    /// Floats from one column to the same column of the next plane.
    #[inline]
    fn pitch(&self) -> usize {
        self.nx + 2 * PAD
    }
    /// Floats per row of points.
    #[inline]
    fn row_len(&self) -> usize {
        CHANNELS * 3 * self.pitch()
    }
    /// The rows of the grid (the ring's rows left out), for the parallel tasks.
    fn rows_mut(&mut self) -> &mut [f32] {
        let r = self.row_len();
        &mut self.v[PAD * r..(PAD + self.nz) * r]
    }
    /// Row `z` (`-PAD <= z < nz + PAD`).
    #[inline]
    fn row(&self, z: isize) -> &[f32] {
        let r = self.row_len();
        &self.v[(z + PAD as isize) as usize * r..][..r]
    }
    #[inline]
    fn row_mut(&mut self, z: isize) -> &mut [f32] {
        let r = self.row_len();
        &mut self.v[(z + PAD as isize) as usize * r..][..r]
    }
    /// Channel `c` of the point with level index `i`.
    #[inline]
    fn at(&self, i: usize, c: usize) -> Vec3 {
        let (x, z) = (i % self.nx, i / self.nx);
        row_get(self.row(z as isize), self.pitch(), x, c)
    }
    /// Every point of the grid: the same channel values `v` (the ring is left as it is).
    fn fill(&mut self, v: &Level) {
        let p = self.pitch();
        let nx = self.nx;
        let r = self.row_len();
        self.rows_mut().par_chunks_mut(r).for_each(|row| {
            for (c, val) in v.iter().enumerate() {
                for k in 0..3 {
                    row[(c * 3 + k) * p + PAD..][..nx].fill(val[k]);
                }
            }
        });
    }
    /// Adds `o`'s light, ring and all.
    fn add(&mut self, o: &LevelLight) {
        let r = self.row_len();
        self.v
            .par_chunks_mut(r)
            .zip(o.v.par_chunks(r))
            .for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(a, b)| *a += b));
    }
    /// The ring from the wrapped columns and rows of the grid (periodic sides).
    fn wrap_ring(&mut self) {
        let (nx, p) = (self.nx, self.pitch());
        for z in 0..self.nz as isize {
            wrap_columns(self.row_mut(z), p, nx);
        }
        self.wrap_ring_rows();
    }
    /// The ring's rows from the wrapped rows of the grid (periodic sides), where each
    /// row's ring columns hold its wrapped columns already ([`wrap_columns`]).
    fn wrap_ring_rows(&mut self) {
        let (nz, r) = (self.nz as isize, self.row_len());
        for z in (-(PAD as isize)..0).chain(nz..nz + PAD as isize) {
            let from = (z.rem_euclid(nz) + PAD as isize) as usize * r;
            let to = (z + PAD as isize) as usize * r;
            self.v.copy_within(from..from + r, to);
        }
    }
}

/// The ring columns of one row of a [`LevelLight`] (planes of pitch `p`, `nx` columns
/// each) from the row's wrapped columns (periodic sides): left the last [`PAD`], right
/// the first.
#[inline]
fn wrap_columns(row: &mut [f32], p: usize, nx: usize) {
    for plane in row.chunks_exact_mut(p) {
        if nx >= PAD {
            // (Element by element: a call to memmove for five floats cost more than
            // the copy.)
            for i in 0..PAD {
                plane[i] = plane[nx + i];
                plane[nx + PAD + i] = plane[PAD + i];
            }
        } else {
            let n = nx as isize;
            for x in (-(PAD as isize)..0).chain(n..n + PAD as isize) {
                plane[(x + PAD as isize) as usize] =
                    plane[(x.rem_euclid(n) + PAD as isize) as usize];
            }
        }
    }
}

/// The mean over a segment of optical depth `depth` (transmittance `tr = e^−depth`) of
/// the transmittance from its start, `(1 − tr) / depth`: a point's light is the mean of
/// its path's light over the segment through its own cell (the crate docs, step 7), as
/// the Monte Carlo reference tallies a cell's mean. 1 for an empty segment, 0 for an
/// opaque one (`depth` infinite), `1 / depth` where `tr` underflows; in `[tr, 1]`. Taken
/// from the depth, not from `tr` alone, so that it stays right (and the GPU's equal)
/// where `tr` is below `f32`'s normal range.
#[inline]
pub fn seg_mean(tr: f32, depth: f32) -> f32 {
    if depth.is_nan() || depth <= 0.0 {
        return 1.0;
    }
    // Below 0.02, the series `1 − x/2 + x²/6 − x³/24` (within 2e-9): `1 − tr` loses
    // digits in `f32`.
    if depth < 0.02 {
        return 1.0 - depth * (0.5 - depth * (1.0 / 6.0 - depth / 24.0));
    }
    (1.0 - tr) / depth
}

/// Points of a row that the row loops of phases 2 and 3 take at a time.
const GATHER_BLOCK: usize = 64;

/// Runs `block(b)` for a block of `b` points with `b` a constant where it is one of the
/// common widths (whole blocks of [`GATHER_BLOCK`], rows of 32 and 16 points): each arm
/// inlines `block` where the optimiser finds it small enough, so that its loops over
/// `0..b` compile without remainder loops or bounds checks. (The bench forest's rows
/// are 16 points: its four passes 3.06–3.10 → 2.84–2.89 ms with the transmit step's
/// blocks alone, ninth round. The optimiser compiles the larger blocks, phase 3's and
/// the collisions', once for any width; writing each arm out by a macro made the
/// forest 1–3 % slower, the crate docs' "Eleventh round".)
#[inline(always)]
fn with_width(b: usize, mut block: impl FnMut(usize)) {
    match b {
        GATHER_BLOCK => block(GATHER_BLOCK),
        32 => block(32),
        16 => block(16),
        b => block(b),
    }
}

/// Columns of ring each side of a row of a level's slot planes ([`Planes::ex`]): the
/// farthest reach of a stencil along a row (`channels_reach_no_farther_than_the_ring`).
const RING: usize = 2;

/// The pitch of a row of `nx` points in a slot plane with its ring ([`RING`]).
#[inline]
fn ring_pitch(nx: usize) -> usize {
    nx + 2 * RING
}

/// The stencil slots whose tap lies beside the point's column (`dx ≠ 0`): the only
/// ones a reader takes ring columns of. The same in both passes (they mirror the
/// vertical only).
fn ring_slots() -> &'static [usize] {
    static SLOTS_OFF_COLUMN: OnceLock<Vec<usize>> = OnceLock::new();
    SLOTS_OFF_COLUMN.get_or_init(|| {
        channels(false)
            .iter()
            .flat_map(|c| {
                let off = c.stencil.iter().enumerate().filter(|(_, t)| t.0 != 0);
                off.map(move |(k, _)| c.first_slot + k)
            })
            .collect()
    })
}

/// Fills the ring of one level row's slot planes (`row`: per slot and colour a row of
/// `nx` points with its ring, [`ring_pitch`]), for the slots that read it
/// ([`ring_slots`]): the wrapped columns on periodic sides, 0 on open ones (a tap
/// beyond an open side adds nothing). A reader then takes a stencil tap's values for
/// a block of a row as one slice, with no columns to wrap or leave out (the bench
/// forest's rows of 16 points ran each tap beside the column as a vector loop over
/// 14 or 15 points, their scalar remainder and one or two wrapped points).
fn fill_rings(row: &mut [f32], nx: usize, periodic: bool) {
    let w = ring_pitch(nx);
    for &slot in ring_slots() {
        for plane in row[slot * 3 * w..][..3 * w].chunks_exact_mut(w) {
            if !periodic {
                plane[..RING].fill(0.0);
                plane[nx + RING..].fill(0.0);
            } else if nx >= RING {
                plane.copy_within(nx..nx + RING, 0);
                plane.copy_within(RING..2 * RING, nx + RING);
            } else {
                for i in (0..RING).chain(nx + RING..w) {
                    let x = (i as isize - RING as isize).rem_euclid(nx as isize) as usize;
                    plane[i] = plane[RING + x];
                }
            }
        }
    }
}

/// Index of point `pt`'s value for stencil slot `slot` and colour `col` in a level's
/// slot planes (removed light, what paths carry, [`Planes::ex`]): per row of `nx`
/// points, slot, colour, column, each row of a slot and colour with its ring
/// ([`ring_pitch`]).
#[inline]
fn plane_index(nx: usize, pt: usize, slot: usize, col: usize) -> usize {
    slot_index(nx, (pt / nx, pt % nx), slot, col)
}

/// [`plane_index`] of column `x` of level row `z` (no division: the row loops').
#[inline]
fn slot_index(nx: usize, (z, x): (usize, usize), slot: usize, col: usize) -> usize {
    ((z * SLOTS + slot) * 3 + col) * ring_pitch(nx) + RING + x
}

/// `len` values of a level's slot planes ([`plane_index`]) for row
/// `zr`, slot and colour, from column `x` (`-RING ≤ x`, `x + len ≤ nx + RING`: the
/// ring's wrapped columns, or zeros beyond an open side, [`fill_rings`]).
#[inline]
fn tap(
    planes: &[f32],
    nx: usize,
    (zr, slot, col): (usize, usize, usize),
    x: i32,
    len: usize,
) -> &[f32] {
    &planes[(slot_index(nx, (zr, 0), slot, col) as isize + x as isize) as usize..][..len]
}

/// Channel `c` of grid column `x` in one row of a [`LevelLight`] of pitch `p`.
#[inline]
fn row_get(row: &[f32], p: usize, x: usize, c: usize) -> Vec3 {
    let b = c * 3 * p + x + PAD;
    Vec3::new(row[b], row[b + p], row[b + 2 * p])
}

#[inline]
fn row_set(row: &mut [f32], p: usize, x: usize, c: usize, v: Vec3) {
    let b = c * 3 * p + x + PAD;
    row[b] = v.x;
    row[b + p] = v.y;
    row[b + 2 * p] = v.z;
}

#[inline]
fn row_add(row: &mut [f32], p: usize, x: usize, c: usize, v: Vec3) {
    let b = c * 3 * p + x + PAD;
    row[b] += v.x;
    row[b + p] += v.y;
    row[b + 2 * p] += v.z;
}

/// Step 1 along a row: `out[i] = (1 - w)·mid[i + 1] + (w/4)·(mid[i + 2] + mid[i] +
/// above[i + 1] + below[i + 1])` (in that order, as the oracle adds its taps), where
/// `mid`, `above` and `below` start one column before the source point of `out[0]`.
#[inline(always)]
fn gather_row(out: &mut [f32], (mid, above, below): (&[f32], &[f32], &[f32]), w0: f32, w1: f32) {
    let n = out.len();
    let m0 = &mid[1..][..n];
    if w1 == 0.0 {
        for (o, v) in out.iter_mut().zip(m0) {
            *o = v * w0;
        }
        return;
    }
    let (mp, mm) = (&mid[2..][..n], &mid[..n]);
    let (za, zb) = (&above[1..][..n], &below[1..][..n]);
    for i in 0..n {
        out[i] = m0[i] * w0 + mp[i] * w1 + mm[i] * w1 + za[i] * w1 + zb[i] * w1;
    }
}

/// Reads one value of every cache line of `v` in a loop of independent loads, so that
/// the lines come from memory many at a time before the row's loops add to them (those
/// loops waited on one point's lines at a time: half of a later pass's adds to the
/// 26-bin output).
#[inline]
fn touch<T: bytemuck::Pod>(v: &[T]) {
    let bytes: &[u8] = bytemuck::cast_slice(v);
    let mut x = 0u8;
    for line in bytes.chunks(64) {
        x ^= line[0];
    }
    std::hint::black_box(x);
}

/// Sinks (a sweep's output while its passes run) of at least this many bytes have
/// each row's next row hinted into cache as the row's gather runs, a share per channel
/// (the crate docs, "Eighth round"): they do not stay in cache between passes (a 64³
/// grid's 26 bins take 82 MB; four passes 5–7 % faster). Smaller ones do, and the
/// hints only cost (the 16 × 64 × 16 canopy's 5 MB: 3 % slower with them).
pub const FETCH_AHEAD_BYTES: usize = 16 << 20;

/// Memory a row's loops will add to after the current row's: the next row of a level's
/// sink, which follows the current one in memory. [`Ctx::gather_row_channels`] hints it
/// into cache a share per channel ([`Ahead::fetch`]), so that the lines arrive while
/// the gather computes; [`touch`] then finds them there. (Read by `touch` alone, the
/// row's lines came from memory while nothing else ran: the largest single cost of a
/// later pass, 12 % of four passes at 64³. All hinted at once, they stalled the gather.)
#[derive(Clone, Copy)]
struct Ahead {
    start: *const u8,
    bytes: usize,
}

impl Ahead {
    /// As many bytes as `v` holds, right after it.
    fn after<T>(v: &[T]) -> Self {
        Self {
            start: v.as_ptr_range().end.cast(),
            bytes: std::mem::size_of_val(v),
        }
    }

    /// Byte offsets of share `i` of `n`: whole cache lines, the shares in order
    /// covering every line once.
    fn share(self, i: usize, n: usize) -> std::ops::Range<usize> {
        let lines = self.bytes.div_ceil(64);
        let at = |i: usize| (lines * i / n).min(lines) * 64;
        at(i)..at(i + 1)
    }

    /// Hints share `i` of `n` into the core's second-level cache.
    #[inline]
    fn fetch(self, i: usize, n: usize) {
        #[cfg(target_arch = "x86_64")]
        for off in self.share(i, n).step_by(64) {
            prefetch_hint(self.start.wrapping_add(off));
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (i, n);
    }
}

/// One of the workspace's two `unsafe` blocks (the other: [`advise_huge_pages`]):
/// `prefetcht1`, a hint that loads nothing into a register and never faults, whatever
/// the address (so `at` may lie past an allocation's end).
/// `std` offers no safe prefetch (`core::intrinsics::prefetch_read_data` is unstable),
/// and the crates that wrap one need nightly or expose `unsafe` themselves.
#[cfg(target_arch = "x86_64")]
#[inline]
#[allow(unsafe_code)]
fn prefetch_hint(at: *const u8) {
    use std::arch::x86_64::{_MM_HINT_T1, _mm_prefetch};
    // SAFETY: `_mm_prefetch` only hints the cache; it reads no memory the program sees
    // and cannot fault.
    unsafe { _mm_prefetch::<_MM_HINT_T1>(at.cast()) }
}

/// Sum in `f64`, four lanes (so that it vectorises; the order is fixed, so the result
/// is deterministic).
#[inline]
fn sum_f64(v: &[f32]) -> f64 {
    let mut lanes = [0f64; 4];
    let chunks = v.chunks_exact(4);
    let rest = chunks.remainder();
    for ch in chunks {
        for (l, x) in lanes.iter_mut().zip(ch) {
            *l += *x as f64;
        }
    }
    let mut s = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
    for x in rest {
        s += *x as f64;
    }
    s
}

/// Channel `chn`'s value in bins `b`: horizontal bins halved where `b` is full-sphere
/// light (a side halo), whole where it is a boundary's one-way light. Part of the
/// specification: the GPU sweeper uploads its boundary light through this.
#[inline]
pub fn channel_value(b: &BinLight, chn: &Channel, full_sphere: bool) -> Vec3 {
    let v = b.0[chn.bin];
    if full_sphere { v * chn.share } else { v }
}

/// The boundary light of the virtual level beyond the grid at column `(x, z)` (clamped
/// to the grid): the bottom light on upward passes, the top light (uniform or per point)
/// on downward ones. Part of the specification, shared with the GPU sweeper.
pub fn virtual_level_light(
    boundary: &Boundary,
    up: bool,
    x: i32,
    z: i32,
    dims: lightgrid_core::glam::UVec3,
) -> &BinLight {
    if up {
        return &boundary.bottom;
    }
    match &boundary.top {
        TopBoundary::Uniform(b) => b,
        TopBoundary::PerPoint(v) => {
            let (nx, nz) = (dims.x as i32, dims.z as i32);
            &v[(x.clamp(0, nx - 1) + nx * z.clamp(0, nz - 1)) as usize]
        }
    }
}

/// Checks the inputs of a sweep as [`run`] does (options, boundary against the grid,
/// boundary light at most [`MAX_LIGHT`]).
pub fn validate_inputs(
    material: &MaterialGrid,
    boundary: &Boundary,
    options: &SweepOptions,
) -> Result<(), SweepError> {
    options.validate()?;
    boundary.validate(material.desc())?;
    check_boundary_scale(boundary)?;
    let desc = material.desc();
    lightgrid_core::limits::check_memory(
        &format!("a sweep of {} points", desc.point_count()),
        sweep_bytes(desc),
    )?;
    Ok(())
}

/// Most bytes [`run`] holds at once for a grid: per point the accumulated bins (312),
/// up to three pending-scatter records (144: two, and a third in accelerated passes;
/// only levels with material hold them), ln(pass) and exposure (8), the output (312),
/// and the transmittances of every path exponent and the quiet mask, kept for the
/// sweep's later passes (41); per level its transmittance planes with their ring
/// (eleven planes of `(nx + 4) × (nz + 4)` floats); per point of one level the level
/// buffers (four 17-channel levels: the two in use, light from outside, the upward
/// light waiting above all material; removals, transmittance, the source rule's
/// sources and masks: 1441), with per row of a level the rings of its three sets of
/// slot planes (removed light, what paths carry, the profile rule's emission: 3 × 2 ×
/// 2 columns × 147 planes × 4 bytes); and the profile rule's set of cell profiles, one
/// per distinct depth of medium and direction, at most two a point and
/// [`crate::profile`]'s cap.
pub fn sweep_bytes(desc: &lightgrid_core::GridDesc) -> u64 {
    let profiles = (2 * desc.point_count()).min(crate::profile::Profiles::KEEP) as u64
        * std::mem::size_of::<crate::profile::CellProfile>() as u64;
    let d = desc.dims();
    let rings = d.z as u64 * (3 * 2 * RING * SLOTS * 3 * 4) as u64;
    let planes = d.y as u64
        * ((d.x as usize + 2 * Planes::R) * (d.z as usize + 2 * Planes::R) * Planes::PER_LEVEL * 4)
            as u64;
    desc.point_count() as u64 * (312 + 144 + 8 + 312 + 41)
        + desc.level_len() as u64 * 1441
        + rings
        + planes
        + profiles
}

pub(crate) fn check_boundary_scale(boundary: &Boundary) -> Result<(), GridError> {
    let big = |b: &BinLight| b.0.iter().any(|v| v.max_element() > MAX_LIGHT);
    let err = |field: &str| {
        Err(GridError::invalid(
            field,
            "a value over 1e30",
            "boundary light must be <= 1e30",
        ))
    };
    let top_big = match &boundary.top {
        TopBoundary::Uniform(b) => big(b),
        TopBoundary::PerPoint(v) => v.iter().any(big),
    };
    if top_big {
        return err("top");
    }
    if big(&boundary.bottom) {
        return err("bottom");
    }
    if let SideBoundary::Given(h) = &boundary.sides
        && h.iter().any(big)
    {
        return err("sides");
    }
    Ok(())
}

/// Boundary light of one pass.
struct Sources<'a> {
    boundary: &'a Boundary,
    /// Boundary light enters only in the first downward and the first upward pass.
    active: bool,
    up: bool,
    dims: UVec3,
    halo: Option<lightgrid_core::HaloLayout>,
}

impl Sources<'_> {
    /// Light of the virtual level beyond the grid (above it downward, below it upward)
    /// at column (x, z), channel `chn`.
    fn virtual_light(&self, x: i32, z: i32, chn: &Channel) -> Vec3 {
        if !self.active {
            return Vec3::ZERO;
        }
        channel_value(
            virtual_level_light(self.boundary, self.up, x, z, self.dims),
            chn,
            false,
        )
    }

    /// Light of a source point outside the grid's sides at (x, level, z).
    fn outside(&self, x: i32, level: i32, z: i32, chn: &Channel) -> Vec3 {
        if !self.active {
            return Vec3::ZERO;
        }
        match (&self.boundary.sides, &self.halo) {
            (SideBoundary::Given(h), Some(layout)) => {
                let lv = level.clamp(0, self.dims.y as i32 - 1) as u32;
                match layout.index(x, lv, z) {
                    Some(i) => channel_value(&h[i], chn, true),
                    None => Vec3::ZERO,
                }
            }
            _ => self.virtual_light(x, z, chn),
        }
    }
}

struct Ctx {
    nx: i32,
    nz: i32,
    periodic: bool,
    smoothing: f32,
    medium: MediumEmission,
    /// Light of either sign (diffusion acceleration, [`crate::accel`]): no clamping
    /// at 0 anywhere, so the sweep stays linear when the light taken back makes a
    /// cell's waiting light negative.
    signed: bool,
    /// Accelerated passes ([`crate::accel`]): a medium cell emits only what waited
    /// before the pair of passes; what collides in it waits for the next pair.
    jacobi: bool,
    ch: &'static [Channel; CHANNELS],
    /// The column index along x (then z) of every `x` in `-WRAP_PAD .. nx + WRAP_PAD`:
    /// wrapped on periodic sides, -1 beyond open or given ones.
    xcol: Vec<i32>,
    zcol: Vec<i32>,
}

/// Offsets beyond the sides that [`Ctx::col`] looks up in a table instead of dividing:
/// every tap and path cell of the sweep lies within this many columns of its point.
const WRAP_PAD: i32 = 8;

impl Ctx {
    fn new(
        nx: i32,
        nz: i32,
        periodic: bool,
        options: &SweepOptions,
        ch: &'static [Channel; CHANNELS],
        mode: Mode,
    ) -> Self {
        let table = |n: i32| -> Vec<i32> {
            (-WRAP_PAD..n + WRAP_PAD)
                .map(|x| {
                    if periodic {
                        x.rem_euclid(n)
                    } else if (0..n).contains(&x) {
                        x
                    } else {
                        -1
                    }
                })
                .collect()
        };
        Self {
            nx,
            nz,
            periodic,
            smoothing: options.smoothing,
            medium: options.medium,
            signed: mode != Mode::Plain,
            jacobi: mode == Mode::Accelerated,
            ch,
            xcol: table(nx),
            zcol: table(nz),
        }
    }
}

impl Ctx {
    /// The flux that the points of a level gather when every source point holds the
    /// channel light `v`, split into what comes from inside the grid and what from
    /// beyond its sides (none on periodic sides): the sums of phase 1's
    /// [`RowFlux::inside`] and [`RowFlux::outside`], counted instead of summed.
    fn uniform_gather(&self, v: &Level) -> (DVec3, DVec3) {
        let (w0, w1) = (1.0 - self.smoothing as f64, 0.25 * self.smoothing as f64);
        // Points whose source point, offset by (a, b), lies inside the grid.
        let count = |a: i32, b: i32| {
            ((self.nx - a.abs()).max(0) as i64 * (self.nz - b.abs()).max(0) as i64) as f64
        };
        let n = count(0, 0);
        let (mut inside, mut all) = (DVec3::ZERO, DVec3::ZERO);
        for (c, chn) in self.ch.iter().enumerate() {
            let flux = v[c].as_dvec3() * chn.mu as f64;
            let (a, b) = (chn.step.x, chn.step.z);
            let share = if self.periodic {
                n
            } else {
                w0 * count(a, b)
                    + w1 * (count(a - 1, b) + count(a + 1, b) + count(a, b - 1) + count(a, b + 1))
            };
            inside += flux * share;
            all += flux * n;
        }
        (inside, all - inside)
    }

    /// Least and most rows a parallel task takes: at least [`MIN_POINTS_PER_TASK`]
    /// points, so that small levels do not pay a task per row; where the rows' cost is
    /// `uneven` (phases 2 and 3), at most [`MAX_POINTS_PER_UNEVEN_TASK`] (at least a
    /// row).
    fn rows_per_task(&self, uneven: bool) -> (usize, usize) {
        let nx = self.nx.max(1) as usize;
        if uneven {
            (1, MAX_POINTS_PER_UNEVEN_TASK.div_ceil(nx))
        } else {
            (MIN_POINTS_PER_TASK.div_ceil(nx), usize::MAX)
        }
    }

    /// Whether the profile rule's loops over a block's stencil slots fetch the block's
    /// cell profiles first ([`touch`]): where a level's profiles (1240 bytes a cell)
    /// outgrow the 1 MB L2, the slot-major loops read each profile a value at a time
    /// from farther out (a 64³ forest, four passes: 51.2–52.6 → 45.8–46.0 ms, phase 2
    /// 18.6 → 11.9 % of the samples); a 16 × 16 level's stay near, and the fetch only
    /// costs (1 %).
    #[inline]
    fn fetch_profiles(&self) -> bool {
        (self.nx * self.nz) as usize > FETCH_PROFILES_ABOVE
    }

    /// Index of column (x, z) within a level, wrapping in periodic mode; `None` outside.
    #[inline]
    fn col(&self, x: i32, z: i32) -> Option<usize> {
        let (tx, tz) = (x + WRAP_PAD, z + WRAP_PAD);
        if let (Some(&cx), Some(&cz)) = (self.xcol.get(tx as usize), self.zcol.get(tz as usize))
            && tx >= 0
            && tz >= 0
        {
            return (cx >= 0 && cz >= 0).then(|| (cx + self.nx * cz) as usize);
        }
        if self.periodic {
            Some((x.rem_euclid(self.nx) + self.nx * z.rem_euclid(self.nz)) as usize)
        } else if x >= 0 && x < self.nx && z >= 0 && z < self.nz {
            Some((x + self.nx * z) as usize)
        } else {
            None
        }
    }
}

impl Ctx {
    /// Steps 1-2, written as the crate docs say them: the oracle of
    /// [`Ctx::phase1_fast`] ([`run_scalar`]).
    #[allow(clippy::too_many_arguments)]
    fn phase1_scalar<S: Sink>(
        &self,
        prev: &LevelLight,
        src: &Sources<'_>,
        from_virtual: bool,
        src_level: i32,
        (pows, lnp): (&[[f32; MAX_EXPONENTS]], &[f32]),
        first: bool,
        cur: &mut LevelLight,
        removed: &mut [f32],
        t_after: &mut [[f32; CHANNELS]],
        g: &mut [S],
        rows: &mut [RowFlux],
    ) -> RowFlux {
        let nx = self.nx as usize;
        let (row_len, p) = (cur.row_len(), cur.pitch());
        cur.rows_mut()
            .par_chunks_mut(row_len)
            .zip(removed.par_chunks_mut(ring_pitch(nx) * SLOTS * 3))
            .zip(t_after.par_chunks_mut(nx))
            .zip(g.par_chunks_mut(nx))
            .zip(rows.par_iter_mut())
            .enumerate()
            .for_each(|(z, ((((cur_row, rem_row), ta_row), g_row), row_out))| {
                let z = z as i32;
                let mut rf = RowFlux::default();
                if first {
                    // The first pass sets every point (its memory may hold anything).
                    g_row.fill(S::default());
                }
                for x in 0..self.nx {
                    let xi = x as usize;
                    let mut rem = [Vec3::ZERO; SLOTS];
                    for (c, chn) in self.ch.iter().enumerate() {
                        // Step 1: gather from the source point and its smoothing taps.
                        let (qx, qz) = (x - chn.step.x, z - chn.step.z);
                        let (ins, outs) =
                            self.gather_edge(prev, src, from_virtual, src_level, chn, c, qx, qz);
                        rf.inside += ins.as_dvec3() * chn.mu as f64;
                        rf.outside += outs.as_dvec3() * chn.mu as f64;
                        let light = ins + outs;
                        // Step 2: transmit along the path, recording what each cell removes.
                        let (t, t_mid, after) =
                            self.transmit((pows, lnp), chn, x, z, None, light, &mut rem);
                        ta_row[xi][c] = after;
                        row_set(cur_row, p, xi, c, light * t);
                        g_row[xi].add(chn.bin, chn.unit, light * t_mid);
                    }
                    for (slot, v) in rem.iter().enumerate() {
                        for col in 0..3 {
                            rem_row[slot_index(nx, (0, xi), slot, col)] = v[col];
                        }
                    }
                }
                fill_rings(rem_row, nx, self.periodic);
                *row_out = rf;
            });
        sum_rows(rows)
    }

    /// Step 2 for one point and channel: along the path cell by cell, each cell removes
    /// `light T_k (1 - τ_k)` (written into `rem`); returns the path's transmittance
    /// `T`, the transmittance to the point's centre `T_mid` and `T_after`. Path cells
    /// are found by [`Ctx::col`], or by index from the point's index `inner` when every
    /// cell of the path lies inside the grid.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn transmit(
        &self,
        (pows, lnp): (&[[f32; MAX_EXPONENTS]], &[f32]),
        chn: &Channel,
        x: i32,
        z: i32,
        inner: Option<usize>,
        light: Vec3,
        rem: &mut [Vec3; SLOTS],
    ) -> (f32, f32, f32) {
        let exps = path_exponents();
        let mut t = 1.0f32;
        let mut t_mid = 1.0f32;
        let mut after = 1.0f32;
        let mut past_centre = false;
        for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
            let ci = match inner {
                Some(pi) => Some((pi as i32 + dx + self.nx * dz) as usize),
                None => self.col(x + dx, z + dz),
            };
            let (tr, half) = match ci {
                Some(ci) => {
                    let tr = pows[ci][chn.pow[k]];
                    (tr, seg_mean(tr, -exps[chn.pow[k]] * lnp[ci]))
                }
                None => (1.0, 1.0),
            };
            rem[chn.first_slot + k] = light * (t * (1.0 - tr));
            if past_centre {
                after *= tr;
            }
            if dx == 0 && dz == 0 {
                t_mid = t * half;
                past_centre = true;
            }
            t *= tr;
        }
        (t, t_mid, after)
    }

    /// Steps 1-2 as [`Ctx::phase1_scalar`], bit for bit in the light, faster: step 1
    /// channel by channel over whole rows of [`LevelLight`]'s planes, a loop the
    /// compiler vectorises, with no side logic: taps beyond the sides read `prev`'s ring
    /// (wrapped light on periodic sides, zero otherwise) and, where light enters from
    /// outside (`ghost`: open sides or a given halo, in a pass that takes boundary
    /// light), the outside light from `ghost`'s ring, for the columns whose taps reach
    /// it. Adding a zero is exact, so the sums equal the oracle's tap-by-tap sums that
    /// skip those taps. Then step 2 point by point, where a point whose 5 × 5
    /// neighbourhood of cells is empty (`quiet`, or `None`: the whole level is empty;
    /// every path cell of every channel passes all light) skips the transmit step: its
    /// light passes unchanged, nothing is removed (its removal slots are not written:
    /// only non-empty cells read slots, and only those of points whose paths cross
    /// them, which are never quiet). Flux tallies sum in another order than the
    /// oracle's (equal to `f64` rounding). `fetch_ahead`: each row's gather hints the
    /// next row's sink into cache ([`Ahead`]).
    #[allow(clippy::too_many_arguments)]
    fn phase1_fast<S: Sink>(
        &self,
        (prev, count, fetch_ahead): (&LevelLight, bool, bool),
        ghost: Option<&LevelLight>,
        planes: &Planes,
        quiet: Option<&[bool]>,
        first: bool,
        cur: &mut LevelLight,
        removed: &mut [f32],
        t_after: &mut [[f32; CHANNELS]],
        g: &mut [S],
        rows: &mut [RowFlux],
        fin: Finish<'_>,
    ) -> RowFlux {
        let nx = self.nx as usize;
        let p = cur.pitch();
        let extra = removed
            .par_chunks_mut(ring_pitch(nx) * SLOTS * 3)
            .zip(t_after.par_chunks_mut(nx));
        self.level_rows(
            cur,
            extra,
            g,
            rows,
            (fin, false),
            |z, cur_row, (rem_row, ta_row), g_row, rf| {
                if first {
                    // The first pass sets every point (its memory may hold anything).
                    g_row.fill(S::default());
                } else {
                    touch(g_row);
                }
                let ahead = fetch_ahead.then(|| Ahead::after(g_row));
                vectorised!(self.gather_row_channels(z, (prev, count, ahead), ghost, cur_row, rf));
                let unchanged = vectorised!(
                    self.transmit_row(z, planes, quiet, p, cur_row, rem_row, ta_row, g_row)
                );
                if unchanged && ghost.is_none() {
                    // The light it sends on is what it gathered (no light from
                    // outside was added after the sum of `inside`).
                    rf.sent = rf.inside;
                    rf.sent_known = true;
                }
            },
        )
    }

    /// The parallel loop over a level's rows (tasks of [`Ctx::rows_per_task`] rows,
    /// `uneven` as there):
    /// `body(z, row of cur, extra's item, row of g, flux tallies)` for every row `z`,
    /// then, in the level's last phase, [`Ctx::finish_row`]; the rows' tallies summed
    /// in row order.
    fn level_rows<S: Sink, T: Send>(
        &self,
        cur: &mut LevelLight,
        extra: impl IndexedParallelIterator<Item = T>,
        g: &mut [S],
        rows: &mut [RowFlux],
        (fin, uneven): (Finish<'_>, bool),
        body: impl Fn(i32, &mut [f32], T, &mut [S], &mut RowFlux) + Sync,
    ) -> RowFlux {
        let nx = self.nx as usize;
        let (min_rows, max_rows) = self.rows_per_task(uneven);
        let (row_len, p) = (cur.row_len(), cur.pitch());
        let (last_phase, avg, dom, wrap) = (fin.last_phase, fin.avg, fin.dom, fin.wrap_columns);
        let resolve = fin.resolve.map(|d| (d, fin.clamp, fin.from_planes));
        cur.rows_mut()
            .par_chunks_mut(row_len)
            .zip(extra)
            .zip(g.par_chunks_mut(nx))
            .zip(rows.par_iter_mut())
            .zip(avg.par_chunks_mut(nx))
            .zip(dom.par_chunks_mut(nx))
            .enumerate()
            .with_min_len(min_rows)
            .with_max_len(max_rows)
            .for_each(
                |(z, (((((cur_row, x), g_row), row_out), avg_row), dom_row))| {
                    let mut rf = RowFlux::default();
                    body(z as i32, cur_row, x, g_row, &mut rf);
                    if last_phase {
                        self.finish_row(cur_row, p, g_row, avg_row, dom_row, resolve, &mut rf);
                        if wrap {
                            wrap_columns(cur_row, p, nx);
                        }
                    }
                    *row_out = rf;
                },
            );
        sum_rows(rows)
    }

    /// Step 1 of [`Ctx::phase1_fast`] for row `z` (its own function, so that profiles
    /// show it); the flux gathered from inside the grid summed into `rf.inside` if
    /// `count` (a level whose flux is known, [`conserves_flux`], leaves it); `ahead`
    /// fetched a share a channel.
    #[inline(always)]
    fn gather_row_channels(
        &self,
        z: i32,
        (prev, count, ahead): (&LevelLight, bool, Option<Ahead>),
        ghost: Option<&LevelLight>,
        cur_row: &mut [f32],
        rf: &mut RowFlux,
    ) {
        let nx = self.nx as usize;
        let p = prev.pitch();
        let (nxi, nzi) = (self.nx, self.nz);
        let s = self.smoothing;
        let (w0, w1) = (1.0 - s, 0.25 * s);
        let mut outs = [0f32; 2 * PAD];
        // Step 1, channel by channel, over the whole row.
        for (c, chn) in self.ch.iter().enumerate() {
            let (sx, qz) = (chn.step.x, (z - chn.step.z) as isize);
            let mu = chn.mu as f64;
            // Source column of x = 0 in the planes (ring included).
            let q0 = (PAD as i32 - sx - 1) as usize;
            if let Some(a) = ahead {
                a.fetch(c, CHANNELS);
            }
            for k in 0..3 {
                let plane = (c * 3 + k) * p;
                let out = &mut cur_row[plane + PAD..][..nx];
                #[inline(always)]
                fn taps(
                    l: &LevelLight,
                    at: usize,
                    n: usize,
                    qz: isize,
                ) -> (&[f32], &[f32], &[f32]) {
                    let row = |z: isize| &l.row(z)[at..][..n];
                    (row(qz), row(qz + 1), row(qz - 1))
                }
                gather_row(out, taps(prev, plane + q0, nx + 2, qz), w0, w1);
                if count {
                    rf.inside[k] += sum_f64(out) * mu;
                }
                let Some(gh) = ghost else { continue };
                // Columns whose taps reach beyond the sides: all of them in a row
                // whose source rows do; else the first and last few.
                let (xa, xb) = if qz >= 1 && qz < nzi as isize - 1 {
                    let xa = (1 + sx).clamp(0, nxi);
                    (xa as usize, (nxi - 1 + sx).clamp(xa, nxi) as usize)
                } else {
                    (nx, nx)
                };
                let (mid, above, below) = taps(gh, plane + q0, nx + 2, qz);
                for range in [0..xa.min(nx), xb.max(xa.min(nx))..nx] {
                    for chunk in range.clone().step_by(outs.len()) {
                        let n = (range.end - chunk).min(outs.len());
                        let o = &mut outs[..n];
                        gather_row(o, (&mid[chunk..], &above[chunk..], &below[chunk..]), w0, w1);
                        rf.outside[k] += sum_f64(o) * mu;
                        for (t, v) in out[chunk..][..n].iter_mut().zip(o.iter()) {
                            *t += v;
                        }
                    }
                }
            }
        }
    }

    /// Step 2 of [`Ctx::phase1_fast`] for row `z` of a level whose planes have pitch `p`:
    /// [`Ctx::transmit`] for every point and channel, the same operations in the same
    /// order, run channel by channel over blocks of the row and segment by segment
    /// (`planes`: the level's transmittances with a ring) so that the loops vectorise.
    /// A row whose points are all quiet passes its light unchanged (and `true` says so).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn transmit_row<S: Sink>(
        &self,
        z: i32,
        planes: &Planes,
        quiet: Option<&[bool]>,
        p: usize,
        cur_row: &mut [f32],
        rem_row: &mut [f32],
        ta_row: &mut [[f32; CHANNELS]],
        g_row: &mut [S],
    ) -> bool {
        const B: usize = GATHER_BLOCK;
        let nx = self.nx as usize;
        let all_quiet = quiet.is_none_or(|q| q[nx * z as usize..][..nx].iter().all(|&b| b));
        if all_quiet {
            for (xi, g_pt) in g_row.iter_mut().enumerate() {
                g_pt.add_channels(self.ch, |c| row_get(cur_row, p, xi, c));
            }
            return true;
        }
        let mut x0 = 0;
        // Set per channel for the block's `b` points only.
        let (mut t, mut t_mid, mut after) = ([1f32; B], [1f32; B], [1f32; B]);
        let (mut lost, mut mean) = ([0f32; B], [[0f32; B]; 3]);
        while x0 < nx {
            let b = B.min(nx - x0);
            with_width(
                b,
                #[inline(always)]
                |b| {
                    for (c, chn) in self.ch.iter().enumerate() {
                        for a in [&mut t, &mut t_mid, &mut after] {
                            a[..b].fill(1.0);
                        }
                        let mut past_centre = false;
                        let light: [&[f32]; 3] = std::array::from_fn(|col| {
                            &cur_row[(c * 3 + col) * p + PAD + x0..][..b]
                        });
                        for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                            let tr =
                                planes.row(Planes::POW + chn.pow[k], z + dz, x0 as i32 + dx, b);
                            let slot = chn.first_slot + k;
                            // What the segment takes of the light entering the path (once,
                            // not per colour).
                            for i in 0..b {
                                lost[i] = t[i] * (1.0 - tr[i]);
                            }
                            for (col, l) in light.iter().enumerate() {
                                let out = &mut rem_row[slot_index(nx, (0, x0), slot, col)..][..b];
                                for i in 0..b {
                                    out[i] = l[i] * lost[i];
                                }
                            }
                            if past_centre {
                                for i in 0..b {
                                    after[i] *= tr[i];
                                }
                            }
                            if dx == 0 && dz == 0 {
                                let lnp = planes.row(Planes::LNP, z, x0 as i32, b);
                                let e = path_exponents()[chn.pow[k]];
                                for i in 0..b {
                                    t_mid[i] = t[i] * seg_mean(tr[i], -e * lnp[i]);
                                }
                                past_centre = true;
                            }
                            for i in 0..b {
                                t[i] *= tr[i];
                            }
                        }
                        // The point's mean light into its bin, and the light that leaves, colour
                        // by colour along the block (as `Vec3`s, point by point, these ran one
                        // float at a time).
                        for (col, m) in mean.iter_mut().enumerate() {
                            let l = &mut cur_row[(c * 3 + col) * p + PAD + x0..][..b];
                            for i in 0..b {
                                m[i] = l[i] * t_mid[i];
                                l[i] *= t[i];
                            }
                        }
                        for i in 0..b {
                            ta_row[x0 + i][c] = after[i];
                            let m = Vec3::new(mean[0][i], mean[1][i], mean[2][i]);
                            g_row[x0 + i].add(chn.bin, chn.unit, m);
                        }
                    }
                },
            );
            x0 += b;
        }
        fill_rings(rem_row, nx, self.periodic);
        false
    }

    /// Step 1, tap by tap (light from inside the grid, light from outside): the
    /// scalar oracle's gather everywhere, the fast path's near the sides.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn gather_edge(
        &self,
        prev: &LevelLight,
        src: &Sources<'_>,
        from_virtual: bool,
        src_level: i32,
        chn: &Channel,
        c: usize,
        qx: i32,
        qz: i32,
    ) -> (Vec3, Vec3) {
        let s = self.smoothing;
        let taps = [
            (qx, qz, 1.0 - s),
            (qx + 1, qz, 0.25 * s),
            (qx - 1, qz, 0.25 * s),
            (qx, qz + 1, 0.25 * s),
            (qx, qz - 1, 0.25 * s),
        ];
        let mut ins = Vec3::ZERO;
        let mut outs = Vec3::ZERO;
        for (tx, tz, w) in taps {
            if w == 0.0 {
                continue;
            }
            match self.col(tx, tz) {
                Some(i) => ins += prev.at(i, c) * w,
                None if from_virtual && src.halo.is_none() => {
                    outs += src.virtual_light(tx, tz, chn) * w
                }
                None => outs += src.outside(tx, src_level, tz, chn) * w,
            }
        }
        (ins, outs)
    }

    /// Points whose 5 × 5 neighbourhood of cells (wrapped on periodic sides; cells
    /// beyond open sides count as empty) holds no material: `lnp` is the level's
    /// `ln(pass)`, 0 for empty cells.
    fn quiet(&self, lnp: &[f32], out: &mut [bool], rows_ok: &mut [bool]) {
        let (nx, nz) = (self.nx, self.nz);
        for z in 0..nz {
            for x in 0..nx {
                rows_ok[(x + nx * z) as usize] =
                    (-2..=2).all(|dx| self.col(x + dx, z).is_none_or(|i| lnp[i] == 0.0));
            }
        }
        for z in 0..nz {
            for x in 0..nx {
                out[(x + nx * z) as usize] =
                    (-2..=2).all(|dz| self.col(x, z + dz).is_none_or(|i| rows_ok[i]));
            }
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn phase2<S: Sink>(
        &self,
        removed: (&[f32], bool),
        (t_after, pows): (&[[f32; CHANNELS]], &[[f32; MAX_EXPONENTS]]),
        cells: &[lightgrid_core::Material],
        exposed: &[u8],
        cur: &mut LevelLight,
        pend_same: &mut [Pending],
        pend_other: &mut [Pending],
        (src, emits, src_hi, prof, ex): EmitRows<'_>,
        g: &mut [S],
        rows: &mut [RowFlux],
        fin: Finish<'_>,
    ) -> RowFlux {
        let nx = self.nx as usize;
        let p = cur.pitch();
        // Under other rules than Profile `src_hi` and `ex` are empty: rows of nothing.
        let hi_rows: Vec<(&mut [[Vec3; 2]], &mut [f32])> = if src_hi.is_empty() {
            (0..self.nz).map(|_| Default::default()).collect()
        } else if ex.is_empty() {
            src_hi
                .chunks_mut(nx)
                .map(|h| (h, Default::default()))
                .collect()
        } else {
            src_hi
                .chunks_mut(nx)
                .zip(ex.chunks_mut(SLOTS * 3 * ring_pitch(nx)))
                .collect()
        };
        let extra = pend_same
            .par_chunks_mut(nx)
            .zip(pend_other.par_chunks_mut(nx))
            .zip(
                src.par_chunks_mut(nx)
                    .zip(emits.par_chunks_mut(nx))
                    .zip(hi_rows),
            );
        self.level_rows(
            cur,
            extra,
            g,
            rows,
            (fin, true),
            |z,
             cur_row,
             ((same_row, other_row), ((src_row, emits_row), (hi_row, ex_row))),
             g_row,
             rf| {
                *rf = vectorised!(self.phase2_row(
                    z,
                    removed,
                    (t_after, pows),
                    cells,
                    exposed,
                    p,
                    cur_row,
                    same_row,
                    other_row,
                    (src_row, emits_row, hi_row, prof, ex_row),
                    g_row,
                ));
            },
        )
    }

    /// The end of a level's last phase for one row ([`Finish`]).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn finish_row<S: Sink>(
        &self,
        cur_row: &[f32],
        p: usize,
        g_row: &mut [S],
        avg_row: &mut [AverageLight],
        dom_row: &mut [DominantDir],
        resolve: Option<(bool, bool, bool)>,
        rf: &mut RowFlux,
    ) {
        let nx = self.nx as usize;
        if !rf.sent_known {
            for (c, chn) in self.ch.iter().enumerate() {
                for k in 0..3 {
                    rf.sent[k] += sum_f64(&cur_row[(c * 3 + k) * p + PAD..][..nx]) * chn.mu as f64;
                }
            }
        }
        if let Some((dominant, clamp, from_planes)) = resolve {
            if clamp {
                g_row.iter_mut().for_each(S::clamp);
            }
            rf.bad |= !if S::ALL_BINS && from_planes {
                vectorised!(resolve_planes(
                    self.ch,
                    cur_row,
                    p,
                    (clamp, dominant),
                    avg_row,
                    dom_row
                ))
            } else {
                vectorised!(S::resolve_all(g_row, avg_row, dom_row, dominant))
            };
        }
    }

    /// Step 3 for the block `x0..x0 + b` of row `z`: per channel and colour, what each
    /// cell removed from the paths crossing it, `Σ_k removed[x − d_k][slot k]` over the
    /// channel's stencil in order (points beyond an open side add nothing), read from
    /// whole rows of the planes `removed` (per row: slot, colour, column).
    #[inline(always)]
    fn gather_removed(
        &self,
        z: i32,
        x0: usize,
        b: usize,
        removed: &[f32],
        out: &mut [[[f32; GATHER_BLOCK]; 3]; CHANNELS],
    ) {
        let nx = self.nx as usize;
        for (c, chn) in self.ch.iter().enumerate() {
            let o = &mut out[c];
            // The first tap sets the sums (as [`Ctx::gather_moments`]: no `memset` per
            // colour and channel).
            let mut set = false;
            for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                let Some(zr) = self.row_of(z - dz) else {
                    continue;
                };
                let first = x0 as i32 - dx;
                for (col, oc) in o.iter_mut().enumerate() {
                    let from = tap(removed, nx, (zr, chn.first_slot + k, col), first, b);
                    let oc = &mut oc[..b];
                    if set {
                        for i in 0..b {
                            oc[i] += from[i];
                        }
                    } else {
                        // (`0 + v`, the sum from zero: a bare copy was a `memcpy` call.)
                        for i in 0..b {
                            oc[i] = 0.0 + from[i];
                        }
                    }
                }
                set = true;
            }
            if !set {
                for col in o.iter_mut() {
                    col[..b].fill(0.0);
                }
            }
        }
    }

    /// [`MediumEmission::Profile`]: [`Ctx::gather_removed`] into `removed_out` and, from
    /// the same reads of the planes, step 3's height moments for the block `x0..x0 + b`
    /// of row `z`: per moment `h` and colour, `Σ_c μ_c Σ_k removed[x − d_k][slot k] ·
    /// w[slot k][h][x]` (taps in stencil order, points beyond an open side adding
    /// nothing), `w` the block's cells' collision moments per slot
    /// ([`crate::profile::CellProfile::coll`]). Every sum takes its terms in the order
    /// the two gathers took them on their own.
    #[inline(always)]
    fn gather_moments(
        &self,
        z: i32,
        (x0, b): (usize, usize),
        removed: &[f32],
        w: &[[[f32; GATHER_BLOCK]; 2]; SLOTS],
        removed_out: &mut [[[f32; GATHER_BLOCK]; 3]; CHANNELS],
        out: &mut [[[f32; GATHER_BLOCK]; 3]; 2],
    ) {
        let nx = self.nx as usize;
        for o in out.iter_mut().flatten() {
            o[..b].fill(0.0);
        }
        let mut t = [[[0f32; GATHER_BLOCK]; 3]; 2];
        for (chn, ro) in self.ch.iter().zip(removed_out.iter_mut()) {
            // The first tap sets the channel's sums, the others add to them (zeroed
            // first, each array was a call to `memset` per channel: 1.6 % of the
            // forest). `0 + v·w` is `v·w` but for the sign of a zero.
            let mut set = false;
            for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                let Some(zr) = self.row_of(z - dz) else {
                    continue;
                };
                let slot = chn.first_slot + k;
                let first = x0 as i32 - dx;
                let (w0, w1) = (&w[slot][0][..b], &w[slot][1][..b]);
                let [t0, t1] = &mut t;
                for col in 0..3 {
                    let from = tap(removed, nx, (zr, slot, col), first, b);
                    let (r, a0, a1) = (&mut ro[col][..b], &mut t0[col][..b], &mut t1[col][..b]);
                    if set {
                        for i in 0..b {
                            r[i] += from[i];
                            a0[i] += from[i] * w0[i];
                            a1[i] += from[i] * w1[i];
                        }
                    } else {
                        for i in 0..b {
                            // (`0 + v`, as the sum from zero: a bare copy compiled to
                            // a call to `memcpy`.)
                            r[i] = 0.0 + from[i];
                            a0[i] = from[i] * w0[i];
                            a1[i] = from[i] * w1[i];
                        }
                    }
                }
                set = true;
            }
            if !set {
                for col in ro.iter_mut().chain(t.iter_mut().flatten()) {
                    col[..b].fill(0.0);
                }
            }
            for (oh, th) in out.iter_mut().zip(&t) {
                for (oc, tc) in oh.iter_mut().zip(th) {
                    for (o, &v) in oc[..b].iter_mut().zip(&tc[..b]) {
                        *o += v * chn.mu;
                    }
                }
            }
        }
    }

    /// [`Ctx::phase2`] for row `z` (its own function, so that profiles show it).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn phase2_row<S: Sink>(
        &self,
        z: i32,
        (removed, scalar): (&[f32], bool),
        (t_after, pows): (&[[f32; CHANNELS]], &[[f32; MAX_EXPONENTS]]),
        cells: &[lightgrid_core::Material],
        exposed: &[u8],
        p: usize,
        cur_row: &mut [f32],
        same_row: &mut [Pending],
        other_row: &mut [Pending],
        (src_row, emits_row, hi_row, prof, ex_row): EmitRows<'_>,
        g_row: &mut [S],
    ) -> RowFlux {
        let nx = self.nx as usize;
        let up = up_pass(self.ch);
        let lanes = pass_lanes(up);
        let mw = medium::weights(up);
        let mut rf = RowFlux::default();
        emits_row.fill(false);
        ex_row.fill(0.0);
        let row_cells = &cells[nx * z as usize..][..nx];
        let mut scratch = Phase2Scratch::take();
        let Phase2Scratch {
            by_row,
            by_row_h,
            coll,
        } = &mut *scratch;
        let profile = self.medium == MediumEmission::Profile;
        let is_profile =
            |m: &lightgrid_core::Material| profile && medium::applies(self.medium, m.pass);
        for x in 0..self.nx {
            let xi = x as usize;
            let ci = xi + nx * z as usize;
            let (i, x0) = (xi % GATHER_BLOCK, xi - xi % GATHER_BLOCK);
            if i == 0 && !scalar {
                let b = GATHER_BLOCK.min(nx - x0);
                if row_cells[x0..x0 + b].iter().any(is_profile) {
                    if coll.is_empty() {
                        *coll = vec![[[0f32; GATHER_BLOCK]; 2]; SLOTS];
                    }
                    // Slot by slot, so that the stores run along the block (point
                    // by point they went to 98 lines a point).
                    let c: [Option<&crate::profile::CellProfile>; GATHER_BLOCK] =
                        std::array::from_fn(|j| {
                            (j < b && is_profile(&row_cells[x0 + j]))
                                .then(|| prof.get(x0 + j + nx * z as usize))
                        });
                    if self.fetch_profiles() {
                        // (The emission planes below read `emit`.)
                        for pr in c[..b].iter().flatten() {
                            touch(&pr.coll[..]);
                            touch(&pr.emit[..]);
                        }
                    }
                    for (slot, w) in coll.iter_mut().enumerate() {
                        for (j, c) in c[..b].iter().enumerate() {
                            let v = c.map_or([0.0; 2], |c| c.coll[slot]);
                            (w[0][j], w[1][j]) = (v[0], v[1]);
                        }
                    }
                    let coll: &[[[f32; GATHER_BLOCK]; 2]; SLOTS] =
                        coll.as_slice().try_into().expect("SLOTS moments");
                    vectorised!(self.gather_moments(z, (x0, b), removed, coll, by_row, by_row_h));
                } else if row_cells[x0..x0 + b].iter().any(|m| m.pass < 1.0) {
                    vectorised!(self.gather_removed(z, x0, b, removed, by_row));
                }
            }
            if cells[ci].pass >= 1.0 {
                // An empty cell removes nothing, so it never holds scattered light.
                continue;
            }
            // Step 3: the flux this cell removed from every path crossing it: gathered
            // for the block of the row, or (the scalar oracle) path point by path point.
            let mat = cells[ci];
            let mut s_raw = Vec3::ZERO;
            let mut m_raw = [Vec3::ZERO; 3];
            for (c, chn) in self.ch.iter().enumerate() {
                let r = if scalar {
                    let mut r = Vec3::ZERO;
                    for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                        if let Some(pt) = self.col(x - dx, z - dz) {
                            let at =
                                |col: usize| removed[plane_index(nx, pt, chn.first_slot + k, col)];
                            r += Vec3::new(at(0), at(1), at(2));
                        }
                    }
                    r
                } else {
                    let g = &by_row[c];
                    Vec3::new(g[0][i], g[1][i], g[2][i])
                };
                let r = r * chn.mu;
                s_raw += r;
                m_raw[0] += r * chn.unit.x;
                m_raw[1] += r * chn.unit.y;
                m_raw[2] += r * chn.unit.z;
            }
            // Step 4: absorb (1 - albedo), keep albedo for scattering.
            let alb = mat.reflectance;
            rf.absorbed += (s_raw * (Vec3::ONE - alb)).as_dvec3();
            let new = Pending { s: s_raw, m: m_raw }.scaled(alb);
            // Step 5: emit this pass's half of what the cell scatters now and of
            // what earlier passes left for this direction. Step 6: what the cell's
            // own material stops of that emission is removed again (absorbed or
            // scattered anew), in up to LOCAL_ROUNDS rounds; the rest waits.
            // Accelerated (`signed`): the media's collisions wait for the next pair of
            // passes (one generation per pair, as diffusion acceleration assumes);
            // `same_row` then keeps them.
            if self.medium == MediumEmission::Profile && medium::applies(self.medium, mat.pass) {
                // A quadratic source in height (`crate::profile`): the collisions'
                // height moments, walked path point by path point, become an isotropic
                // source; this pass emits what waits for it, the other pass's waits.
                let pr = prof.get(xi + nx * z as usize);
                let r = if scalar {
                    let mut r = [s_raw, Vec3::ZERO, Vec3::ZERO];
                    for chn in self.ch.iter() {
                        let mut t = [Vec3::ZERO; 2];
                        for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                            if let Some(pt) = self.col(x - dx, z - dz) {
                                let slot = chn.first_slot + k;
                                let at = |col: usize| removed[plane_index(nx, pt, slot, col)];
                                let v = Vec3::new(at(0), at(1), at(2));
                                t[0] += v * pr.coll[slot][0];
                                t[1] += v * pr.coll[slot][1];
                            }
                        }
                        r[1] += t[0] * chn.mu;
                        r[2] += t[1] * chn.mu;
                    }
                    r
                } else {
                    let v = |a: &[[f32; GATHER_BLOCK]; 3]| Vec3::new(a[0][i], a[1][i], a[2][i]);
                    [s_raw, v(&by_row_h[0]), v(&by_row_h[1])]
                };
                let dj = Pending::of_coeffs(vectorised!(crate::profile::source_rgb(
                    pr,
                    alb,
                    r,
                    &mut rf.absorbed
                )));
                // Accelerated (`jacobi`): only what waited is emitted; the new source
                // waits for the next pair, as under the flat rule.
                let emit = if self.jacobi {
                    same_row[xi]
                } else {
                    same_row[xi].add(&dj)
                }
                .coeffs();
                src_row[xi] = emit[0];
                hi_row[xi] = [emit[1], emit[2]];
                emits_row[xi] = emit.iter().any(|v| *v != Vec3::ZERO);
                if emits_row[xi] && !ex_row.is_empty() {
                    // Phase 3's emission planes (`Planes::ex`) for this cell: per slot,
                    // three rows of `nx` and their ring. (Indexed as `(slot · 3 +
                    // colour) · pitch + x`, each colour of a `Vec3` looked up and every
                    // store checked, the 147 stores were a quarter of phase 2 on the
                    // forest.)
                    let (e1, e2) = (emit[1].to_array(), emit[2].to_array());
                    let w = ring_pitch(nx);
                    for (rows, wt) in ex_row.chunks_exact_mut(3 * w).zip(&pr.emit) {
                        for ((row, a), b) in rows.chunks_exact_mut(w).zip(e1).zip(e2) {
                            row[RING + xi] = a * wt[0] + b * wt[1];
                        }
                    }
                }
                same_row[xi] = if self.jacobi { dj } else { Pending::default() };
                let other = other_row[xi].add(&dj);
                other_row[xi] = other;
                rf.pending += self.waiting(crate::profile::flux_rgb(pr, 1, &other.coeffs()));
                continue;
            }
            let jacobi = self.jacobi && medium::applies(self.medium, mat.pass);
            let mut own = if jacobi {
                same_row[xi]
            } else {
                new.add(&same_row[xi])
            };
            let mut other = other_row[xi].add(&new);
            // The cell's weights, once (a logarithm for a medium), as lanes.
            let em = Emission::new(mat.pass, exposed[ci], self.medium);
            let source_rule = medium::applies(self.medium, mat.pass);
            // The source rule's ½ β (`medium::split`), downward sign.
            let half_beta = if source_rule {
                let b = 0.5 * medium::split(mat.pass.ln());
                if up { -b } else { b }
            } else {
                0.0
            };
            if source_rule {
                // The source rule: this direction's share ½ (S ∓ β M_y) of the scattered
                // light as the cell's source, which its path segments emit in phase 3
                // (`crate::medium`).
                let share = own.s * 0.5 + own.m[1] * half_beta;
                let (g, kk) = medium::cell_sums(mw, mat.pass.ln(), &pows[ci]);
                let mut j = Vec3::ZERO;
                for k in 0..3 {
                    let (jk, absorbed) = if self.signed {
                        medium::source_signed(g, kk, share[k], alb[k])
                    } else {
                        medium::source_of(g, kk, share[k].max(0.0), alb[k])
                    };
                    j[k] = jk;
                    rf.absorbed[k] += absorbed as f64;
                }
                src_row[xi] = j;
                emits_row[xi] = j != Vec3::ZERO;
                own = Pending::default();
            } else if own.s != Vec3::ZERO {
                let cw = em.lanes(lanes, self.ch, &t_after[ci]);
                // Per colour and channel: what leaves the level, what is emitted.
                let mut leave = [[0f32; LANES]; 3];
                let mut emit = [[0f32; LANES]; 3];
                for _ in 0..LOCAL_ROUNDS {
                    if own.s == Vec3::ZERO {
                        break;
                    }
                    let mut lost_s = Vec3::ZERO;
                    let mut lost_m = [Vec3::ZERO; 3];
                    for k in 0..3 {
                        let (sk, mk) = (own.s[k], [own.m[0][k], own.m[1][k], own.m[2][k]]);
                        let lost =
                            cw.round(lanes, sk, mk, (&mut leave[k], &mut emit[k]), self.signed);
                        lost_s[k] = lanes_sum(&lost);
                        for a in 0..3 {
                            lost_m[a][k] = lanes_dot(&lost, &lanes.u[a]);
                        }
                    }
                    rf.absorbed += (lost_s * (Vec3::ONE - alb)).as_dvec3();
                    own = Pending {
                        s: lost_s * alb,
                        m: lost_m.map(|v| v * alb),
                    };
                    other = other.add(&own);
                }
                for (c, chn) in self.ch.iter().enumerate() {
                    let lv = Vec3::new(leave[0][c], leave[1][c], leave[2][c]);
                    row_add(cur_row, p, xi, c, lv * lanes.length[c]);
                    let ev = Vec3::new(emit[0][c], emit[1][c], emit[2][c]);
                    g_row[xi].add(chn.bin, chn.unit, ev * lanes.half_length[c]);
                }
            }
            let recycled = own;
            same_row[xi] = if jacobi { new } else { recycled };
            other_row[xi] = other;
            if source_rule {
                // What the other direction's pass will emit (`medium::split`); nothing
                // waits for this one.
                let share = other.s * 0.5 - other.m[1] * half_beta;
                rf.pending += if self.signed {
                    share
                } else {
                    share.max(Vec3::ZERO)
                }
                .as_dvec3();
            } else {
                let other_ch = channels(!up_pass(self.ch));
                rf.pending +=
                    (em.budget(&recycled, self.ch) + em.budget(&other, other_ch)).as_dvec3();
            }
        }
        Phase2Scratch::give_back(scratch);
        if emits_row.contains(&true) && !ex_row.is_empty() {
            fill_rings(ex_row, nx, self.periodic);
        }
        rf
    }
}

/// [`Ctx::phase2_row`]'s blocks of gathered removed light, one per thread, kept from
/// row to row: as locals they were zeroed in full for every row (13 KiB, and 25 KiB of
/// profile moments, for a row of 16 points that reads 16 of each 64). Only the points
/// a block gathers are read, and the gathers write them first.
struct Phase2Scratch {
    /// Per channel and colour: what each cell of the block removed ([`Ctx::gather_removed`]).
    by_row: [[[f32; GATHER_BLOCK]; 3]; CHANNELS],
    /// Profile: the height moments of what each cell removed ([`Ctx::gather_moments`]).
    by_row_h: [[[f32; GATHER_BLOCK]; 3]; 2],
    /// Profile: the block's cells' collision moments per slot (empty until a block
    /// has such cells).
    coll: Vec<[[f32; GATHER_BLOCK]; 2]>,
}

thread_local! {
    static PHASE2_SCRATCH: std::cell::Cell<Option<Box<Phase2Scratch>>> =
        const { std::cell::Cell::new(None) };
}

impl Phase2Scratch {
    /// This thread's scratch (a new one the first time).
    fn take() -> Box<Self> {
        PHASE2_SCRATCH.take().unwrap_or_else(|| {
            Box::new(Self {
                by_row: [[[0.0; GATHER_BLOCK]; 3]; CHANNELS],
                by_row_h: [[[0.0; GATHER_BLOCK]; 3]; 2],
                coll: Vec::new(),
            })
        })
    }
    fn give_back(s: Box<Self>) {
        PHASE2_SCRATCH.set(Some(s));
    }
}

/// [`Ctx::collide_row`]'s running sums for one colour of a block of points: what the
/// points' cells stopped (`s`), its first moment (`m`, per axis) and, under the profile
/// rule, its height moments (`h`).
struct Tally<'a> {
    s: &'a mut [f32],
    m: [&'a mut [f32]; 3],
    h: Option<[&'a mut [f32]; 2]>,
}

impl Tally<'_> {
    /// For the block's points `range` (and `v`, what their paths carry into the
    /// segment, one value a point): `r = v·((1 − pw)·om)` joins `s`, `r·unit` joins `m`,
    /// `r·cw` joins `h`, in that order. Slices of one length and no closure, so that
    /// the loop vectorises (as a closure indexing `unit[a]` it ran one float at a
    /// time, a bounds check a term).
    #[inline(always)]
    fn add(
        &mut self,
        range: std::ops::Range<usize>,
        v: &[f32],
        (pw, om, unit): (&[f32], f32, [f32; 3]),
        cw: &[[f32; GATHER_BLOCK]; 2],
    ) {
        let n = range.len();
        let (v, pw) = (&v[..n], &pw[range.clone()][..n]);
        let s = &mut self.s[range.clone()][..n];
        let [m0, m1, m2] = &mut self.m;
        let (m0, m1, m2) = (
            &mut m0[range.clone()][..n],
            &mut m1[range.clone()][..n],
            &mut m2[range.clone()][..n],
        );
        let r = |i: usize| v[i] * ((1.0 - pw[i]) * om);
        for i in 0..n {
            let r = r(i);
            s[i] += r;
            m0[i] += r * unit[0];
            m1[i] += r * unit[1];
            m2[i] += r * unit[2];
        }
        // (A loop of its own, `r` computed again, the same value: each sum still takes
        // its terms in order.)
        if let Some([h0, h1]) = &mut self.h {
            let (h0, h1) = (&mut h0[range.clone()][..n], &mut h1[range.clone()][..n]);
            let (c0, c1) = (&cw[0][range.clone()][..n], &cw[1][range][..n]);
            for i in 0..n {
                let r = r(i);
                h0[i] += r * c0[i];
                h1[i] += r * c1[i];
            }
        }
    }
}

impl Ctx {
    /// Phase 3 of a level under the source rule ([`crate::medium`]): every path
    /// gains what its segments' sources emit, attenuated by the segments after them
    /// (and `pre` keeps what each path carries into each of its segments); the level is
    /// finished ([`Finish`]); then every cell with material collects what it stops of
    /// its level-mates' emission (scattered light for the next passes).
    ///
    /// The emission runs channel by channel over blocks of a row, segment by segment
    /// ([`Planes`] of the level's transmittances and sources, with a ring beyond the
    /// sides), so that its loops vectorise; each point's sums are the same operations
    /// in the same order as a walk along its paths, so the light is the same bit for bit.
    #[allow(clippy::too_many_arguments)]
    fn phase3<S: Sink>(
        &self,
        (src, emits): (&[Vec3], &[bool]),
        hi: (&[[Vec3; 2]], &crate::profile::Profiles),
        (pows, lnp, planes): (&[[f32; MAX_EXPONENTS]], &[f32], &mut Planes),
        cells: &[lightgrid_core::Material],
        cur: &mut LevelLight,
        (pre, pre_rows): (&mut [f32], &mut [bool]),
        (pend_same, pend_other): (&mut [Pending], &mut [Pending]),
        g: &mut [S],
        rows: &mut [RowFlux],
        fin: Finish<'_>,
        scalar: bool,
    ) -> RowFlux {
        let nx = self.nx as usize;
        let p = cur.pitch();
        let profile = self.medium == MediumEmission::Profile;
        planes.fill_src(self, src, emits);
        let planes = &*planes;
        // Rows whose paths carry anything: within [`RING`] rows of an emitting cell, as
        // far as a path reaches (every row, scalar).
        let emitting: Vec<bool> = emits.chunks(nx).map(|r| r.contains(&true)).collect();
        let reach = RING as i32;
        for (z, r) in pre_rows.iter_mut().enumerate() {
            *r = scalar
                || (-reach..=reach)
                    .any(|d| self.row_of(z as i32 + d).is_some_and(|zr| emitting[zr]));
        }
        let pre_rows = &*pre_rows;
        let emitted = self.level_rows(
            cur,
            pre.par_chunks_mut(ring_pitch(nx) * SLOTS * 3),
            g,
            rows,
            (fin, true),
            |z, cur_row, pre_row, g_row, _| {
                if scalar {
                    self.phase3_row_scalar(
                        z,
                        (src, emits),
                        hi,
                        (pows, lnp),
                        p,
                        cur_row,
                        pre_row,
                        g_row,
                    );
                } else if pre_rows[z as usize] {
                    let hi = profile.then_some((hi.0, hi.1, emits));
                    vectorised!(self.phase3_row(z, (planes, hi), p, cur_row, pre_row, g_row));
                } else {
                    return;
                }
                fill_rings(pre_row, nx, self.periodic);
            },
        );
        let pre = &*pre;
        pend_same
            .par_chunks_mut(nx)
            .zip(pend_other.par_chunks_mut(nx))
            .zip(rows.par_iter_mut())
            .enumerate()
            .with_max_len(self.rows_per_task(true).1)
            .for_each(|(z, ((same_row, other_row), rf))| {
                *rf = RowFlux::default();
                vectorised!(self.collide_row(
                    z as i32,
                    (src, emits),
                    hi,
                    (pows, planes),
                    cells,
                    (pre, pre_rows),
                    (same_row, other_row),
                    rf,
                ));
            });
        RowFlux {
            sent: emitted.sent,
            bad: emitted.bad,
            ..sum_rows(rows)
        }
    }

    /// [`Ctx::phase3`]'s emission for row `z`: the row's paths gain their segments'
    /// emission; `pre_row[(slot · 3 + colour) · ring_pitch + RING + x]` ([`plane_index`]'s
    /// layout) is what the path of point `x`
    /// carries into the segment of stencil slot `slot` (written for the segments after
    /// a path's first, the only ones [`Ctx::collide_row`] reads).
    #[inline(always)]
    fn phase3_row<S: Sink>(
        &self,
        z: i32,
        (planes, hi): (&Planes, Option<ProfileRows<'_>>),
        p: usize,
        cur_row: &mut [f32],
        pre_row: &mut [f32],
        g_row: &mut [S],
    ) {
        const B: usize = 64;
        let nx = self.nx as usize;
        let mw = medium::weights(up_pass(self.ch));
        let mut x0 = 0;
        // Set by each channel's first segment (`acc`) and its own cell's (`centre`:
        // every stencil holds it), not zeroed first (a call to `memset` per array and
        // channel).
        let (mut acc, mut centre) = ([[0f32; B]; 3], [[0f32; B]; 3]);
        let mut mean = [0f32; B];
        while x0 < nx {
            let b = B.min(nx - x0);
            with_width(
                b,
                #[inline(always)]
                |b| {
                    for (c, chn) in self.ch.iter().enumerate() {
                        for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                            let slot = chn.first_slot + k;
                            let at = |plane: usize| planes.row(plane, z + dz, x0 as i32 + dx, b);
                            let tr = at(Planes::POW + chn.pow[k]);
                            // What the path carries out of this segment is what it carries
                            // into the next one: stored as it is computed (a path carries
                            // nothing into its first segment, and the collisions read only
                            // the later ones).
                            let next = k + 1 < chn.stencil.len();
                            if dx == 0 && dz == 0 {
                                let lnp = at(Planes::LNP);
                                let e = path_exponents()[chn.pow[k]];
                                for i in 0..b {
                                    mean[i] = seg_mean(tr[i], -e * lnp[i]);
                                }
                                let half = &mean[..b];
                                for col in 0..3 {
                                    let sv = at(Planes::SRC + col);
                                    let (a, ce) = (&acc[col], &mut centre[col]);
                                    if k == 0 {
                                        // Nothing carried in: `0 · h + v` is `v` (but for
                                        // the sign of a zero).
                                        for i in 0..b {
                                            ce[i] = sv[i] * (1.0 - half[i]);
                                        }
                                    } else {
                                        for i in 0..b {
                                            ce[i] = a[i] * half[i] + sv[i] * (1.0 - half[i]);
                                        }
                                    }
                                }
                                // The point's own cell's `P_1`, `P_2` share of its mean light.
                                if let Some((src_hi, prof, emits)) = hi {
                                    for i in 0..b {
                                        let q = x0 + i + nx * z as usize;
                                        if emits[q] {
                                            let w = prof.get(q).mean[slot];
                                            let m = src_hi[q][0] * w[0] + src_hi[q][1] * w[1];
                                            for (col, ce) in centre.iter_mut().enumerate() {
                                                ce[i] += m[col];
                                            }
                                        }
                                    }
                                }
                            }
                            for (col, a) in acc.iter_mut().enumerate() {
                                let sv = at(Planes::SRC + col);
                                let ex = hi.map(|_| {
                                    planes.ex_row(self, (slot, col), z + dz, x0 as i32 + dx, b)
                                });
                                let out = next.then(|| {
                                    &mut pre_row[slot_index(nx, (0, x0), slot + 1, col)..][..b]
                                });
                                if k == 0 {
                                    Self::segment::<true>(&mut a[..b], (tr, sv, ex), out);
                                } else {
                                    Self::segment::<false>(&mut a[..b], (tr, sv, ex), out);
                                }
                            }
                        }
                        let om = mw.omega[c];
                        for (col, a) in acc.iter().enumerate() {
                            let out = &mut cur_row[(c * 3 + col) * p + PAD + x0..][..b];
                            for i in 0..b {
                                out[i] += a[i] * om;
                            }
                        }
                        for i in 0..b {
                            let ce = Vec3::new(centre[0][i], centre[1][i], centre[2][i]);
                            if ce != Vec3::ZERO {
                                g_row[x0 + i].add(chn.bin, chn.unit, ce * om);
                            }
                        }
                    }
                },
            );
            x0 += b;
        }
    }

    /// [`Ctx::phase3_row`] written out for the scalar oracle ([`run_scalar`]): point by
    /// point, channel by channel, along each path cell by cell ([`Ctx::col`]).
    #[allow(clippy::too_many_arguments)]
    fn phase3_row_scalar<S: Sink>(
        &self,
        z: i32,
        (src, emits): (&[Vec3], &[bool]),
        (src_hi, prof): (&[[Vec3; 2]], &crate::profile::Profiles),
        (pows, lnp): (&[[f32; MAX_EXPONENTS]], &[f32]),
        p: usize,
        cur_row: &mut [f32],
        pre_row: &mut [f32],
        g_row: &mut [S],
    ) {
        let nx = self.nx as usize;
        let mw = medium::weights(up_pass(self.ch));
        // A segment's transmittance and emission (light per unit `ω_b σ_c`); beyond
        // open sides empty.
        let profile = self.medium == MediumEmission::Profile;
        let seg = |q: Option<usize>, pow: usize, slot: usize| -> (f32, Vec3) {
            match q {
                Some(q) if emits[q] => {
                    let tr = pows[q][pow];
                    let mut e = src[q] * (1.0 - tr);
                    if profile {
                        let w = prof.get(q).emit[slot];
                        e += src_hi[q][0] * w[0] + src_hi[q][1] * w[1];
                    }
                    (tr, e)
                }
                Some(q) => (pows[q][pow], Vec3::ZERO),
                None => (1.0, Vec3::ZERO),
            }
        };
        for x in 0..self.nx {
            let xi = x as usize;
            let ci = xi + nx * z as usize;
            for (c, chn) in self.ch.iter().enumerate() {
                let mut acc = Vec3::ZERO;
                let mut centre = Vec3::ZERO;
                for (k, &(dx, dz, _)) in chn.stencil.iter().enumerate() {
                    for col in 0..3 {
                        pre_row[slot_index(nx, (0, xi), chn.first_slot + k, col)] = acc[col];
                    }
                    let slot = chn.first_slot + k;
                    let (tr, e) = seg(self.col(x + dx, z + dz), chn.pow[k], slot);
                    if dx == 0 && dz == 0 {
                        let half = seg_mean(
                            pows[ci][chn.pow[k]],
                            -path_exponents()[chn.pow[k]] * lnp[ci],
                        );
                        centre = acc * half;
                        if emits[ci] {
                            centre += src[ci] * (1.0 - half);
                            if profile {
                                let w = prof.get(ci).mean[slot];
                                centre += src_hi[ci][0] * w[0] + src_hi[ci][1] * w[1];
                            }
                        }
                    }
                    acc = acc * tr + e;
                }
                let om = mw.omega[c];
                if acc != Vec3::ZERO {
                    row_add(cur_row, p, xi, c, acc * om);
                }
                if centre != Vec3::ZERO {
                    g_row[xi].add(chn.bin, chn.unit, centre * om);
                }
            }
        }
    }

    /// One segment of phase 3's emission for a block of paths: `a` (what each path
    /// carries) becomes `a·τ + (s·(1 − τ) + e)` with the segment's transmittances `tr`,
    /// sources `sv` and the profile rule's emission `e` (or `a·τ + s·(1 − τ)` without it),
    /// also stored into `next` (what the paths carry into their next segment) where given.
    /// `FIRST`: a path's first segment, which nothing enters: `a` set to `s·(1 − τ) +
    /// e` (`0·τ + v` is `v` but for the sign of a zero; zeroing `a` first was a call to
    /// `memset` per channel and colour). One loop a case, so that each vectorises and
    /// stores as it goes (a copy of `a` afterwards was a call to `memcpy` per slot and
    /// colour: 2.3 % of the bench forest).
    #[inline(always)]
    fn segment<const FIRST: bool>(
        a: &mut [f32],
        (tr, sv, ex): (&[f32], &[f32], Option<&[f32]>),
        next: Option<&mut [f32]>,
    ) {
        let b = a.len();
        let (tr, sv) = (&tr[..b], &sv[..b]);
        match (ex, next) {
            (Some(ex), Some(next)) => {
                let (ex, next) = (&ex[..b], &mut next[..b]);
                for i in 0..b {
                    let own = sv[i] * (1.0 - tr[i]) + ex[i];
                    a[i] = if FIRST { own } else { a[i] * tr[i] + own };
                    next[i] = a[i];
                }
            }
            (Some(ex), None) => {
                let ex = &ex[..b];
                for i in 0..b {
                    let own = sv[i] * (1.0 - tr[i]) + ex[i];
                    a[i] = if FIRST { own } else { a[i] * tr[i] + own };
                }
            }
            (None, Some(next)) => {
                let next = &mut next[..b];
                for i in 0..b {
                    let own = sv[i] * (1.0 - tr[i]);
                    a[i] = if FIRST { own } else { a[i] * tr[i] + own };
                    next[i] = a[i];
                }
            }
            (None, None) => {
                for i in 0..b {
                    let own = sv[i] * (1.0 - tr[i]);
                    a[i] = if FIRST { own } else { a[i] * tr[i] + own };
                }
            }
        }
    }

    /// [`Ctx::phase3`]'s collisions for row `z`: each cell with material (a medium, or
    /// an opaque cell: a surface) stops its level-mates' emission on the horizontal
    /// paths it crosses as segment `j` (the path of point `x − d_j`, which carries
    /// `pre` at slot `j` into it), and scatters it as what it removes in phase 1. Run
    /// channel by channel over blocks of the row (rows of `pre` not written this level,
    /// `!pre_rows[z]`, carry nothing); what a cell emits into the paths of points beyond
    /// an open side leaves through the side.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn collide_row(
        &self,
        z: i32,
        (src, emits): (&[Vec3], &[bool]),
        (src_hi, prof): (&[[Vec3; 2]], &crate::profile::Profiles),
        (pows, planes): (&[[f32; MAX_EXPONENTS]], &Planes),
        cells: &[lightgrid_core::Material],
        (pre, pre_rows): (&[f32], &[bool]),
        (same_row, other_row): (&mut [Pending], &mut [Pending]),
        rf: &mut RowFlux,
    ) {
        const B: usize = GATHER_BLOCK;
        let nx = self.nx as usize;
        let row_cells = &cells[nx * z as usize..][..nx];
        if row_cells.iter().all(|m| m.pass >= 1.0) {
            return;
        }
        let mw = medium::weights(up_pass(self.ch));
        let profile = self.medium == MediumEmission::Profile;
        let mut x0 = 0;
        // Zeroed per block for its `b` points only.
        let mut got_s = [[0f32; B]; 3];
        let mut got_m = [[[0f32; B]; 3]; 3];
        // Profile: the collisions' height moments (P_1, P_2) per colour.
        let mut got_h = [[[0f32; B]; 3]; 2];
        let mut cw = [[0f32; B]; 2];
        while x0 < nx {
            let b = B.min(nx - x0);
            with_width(
                b,
                #[inline(always)]
                |b| {
                    for a in got_s.iter_mut().chain(got_m.iter_mut().flatten()) {
                        a[..b].fill(0.0);
                    }
                    for a in got_h.iter_mut().flatten() {
                        a[..b].fill(0.0);
                    }
                    // Profile: the block's media's profiles (found once, read for every slot).
                    let block_prof: [Option<&crate::profile::CellProfile>; B] =
                        std::array::from_fn(|i| {
                            let ci = x0 + i + nx * z as usize;
                            (profile && i < b && medium::applies(self.medium, cells[ci].pass))
                                .then(|| prof.get(ci))
                        });
                    if self.fetch_profiles() {
                        for pr in block_prof[..b].iter().flatten() {
                            touch(&pr.coll[..]);
                        }
                    }
                    for (c, chn) in self.ch.iter().enumerate() {
                        let om = mw.omega[c] * chn.mu;
                        // A path carries nothing into its first segment.
                        for (j, &(djx, djz, _)) in chn.stencil.iter().enumerate().skip(1) {
                            let Some(zr) = self.row_of(z - djz).filter(|&zr| pre_rows[zr]) else {
                                continue;
                            };
                            let slot = chn.first_slot + j;
                            let pw = planes.row(Planes::POW + chn.pow[j], z, x0 as i32, b);
                            // Columns of the points `x − d_j` (the ring beyond the row's
                            // ends: wrapped, or nothing beyond an open side).
                            let first = x0 as i32 - djx;
                            // Profile: the block's media's collision moments for this slot
                            // (0 elsewhere: what is tallied there is not read).
                            if profile {
                                for (i, pr) in block_prof[..b].iter().enumerate() {
                                    (cw[0][i], cw[1][i]) = pr.map_or((0.0, 0.0), |pr| {
                                        (pr.coll[slot][0], pr.coll[slot][1])
                                    });
                                }
                            }
                            let unit = chn.unit.to_array();
                            let [m0, m1, m2] = &mut got_m;
                            let [h0, h1] = &mut got_h;
                            for col in 0..3 {
                                let mut sums = Tally {
                                    s: &mut got_s[col][..b],
                                    m: [&mut m0[col][..b], &mut m1[col][..b], &mut m2[col][..b]],
                                    h: profile.then_some([&mut h0[col][..b], &mut h1[col][..b]]),
                                };
                                let from = tap(pre, nx, (zr, slot, col), first, b);
                                sums.add(0..b, from, (&pw[..b], om, unit), &cw);
                            }
                        }
                    }
                    for i in 0..b {
                        let xi = x0 + i;
                        let ci = xi + nx * z as usize;
                        let mat = cells[ci];
                        if mat.pass >= 1.0 {
                            continue;
                        }
                        if !self.periodic && emits[ci] {
                            let hi = profile.then(|| (src_hi[ci], prof.get(ci)));
                            self.lost_through_sides(xi as i32, z, src[ci], hi, &pows[ci], rf);
                        }
                        let v = |a: &[[f32; B]; 3]| Vec3::new(a[0][i], a[1][i], a[2][i]);
                        let got = Pending {
                            s: v(&got_s),
                            m: [v(&got_m[0]), v(&got_m[1]), v(&got_m[2])],
                        };
                        if got.s == Vec3::ZERO {
                            continue;
                        }
                        let alb = mat.reflectance;
                        if profile && medium::applies(self.medium, mat.pass) {
                            // Waits for the next passes of both directions, as an isotropic
                            // source.
                            let r = [got.s, v(&got_h[0]), v(&got_h[1])];
                            rf.absorbed += (got.s * (Vec3::ONE - alb)).as_dvec3();
                            let pr = prof.get(ci);
                            let dj = vectorised!(crate::profile::source_rgb(
                                pr,
                                alb,
                                r,
                                &mut rf.absorbed
                            ));
                            let add = Pending::of_coeffs(dj);
                            same_row[xi] = same_row[xi].add(&add);
                            other_row[xi] = other_row[xi].add(&add);
                            rf.pending += self.waiting(
                                crate::profile::flux_rgb(pr, 0, &dj)
                                    + crate::profile::flux_rgb(pr, 1, &dj),
                            );
                            continue;
                        }
                        rf.absorbed += (got.s * (Vec3::ONE - alb)).as_dvec3();
                        let sc = got.scaled(alb);
                        same_row[xi] = same_row[xi].add(&sc);
                        other_row[xi] = other_row[xi].add(&sc);
                        // Each direction's pass emits half of it.
                        rf.pending += sc.s.as_dvec3();
                    }
                },
            );
            x0 += b;
        }
    }

    /// What an emitting cell at `(x, z)` with source `src` sends into the paths of
    /// points beyond an open side: their paths are not traced, so it leaves through the
    /// side (`rf.side_out`).
    fn lost_through_sides(
        &self,
        x: i32,
        z: i32,
        src: Vec3,
        hi: Option<([Vec3; 2], &crate::profile::CellProfile)>,
        pows: &[f32; MAX_EXPONENTS],
        rf: &mut RowFlux,
    ) {
        let r = Planes::R as i32;
        if x >= r && x < self.nx - r && z >= r && z < self.nz - r {
            return;
        }
        let mw = medium::weights(up_pass(self.ch));
        for (c, chn) in self.ch.iter().enumerate() {
            let om = mw.omega[c] * chn.mu;
            for (j, &(djx, djz, _)) in chn.stencil.iter().enumerate() {
                if self.col(x - djx, z - djz).is_none() {
                    let mut e = src * (1.0 - pows[chn.pow[j]]);
                    if let Some((h, pr)) = hi {
                        let w = pr.emit[chn.first_slot + j];
                        e += h[0] * w[0] + h[1] * w[1];
                    }
                    rf.side_out += (e * om).as_dvec3();
                }
            }
        }
    }

    /// Light waiting `v` as the pass counts it: of either sign in accelerated passes
    /// (`signed`), else clamped at 0.
    #[inline]
    fn waiting(&self, v: Vec3) -> DVec3 {
        if self.signed { v } else { v.max(Vec3::ZERO) }.as_dvec3()
    }

    /// The level row that row `z` resolves to ([`Ctx::col`]'s rule).
    #[inline]
    fn row_of(&self, z: i32) -> Option<usize> {
        if self.periodic {
            Some(z.rem_euclid(self.nz) as usize)
        } else {
            (0..self.nz).contains(&z).then_some(z as usize)
        }
    }
}

/// A level conserves the flux it gathers, so the passes book its flux as what the
/// level before it sent on instead of summing its values (the crate docs, "Energy"):
/// a level without material (every point passes its light on unchanged, and
/// nothing scatters) under periodic sides (every source point of its gather is a grid
/// point, and the gather's weights, `1 − w` and four times `w/4`, sum to 1), other
/// than the first of a pass (which gathers from the boundary).
pub fn conserves_flux(periodic: bool, material: bool, first_level: bool) -> bool {
    periodic && !material && !first_level
}

/// Mask of each opaque cell's faces that can receive light (bit order of
/// [`FACE_NORMALS`]); 0 for cells with `p > 0`.
///
/// A face is exposed when it borders a non-opaque cell, or the outside through a side
/// (open sides: the empty world under the sky; given: the halo). The bottom face of a
/// bottom-level cell is **never** exposed: below the grid is the ground the bottom level
/// stands on, not empty space, so an opaque cell there emits nothing downward (emitting
/// half the ground's bounce light into nothing was a leak: a one-level ground reflected
/// half its albedo).
pub fn exposure(material: &MaterialGrid, periodic: bool) -> Vec<u8> {
    let d = *material.desc();
    let dims = d.dims().as_ivec3();
    let cells = material.data();
    (0..d.point_count())
        .into_par_iter()
        .map(|i| {
            if cells[i].pass > 0.0 {
                return 0;
            }
            let p = d.coords(i).expect("index in range").as_ivec3();
            let mut mask = 0u8;
            for (f, n) in FACE_NORMALS.iter().enumerate() {
                let mut q = p + n.as_ivec3();
                if periodic && n.y == 0.0 {
                    q.x = q.x.rem_euclid(dims.x);
                    q.z = q.z.rem_euclid(dims.z);
                }
                let open = if q.y < 0 {
                    false // the ground below the grid
                } else if q.cmplt(IVec3::ZERO).any() || q.cmpge(dims).any() {
                    true
                } else {
                    cells[d.index_unchecked(q.as_uvec3())].pass > 0.0
                };
                if open {
                    mask |= 1 << f;
                }
            }
            mask
        })
        .collect()
}

/// Runs the sweep; see the crate docs for the semantics.
pub fn run(
    material: &MaterialGrid,
    boundary: &Boundary,
    options: &SweepOptions,
) -> Result<Sweep, SweepError> {
    run_with_source(material, boundary, None, options)
}

/// [`run`] with light already deposited in cells (see [`CellSource`]).
pub fn run_with_source(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: Option<&CellSource>,
    options: &SweepOptions,
) -> Result<Sweep, SweepError> {
    run_impl(material, boundary, source, options, true)
}

/// The sweep written as the crate docs say it, step by step, with none of the fast
/// path's shortcuts: the oracle the fast path ([`run`], [`run_with_source`]) is
/// property-tested against (the light bit for bit, the energy balance to `f64` rounding)
/// and benchmarked beside.
pub fn run_scalar(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: Option<&CellSource>,
    options: &SweepOptions,
) -> Result<Sweep, SweepError> {
    run_impl(material, boundary, source, options, false)
}

fn run_impl(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: Option<&CellSource>,
    options: &SweepOptions,
    fast: bool,
) -> Result<Sweep, SweepError> {
    run_reusing(
        material,
        boundary,
        source,
        options,
        fast,
        &mut Spare::default(),
    )
}

/// Output memory of an earlier sweep, reused by the next one of the same size (see
/// [`crate::CpuSweeper::recycle`]): a fresh output's pages must be faulted in and
/// zeroed by the kernel, some 25 ms of a 64³ sweep with 26 bins on the 2-core VM.
#[derive(Clone, Default)]
pub(crate) struct Spare {
    pub(crate) bins: Vec<BinLight>,
    pub(crate) average: Vec<AverageLight>,
    pub(crate) dominant: Vec<DominantDir>,
    work: Option<Work>,
}

impl std::fmt::Debug for Spare {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Spare")
            .field("bins", &self.bins.len())
            .field("average", &self.average.len())
            .field("dominant", &self.dominant.len())
            .field("work", &self.work.as_ref().map(|w| (w.prev.nx, w.prev.nz)))
            .finish()
    }
}

/// `spare` if it holds `n` values (their contents are overwritten, never read), else
/// [`fresh_buffer`].
fn take_buffer<T: bytemuck::Zeroable + Clone>(spare: &mut Vec<T>, n: usize) -> Vec<T> {
    if spare.len() == n {
        std::mem::take(spare)
    } else {
        fresh_buffer(n)
    }
}

/// A zeroed vector of `n` values from pages the kernel maps on first touch, by the
/// threads that first write them; on Linux advised to be backed by 2 MB pages
/// ([`advise_huge_pages`]). A sweep without `recycle` writes a fresh 82 MB output at
/// 64³ (26 bins): with 4 KB pages its 20 000 page faults took about 23 ms of a 33 ms
/// one-pass sweep (19 ms with 2 MB pages; 10 ms recycled).
fn fresh_buffer<T: bytemuck::Zeroable + Clone>(n: usize) -> Vec<T> {
    let mut v = bytemuck::zeroed_vec(n);
    advise_huge_pages(&mut v);
    v
}

/// `madvise(MADV_HUGEPAGE)` on the whole 2 MB pages inside `v` (Linux; a no-op
/// elsewhere, for buffers holding no such page, and where the kernel has transparent
/// huge pages off). Touching 82 MB of fresh memory: 31 ms with 4 KB pages, 4.5 ms with
/// 2 MB ones (one thread, this VM, whose kernel backs only advised ranges with them).
#[allow(unsafe_code)]
fn advise_huge_pages<T>(v: &mut [T]) {
    #[cfg(target_os = "linux")]
    if let Some(r) = huge_pages_inside(v.as_mut_ptr() as usize, std::mem::size_of_val(v)) {
        // SAFETY: `r` lies inside `v`'s allocation ([`huge_pages_inside`]), which this
        // function borrows mutably; MADV_HUGEPAGE changes how the kernel backs those
        // pages, never their contents, and the result (an error where huge pages are
        // off) is advice only.
        unsafe { libc::madvise(r.start as *mut libc::c_void, r.len(), libc::MADV_HUGEPAGE) };
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

/// The addresses of the whole 2 MB pages inside `bytes` bytes from address `start`
/// (`None` if none fits).
fn huge_pages_inside(start: usize, bytes: usize) -> Option<std::ops::Range<usize>> {
    const HUGE: usize = 2 << 20;
    let (a, b) = (start.next_multiple_of(HUGE), (start + bytes) / HUGE * HUGE);
    (b > a).then_some(a..b)
}

/// [`run_impl`] writing into `spare`'s memory where it fits (and leaving what the output
/// does not use there).
pub(crate) fn run_reusing(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: Option<&CellSource>,
    options: &SweepOptions,
    fast: bool,
    spare: &mut Spare,
) -> Result<Sweep, SweepError> {
    validate_inputs(material, boundary, options)?;
    let desc = *material.desc();
    if let Some(src) = source
        && *src.desc() != desc
    {
        return Err(GridError::invalid(
            "source",
            src.desc(),
            "must lie on the material grid's descriptor",
        )
        .into());
    }
    let n = desc.point_count();
    let mut avg = take_buffer(&mut spare.average, n);
    let mut dom = take_buffer(&mut spare.dominant, n);
    let (want_avg, want_dom) = (options.outputs.average, options.outputs.dominant);
    let mut run = Run {
        material,
        boundary,
        source,
        options,
        fast,
        avg: &mut avg,
        dom: &mut dom,
        work: spare.work.take(),
    };
    let (bins, ok, balance, stats) = if options.outputs.bins {
        let (g, ok, balance, stats) = run.run(take_buffer(&mut spare.bins, n));
        (Some(Grid::from_trusted(desc, g)), ok, balance, stats)
    } else {
        let (_, ok, balance, stats) = run.run(fresh_buffer::<AvgAcc>(n));
        (None, ok, balance, stats)
    };
    spare.work = run.work.take();
    // Outputs not asked for keep their memory for the next sweep.
    let average = if want_avg {
        Some(Grid::from_trusted(desc, avg))
    } else {
        spare.average = avg;
        None
    };
    let dominant = if want_dom {
        Some(Grid::from_trusted(desc, dom))
    } else {
        spare.dominant = dom;
        None
    };
    if !ok {
        return Err(SweepError::Backend {
            backend: "cpu",
            message: "light overflowed f32 (boundary light too large for this grid)".into(),
        });
    }
    Ok(Sweep {
        output: SweepOutput {
            bins,
            average,
            dominant,
            stats,
            resident: None,
        },
        balance,
    })
}

/// The inputs of one sweep and where its resolved values go.
struct Run<'a> {
    material: &'a MaterialGrid,
    boundary: &'a Boundary,
    source: Option<&'a CellSource>,
    options: &'a SweepOptions,
    fast: bool,
    avg: &'a mut [AverageLight],
    dom: &'a mut [DominantDir],
    /// Working buffers of an earlier sweep (taken, and given back after the passes).
    work: Option<Work>,
}

impl Run<'_> {
    /// The passes, accumulating into `g` (whose contents are overwritten: the first
    /// pass sets every point), then [`resolve`]: level by level as the last pass (when it
    /// is known to be the last: the pass limit) finishes each level, while its values
    /// are still in cache, else over the grid afterwards. Returns `g`, whether every
    /// value was valid, the balance and the stats.
    ///
    /// The passes run on a worker of rayon's pool (`rayon::scope`): a level's parallel
    /// loops then start from inside the pool, and a level small enough for one task runs
    /// on that worker at once instead of waking another thread for it.
    fn run<S: Sink>(&mut self, g: Vec<S>) -> (Vec<S>, bool, EnergyBalance, SweepStats) {
        rayon::scope(|_| run_with(self, g))
    }
}

fn run_with<S: Sink>(
    run: &mut Run<'_>,
    mut g: Vec<S>,
) -> (Vec<S>, bool, EnergyBalance, SweepStats) {
    let (material, boundary, source, options, fast) = (
        run.material,
        run.boundary,
        run.source,
        run.options,
        run.fast,
    );
    let want_dom = options.outputs.dominant;
    let mut ok = true;
    let mut resolved = false;
    let desc = *material.desc();
    let dims = desc.dims();
    let (nx, ny, nz) = (dims.x as i32, dims.y as i32, dims.z as i32);
    let cells = material.data();
    let fixed = Fixed::of(material, boundary);
    let mut w = Work::reuse(
        run.work.take(),
        nx as usize,
        nz as usize,
        desc.point_count(),
    );
    w.prof.begin_sweep();
    let mut bal = EnergyBalance::default();
    let mut stats = SweepStats::default();
    if let Some(src) = source {
        // Step 4 for the beam's deposit: absorb (1 - a), and the rest waits in both
        // directions' pending light (each pass emits its half, as for removed light).
        for (i, (&r, mat)) in src.removed().iter().zip(cells).enumerate() {
            if r == Vec3::ZERO {
                continue;
            }
            bal.source_in += r.as_dvec3();
            bal.absorbed += (r * (Vec3::ONE - mat.reflectance)).as_dvec3();
            if options.medium == MediumEmission::Profile
                && medium::applies(options.medium, mat.pass)
            {
                // The beam's first collisions have the height moments of a beam
                // entering the cell through its top (or bottom) face.
                let (j, absorbed) = crate::profile::beam_source(mat, src.dir(), r);
                bal.absorbed += absorbed.as_dvec3();
                w.pend_down[i] = Pending::of_coeffs(j);
                w.pend_up[i] = Pending::of_coeffs(j);
                w.pend_dirty[i / desc.level_len()] = true;
                continue;
            }
            let s = r * mat.reflectance;
            let p = Pending {
                s,
                m: [s * src.dir().x, s * src.dir().y, s * src.dir().z],
            };
            w.pend_down[i] = p;
            w.pend_up[i] = p;
            w.pend_dirty[i / desc.level_len()] = true;
        }
    }

    // A sink this large stays in no cache between passes: each row's next row is
    // fetched ahead (`Ahead`).
    let fetch_ahead = std::mem::size_of_val(&g[..]) >= FETCH_AHEAD_BYTES;
    // Diffusion acceleration (`crate::accel`): its operator, built when the passes
    // switch to it (a sweep that converges fast pays nothing), and the correction
    // outstanding in the media's waiting light.
    let may_accelerate = crate::accel::wanted(options) && fixed.level_medium.iter().any(|&m| m);
    let mut dsa: Option<crate::accel::Diffusion> = None;
    let mut debt = Debt::new(None);
    // How the passes run (accelerated from the first pair whose light waiting fell
    // slowly), the waiting light after the last pair, and for how many pairs in a row
    // it grew.
    let mut mode = Mode::Plain;
    // The quadratic source in height (`crate::profile`) is not positive everywhere: its
    // light is resolved after the sweep, clamped at 0, as an accelerated sweep's.
    let signed_light = options.medium == MediumEmission::Profile;
    let mut waited = f64::INFINITY;
    let mut grew = 0;

    // Upward light above all material (the crate docs, "Skipped work"): the levels
    // above the top level with material only carry light up, so an upward pass that
    // another upward pass follows, and in which no light enters them from the sides,
    // stops below them and leaves what it sends on in `w.above` (`above`: its flux);
    // the last upward pass carries the sum through them once. If the sweep ends
    // otherwise (converged, or a last downward pass, which resolves those levels,
    // comes next), a run of its own carries it first.
    let defer = options.skip_empty_levels && fixed.top_material >= 0 && fixed.top_material + 1 < ny;
    let mut above: Option<DVec3> = None;
    let mut pass = 0;
    let mut converged = false;
    loop {
        let ends = converged || pass >= options.max_passes;
        let carry = above.is_some() && (ends || (pass + 1 == options.max_passes && pass % 2 == 0));
        if ends && !carry {
            break;
        }
        let up = carry || pass % 2 == 1;
        let (first, final_pass) = (
            pass == 0 && !carry,
            pass + 1 == options.max_passes && !carry,
        );
        let ch = channels(up);
        let src = Sources {
            boundary,
            active: pass < 2 && !carry,
            up,
            dims,
            halo: fixed.halo,
        };
        let ctx = Ctx::new(nx, nz, fixed.periodic, options, ch, mode);
        // The last plain pass resolves each level as it ends (clamping light of either
        // sign at 0 first); after accelerated passes the light is resolved after the
        // sweep.
        let last = final_pass && mode == Mode::Plain;
        if !carry {
            stats.passes += 1;
        }
        // This upward pass stops below the levels above all material (unless light
        // enters them from the sides: the passes' convergence test counts it as it
        // enters).
        let side_light = src.active
            && match &boundary.sides {
                SideBoundary::Periodic => false,
                SideBoundary::Open => boundary.bottom != BinLight::ZERO,
                SideBoundary::Given(_) => true,
            };
        let stops = up && defer && !carry && !final_pass && !side_light;
        let mut pending = DVec3::ZERO;
        // The flux the last level's final light sends on.
        let mut sent_on = DVec3::ZERO;
        // Levels copied in a row just before this one (all with the same light).
        let mut copied_in_row = 0;
        // `w.prev`'s rows hold their wrapped columns in the ring already
        // ([`Finish::wrap_columns`]; sums with `w.above` keep that).
        let mut prev_columns_wrapped = false;
        let start = if carry { fixed.top_material + 1 } else { 0 };
        for li in start..ny {
            let j = if up { li } else { ny - 1 - li };
            if up && defer && j == fixed.top_material + 1 {
                if stops {
                    match above.as_mut() {
                        Some(sent) => {
                            w.above.add(&w.prev);
                            *sent += sent_on;
                        }
                        None => {
                            w.above.v.copy_from_slice(&w.prev.v);
                            above = Some(sent_on);
                        }
                    }
                    break;
                }
                if let Some(sent) = above.take() {
                    if carry {
                        std::mem::swap(&mut w.prev, &mut w.above);
                    } else {
                        w.prev.add(&w.above);
                    }
                    sent_on += sent;
                }
            }
            let from_virtual = li == 0;
            let range = desc.level_range(j as u32);
            if from_virtual {
                w.fill_from_boundary(&src, &ctx);
                prev_columns_wrapped = false;
            }
            // Skip: a level above all material, in a downward pass, under a laterally
            // uniform boundary (or with no boundary light at all), receives exactly what
            // it passes on. Copy instead of computing.
            if options.skip_empty_levels
                && !up
                && j > fixed.top_material
                && (fixed.laterally_uniform || !src.active)
            {
                let v: Level = std::array::from_fn(|c| src.virtual_light(0, 0, &ch[c]));
                // Booked as a computed level books it: of what its points gather, the
                // share from source points beyond open sides enters through the sides,
                // and as much of what the level above sent on left through them.
                let (inside, outside) = ctx.uniform_gather(&v);
                if from_virtual {
                    bal.top_in += inside;
                } else {
                    bal.side_out += outside;
                }
                bal.side_in += outside;
                // Every point of the level receives the same light: one sink value.
                let mut one = S::default();
                for (c, chn) in ch.iter().enumerate() {
                    one.add(chn.bin, chn.unit, v[c]);
                }
                if first {
                    g[range.clone()]
                        .par_chunks_mut(MIN_POINTS_PER_TASK)
                        .for_each(|gc| gc.fill(one));
                } else if src.active {
                    g[range.clone()]
                        .par_chunks_mut(MIN_POINTS_PER_TASK)
                        .for_each(|gc| {
                            touch(gc);
                            for gp in gc {
                                gp.add_channels(ch, |c| v[c]);
                            }
                        });
                }
                // From the third copied level on, `cur` is the level two back, which
                // holds `v` already (nothing writes a level's light while it is `prev`
                // of a copied level).
                if copied_in_row < 2 {
                    w.cur.fill(&v);
                }
                copied_in_row += 1;
                sent_on = (0..CHANNELS)
                    .map(|c| v[c].as_dvec3() * ch[c].mu as f64)
                    .sum::<DVec3>()
                    * desc.level_len() as f64;
                stats.levels_copied += 1;
                std::mem::swap(&mut w.prev, &mut w.cur);
                prev_columns_wrapped = false;
                if last && first {
                    // One pass: the level's points are all `one`.
                    let (valid, a, d) = one.resolve(want_dom);
                    ok &= valid & a.is_finite() & d.is_finite();
                    run.avg[range.clone()].fill(AverageLight(a));
                    run.dom[range].fill(DominantDir(d));
                } else if last {
                    ok &= resolve(
                        &g[range.clone()],
                        &mut run.avg[range.clone()],
                        &mut run.dom[range],
                        want_dom,
                    );
                }
                continue;
            }
            stats.levels_computed += 1;
            copied_in_row = 0;
            // The next level of this pass has no material: this level's rows wrap
            // their ring columns for it as they end ([`Finish::wrap_columns`]).
            let wrap_in_rows = fast
                && fixed.periodic
                && li + 1 < ny
                && !fixed.level_material[(if up { j + 1 } else { j - 1 }) as usize];
            let src_level = if up { j - 1 } else { j + 1 };
            let sent = sent_on;
            // A level without material: every point is quiet, and nothing scatters.
            let material_here = fixed.level_material[j as usize] || !fast;
            // Levels with media under the profile rule: their cells' profiles, and
            // the emission planes phase 2 writes.
            let profile_level =
                options.medium == MediumEmission::Profile && fixed.level_medium[j as usize];
            // The level's per-cell values and the ring of the light it gathers from:
            // the transmittances on one thread while the other wraps the ring, finds
            // the quiet points and the media's profiles (each a short step of one
            // thread that left the other waiting, a tenth of a 16³ sweep). The
            // transmittances, their planes and the quiet points are the same in every
            // pass: found at a level's first visit of the sweep, kept for the others
            // (`Work::set_up`).
            {
                let lnp = &fixed.lnp[range.clone()];
                let level = &cells[range.clone()];
                let first_visit = material_here && !w.set_up[j as usize];
                w.set_up[j as usize] |= material_here;
                w.planes.level = j as usize;
                let Work {
                    pows,
                    planes,
                    prev,
                    quiet,
                    quiet_rows,
                    prof,
                    ..
                } = &mut w;
                let (pows, quiet) = (&mut pows[range.clone()], &mut quiet[range.clone()]);
                let mut each_pass = || {
                    if fast && fixed.periodic {
                        // The level before wrapped its rows' columns as they ended if
                        // this level has no material (`Finish::wrap_columns`).
                        if prev_columns_wrapped {
                            prev.wrap_ring_rows();
                        } else {
                            prev.wrap_ring();
                        }
                    }
                    if profile_level {
                        prof.level(up, lnp, |q| medium::applies(options.medium, level[q].pass));
                    }
                };
                if first_visit {
                    rayon::join(
                        || {
                            level_powers(pows, lnp);
                            planes.fill_pows(&ctx, pows, lnp);
                        },
                        || {
                            each_pass();
                            if fast {
                                ctx.quiet(lnp, quiet, quiet_rows);
                            }
                        },
                    );
                } else {
                    each_pass();
                }
            }
            // Its flux is what the level before it sent on: booked so, not summed.
            let conserved = conserves_flux(
                fixed.periodic,
                fixed.level_material[j as usize],
                from_virtual,
            );
            let mut f1 = if fast {
                // Light from outside the sides: the ring of `ghost`.
                let ghost_on = src.active && !fixed.periodic;
                if ghost_on {
                    w.fill_ghost(&src, &ctx, from_virtual, src_level);
                }
                let quiet = material_here.then_some(&w.quiet[range.clone()]);
                ctx.phase1_fast(
                    (&w.prev, !conserved, fetch_ahead),
                    ghost_on.then_some(&w.ghost),
                    &w.planes,
                    quiet,
                    first,
                    &mut w.cur,
                    &mut w.removed,
                    &mut w.t_after,
                    &mut g[range.clone()],
                    &mut w.rows,
                    Finish {
                        avg: &mut run.avg[range.clone()],
                        dom: &mut run.dom[range.clone()],
                        last_phase: !material_here,
                        resolve: last.then_some(want_dom),
                        clamp: signed_light,
                        from_planes: first && !material_here,
                        wrap_columns: wrap_in_rows,
                    },
                )
            } else {
                ctx.phase1_scalar(
                    &w.prev,
                    &src,
                    from_virtual,
                    src_level,
                    (&w.pows[range.clone()], &fixed.lnp[range.clone()]),
                    first,
                    &mut w.cur,
                    &mut w.removed,
                    &mut w.t_after,
                    &mut g[range.clone()],
                    &mut w.rows,
                )
            };
            if conserved {
                (f1.inside, f1.sent) = (sent, sent);
            }
            if from_virtual {
                if up {
                    bal.bottom_in += f1.inside;
                } else {
                    bal.top_in += f1.inside;
                }
            } else {
                // Light that left the previous level but reached no point of this one
                // crossed a side face.
                // (Clamped at 0 against rounding, unless light of either sign flows.)
                let side = sent - f1.inside;
                bal.side_out += if mode == Mode::Plain {
                    side.max(DVec3::ZERO)
                } else {
                    side
                };
            }
            bal.side_in += f1.outside;
            if !material_here {
                // Phase 1 finished the level.
                sent_on = f1.sent;
                ok &= !f1.bad;
                std::mem::swap(&mut w.prev, &mut w.cur);
                prev_columns_wrapped = wrap_in_rows;
                continue;
            }
            w.pend_dirty[j as usize] = true;
            // Accelerated: a downward pass leaves the upward share of what collides in
            // it in `pend_next` (the next pair's), so the upward pass emits only what
            // the last pair left; its own collisions go to `pend_down` and `pend_up`.
            let (same, other) = match (up, mode == Mode::Accelerated) {
                (true, _) => (&mut w.pend_up, &mut w.pend_down),
                (false, false) => (&mut w.pend_down, &mut w.pend_up),
                (false, true) => (&mut w.pend_down, &mut w.pend_next),
            };
            // The source rules emit from media in a third phase.
            let phase3 = matches!(
                options.medium,
                MediumEmission::Source | MediumEmission::Profile
            ) && fixed.level_medium[j as usize];
            if profile_level {
                let n = range.len();
                if w.src_hi.len() != n {
                    w.src_hi = vec![[Vec3::ZERO; 2]; n];
                }
                // Phase 3's emission planes, written (zeroed row by row first) by phase
                // 2 on the fast path; grown once, kept across levels.
                w.planes.ex.resize(
                    if fast {
                        SLOTS * 3 * nz as usize * ring_pitch(nx as usize)
                    } else {
                        0
                    },
                    0.0,
                );
            }
            let f2 = ctx.phase2(
                (&w.removed, !fast),
                (&w.t_after, &w.pows[range.clone()]),
                &cells[range.clone()],
                &fixed.exposed[range.clone()],
                &mut w.cur,
                same.level_mut(j as usize),
                other.level_mut(j as usize),
                (
                    &mut w.src,
                    &mut w.emits,
                    &mut w.src_hi,
                    &w.prof,
                    if profile_level {
                        &mut w.planes.ex[..]
                    } else {
                        &mut []
                    },
                ),
                &mut g[range.clone()],
                &mut w.rows,
                Finish {
                    avg: &mut run.avg[range.clone()],
                    dom: &mut run.dom[range.clone()],
                    last_phase: !phase3,
                    resolve: last.then_some(want_dom),
                    clamp: signed_light,
                    from_planes: false,
                    wrap_columns: wrap_in_rows,
                },
            );
            bal.absorbed += f2.absorbed;
            pending += f2.pending;
            // (The scalar oracle runs phase 2 on levels without material too.)
            sent_on = if conserved { sent } else { f2.sent };
            ok &= !f2.bad;
            if phase3 {
                let f3 = ctx.phase3(
                    (&w.src, &w.emits),
                    (&w.src_hi, &w.prof),
                    (
                        &w.pows[range.clone()],
                        &fixed.lnp[range.clone()],
                        &mut w.planes,
                    ),
                    &cells[range.clone()],
                    &mut w.cur,
                    (&mut w.pre, &mut w.pre_rows),
                    (same.level_mut(j as usize), other.level_mut(j as usize)),
                    &mut g[range.clone()],
                    &mut w.rows,
                    Finish {
                        avg: &mut run.avg[range.clone()],
                        dom: &mut run.dom[range.clone()],
                        last_phase: true,
                        resolve: last.then_some(want_dom),
                        clamp: signed_light,
                        from_planes: false,
                        wrap_columns: wrap_in_rows,
                    },
                    !fast,
                );
                bal.absorbed += f3.absorbed;
                bal.side_out += f3.side_out;
                pending += f3.pending;
                sent_on = f3.sent;
                ok &= !f3.bad;
            }
            std::mem::swap(&mut w.prev, &mut w.cur);
            prev_columns_wrapped = wrap_in_rows;
        }
        // What leaves the last level leaves the grid.
        let leaving = sent_on;
        if carry {
            bal.top_out += leaving;
            continue;
        }
        resolved = last;
        if !up {
            bal.bottom_out += leaving;
        } else if !stops {
            bal.top_out += leaving;
        }
        // With acceleration: what waits net of the correction not yet taken back, and
        // the convergence test on the largest waiting light of either sign, after
        // each pair.
        let waiting = if let Some(d) = dsa.as_ref().filter(|_| mode != Mode::Plain) {
            let before = debt.waiting(d, &w, cells, &fixed, options.medium);
            bal.pending = before.net;
            if up && mode == Mode::Accelerated {
                // Two pairs in a row that left more waiting: the estimate does
                // not suit this medium; back to plain passes (light of either
                // sign now).
                let now = before.abs.max_element();
                grew = if now > waited { grew + 1 } else { 0 };
                waited = now;
                if grew >= 2 {
                    debt.release(d, &mut w, (&fixed.lnp, cells, options.medium));
                    mode = Mode::Fallback;
                } else {
                    stats.corrections += 1;
                    debt.correct(d, &mut w, (&fixed.lnp, cells, options.medium));
                }
            }
            if up { before.abs } else { DVec3::INFINITY }
        } else {
            bal.pending = pending;
            if may_accelerate && up {
                // Plain passes while the light waiting falls fast; accelerated from
                // the first pair after which it fell by less than
                // `crate::accel::SWITCH`.
                let now = pending.max_element();
                if now > crate::accel::SWITCH * waited
                    && now > options.tolerance as f64 * bal.input().max_element()
                    && pass + 1 < options.max_passes
                    && let Some(d) = crate::accel::Diffusion::of(material, fixed.periodic, options)
                {
                    if w.pend_next.len() != desc.point_count() {
                        w.pend_next = PendingLevels::new(desc.level_len(), ny as usize);
                    }
                    debt = Debt::new(Some(&d));
                    mode = Mode::Accelerated;
                    stats.corrections += 1;
                    debt.correct(&d, &mut w, (&fixed.lnp, cells, options.medium));
                    dsa = Some(d);
                }
                waited = now;
            }
            pending
        };
        let input = bal.input().max_element();
        converged = waiting.max_element() <= options.tolerance as f64 * input && pass >= 1;
        pass += 1;
    }
    if !resolved && (mode != Mode::Plain || signed_light) {
        // What the accelerated passes left: light off by up to the tolerance either
        // way, so a point in the dark may hold a little below 0. (A quadratic source
        // in height may dip below 0 within a cell, and a near-transparent cell's mean
        // light round below 0.)
        g.par_chunks_mut(RESOLVE_CHUNK)
            .for_each(|c| c.iter_mut().for_each(S::clamp));
    }
    if !resolved {
        ok = resolve(&g, run.avg, run.dom, want_dom);
    }
    run.work = Some(w);
    (g, ok, bal, stats)
}

/// What a sweep derives once from its inputs.
/// How a sweep's passes run ([`crate::accel`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// The plain passes.
    Plain,
    /// Accelerated: one generation per pair, with the diffusion estimate.
    Accelerated,
    /// Plain passes again after acceleration failed to converge, with light of
    /// either sign.
    Fallback,
}

/// The diffusion correction outstanding in the media's waiting light
/// ([`crate::accel`]), the waiting light held back from the next pair, and the
/// solve's buffers.
struct Debt {
    /// Per media cell: the correction added after the last pair of passes.
    delta: Vec<Vec3>,
    /// Per media cell: the share `1 − ω` of its waiting light held back from the
    /// next pair (downward, upward).
    hold: Vec<(Pending, Pending)>,
    q: Vec<Vec3>,
    next: Vec<Vec3>,
}

/// The light still waiting in the cells of an accelerated sweep: the sum of every
/// cell's shares (net of the outstanding correction), and the same with each cell's
/// counted at its absolute value (for the convergence test).
#[derive(Clone, Copy, Default)]
struct Waiting {
    net: DVec3,
    abs: DVec3,
}

/// What the diffusion correction `delta` (scattered flux, RGB) adds to a medium cell's
/// waiting light in each direction: flux `delta` under the flat rule (each pass emits
/// half of it), the source coefficients that scatter `delta` under the profile rule
/// ([`crate::profile::CellProfile::source_of_scattered`]).
fn correction(
    (lnp, cells, rule): (&[f32], &[lightgrid_core::Material], MediumEmission),
    i: usize,
    delta: Vec3,
) -> Pending {
    if rule == MediumEmission::Profile {
        let a = cells[i].reflectance;
        let j: [[f32; 3]; 3] = crate::profile::with_profile(false, lnp[i], |pr| {
            std::array::from_fn(|k| pr.source_of_scattered(a[k], delta[k]))
        });
        Pending::of_coeffs(std::array::from_fn(|n| {
            Vec3::new(j[0][n], j[1][n], j[2][n])
        }))
    } else {
        Pending {
            s: delta,
            m: [Vec3::ZERO; 3],
        }
    }
}

/// The shares of a medium cell's waiting light `(pd, pu)` that the downward and the
/// upward pass emit (step 5), summed.
#[inline]
fn shares(beta: f32, pd: &Pending, pu: &Pending) -> Vec3 {
    0.5 * (pd.s + beta * pd.m[1]) + 0.5 * (pu.s - beta * pu.m[1])
}

impl Debt {
    fn new(d: Option<&crate::accel::Diffusion>) -> Self {
        let (media, n) = d.map_or((0, 0), |d| (d.media, d.cells.len()));
        Self {
            delta: vec![Vec3::ZERO; media],
            hold: vec![Default::default(); media],
            q: vec![Vec3::ZERO; n],
            next: vec![Vec3::ZERO; n],
        }
    }

    /// What waits in `w` and here for the passes to come: per cell, the downward
    /// pass's share of `pend_down` and the upward pass's of `pend_up` and `pend_next`,
    /// with what is held back, less the outstanding correction.
    fn waiting(
        &self,
        d: &crate::accel::Diffusion,
        w: &Work,
        cells: &[lightgrid_core::Material],
        fixed: &Fixed,
        rule: MediumEmission,
    ) -> Waiting {
        let level_len = w.prev.nx * w.prev.nz;
        let (down, up) = (channels(false), channels(true));
        let mut out = Waiting::default();
        for (j, _) in w.pend_dirty.iter().enumerate().filter(|(_, d)| **d) {
            for i in j * level_len..(j + 1) * level_len {
                let mat = &cells[i];
                if mat.is_empty() {
                    continue;
                }
                let (pd, pu, pn) = (&w.pend_down[i], &w.pend_up[i], &w.pend_next[i]);
                let v = if rule == MediumEmission::Profile && medium::applies(rule, mat.pass) {
                    // What the waiting sources will send out of the cell (their own
                    // material's share was absorbed when they were solved for), less
                    // the outstanding correction's.
                    let pr = crate::profile::with_profile(false, fixed.lnp[i], |pr| *pr);
                    let out = |which: usize, p: &Pending| {
                        crate::profile::flux_rgb(&pr, which, &p.coeffs())
                    };
                    let mut v = out(0, pd) + out(1, &pu.add(pn));
                    if let Some(k) = d.slot.get(i).copied().filter(|&k| k != u32::MAX) {
                        let (hd, hu) = &self.hold[k as usize];
                        let fx = (&fixed.lnp[..], cells, rule);
                        let c = correction(fx, i, self.delta[k as usize]);
                        v += out(0, hd) + out(1, hu) - out(0, &c) - out(1, &c);
                    }
                    v
                } else if medium::applies(rule, mat.pass) {
                    let beta = medium::split(fixed.lnp[i]);
                    let mut v = shares(beta, pd, &pu.add(pn));
                    if let Some(k) = d.slot.get(i).copied().filter(|&k| k != u32::MAX) {
                        let (hd, hu) = &self.hold[k as usize];
                        v += shares(beta, hd, hu) - self.delta[k as usize];
                    }
                    v
                } else {
                    let em = Emission::new(mat.pass, fixed.exposed[i], rule);
                    em.budget(pd, down) + em.budget(pu, up) + em.budget(pn, up)
                };
                out.net += v.as_dvec3();
                out.abs += v.abs().as_dvec3();
            }
        }
        out
    }

    /// Ends acceleration after a pair of passes: what `pend_next`, the outstanding
    /// correction and the held-back light stand for goes back to the waiting light.
    fn release(
        &mut self,
        d: &crate::accel::Diffusion,
        w: &mut Work,
        fx: (&[f32], &[lightgrid_core::Material], MediumEmission),
    ) {
        self.merge_next(w);
        for (k, &ci) in d.cells[..d.media].iter().enumerate() {
            let i = ci as usize;
            let (hd, hu) = std::mem::take(&mut self.hold[k]);
            let delta = std::mem::take(&mut self.delta[k]);
            let back = correction(fx, i, delta);
            let (pd, pu) = (&mut w.pend_down[i], &mut w.pend_up[i]);
            *pd = pd.add(&back.scaled(Vec3::splat(-1.0)));
            *pu = pu.add(&back.scaled(Vec3::splat(-1.0)));
            *pd = pd.add(&hd);
            *pu = pu.add(&hu);
        }
    }

    /// `pend_next` added to `pend_up` (and cleared).
    fn merge_next(&self, w: &mut Work) {
        for (j, _) in w.pend_dirty.iter().enumerate().filter(|(_, d)| **d) {
            let up = w.pend_up.level_mut(j);
            match w.pend_next.levels.get_mut(j).filter(|l| !l.is_empty()) {
                Some(next) => {
                    for (u, n) in up.iter_mut().zip(next) {
                        *u = u.add(&std::mem::take(n));
                    }
                }
                // (Added all the same: `-0 + 0` is `+0`, as before.)
                None => up.iter_mut().for_each(|u| *u = u.add(&PendingLevels::ZERO)),
            }
        }
    }

    /// After a pair of passes: moves the upward share of the downward pass's
    /// collisions (`pend_next`) to `pend_up` for the next pair, takes back the last
    /// correction (the pair emitted it), and sets the next pair's light in the media:
    /// `ω` of what waits (the rest held back: a damped iteration, whose rate at the
    /// media's alternating, cell-to-cell patterns stays well below 1) and the
    /// diffusion correction for it.
    fn correct(
        &mut self,
        d: &crate::accel::Diffusion,
        w: &mut Work,
        fx: (&[f32], &[lightgrid_core::Material], MediumEmission),
    ) {
        let (lnp, cells, rule) = fx;
        let omega = crate::accel::DAMPING;
        let level_len = w.prev.nx * w.prev.nz;
        self.merge_next(w);
        for (k, &ci) in d.cells[..d.media].iter().enumerate() {
            let i = ci as usize;
            let (hd, hu) = std::mem::take(&mut self.hold[k]);
            let back = correction(fx, i, self.delta[k]);
            let (pd, pu) = (&mut w.pend_down[i], &mut w.pend_up[i]);
            *pd = pd.add(&back.scaled(Vec3::splat(-1.0)));
            *pu = pu.add(&back.scaled(Vec3::splat(-1.0)));
            *pd = pd.add(&hd);
            *pu = pu.add(&hu);
            self.hold[k] = (
                pd.scaled(Vec3::splat(1.0 - omega)),
                pu.scaled(Vec3::splat(1.0 - omega)),
            );
            *pd = pd.scaled(Vec3::splat(omega));
            *pu = pu.scaled(Vec3::splat(omega));
            self.q[k] = if rule == MediumEmission::Profile {
                let a = cells[i].reflectance;
                crate::profile::with_profile(false, lnp[i], |pr| {
                    let sc = |p: &Pending| crate::profile::scattered_rgb(pr, a, &p.coeffs());
                    0.5 * (sc(pd) + sc(pu))
                })
            } else {
                shares(medium::split(lnp[i]), pd, pu)
            };
        }
        d.correct(&self.q, &mut self.next);
        for (k, &ci) in d.cells[..d.media].iter().enumerate() {
            let i = ci as usize;
            let delta = self.next[k] * crate::accel::GAIN;
            let add = correction(fx, i, delta);
            w.pend_down[i] = w.pend_down[i].add(&add);
            w.pend_up[i] = w.pend_up[i].add(&add);
            w.pend_dirty[i / level_len] = true;
            self.delta[k] = delta;
        }
    }
}

struct Fixed {
    /// ln(pass) per cell: -inf for opaque cells, whose exp(f * l * -inf) is exactly 0
    /// (f * l > 0 always, so no 0 * inf).
    lnp: Vec<f32>,
    /// Exposed-face masks of opaque cells ([`exposure`]).
    exposed: Vec<u8>,
    /// The highest level holding material (-1: none).
    top_material: i32,
    /// Per level: some cell of it holds material (`p < 1`).
    level_material: Vec<bool>,
    /// Per level: some cell of it is a medium (`0 < p < 1`).
    level_medium: Vec<bool>,
    /// The boundary is the same at every column (uniform top, open or periodic sides).
    laterally_uniform: bool,
    periodic: bool,
    halo: Option<lightgrid_core::HaloLayout>,
}

impl Fixed {
    fn of(material: &MaterialGrid, boundary: &Boundary) -> Self {
        let desc = material.desc();
        let cells = material.data();
        let periodic = matches!(boundary.sides, SideBoundary::Periodic);
        // On every core: a logarithm a cell and the levels' scans took a millisecond of
        // one core at 64³ every sweep.
        let (level_material, level_medium): (Vec<bool>, Vec<bool>) = (0..desc.levels())
            .into_par_iter()
            .map(|j| {
                let level = &cells[desc.level_range(j)];
                (
                    level.iter().any(|m| !m.is_empty()),
                    level.iter().any(|m| m.pass > 0.0 && m.pass < 1.0),
                )
            })
            .unzip();
        let top_material = level_material
            .iter()
            .rposition(|&m| m)
            .map_or(-1, |j| j as i32);
        Self {
            top_material,
            lnp: cells.par_iter().map(|m| m.pass.ln()).collect(),
            exposed: exposure(material, periodic),
            level_material,
            level_medium,
            laterally_uniform: matches!(boundary.top, TopBoundary::Uniform(_))
                && matches!(boundary.sides, SideBoundary::Open | SideBoundary::Periodic),
            periodic,
            halo: matches!(boundary.sides, SideBoundary::Given(_))
                .then(|| lightgrid_core::HaloLayout::new(desc.dims())),
        }
    }
}

/// The working buffers of a sweep, allocated once (per level, and per point for the
/// pending light), and kept for the next sweep of the same size in [`Spare`].
/// A level's per-cell values as padded planes for phase 3's row loops: the
/// transmittance of every path exponent ([`Planes::POW`] + exponent) and the source
/// rule's source per colour ([`Planes::SRC`] + colour; 0 where a cell does not emit),
/// each a plane of `(nx + 2R) × (nz + 2R)` with a ring of `R` cells beyond the sides:
/// wrapped on periodic sides, else empty space (transmittance 1, no source), as
/// [`Ctx::col`] resolves a cell beyond a side.
#[derive(Clone)]
struct Planes {
    /// Every level's transmittance and `ln(pass)` planes ([`Planes::PER_LEVEL`] a
    /// level), written at the level's first visit of a sweep (`Work::set_up`).
    v: Vec<f32>,
    /// The source planes of the level being swept.
    src: Vec<f32>,
    /// The level whose planes [`Planes::row`] reads.
    level: usize,
    nx: usize,
    nz: usize,
    /// [`MediumEmission::Profile`]: what each cell's `P_1`, `P_2` source terms emit into
    /// the segment of each stencil slot; per row of the level: slot, colour, column (no
    /// ring; 0 where the cell does not emit; empty under other rules). Written by phase
    /// 2 as it solves each cell's source ([`Ctx::phase2_row`]).
    ex: Vec<f32>,
}

impl Planes {
    /// The ring: the farthest stencil offset.
    const R: usize = RING;
    const POW: usize = 0;
    /// The cells' `ln(pass)` (0 beyond open sides), for [`seg_mean`].
    const LNP: usize = MAX_EXPONENTS;
    /// Planes kept per level.
    const PER_LEVEL: usize = MAX_EXPONENTS + 1;
    const SRC: usize = Self::PER_LEVEL;

    fn new(nx: usize, nz: usize, levels: usize) -> Self {
        let plane = (nx + 2 * Self::R) * (nz + 2 * Self::R);
        Self {
            v: vec![0.0; levels * Self::PER_LEVEL * plane],
            src: vec![0.0; 3 * plane],
            level: 0,
            nx,
            nz,
            ex: Vec::new(),
        }
    }

    /// Floats of one plane.
    #[inline]
    fn plane_len(&self) -> usize {
        self.width() * (self.nz + 2 * Self::R)
    }

    /// Plane `plane` of the current level ([`Planes::level`]; the source planes are
    /// the level being swept's).
    #[inline]
    fn plane(&self, plane: usize) -> &[f32] {
        let n = self.plane_len();
        if plane >= Self::SRC {
            &self.src[(plane - Self::SRC) * n..][..n]
        } else {
            &self.v[(self.level * Self::PER_LEVEL + plane) * n..][..n]
        }
    }

    /// [`Planes::plane`], to write.
    #[inline]
    fn plane_mut(&mut self, plane: usize) -> &mut [f32] {
        let n = self.plane_len();
        if plane >= Self::SRC {
            &mut self.src[(plane - Self::SRC) * n..][..n]
        } else {
            &mut self.v[(self.level * Self::PER_LEVEL + plane) * n..][..n]
        }
    }

    #[inline]
    fn width(&self) -> usize {
        self.nx + 2 * Self::R
    }

    /// `len` values of `plane` from column `x` of row `z` (`-R ≤ x`, `x + len ≤ nx + R`,
    /// `-R ≤ z < nz + R`).
    #[inline]
    fn row(&self, plane: usize, z: i32, x: i32, len: usize) -> &[f32] {
        let w = self.width();
        let r = (z + Self::R as i32) as usize * w;
        &self.plane(plane)[r + (x + Self::R as i32) as usize..][..len]
    }

    /// Fills the current level's transmittance planes from its `pows`.
    fn fill_pows(&mut self, ctx: &Ctx, pows: &[[f32; MAX_EXPONENTS]], lnp: &[f32]) {
        self.fill(ctx, Self::POW, MAX_EXPONENTS, 1.0, |q, e| pows[q][e]);
        self.fill(ctx, Self::LNP, 1, 0.0, |q, _| lnp[q]);
    }

    /// Fills the source planes from the level's sources (0 where a cell does not emit).
    fn fill_src(&mut self, ctx: &Ctx, src: &[Vec3], emits: &[bool]) {
        self.fill(ctx, Self::SRC, 3, 0.0, |q, col| {
            if emits[q] { src[q][col] } else { 0.0 }
        });
    }

    /// `len` values of [`Planes::ex`] for `slot`, colour `col`, row `z`, columns `x..x +
    /// len` (`-RING ≤ x`, `x + len ≤ nx + RING`; the ring holds the wrapped columns on
    /// periodic sides, 0 beyond open ones; a row beyond an open side is 0).
    #[inline]
    fn ex_row(&self, ctx: &Ctx, (slot, col): (usize, usize), z: i32, x: i32, len: usize) -> &[f32] {
        static ZERO: [f32; GATHER_BLOCK] = [0.0; GATHER_BLOCK];
        let Some(zr) = ctx.row_of(z) else {
            return &ZERO[..len];
        };
        tap(&self.ex, self.nx, (zr, slot, col), x, len)
    }

    /// Planes `first..first + count`: `value(cell, plane - first)` at every cell of
    /// the ring and the level (the cell [`Ctx::col`] finds), `outside` beyond open sides.
    fn fill(
        &mut self,
        ctx: &Ctx,
        first: usize,
        count: usize,
        outside: f32,
        value: impl Fn(usize, usize) -> f32,
    ) {
        let (w, h) = (self.width(), self.nz + 2 * Self::R);
        let r = Self::R as i32;
        // Column and row of the level each ring position reads (`None`: outside).
        let axis = |i: usize, n: i32| -> Option<usize> {
            let v = i as i32 - r;
            if ctx.periodic {
                Some(v.rem_euclid(n) as usize)
            } else {
                (0..n).contains(&v).then_some(v as usize)
            }
        };
        let xs: Vec<Option<usize>> = (0..w).map(|i| axis(i, ctx.nx)).collect();
        let nx = self.nx;
        for k in 0..count {
            let plane = self.plane_mut(first + k);
            for zz in 0..h {
                let zs = axis(zz, ctx.nz);
                let dst = &mut plane[zz * w..][..w];
                match zs {
                    None => dst.fill(outside),
                    Some(z) => {
                        for (d, x) in dst.iter_mut().zip(&xs) {
                            *d = x.map_or(outside, |x| value(x + nx * z, k));
                        }
                    }
                }
            }
        }
    }
}

#[derive(Clone)]
struct Work {
    prev: LevelLight,
    cur: LevelLight,
    /// The upward light left at the levels above all material for a later pass to
    /// carry (its ring as `prev`'s).
    above: LevelLight,
    /// Light from outside the sides in its ring, zero inside ([`LevelLight`]), and the
    /// source level it was last filled for (`None`: not filled).
    ghost: LevelLight,
    ghost_for: Option<(bool, i32)>,
    /// Phase 1: what every point's path lost in each of its segments (per row: slot,
    /// colour, column).
    removed: Vec<f32>,
    /// Phase 3: what each point's path carries into each of its segments (per row:
    /// slot, colour, column), and the level's transmittances and sources with a ring.
    pre: Vec<f32>,
    /// Per row: `pre` was written this level (some point of the row is near an
    /// emitting cell).
    pre_rows: Vec<bool>,
    planes: Planes,
    t_after: Vec<[f32; CHANNELS]>,
    rows: Vec<RowFlux>,
    /// Transmittance of every cell for each path exponent (a level's written at its
    /// first visit of a sweep, `set_up`).
    pows: Vec<[f32; MAX_EXPONENTS]>,
    /// Points with no material within two cells of their level ([`Ctx::quiet`];
    /// written with `pows`).
    quiet: Vec<bool>,
    quiet_rows: Vec<bool>,
    /// Per level: `pows`, `quiet` and the level's transmittance planes
    /// ([`Planes::level`]) hold its values this sweep.
    set_up: Vec<bool>,
    /// The source rule's source per cell of the level ([`crate::medium`]) and whether a
    /// cell emits.
    src: Vec<Vec3>,
    emits: Vec<bool>,
    /// [`MediumEmission::Profile`]: the level's cells' profiles for this pass and the
    /// source's coefficients of `P_1`, `P_2` in height (empty under other rules).
    prof: crate::profile::Profiles,
    src_hi: Vec<[Vec3; 2]>,
    /// Scattered light waiting to be emitted in downward / upward channels.
    pend_down: PendingLevels,
    pend_up: PendingLevels,
    /// Accelerated sweeps ([`crate::accel`]): the upward share of what collides in a
    /// downward pass, for the next pair of passes (empty otherwise).
    pend_next: PendingLevels,
    /// Per level: some pending light of it was written (zeroed again on reuse).
    pend_dirty: Vec<bool>,
}

impl Work {
    fn new(nx: usize, nz: usize, n: usize) -> Self {
        let level_len = nx * nz;
        Self {
            prev: LevelLight::new(nx, nz),
            cur: LevelLight::new(nx, nz),
            above: LevelLight::new(nx, nz),
            ghost: LevelLight::new(nx, nz),
            ghost_for: None,
            removed: vec![0.0; nz * ring_pitch(nx) * SLOTS * 3],
            pre: vec![0.0; nz * ring_pitch(nx) * SLOTS * 3],
            pre_rows: vec![false; nz],
            planes: Planes::new(nx, nz, n / level_len.max(1)),
            t_after: vec![[1.0; CHANNELS]; level_len],
            rows: vec![RowFlux::default(); nz],
            pows: vec![[1.0; MAX_EXPONENTS]; n],
            quiet: vec![false; n],
            quiet_rows: vec![false; level_len],
            set_up: vec![false; n / level_len.max(1)],
            src: vec![Vec3::ZERO; level_len],
            emits: vec![false; level_len],
            prof: Default::default(),
            src_hi: Vec::new(),
            pend_down: PendingLevels::new(level_len, n / level_len.max(1)),
            pend_up: PendingLevels::new(level_len, n / level_len.max(1)),
            pend_next: PendingLevels::default(),
            pend_dirty: vec![false; n / level_len.max(1)],
        }
    }

    /// `old` made ready for a new sweep if it has the size (the level buffers and the
    /// levels of pending light that were written zeroed), else new buffers.
    fn reuse(old: Option<Work>, nx: usize, nz: usize, n: usize) -> Self {
        match old {
            Some(mut w) if w.prev.nx == nx && w.prev.nz == nz && w.pend_down.len() == n => {
                w.prev.v.fill(0.0);
                w.cur.v.fill(0.0);
                w.ghost.v.fill(0.0);
                w.ghost_for = None;
                w.set_up.fill(false);
                for (j, dirty) in w.pend_dirty.iter_mut().enumerate() {
                    if std::mem::take(dirty) {
                        w.pend_down.clear_level(j);
                        w.pend_up.clear_level(j);
                        if w.pend_next.len() == n {
                            w.pend_next.clear_level(j);
                        }
                    }
                }
                w
            }
            _ => Self::new(nx, nz, n),
        }
    }

    /// The first level of a pass gathers from the virtual level beyond the grid: its
    /// channel light goes into `prev`.
    fn fill_from_boundary(&mut self, src: &Sources, ctx: &Ctx) {
        let p = self.prev.pitch();
        for z in 0..ctx.nz {
            let row = self.prev.row_mut(z as isize);
            for x in 0..ctx.nx {
                for (c, chn) in ctx.ch.iter().enumerate() {
                    row_set(row, p, x as usize, c, src.virtual_light(x, z, chn));
                }
            }
        }
    }

    /// The ring of `ghost`: what the oracle's [`Ctx::gather_edge`] reads for a tap at
    /// each column beyond the sides. Without a halo that is the virtual level's light,
    /// the same for every level of a pass (filled once a pass); with one, the halo's
    /// light at the source level.
    fn fill_ghost(&mut self, src: &Sources, ctx: &Ctx, from_virtual: bool, src_level: i32) {
        let key = (src.up, if src.halo.is_none() { 0 } else { src_level });
        if self.ghost_for == Some(key) {
            return;
        }
        self.ghost_for = Some(key);
        let (nx, nz) = (ctx.nx as isize, ctx.nz as isize);
        let p = self.ghost.pitch();
        let pad = PAD as isize;
        for z in -pad..nz + pad {
            let row = self.ghost.row_mut(z);
            for x in -pad..nx + pad {
                if (0..nx).contains(&x) && (0..nz).contains(&z) {
                    continue;
                }
                let (xi, zi) = (x as i32, z as i32);
                for (c, chn) in ctx.ch.iter().enumerate() {
                    let v = if from_virtual && src.halo.is_none() {
                        src.virtual_light(xi, zi, chn)
                    } else {
                        src.outside(xi, src_level, zi, chn)
                    };
                    let b = c * 3 * p + (x + pad) as usize;
                    row[b] = v.x;
                    row[b + p] = v.y;
                    row[b + 2 * p] = v.z;
                }
            }
        }
    }
}

/// `pows` for the level whose cells have `ln(pass)` = `lnp`.
fn level_powers(pows: &mut [[f32; MAX_EXPONENTS]], lnp: &[f32]) {
    let exps = path_exponents();
    pows.par_iter_mut()
        .zip(lnp)
        .with_min_len(MIN_POINTS_PER_TASK)
        .for_each(|(pw, &l)| {
            for (k, e) in exps.iter().enumerate() {
                pw[k] = if l == 0.0 { 1.0 } else { (e * l).exp() };
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One value put into a point's light by the resolve tests (none, invalid ones, and
    /// the valid extremes -0 and the largest `f32`, whose sums overflow).
    const BAD_VALUES: [Option<f32>; 6] = [
        None,
        Some(f32::NAN),
        Some(-1e-3),
        Some(f32::INFINITY),
        Some(-0.0),
        Some(f32::MAX),
    ];

    /// A xorshift generator of test values from `seed` (not 0).
    fn xorshift(mut seed: u64) -> impl FnMut() -> u64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        }
    }

    /// Every stencil tap lies within [`RING`] columns of its point (the slot planes'
    /// rings hold all a tap reads beyond a row's ends), and [`ring_slots`] names
    /// exactly the slots of taps beside the column, in both passes. Every stencil holds
    /// its point's own cell once ([`Ctx::phase3_row`] sets its mean light there, without
    /// zeroing it first).
    #[test]
    fn channels_reach_no_farther_than_the_ring() {
        for up in [false, true] {
            let mut beside = Vec::new();
            for chn in channels(up) {
                let own = chn.stencil.iter().filter(|t| (t.0, t.1) == (0, 0)).count();
                assert_eq!(own, 1, "bin {}", chn.bin);
                for (k, &(dx, _, _)) in chn.stencil.iter().enumerate() {
                    assert!(
                        dx.unsigned_abs() as usize <= RING,
                        "tap {dx} beyond the ring"
                    );
                    if dx != 0 {
                        beside.push(chn.first_slot + k);
                    }
                }
            }
            assert_eq!(beside, ring_slots(), "up {up}");
        }
        assert!(!ring_slots().is_empty());
    }

    /// [`fill_rings`]: on periodic sides each ring column holds the row's wrapped
    /// column (rows shorter than the ring included), on open sides 0; the row itself
    /// and the planes of slots that read no ring are left as they were.
    #[test]
    fn rings_hold_the_wrapped_columns_or_zeros() {
        let mut next = xorshift(0x5eed);
        for nx in [1usize, 2, 3, 5, 16] {
            let w = ring_pitch(nx);
            for periodic in [true, false] {
                let row: Vec<f32> = (0..SLOTS * 3 * w)
                    .map(|_| (next() % 1000) as f32 + 1.0)
                    .collect();
                let mut filled = row.clone();
                fill_rings(&mut filled, nx, periodic);
                for slot in 0..SLOTS {
                    let reads = ring_slots().contains(&slot);
                    for col in 0..3 {
                        let at = (slot * 3 + col) * w;
                        let (before, after) = (&row[at..][..w], &filled[at..][..w]);
                        assert_eq!(before[RING..RING + nx], after[RING..RING + nx]);
                        for i in (0..RING).chain(nx + RING..w) {
                            let want = if !reads {
                                before[i]
                            } else if periodic {
                                let x = (i as i64 - RING as i64).rem_euclid(nx as i64);
                                before[RING + x as usize]
                            } else {
                                0.0
                            };
                            assert_eq!(
                                after[i], want,
                                "nx {nx} periodic {periodic} slot {slot} col {i}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The range the huge-page advice covers is the whole 2 MB pages inside a buffer,
    /// all of them, and nothing outside it (checked against counting the pages one by
    /// one), for buffers at any alignment and of any size.
    #[test]
    fn huge_page_range_is_every_whole_page_inside() {
        const HUGE: usize = 2 << 20;
        for start in [0, 1, 4096, HUGE - 16, HUGE, 3 * HUGE + 12_288] {
            for bytes in [0, 1, HUGE - 1, HUGE, HUGE + 1, 2 * HUGE, 5 * HUGE + 777] {
                let pages: Vec<usize> = (0..=(start + bytes) / HUGE)
                    .map(|p| p * HUGE)
                    .filter(|&p| p >= start && p + HUGE <= start + bytes)
                    .collect();
                let want = (!pages.is_empty()).then(|| pages[0]..pages[pages.len() - 1] + HUGE);
                assert_eq!(huge_pages_inside(start, bytes), want, "{start} + {bytes}");
            }
        }
    }

    /// Pending light per level: a level never written reads as zero and holds no
    /// records; writing one point allocates its level only; a cleared level reads as
    /// zero again and stays allocated.
    #[test]
    fn pending_levels_allocate_the_levels_written() {
        let mut p = PendingLevels::new(6, 4);
        assert_eq!(p.len(), 24);
        assert!(p.levels.iter().all(Vec::is_empty));
        assert!((0..24).all(|i| p[i].s == Vec3::ZERO && p[i].m == [Vec3::ZERO; 3]));
        let v = Pending {
            s: Vec3::new(1.0, 2.0, 3.0),
            m: [Vec3::X, Vec3::Y, Vec3::Z],
        };
        p[14] = v;
        let sizes: Vec<usize> = p.levels.iter().map(Vec::len).collect();
        assert_eq!(sizes, [0, 0, 6, 0]);
        for i in 0..24 {
            let want = if i == 14 { v.s } else { Vec3::ZERO };
            assert_eq!(p[i].s, want, "point {i}");
        }
        assert_eq!(p.level_mut(2)[2].m, v.m);
        p.clear_level(2);
        p.clear_level(3);
        assert_eq!(
            p.levels.iter().map(Vec::len).collect::<Vec<_>>(),
            [0, 0, 6, 0]
        );
        assert!((0..24).all(|i| p[i].s == Vec3::ZERO && p[i].m == [Vec3::ZERO; 3]));
    }

    /// A sweep keeps pending light only for levels that hold material: four passes over
    /// the 16³ canopy (ground and leaves in 4 of 16 levels) allocate those levels'
    /// records and no others, and the same sweep into the reused buffers gives the same
    /// light.
    #[test]
    fn pending_light_held_only_where_material_is() {
        let (m, b) = crate::scenes::Scene::Canopy.build(16);
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = 4;
        o.tolerance = 0.0;
        let mut spare = Spare::default();
        let first = run_reusing(&m, &b, None, &o, true, &mut spare).expect("sweep");
        let w = spare.work.as_ref().expect("work kept");
        let level_len = m.desc().level_len();
        let with_material: Vec<bool> = m
            .data()
            .chunks(level_len)
            .map(|l| l.iter().any(|c| !c.is_empty()))
            .collect();
        assert!(with_material.iter().any(|&b| b) && !with_material.iter().all(|&b| b));
        for p in [&w.pend_down, &w.pend_up] {
            let held: Vec<bool> = p.levels.iter().map(|l| !l.is_empty()).collect();
            assert_eq!(held, with_material);
        }
        let again = run_reusing(&m, &b, None, &o, true, &mut spare).expect("sweep");
        let bits = |s: &Sweep| -> Vec<u32> {
            let g = s.output.bins.as_ref().expect("bins");
            bytemuck::cast_slice::<BinLight, u32>(g.data()).to_vec()
        };
        assert!(bits(&first) == bits(&again));
    }

    /// The huge-page advice leaves a buffer's contents as they are (it only changes how
    /// the kernel backs its pages), for buffers with whole 2 MB pages inside and
    /// without; `fresh_buffer` gives zeros.
    #[test]
    fn huge_page_advice_keeps_contents() {
        for n in [0usize, 1000, 1 << 20, 3 << 20] {
            let mut v: Vec<u32> = (0..n as u32)
                .map(|i| i.wrapping_mul(2_654_435_761))
                .collect();
            let want = v.clone();
            advise_huge_pages(&mut v);
            assert!(v == want, "{n} values");
            let z: Vec<u32> = fresh_buffer(n);
            assert!(z.len() == n && z.iter().all(|&x| x == 0), "{n} zeros");
        }
    }

    /// `Ahead`'s shares cover the lines of the bytes after a row once each, in order,
    /// for rows of any size and any number of shares (more shares than lines too).
    #[test]
    fn fetch_ahead_shares_cover_every_line_once() {
        for bytes in [0usize, 1, 63, 64, 65, 312, 20 * 312, 64 * 312, 1000] {
            let row = vec![0u8; bytes];
            let a = Ahead::after(&row);
            assert_eq!(a.start, row.as_ptr_range().end);
            for n in [1usize, 2, 7, CHANNELS, 200] {
                let offs: Vec<usize> = (0..n).flat_map(|i| a.share(i, n).step_by(64)).collect();
                let want: Vec<usize> = (0..bytes.div_ceil(64)).map(|l| l * 64).collect();
                assert_eq!(offs, want, "{bytes} bytes in {n} shares");
            }
        }
    }

    /// `BinLight`'s four-point `resolve_all` gives `BinLight::average` and `dominant`
    /// bit for bit, and flags what `is_valid` rejects, for any number of points (the
    /// tail after the last four too).
    #[test]
    fn resolve_all_equals_average_and_dominant() {
        let mut next = xorshift(0x2545_f491_4f6c_dd1d_u64);
        for n in 0..=11 {
            for bad in BAD_VALUES {
                let mut g: Vec<BinLight> = (0..n)
                    .map(|_| {
                        BinLight(std::array::from_fn(|_| {
                            Vec3::from_array(std::array::from_fn(|_| {
                                let r = next();
                                // Zeros, and values over many magnitudes.
                                if r.is_multiple_of(5) {
                                    0.0
                                } else {
                                    (r >> 40) as f32 * 2f32.powi((r % 40) as i32 - 30)
                                }
                            }))
                        }))
                    })
                    .collect();
                if let (Some(v), true) = (bad, n > 0) {
                    let i = (next() % n as u64) as usize;
                    g[i].0[(next() % NUM_DIRS as u64) as usize].y = v;
                }
                for dominant in [false, true] {
                    let mut avg = vec![AverageLight(Vec3::splat(7.0)); n];
                    let mut dom = vec![DominantDir(Vec3::splat(7.0)); n];
                    let ok = BinLight::resolve_all(&g, &mut avg, &mut dom, dominant);
                    assert_eq!(ok, g.iter().all(|b| b.is_valid()), "n {n} bad {bad:?}");
                    if !ok {
                        continue;
                    }
                    for (i, b) in g.iter().enumerate() {
                        assert_eq!(
                            avg[i].0.to_array().map(f32::to_bits),
                            b.average().to_array().map(f32::to_bits)
                        );
                        let want = if dominant { b.dominant() } else { Vec3::ZERO };
                        assert_eq!(
                            dom[i].0.to_array().map(f32::to_bits),
                            want.to_array().map(f32::to_bits)
                        );
                    }
                }
            }
        }
    }

    /// `resolve_planes` (a row's resolve from its planes) gives what `BinLight`'s
    /// `clamp` then `resolve_all` give on the bins the pass's channels fill, bit for bit,
    /// with the same verdict on bad values, for rows of any length (block tails too),
    /// both passes, with and without the clamp and the dominant direction.
    #[test]
    fn resolve_planes_equals_resolve_all() {
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15_u64);
        for nx in [1, 3, 16, 63, 64, 65, 130] {
            for up in [false, true] {
                let ch = channels(up);
                for bad in BAD_VALUES {
                    let mut level = LevelLight::new(nx, 1);
                    let p = level.pitch();
                    let row = level.row_mut(0);
                    for c in 0..CHANNELS {
                        for k in 0..3 {
                            for x in 0..nx {
                                let r = next();
                                row[(c * 3 + k) * p + PAD + x] = match r % 7 {
                                    0 => 0.0,
                                    // Light of either sign (the profile rule's).
                                    1 => -((r >> 40) as f32) * 1e-9,
                                    _ => (r >> 40) as f32 * 2f32.powi((r % 40) as i32 - 30),
                                };
                            }
                        }
                    }
                    if let Some(v) = bad {
                        let (c, k, x) = (
                            next() as usize % CHANNELS,
                            next() as usize % 3,
                            next() as usize % nx,
                        );
                        row[(c * 3 + k) * p + PAD + x] = v;
                    }
                    let row = level.row(0);
                    for clamp in [false, true] {
                        for dominant in [false, true] {
                            let mut g = vec![BinLight::default(); nx];
                            for (x, gp) in g.iter_mut().enumerate() {
                                gp.add_channels(ch, |c| row_get(row, p, x, c));
                                if clamp {
                                    Sink::clamp(gp);
                                }
                            }
                            let mut want = (
                                vec![AverageLight(Vec3::splat(7.0)); nx],
                                vec![DominantDir(Vec3::splat(7.0)); nx],
                            );
                            let mut got = want.clone();
                            let ok_want =
                                BinLight::resolve_all(&g, &mut want.0, &mut want.1, dominant);
                            let ok_got = resolve_planes(
                                ch,
                                row,
                                p,
                                (clamp, dominant),
                                &mut got.0,
                                &mut got.1,
                            );
                            let case = format!(
                                "nx {nx} up {up} bad {bad:?} clamp {clamp} dominant {dominant}"
                            );
                            assert_eq!(ok_got, ok_want, "{case}");
                            // A bad value can leave the clamp (NaN -> 0): valid again.
                            assert_eq!(ok_want, g.iter().all(|b| b.is_valid()), "{case}");
                            let bits = |v: &[AverageLight]| {
                                v.iter()
                                    .map(|a| a.0.to_array().map(f32::to_bits))
                                    .collect::<Vec<_>>()
                            };
                            let dbits = |v: &[DominantDir]| {
                                v.iter()
                                    .map(|a| a.0.to_array().map(f32::to_bits))
                                    .collect::<Vec<_>>()
                            };
                            if ok_want {
                                assert_eq!(bits(&got.0), bits(&want.0), "{case}");
                                assert_eq!(dbits(&got.1), dbits(&want.1), "{case}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// `BinLight`'s `clamp` (flat floats) is `Vec3::max(ZERO)` on every bin, bit for bit:
    /// NaN and -0 become +0, negative values 0, the rest stay.
    #[test]
    fn clamp_equals_vec3_max() {
        let vals = [
            f32::NAN,
            -0.0,
            0.0,
            -1e-30,
            -5.0,
            1e-40,
            3.5,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        let mut b = BinLight(std::array::from_fn(|d| {
            Vec3::from_array(std::array::from_fn(|k| vals[(d * 3 + k) % vals.len()]))
        }));
        let want = b.0.map(|v| v.max(Vec3::ZERO));
        Sink::clamp(&mut b);
        for (got, want) in b.0.iter().zip(&want) {
            assert_eq!(
                got.to_array().map(f32::to_bits),
                want.to_array().map(f32::to_bits)
            );
        }
    }
}
