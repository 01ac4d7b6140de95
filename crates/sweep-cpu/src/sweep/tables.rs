//! The sweep's tables, shared with the GPU sweeper: the 26 channels and their path
//! lengths, the path exponents, the surface weights of exposed faces, the medium's
//! emission split and the segment mean. A leaf: it uses no other part of the sweep.

use super::*;

/// Number of transport channels of one pass (9 vertical-ish bins + 8 horizontal halves).
pub const CHANNELS: usize = NUM_SWEEP_DIRS;

pub use lightgrid_core::MAX_LIGHT;

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

pub use lightgrid_core::dirs::channel_length;

/// Most distinct exponents (see [`path_exponents`]).
pub const MAX_EXPONENTS: usize = 10;

pub(crate) fn exponent_index(v: f32) -> usize {
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
            let stencil = dirs::level_stencil(v);
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
/// 7 % too bright looking down, measured in `measure/tests/exact.rs`.)
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
/// +9 % and −4 % with this rule; `lightgrid_measure::exact`.)
pub fn medium_emission(pass: f32) -> (f32, f32) {
    if !(pass > 0.0 && pass < 1.0) {
        return (1.0, 0.0);
    }
    let forward = -pass.ln() * pass / (1.0 - pass);
    let back = (1.0 + pass) * 0.5;
    ((forward + back) * 0.5, (back - forward) * 0.5)
}

pub use lightgrid_core::light::seg_mean;

/// Channel `chn`'s value in bins `b`: whole where `b` is a boundary's one-way light;
/// where it is full-sphere light (a side halo), a horizontal bin's part travelling the
/// channel's way, split across the horizon by [`BinLight::horizon_share`] (the
/// downward pass takes `h · share`, the upward pass the rest; exact where the radiance
/// is constant over each hemisphere, as a coarser grid's light above a ground or a
/// canopy nearly is). Part of the specification: the GPU sweeper uploads its boundary
/// light through this.
#[inline]
pub fn channel_value(b: &BinLight, chn: &Channel, full_sphere: bool) -> Vec3 {
    let v = b.0[chn.bin];
    if !full_sphere || chn.share == 1.0 {
        return v;
    }
    let down = v * b.horizon_share(chn.bin);
    if chn.pass() == 0 {
        down
    } else {
        (v - down).max(Vec3::ZERO)
    }
}

/// [`channel_value`] where the downward halves of `b`'s horizontal bins are given
/// (`down`, from [`SideBoundary::GivenHalves`](lightgrid_core::SideBoundary::GivenHalves)):
/// a horizontal channel's downward pass takes its bin's downward half (clamped to
/// `[0, h]`), the upward pass the rest. Without `down`, [`channel_value`]. Part of the
/// specification, as [`channel_value`].
#[inline]
pub fn channel_value_halves(
    b: &BinLight,
    down: Option<&lightgrid_core::HorizonLight>,
    chn: &Channel,
    full_sphere: bool,
) -> Vec3 {
    let Some(d) = down else {
        return channel_value(b, chn, full_sphere);
    };
    let v = b.0[chn.bin];
    if !full_sphere || chn.share == 1.0 {
        return v;
    }
    let half = d.0[chn.bin - lightgrid_core::dirs::FIRST_HORIZONTAL]
        .min(v)
        .max(Vec3::ZERO);
    if chn.pass() == 0 {
        half
    } else {
        (v - half).max(Vec3::ZERO)
    }
}
