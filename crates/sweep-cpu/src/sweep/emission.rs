//! What a medium cell emits: the flat source and the profile rule's lanes.

use super::*;

/// Phase 2's outputs for the source rules, per cell of a level (or row): the flat
/// source `J_0`, whether the cell emits, the `P_1`, `P_2` coefficients of a quadratic
/// source in height (empty unless [`MediumEmission::Profile`]), the cells' profiles, and
/// what the `P_1`, `P_2` terms emit into each slot's segment (phase 3's [`Planes::ex`];
/// empty unless the profile rule on the fast path).
pub(crate) type EmitRows<'a> = (
    &'a mut [Vec3],
    &'a mut [bool],
    &'a mut [[Vec3; 2]],
    &'a crate::profile::Profiles,
    &'a mut [f32],
);

/// [`MediumEmission::Profile`] in phase 3's row kernel: the level's `P_1`, `P_2` source
/// coefficients, its cells' profiles, and which cells emit.
pub(crate) type ProfileRows<'a> = (&'a [[Vec3; 2]], &'a crate::profile::Profiles, &'a [bool]);

/// How a cell distributes scattered light `(S, M)` over the bins (step 5).
pub(crate) enum Emission {
    /// A medium (`p > 0`): `omega_b / 4pi * (A S - B u_b · M)` with `(A, B)` of
    /// [`medium_emission`]; the rest of each bin's isotropic share is stopped in the cell.
    Medium { a: f32, b: f32 },
    /// An opaque cell (`p = 0`): diffuse (Lambertian) faces where it borders a
    /// non-opaque cell, with fixed weights per channel (see [`surface_weights`]).
    Surface { w: &'static SurfaceWeights },
}

impl Emission {
    pub(crate) fn new(pass: f32, exposed: u8, rule: MediumEmission) -> Self {
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
    /// fixed weight `w S`, the `free` part of it past `T_after`. (Inlined into phase 2's
    /// row kernel, so that it runs on the kernel's instruction set: [`crate::isa`].)
    #[inline(always)]
    pub(crate) fn lanes(
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
    pub(crate) fn full(&self, p: &Pending, chn: &Channel) -> Vec3 {
        match self {
            Emission::Medium { .. } => {
                p.s * (dirs::solid_angles()[chn.bin] / (4.0 * PI) * chn.share)
            }
            Emission::Surface { w } => p.s * w.w[chn.pass()][chn.bin],
        }
    }

    /// The share of `p` that the pass with channels `ch` will emit (half, for a medium).
    /// (Inlined into phase 2's row kernel, as [`Emission::lanes`].)
    #[inline(always)]
    pub(crate) fn budget(&self, p: &Pending, ch: &[Channel; CHANNELS]) -> Vec3 {
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
pub(crate) const LANES: usize = CHANNELS.next_multiple_of(4);

/// The channels of one pass as [`LANES`]: unit vectors, isotropic shares (`ω_b / 4π`
/// times the channel's share), path lengths and half of them.
pub(crate) struct PassLanes {
    pub(crate) u: [[f32; LANES]; 3],
    pub(crate) iso: [f32; LANES],
    pub(crate) length: [f32; LANES],
    pub(crate) half_length: [f32; LANES],
}

pub(crate) fn pass_lanes(up: bool) -> &'static PassLanes {
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
pub(crate) struct CellLanes {
    /// Flux into a channel: `max(0, S·fa − (u·M)·fb)`.
    pub(crate) fa: [f32; LANES],
    pub(crate) fb: [f32; LANES],
    /// The part of that flux that leaves free of `T_after` (a top or bottom face's
    /// horizontal light): `S·free`.
    pub(crate) free: [f32; LANES],
    /// The channel's share before anything stops it: `S·full`.
    pub(crate) full: [f32; LANES],
    /// `T_after` of each channel.
    pub(crate) t_after: [f32; LANES],
}

impl CellLanes {
    /// One round of step 6 for one colour (scattered flux `s`, moment `m`): adds what
    /// leaves the level to `leave` and what is emitted to `emit`, returns what the
    /// cell's own material stops, per channel.
    #[inline]
    pub(crate) fn round(
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
pub(crate) fn lanes_sum(v: &[f32; LANES]) -> f32 {
    let mut a = [0f32; 4];
    for ch in v.chunks_exact(4) {
        for i in 0..4 {
            a[i] += ch[i];
        }
    }
    (a[0] + a[1]) + (a[2] + a[3])
}

#[inline]
pub(crate) fn lanes_dot(v: &[f32; LANES], w: &[f32; LANES]) -> f32 {
    let mut a = [0f32; 4];
    for (x, y) in v.chunks_exact(4).zip(w.chunks_exact(4)) {
        for i in 0..4 {
            a[i] += x[i] * y[i];
        }
    }
    (a[0] + a[1]) + (a[2] + a[3])
}

pub(crate) fn up_pass(ch: &[Channel; CHANNELS]) -> bool {
    ch[0].step.y > 0
}
