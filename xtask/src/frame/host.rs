//! What the machine did to a frame besides running it: the time its cores ran other
//! virtual machines (the hypervisor's steal) and the time this process's threads were
//! ready to run but waited for a core (another process, or the kernel, ran instead).
//! A frame that took long because of either is the machine's, not the hierarchy's:
//! `cargo xtask frame` reports both beside each frame's time so that they can be told
//! apart. Read from Linux's `/proc`; `None` elsewhere.

use serde::Serialize;

/// The machine's clocks at one instant ([`Clocks::now`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Clocks {
    /// Steal over all CPUs, in clock ticks (USER_HZ, 100 a second): `/proc/stat`.
    steal_ticks: Option<u64>,
    /// Nanoseconds this process's threads have spent running and runnable but not
    /// running: the first two fields of each `/proc/self/task/*/schedstat`.
    ran_ns: Option<u64>,
    waited_ns: Option<u64>,
    /// This process's minor page faults (`/proc/self/stat`).
    faults: Option<u64>,
}

/// What the machine took from an interval (a frame, in `cargo xtask frame`), in
/// milliseconds.
#[derive(Debug, Clone, Copy, Default, Serialize, PartialEq)]
pub struct Interference {
    /// CPU time the hypervisor gave to other machines, over all cores (10 ms steps).
    pub steal_ms: Option<f64>,
    /// Time this process's threads waited for a core, summed over its threads.
    pub waited_ms: Option<f64>,
    /// Time this process's threads ran, summed over its threads: the frame's work.
    pub ran_ms: Option<f64>,
    /// Pages this process touched for the first time (minor page faults).
    pub page_faults: Option<u64>,
}

impl Interference {
    /// The larger of the two (0 where neither is known): the most of a frame's time
    /// the machine may have taken.
    pub fn lost_ms(&self) -> f64 {
        self.steal_ms
            .unwrap_or(0.0)
            .max(self.waited_ms.unwrap_or(0.0))
    }
}

impl Clocks {
    /// The clocks now.
    pub(crate) fn now() -> Self {
        let (ran_ns, waited_ns) = schedstat().unzip();
        Self {
            steal_ticks: steal_ticks(),
            ran_ns,
            waited_ns,
            faults: stat_field(7),
        }
    }

    /// What the machine took between `self` and `later`.
    pub(crate) fn since(&self, later: &Clocks) -> Interference {
        let d = |a: Option<u64>, b: Option<u64>| a.zip(b).map(|(a, b)| b.saturating_sub(a));
        Interference {
            steal_ms: d(self.steal_ticks, later.steal_ticks).map(|t| t as f64 * 10.0),
            waited_ms: d(self.waited_ns, later.waited_ns).map(|ns| ns as f64 / 1e6),
            ran_ms: d(self.ran_ns, later.ran_ns).map(|ns| ns as f64 / 1e6),
            page_faults: d(self.faults, later.faults),
        }
    }
}

/// Steal of all CPUs so far: the eighth value of `/proc/stat`'s `cpu` line.
fn steal_ticks() -> Option<u64> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    parse_steal(&stat)
}

fn parse_steal(stat: &str) -> Option<u64> {
    let line = stat.lines().find(|l| l.starts_with("cpu "))?;
    line.split_whitespace().nth(8)?.parse().ok()
}

/// Time on a core and run-queue waits of every thread of this process so far (threads
/// that ended are no longer counted: the hierarchy's pool lives as long as the process).
fn schedstat() -> Option<(u64, u64)> {
    let (mut ran, mut waited) = (0u64, 0u64);
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let path = task.ok()?.path().join("schedstat");
        let Ok(s) = std::fs::read_to_string(path) else {
            continue; // a thread that ended meanwhile
        };
        let mut f = s.split_whitespace().map(str::parse::<u64>);
        ran += f.next()?.ok()?;
        waited += f.next()?.ok()?;
    }
    Some((ran, waited))
}

/// The process's CPU time so far, all threads, user and system (ms; Linux's
/// `/proc/self/stat`, in 10 ms ticks), or `None` where there is none to read.
pub(crate) fn process_cpu_ms() -> Option<f64> {
    // utime and stime, in clock ticks (USER_HZ, 100 a second).
    Some((stat_field(11)? + stat_field(12)?) as f64 * 10.0)
}

/// Value `i` (from 0) of `/proc/self/stat` after the command's closing parenthesis:
/// 7 minor faults, 11 user time, 12 system time (`man 5 proc`: fields 10, 14, 15).
fn stat_field(i: usize) -> Option<u64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    stat.rsplit_once(')')?
        .1
        .split_whitespace()
        .nth(i)?
        .parse()
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steal_is_the_eighth_value_of_the_cpu_line() {
        let stat = "cpu  10168512 26542 1500994 3661004 229959 0 6387 37829 0 0\n\
                    cpu0 1 2 3 4 5 6 7 8 9 10\n";
        assert_eq!(parse_steal(stat), Some(37829));
        assert_eq!(parse_steal("cpu0 1 2 3 4 5 6 7 8\n"), None);
    }

    #[test]
    fn an_interval_is_the_difference_of_its_clocks() {
        let a = Clocks {
            steal_ticks: Some(100),
            ran_ns: Some(1_000_000),
            waited_ns: Some(5_000_000),
            faults: Some(10),
        };
        let b = Clocks {
            steal_ticks: Some(104),
            ran_ns: Some(31_000_000),
            waited_ns: Some(7_500_000),
            faults: Some(15),
        };
        let i = a.since(&b);
        assert_eq!(i.steal_ms, Some(40.0));
        assert_eq!(i.waited_ms, Some(2.5));
        assert_eq!(i.ran_ms, Some(30.0));
        assert_eq!(i.page_faults, Some(5));
        assert_eq!(i.lost_ms(), 40.0);
        // A clock that could not be read leaves its part unknown, not zero.
        let c = Clocks {
            steal_ticks: None,
            ..b
        };
        assert_eq!(a.since(&c).steal_ms, None);
        assert_eq!(a.since(&c).lost_ms(), 2.5);
    }

    #[test]
    fn both_clocks_are_read_on_linux() {
        let c = Clocks::now();
        assert_eq!(c.steal_ticks.is_some(), cfg!(target_os = "linux"));
        assert_eq!(c.waited_ns.is_some(), cfg!(target_os = "linux"));
        assert_eq!(c.ran_ns.is_some(), cfg!(target_os = "linux"));
        assert_eq!(c.faults.is_some(), cfg!(target_os = "linux"));
        assert_eq!(process_cpu_ms().is_some(), cfg!(target_os = "linux"));
    }
}
