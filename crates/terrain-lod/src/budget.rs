//! The frame's budget: of points ([`crate::HierarchyParams::budget_points`]) or of time
//! ([`crate::HierarchyParams::budget_ms`]): whether a job fits the frame, whether new
//! materials wait, and the warning when one job alone overruns the time.

use crate::{FIRST_RATE, FrameStats, Hierarchy};

impl Hierarchy {
    /// Whether `cost` more points after `swept` this frame are over its budget.
    ///
    /// Under a time budget ([`HierarchyParams::budget_ms`]):
    /// - after the frame's first jobs, a job is over when the frame is past its time
    ///   ([`Hierarchy::out_of_time`]), or the jobs selected since the depth's step
    ///   began and it would not end within the time left at the measured rate of the
    ///   last frames' steps (`step_rate`; before one is measured, when the frame's
    ///   points budget is spent), or `budget_points` is;
    /// - the frame's first job runs whatever it costs, so that frames get on however
    ///   small the budget, unless the frame already spent half its budget before it
    ///   (composing new nodes' materials: a camera's first frame composes every node
    ///   of depth 1) and the last frame swept: then the job waits for the next frame,
    ///   which finds the materials kept. No two frames in a row go without a sweep
    ///   while work waits. (The job's time is not predicted: a process's first sweeps
    ///   run at half the measured rate.)
    pub(crate) fn over_budget(&self, swept: u64, cost: u64) -> bool {
        let Some(ms) = self.params.budget_ms else {
            return swept + cost > self.frame_budget;
        };
        if swept > 0 {
            if self.out_of_time(swept) {
                return true;
            }
            // The time left against the jobs selected and this one at the steps'
            // measured rate (the frame's own rate, composing included, left frames
            // with light composition a third of their budget unused).
            return match self.step_rate {
                Some(rate) => {
                    let left = ms as f64 / 1e3 - self.frame_started.elapsed().as_secs_f64();
                    let selected = swept.saturating_sub(self.step_swept) + cost;
                    selected as f64 > rate * left || swept + cost > self.params.budget_points
                }
                None => swept + cost > self.frame_budget,
            };
        }
        let spent = self.frame_started.elapsed().as_secs_f64() * 1e3;
        self.last_frame_swept && spent > 0.5 * ms as f64
    }

    /// Under a time budget, warns once when a frame of a single job (one node's sky
    /// sweep or its sun) took over twice the budget: the first job of a frame runs
    /// whatever it costs, so where jobs cost that much frames run over whatever the
    /// budget does (one 16-point node's sweep takes an NVIDIA H200 40-60 ms with the
    /// GPU sweeper, its levels' latency; a host's steal can do it once too).
    pub(crate) fn warn_single_job(&mut self, stats: &FrameStats) {
        let Some(ms) = self.params.budget_ms else {
            return;
        };
        let took = self.frame_started.elapsed().as_secs_f64() * 1e3;
        if !self.warned_single_job && stats.built + stats.sun_built == 1 && took > 2.0 * ms as f64 {
            self.warned_single_job = true;
            tracing::warn!(
                took_ms = took,
                budget_ms = ms,
                "one job alone took over twice the frame's time budget (a frame runs its \
                 first job whatever it costs: where its jobs cost this much, frames run \
                 over; a larger budget, smaller nodes or the CPU sweeper hold it)"
            );
        }
    }

    /// Whether a frame that has swept `swept` points has spent its time budget (then it
    /// neither composes nor sweeps anything more).
    pub(crate) fn out_of_time(&self, swept: u64) -> bool {
        self.params.budget_ms.is_some_and(|ms| {
            swept > 0 && self.frame_started.elapsed().as_secs_f64() * 1e3 > ms as f64
        })
    }

    /// Whether, under a time budget, the next batch of new nodes' materials waits for a
    /// later frame: once this frame has composed some (`composed`) and spent half its budget
    /// (composition is not in the points budget: a depth of many new nodes, composed
    /// all at once, ran frames to two and three times the budget). A frame always
    /// composes its first batch, so that frames get on.
    pub(crate) fn composition_waits(&self, composed: u32) -> bool {
        self.params.budget_ms.is_some_and(|ms| {
            composed > 0 && self.frame_started.elapsed().as_secs_f64() * 1e3 > 0.5 * ms as f64
        })
    }

    /// The points a frame may sweep: `budget_points`, or under a time budget what the
    /// measured rate (points a second of the last frames' update time) gets through in
    /// it: the build order's measure of what fits a frame ([`Hierarchy::all_fit`]);
    /// once the jobs' own rate is measured, their predicted time decides instead
    /// ([`Hierarchy::over_budget`]).
    pub(crate) fn frame_budget_points(&self) -> u64 {
        let p = &self.params;
        match p.budget_ms {
            None => p.budget_points,
            Some(ms) => {
                let rate = self.rate.unwrap_or(FIRST_RATE);
                let points = (rate * ms as f64 / 1e3).min(u64::MAX as f64 / 2.0) as u64;
                points.min(p.budget_points)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::testing::layer_hierarchy;

    /// Under a time budget a job fits while the jobs selected and it, at the measured
    /// rate, end within the time left; the points budget bounds the frame all the same;
    /// before any rate is measured the frame's points budget decides.
    #[test]
    fn a_job_fits_the_time_left_at_the_measured_rate() {
        let mut h = layer_hierarchy(0, false);
        h.params.budget_ms = Some(60_000.0); // a minute: the test's own time is nothing
        h.frame_started = std::time::Instant::now();
        h.frame_budget = 100;
        h.step_swept = 1_000;
        h.step_rate = None;
        // No rate yet: the frame's points budget.
        assert!(!h.over_budget(50, 50));
        assert!(h.over_budget(50, 51));
        // 10 points a second for a minute: 600 points in all, those selected since the
        // step began (1,000 counted then) included.
        h.step_rate = Some(10.0);
        assert!(!h.over_budget(1_100, 499));
        assert!(h.over_budget(1_100, 501));
        assert!(!h.over_budget(1_000, 599));
        assert!(h.over_budget(1_000, 601));
        // The points budget still bounds the frame.
        h.params.budget_points = 1_200;
        assert!(h.over_budget(1_000, 201));
        // A frame's first job runs whatever it costs.
        assert!(!h.over_budget(0, 1_000_000));
        // Past its time, nothing more.
        h.params.budget_ms = Some(0.001);
        std::thread::sleep(std::time::Duration::from_millis(2));
        assert!(h.over_budget(1_000, 1));
    }

    /// A frame whose one job takes over twice the budget warns, once: a moved sun's
    /// responses swept a job a frame under a budget of a microsecond; under a minute's
    /// budget none.
    #[test]
    fn a_single_job_over_twice_the_budget_warns_once() {
        use lightgrid_core::glam::Vec3;
        for (ms, warns) in [(0.001, true), (60_000.0, false)] {
            let mut h = layer_hierarchy(0, false);
            h.params.budget_ms = Some(ms);
            h.set_sun(Some(crate::SunLight {
                to_sun: Vec3::new(-0.3, 0.5, 0.6),
                irradiance: Vec3::splat(3.0),
            }))
            .unwrap();
            let mut single = 0;
            for _ in 0..4 {
                let s = h.update(Vec3::new(32.0, 5.0, 32.0)).unwrap();
                single += (s.built + s.sun_built == 1) as u32;
                if !warns {
                    assert!(!h.warned_single_job, "{s:?}");
                }
            }
            if warns {
                assert!(single > 0, "no frame of a single job");
                assert!(h.warned_single_job);
            }
        }
    }
}
