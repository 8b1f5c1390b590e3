//! Identification without the GIL, stopped cleanly by Ctrl-C.
//!
//! The run goes to a worker thread while the calling thread, with the GIL
//! released, waits for it in slices of [`SLICE`]; between slices Python
//! checks its signals. On Ctrl-C (`KeyboardInterrupt` from
//! `check_signals`) the run's stop flag is raised: the back-end finds its
//! deadline passed at its next check and returns, its model is dropped,
//! and the `KeyboardInterrupt` reaches Python. No thread outlives the call.

use crate::error::Failure;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread;
use std::time::Duration;

/// How long the calling thread waits between two checks for signals.
const SLICE: Duration = Duration::from_millis(50);

/// The worker's stack: that of a main thread, as the program has.
const STACK: usize = 8 << 20;

/// Where the worker leaves its result.
struct Slot<T> {
    value: Mutex<Option<thread::Result<T>>>,
    ready: Condvar,
}

/// Runs `work`, given the stop flag that Ctrl-C raises, on a worker
/// thread; returns its value, a `KeyboardInterrupt` when the user pressed
/// Ctrl-C, or a `MethodError` naming a panic (a bug).
pub fn run<T: Send>(py: Python<'_>, work: impl FnOnce(Arc<AtomicBool>) -> T + Send) -> PyResult<T> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let slot = Slot {
        value: Mutex::new(None),
        ready: Condvar::new(),
    };
    thread::scope(|scope| {
        let slot = &slot;
        let worker = thread::Builder::new()
            .name("hysid-identify".into())
            .stack_size(STACK)
            .spawn_scoped(scope, move || {
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(flag)));
                *slot.value.lock().unwrap_or_else(PoisonError::into_inner) = Some(result);
                slot.ready.notify_all();
            })
            .map_err(|e| Failure::method(format!("cannot start the identification thread: {e}")))?;
        let wait = |limit: Option<Duration>| {
            py.detach(|| {
                let guard = slot.value.lock().unwrap_or_else(PoisonError::into_inner);
                let mut guard = match limit {
                    Some(t) => {
                        slot.ready
                            .wait_timeout_while(guard, t, |v| v.is_none())
                            .unwrap_or_else(PoisonError::into_inner)
                            .0
                    }
                    None => slot
                        .ready
                        .wait_while(guard, |v| v.is_none())
                        .unwrap_or_else(PoisonError::into_inner),
                };
                guard.take()
            })
        };
        let outcome = loop {
            if let Some(done) = wait(Some(SLICE)) {
                break done;
            }
            if let Err(interrupt) = py.check_signals() {
                stop.store(true, Ordering::Relaxed);
                // The worker returns at its next check of the deadline.
                let _ = wait(None);
                let _ = worker.join();
                return Err(interrupt);
            }
        };
        let _ = worker.join();
        outcome.map_err(|panic| {
            let message = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".into());
            Failure::method(format!("internal error: {message} (please report)")).into()
        })
    })
}
