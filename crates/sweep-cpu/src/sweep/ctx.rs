//! One sweep's fixed context (`Ctx`) and where light enters from outside (`Sources`).

use super::*;

/// Boundary light of one pass.
pub(crate) struct Sources<'a> {
    pub(crate) boundary: &'a Boundary,
    /// Boundary light enters only in the first downward and the first upward pass.
    pub(crate) active: bool,
    pub(crate) up: bool,
    pub(crate) dims: UVec3,
    pub(crate) halo: Option<lightgrid_core::HaloLayout>,
}

impl Sources<'_> {
    /// Light of the virtual level beyond the grid (above it downward, below it upward)
    /// at column (x, z), channel `chn`.
    pub(crate) fn virtual_light(&self, x: i32, z: i32, chn: &Channel) -> Vec3 {
        Self::value(self.virtual_bins(x, z), chn)
    }

    /// Light of a source point outside the grid's sides at (x, level, z).
    pub(crate) fn outside(&self, x: i32, level: i32, z: i32, chn: &Channel) -> Vec3 {
        Self::value(self.outside_bins(x, level, z), chn)
    }

    /// The bins [`Sources::virtual_light`] reads a channel of at column (x, z), and
    /// whether they span the full sphere (`None`: no light enters this pass).
    pub(crate) fn virtual_bins(&self, x: i32, z: i32) -> Option<SourceBins<'_>> {
        self.active.then(|| SourceBins {
            light: virtual_level_light(self.boundary, self.up, x, z, self.dims),
            down: None,
            full_sphere: false,
        })
    }

    /// The bins [`Sources::outside`] reads a channel of at (x, level, z), found once for
    /// all channels (a ring of a level is filled point by point, `Work::fill_ghost`).
    pub(crate) fn outside_bins(&self, x: i32, level: i32, z: i32) -> Option<SourceBins<'_>> {
        if !self.active {
            return None;
        }
        match (self.boundary.sides.halo(), &self.halo) {
            (Some(h), Some(layout)) => {
                let lv = level.clamp(0, self.dims.y as i32 - 1) as u32;
                layout.index(x, lv, z).map(|i| SourceBins {
                    light: &h[i],
                    down: self.boundary.sides.halo_down().map(|d| &d[i]),
                    full_sphere: true,
                })
            }
            _ => self.virtual_bins(x, z),
        }
    }

    /// Channel `chn` of bins found by [`Sources::outside_bins`] or
    /// [`Sources::virtual_bins`] (0 where none).
    #[inline(always)]
    pub(crate) fn value(bins: Option<SourceBins<'_>>, chn: &Channel) -> Vec3 {
        bins.map_or(Vec3::ZERO, |b| {
            channel_value_halves(b.light, b.down, chn, b.full_sphere)
        })
    }
}

/// Light entering from outside at one source point: its bins, the downward halves of
/// its horizontal bins where given ([`SideBoundary::GivenHalves`]), and whether it is
/// full-sphere light (a side halo's) or one-way (the virtual level's).
#[derive(Clone, Copy)]
pub(crate) struct SourceBins<'a> {
    pub(crate) light: &'a BinLight,
    pub(crate) down: Option<&'a lightgrid_core::HorizonLight>,
    pub(crate) full_sphere: bool,
}

pub(crate) struct Ctx {
    pub(crate) nx: i32,
    pub(crate) nz: i32,
    pub(crate) periodic: bool,
    pub(crate) smoothing: f32,
    pub(crate) medium: MediumEmission,
    /// Light of either sign (diffusion acceleration, [`crate::accel`]): no clamping
    /// at 0 anywhere, so the sweep stays linear when the light taken back makes a
    /// cell's waiting light negative.
    pub(crate) signed: bool,
    /// Accelerated passes ([`crate::accel`]): a medium cell emits only what waited
    /// before the pair of passes; what collides in it waits for the next pair.
    pub(crate) jacobi: bool,
    pub(crate) ch: &'static [Channel; CHANNELS],
    /// The column index along x (then z) of every `x` in `-WRAP_PAD .. nx + WRAP_PAD`:
    /// wrapped on periodic sides, -1 beyond open or given ones.
    pub(crate) xcol: Vec<i32>,
    pub(crate) zcol: Vec<i32>,
}

/// Offsets beyond the sides that [`Ctx::col`] looks up in a table instead of dividing:
/// every tap and path cell of the sweep lies within this many columns of its point.
pub(crate) const WRAP_PAD: i32 = 8;

impl Ctx {
    pub(crate) fn new(
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
    pub(crate) fn uniform_gather(&self, v: &Level) -> (DVec3, DVec3) {
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
    pub(crate) fn rows_per_task(&self, uneven: bool) -> (usize, usize) {
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
    #[inline(always)]
    pub(crate) fn fetch_profiles(&self) -> bool {
        (self.nx * self.nz) as usize > FETCH_PROFILES_ABOVE
    }

    /// Index of column (x, z) within a level, wrapping in periodic mode; `None` outside.
    #[inline(always)]
    pub(crate) fn col(&self, x: i32, z: i32) -> Option<usize> {
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
    /// Light waiting `v` as the pass counts it: of either sign in accelerated passes
    /// (`signed`), else clamped at 0.
    #[inline(always)]
    pub(crate) fn waiting(&self, v: Vec3) -> DVec3 {
        if self.signed { v } else { v.max(Vec3::ZERO) }.as_dvec3()
    }

    /// The level row that row `z` resolves to ([`Ctx::col`]'s rule).
    #[inline(always)]
    pub(crate) fn row_of(&self, z: i32) -> Option<usize> {
        if self.periodic {
            Some(z.rem_euclid(self.nz) as usize)
        } else {
            (0..self.nz).contains(&z).then_some(z as usize)
        }
    }
}
