//! The diffusion acceleration's bookkeeping between passes (`Debt`).

use super::*;

/// The diffusion correction outstanding in the media's waiting light
/// ([`crate::accel`]), the waiting light held back from the next pair, and the
/// solve's buffers.
pub(crate) struct Debt {
    /// Per media cell: the correction added after the last pair of passes.
    pub(crate) delta: Vec<Vec3>,
    /// Per media cell: the share `1 − ω` of its waiting light held back from the
    /// next pair (downward, upward).
    pub(crate) hold: Vec<(Pending, Pending)>,
    pub(crate) q: Vec<Vec3>,
    pub(crate) next: Vec<Vec3>,
}

/// The light still waiting in the cells of an accelerated sweep: the sum of every
/// cell's shares (net of the outstanding correction), and the same with each cell's
/// counted at its absolute value (for the convergence test).
#[derive(Clone, Copy, Default)]
pub(crate) struct Waiting {
    pub(crate) net: DVec3,
    pub(crate) abs: DVec3,
}

/// What the diffusion correction `delta` (scattered flux, RGB) adds to a medium cell's
/// waiting light in each direction: flux `delta` under the flat rule (each pass emits
/// half of it), the source coefficients that scatter `delta` under the profile rule
/// ([`crate::profile::CellProfile::source_of_scattered`]).
pub(crate) fn correction(
    (lnp, cells, rule): (&[f32], &[lightgrid_core::Material], MediumEmission),
    i: usize,
    delta: Vec3,
) -> Pending {
    if medium::profiled(rule, cells[i].pass) {
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
pub(crate) fn shares(beta: f32, pd: &Pending, pu: &Pending) -> Vec3 {
    0.5 * (pd.s + beta * pd.m[1]) + 0.5 * (pu.s - beta * pu.m[1])
}

impl Debt {
    pub(crate) fn new(d: Option<&crate::accel::Diffusion>) -> Self {
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
    pub(crate) fn waiting(
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
                let v = if medium::profiled(rule, mat.pass) {
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
    pub(crate) fn release(
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
    pub(crate) fn merge_next(&self, w: &mut Work) {
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
    pub(crate) fn correct(
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
            self.q[k] = if medium::profiled(rule, cells[i].pass) {
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
