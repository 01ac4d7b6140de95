//! A second worker kept awake through a sweep's levels.
//!
//! A level's phases are short parallel loops (a 16 × 16 level's: tens of microseconds
//! each) with short serial steps between them (the ghost ring, the level's set-up). Between
//! two loops rayon's idle workers spin a few dozen yields, then sleep on a futex, and the
//! next loop's tasks wait for one to wake: on a 2-core VM a lone 16³ node swept in
//! 5.37 ms on two threads and 6.14 ms on one (`halo_node`, `SIDES=halves`), most of the
//! second thread's time spent going to sleep and waking. A [`Helper`] puts a job on the
//! pool at each level that spins on [`rayon::yield_now`], so the next loop's tasks are
//! taken at once: 3.62–3.75 ms on two threads.
//!
//! It cannot hold a sweep up for long:
//! - it runs only on a worker that is not running a sweep of its own ([`Sweeping`]): a
//!   sweep's own worker that finds it while waiting on a loop drops it, and two sweeps
//!   side by side never wait on each other's helpers;
//! - it stops once the sweep ends, or after [`IDLE_LIMIT`] without work, and the next
//!   level starts another. (A worker that takes it while waiting inside one of the
//!   sweep's own tasks holds that task until the helper stops: until the pool has had no
//!   work for that long, the sweep's owner idle too. Each level's helper is queued
//!   before the level's tasks, so an idle worker takes it first.)
//! - with one thread in the pool there is none.
//!
//! It only runs the pool's tasks sooner: a sweep's result is the same bit for bit.

use std::cell::Cell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long a helper spins without finding work before it stops (longer than a
/// level's serial steps; a sweep's set-up or its resolve may outlast it).
pub(crate) const IDLE_LIMIT: Duration = Duration::from_micros(200);

thread_local! {
    /// Sweeps running on this thread (nested: a sweep may wait on another's tasks).
    static SWEEPING: Cell<u32> = const { Cell::new(0) };
}

/// Marks the current thread as running a sweep while it lives.
pub(crate) struct Sweeping(());

impl Sweeping {
    pub(crate) fn enter() -> Self {
        SWEEPING.with(|s| s.set(s.get() + 1));
        Self(())
    }

    /// Whether the current thread is running a sweep.
    fn here() -> bool {
        SWEEPING.with(|s| s.get() > 0)
    }
}

impl Drop for Sweeping {
    fn drop(&mut self) {
        SWEEPING.with(|s| s.set(s.get().saturating_sub(1)));
    }
}

/// One sweep's helpers (see the module docs); the sweep is over when it is dropped.
pub(crate) struct Helper {
    state: Arc<State>,
    /// The pool has a second thread to help.
    on: bool,
}

#[derive(Default)]
struct State {
    /// The sweep ended.
    done: AtomicBool,
    /// A helper is on the pool (queued or spinning).
    alive: AtomicBool,
}

impl Helper {
    pub(crate) fn new() -> Self {
        Self {
            state: Arc::default(),
            on: rayon::current_num_threads() > 1,
        }
    }

    /// Puts a helper on the pool unless one is there (at each level's start).
    pub(crate) fn ensure(&self) {
        if !self.on || self.state.alive.swap(true, Ordering::AcqRel) {
            return;
        }
        let state = Arc::clone(&self.state);
        rayon::spawn(move || {
            state.help();
            state.alive.store(false, Ordering::Release);
        });
    }
}

impl Drop for Helper {
    fn drop(&mut self) {
        self.state.done.store(true, Ordering::Release);
    }
}

impl State {
    /// Runs the pool's tasks as they come until the sweep ends or none come for
    /// [`IDLE_LIMIT`]; at once nothing on a thread that runs a sweep.
    fn help(&self) {
        if Sweeping::here() {
            return;
        }
        let mut idle_since: Option<Instant> = None;
        while !self.done.load(Ordering::Acquire) {
            match rayon::yield_now() {
                Some(rayon::Yield::Executed) => idle_since = None,
                _ => {
                    if idle_since.get_or_insert_with(Instant::now).elapsed() > IDLE_LIMIT {
                        return;
                    }
                    std::hint::spin_loop();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A helper that no sweep ends stops after its idle limit and frees its worker; on
    /// a thread marked as sweeping it does nothing.
    #[test]
    fn a_helper_stops_when_idle_and_never_runs_beside_a_sweep() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        pool.install(|| {
            let h = Helper::new();
            assert!(h.on);
            h.ensure();
            // A second call while one is alive queues nothing more.
            h.ensure();
            let t = Instant::now();
            while h.state.alive.load(Ordering::Acquire) {
                assert!(
                    t.elapsed() < Duration::from_secs(10),
                    "the helper never stopped"
                );
                std::thread::yield_now();
            }
            // On a sweeping thread: back at once, the sweep not over.
            let _s = Sweeping::enter();
            let t = Instant::now();
            h.state.help();
            assert!(t.elapsed() < IDLE_LIMIT);
            assert!(!h.state.done.load(Ordering::Acquire));
        });
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        one.install(|| assert!(!Helper::new().on));
    }
}
