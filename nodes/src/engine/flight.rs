//! Computations in flight, shared between evaluations: when an edit makes a newer evaluation
//! ask for a stage that an older, now cancelled, evaluation is still computing with the same
//! key, the newer one waits for that computation instead of starting over. The computation
//! stops only when every evaluation that wants it has been cancelled.
//!
//! Waiting happens only on an evaluation's own thread, never on a rayon worker: a worker
//! that blocked could be the one the leader's parallel loops need (or sit on the leader's
//! own stack after a steal).

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
    fn new(cancel: &CancelToken) -> Arc<Self> {
        Arc::new(Flight {
            token: CancelToken::wanted_by(cancel),
            result: Mutex::new(None),
            finished: Condvar::new(),
            progress: AtomicU64::new(0f64.to_bits()),
        })
    }

    pub fn set_progress(&self, fraction: f64) {
        self.progress.store(fraction.to_bits(), Ordering::Relaxed);
    }

    fn progress(&self) -> f64 {
        f64::from_bits(self.progress.load(Ordering::Relaxed))
    }

    /// Waits for the result while `cancel` stands, calling `on_progress` as it advances;
    /// `None` once `cancel` is cancelled.
    pub fn wait(&self, cancel: &CancelToken, on_progress: impl Fn(f64)) -> Option<StageResult> {
        let mut last = -1.0;
        loop {
            if let Some(r) = self.result.lock().unwrap().as_ref() {
                return Some(r.clone());
            }
            if cancel.is_cancelled() {
                return None;
            }
            let p = self.progress();
            if p != last {
                on_progress(p);
                last = p;
            }
            let guard = self.result.lock().unwrap();
            if guard.is_none() {
                drop(self.finished.wait_timeout(guard, Duration::from_millis(50)).unwrap());
            }
        }
    }
}

/// Whether the caller computes the stage or waits for another evaluation's computation.
pub(super) enum Role {
    Lead(Arc<Flight>),
    Wait(Arc<Flight>),
}

/// The computations in flight, by stage key.
#[derive(Default)]
pub(super) struct Flights(Mutex<HashMap<Key, Arc<Flight>>>);

impl Flights {
    /// Whether any computation runs for an evaluation that still wants it.
    pub fn any_live(&self) -> bool {
        self.0.lock().unwrap().values().any(|f| !f.token.is_cancelled())
    }

    /// A newer evaluation that will need `key` keeps its live computation going.
    pub fn adopt(&self, key: Key, cancel: &CancelToken) {
        if let Some(flight) = self.0.lock().unwrap().get(&key)
            && !flight.token.is_cancelled()
        {
            flight.token.also_wanted_by(cancel);
        }
    }

    /// Whether `key` is being computed for an evaluation that still wants it.
    pub fn is_live(&self, key: Key) -> bool {
        self.0.lock().unwrap().get(&key).is_some_and(|f| !f.token.is_cancelled())
    }

    /// Joins the live computation of `key` when `may_wait` (the caller is not a rayon
    /// worker), or leads a new one (then the caller computes it and must call
    /// [`Flights::finish`]). A leader that may not wait computes on its own, unregistered.
    pub fn join(&self, key: Key, cancel: &CancelToken, may_wait: bool) -> Role {
        let mut map = self.0.lock().unwrap();
        if let Some(flight) = map.get(&key)
            && !flight.token.is_cancelled()
        {
            if may_wait {
                flight.token.also_wanted_by(cancel);
                return Role::Wait(flight.clone());
            }
            return Role::Lead(Flight::new(cancel));
        }
        let flight = Flight::new(cancel);
        map.insert(key, flight.clone());
        Role::Lead(flight)
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

/// Finishes a flight with an error if its leader unwinds before finishing it (a panicking
/// stage), so no evaluation waits for it forever.
pub(super) struct FinishOnUnwind<'a> {
    pub flights: &'a Flights,
    pub key: Key,
    pub flight: &'a Arc<Flight>,
    pub done: bool,
}

impl Drop for FinishOnUnwind<'_> {
    fn drop(&mut self) {
        if !self.done {
            self.flights.finish(
                self.key,
                self.flight,
                Err(StageError::Internal("the stage's computation stopped unexpectedly".into())),
            );
        }
    }
}
