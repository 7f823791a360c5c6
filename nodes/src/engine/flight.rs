//! Computations in flight, shared between evaluations: when an edit makes a newer evaluation
//! ask for a stage that an older, now cancelled, evaluation is still computing with the same
//! key, the newer one joins that computation instead of starting over. The computation stops
//! only when every evaluation that wants it has been cancelled.

use super::{CancelToken, Key, StageError, StageValue};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

pub(super) type StageResult = Result<Arc<StageValue>, StageError>;

/// One stage computation and the evaluations waiting for it.
pub(super) struct Flight {
    /// Cancelled when every evaluation that wants the result is cancelled.
    pub token: CancelToken,
    result: Mutex<Option<StageResult>>,
    finished: Condvar,
    /// The computation's progress, 0..1, as `f64` bits.
    progress: AtomicU64,
}

impl Flight {
    pub fn set_progress(&self, fraction: f64) {
        self.progress.store(fraction.to_bits(), Ordering::Relaxed);
    }

    pub fn progress(&self) -> f64 {
        f64::from_bits(self.progress.load(Ordering::Relaxed))
    }

    /// Waits for the result while `cancel` stands, calling `on_progress` as it advances;
    /// `Err(Cancelled)` once `cancel` is cancelled. On a rayon worker it runs other pool work
    /// while it waits, so the leader's own parallel loops always find a thread.
    pub fn wait(&self, cancel: &CancelToken, on_progress: impl Fn(f64)) -> StageResult {
        let mut last = -1.0;
        loop {
            {
                let result = self.result.lock().unwrap();
                if let Some(r) = result.as_ref() {
                    return r.clone();
                }
                if cancel.is_cancelled() {
                    return Err(StageError::Cancelled);
                }
                let p = self.progress();
                if p != last {
                    on_progress(p);
                    last = p;
                }
                if rayon::yield_now() == Some(rayon::Yield::Executed) {
                    continue;
                }
                drop(self.finished.wait_timeout(result, Duration::from_millis(50)).unwrap());
            }
        }
    }
}

/// The computations in flight, by stage key.
#[derive(Default)]
pub(super) struct Flights(Mutex<HashMap<Key, Arc<Flight>>>);

impl Flights {
    /// Joins the computation of `key`, or starts one (then the caller computes it and must
    /// call [`Flights::finish`]). Returns the flight and whether the caller leads it.
    pub fn join(&self, key: Key, cancel: &CancelToken) -> (Arc<Flight>, bool) {
        let mut map = self.0.lock().unwrap();
        if let Some(flight) = map.get(&key) {
            flight.token.also_wanted_by(cancel);
            return (flight.clone(), false);
        }
        let flight = Arc::new(Flight {
            token: CancelToken::wanted_by(cancel),
            result: Mutex::new(None),
            finished: Condvar::new(),
            progress: AtomicU64::new(0f64.to_bits()),
        });
        map.insert(key, flight.clone());
        (flight, true)
    }

    /// Publishes the leader's result to the evaluations waiting for it.
    pub fn finish(&self, key: Key, flight: &Arc<Flight>, result: StageResult) {
        *flight.result.lock().unwrap() = Some(result);
        flight.finished.notify_all();
        let mut map = self.0.lock().unwrap();
        if map.get(&key).is_some_and(|f| Arc::ptr_eq(f, flight)) {
            map.remove(&key);
        }
    }
}
