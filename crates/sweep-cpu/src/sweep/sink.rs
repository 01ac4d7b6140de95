//! Where a point's light lands (`Sink`: 26 bins or the average alone) and how it
//! resolves into average light and dominant direction.

use super::*;

/// Where the final light of a point goes: all 26 bins, or only what the average and the
/// dominant direction need.
pub(crate) trait Sink: Copy + Default + Send + Sync + bytemuck::Pod {
    /// The sink holds every bin (so [`resolve_planes`] computes what its `resolve`
    /// would, from the level's planes, where a point's bins hold exactly one pass's
    /// channel light).
    const ALL_BINS: bool = false;
    /// Adds light `g` of channel `chn` (into its bin).
    fn add(&mut self, chn: &Channel, g: Vec3);
    /// [`Sink::add`] of every channel of a pass, in channel order: `light(c)` into
    /// channel `c`'s bin.
    #[inline]
    fn add_channels(&mut self, ch: &[Channel; CHANNELS], light: impl Fn(usize) -> Vec3) {
        for (c, chn) in ch.iter().enumerate() {
            self.add(chn, light(c));
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
pub(crate) fn resolve_each<S: Sink>(
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
    fn add(&mut self, chn: &Channel, g: Vec3) {
        self.0[chn.bin] += g;
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
                    let r: [f32; N] = crate::isa::array_from(|j| g[j].0[b].x);
                    let gg: [f32; N] = crate::isa::array_from(|j| g[j].0[b].y);
                    let bb: [f32; N] = crate::isa::array_from(|j| g[j].0[b].z);
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
pub(crate) fn resolved(total: Vec3, v: Vec3, sum: f32) -> (Vec3, Vec3) {
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
pub(crate) fn valid_bins(b: &BinLight) -> bool {
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
pub(crate) fn resolve_planes(
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
pub(crate) fn resolve_planes_as<const CLAMP: bool, const DOMINANT: bool>(
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

/// The 26 bins and, apart, what the downward passes' horizontal channels brought
/// ([`HorizonLight`]: the downward-travelling halves of the horizontal bins).
#[derive(Clone, Copy, Default, bytemuck::Zeroable, bytemuck::Pod)]
#[repr(C)]
pub(crate) struct SplitBins {
    pub(crate) bins: BinLight,
    pub(crate) down: lightgrid_core::HorizonLight,
}

impl Sink for SplitBins {
    #[inline]
    fn add(&mut self, chn: &Channel, g: Vec3) {
        self.bins.0[chn.bin] += g;
        if chn.pass() == 0
            && let Some(k) = chn.bin.checked_sub(dirs::FIRST_HORIZONTAL)
            && k < dirs::HORIZONTAL_BINS
        {
            self.down.0[k] += g;
        }
    }
    #[inline]
    fn clamp(&mut self) {
        self.bins.clamp();
        for v in &mut self.down.0 {
            *v = v.max(Vec3::ZERO);
        }
    }
    #[inline]
    fn resolve(&self, dominant: bool) -> (bool, Vec3, Vec3) {
        let (ok, a, d) = self.bins.resolve(dominant);
        let down_ok = self
            .down
            .0
            .iter()
            .all(|v| v.is_finite() && v.cmpge(Vec3::ZERO).all());
        (ok & down_ok, a, d)
    }
}

/// Running sums for the average (`sum`) and dominant direction (`num / den`).
#[derive(Clone, Copy, Default, bytemuck::Zeroable, bytemuck::Pod)]
#[repr(C)]
pub(crate) struct AvgAcc {
    pub(crate) sum: Vec3,
    pub(crate) num: Vec3,
    pub(crate) den: f32,
}

impl Sink for AvgAcc {
    #[inline]
    fn add(&mut self, chn: &Channel, g: Vec3) {
        self.sum += g;
        let l = luminance(g);
        self.num += chn.unit * l;
        self.den += l;
    }
    /// The sums in a local: adding in place made each channel's add wait on the
    /// store of the one before (one chain through memory per point).
    #[inline]
    fn add_channels(&mut self, ch: &[Channel; CHANNELS], light: impl Fn(usize) -> Vec3) {
        let mut acc = *self;
        for (c, chn) in ch.iter().enumerate() {
            acc.add(chn, light(c));
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
pub(crate) const RESOLVE_CHUNK: usize = 512;

/// Every point's final values into `avg` and `dom` (the grids `LightGrid::average_grid`
/// and `dominant_grid` would give, for all 26 bins), on every core; `false` if any value
/// is negative, NaN or infinite.
pub(crate) fn resolve<S: Sink>(
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
