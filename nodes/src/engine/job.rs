//! Evaluations on background threads: a job per request, and a scheduler that keeps one in
//! flight.

use super::*;

impl Engine {
    /// Runs [`Engine::evaluate`] (every stage) on a background thread.
    pub fn spawn(self: &Arc<Self>, graph: Graph) -> EvalJob {
        let request = Request::everything(&graph);
        self.spawn_request(graph, request)
    }

    /// Runs [`Engine::evaluate_request`] on a background thread; the evaluation after each
    /// tier but the last is kept for [`EvalJob::take_partial`].
    pub fn spawn_request(self: &Arc<Self>, graph: Graph, request: Request) -> EvalJob {
        let cancel = CancelToken::default();
        // Stages it needs that an older evaluation is computing keep running for it, even
        // when that evaluation is cancelled right after this call.
        // (Only while something runs: scheduling hashes the graph's files, which the running
        // evaluation has already done.)
        if self.flights.any_live() {
            let (instances, index) = self.schedule(&graph);
            let tier_of = request::needed_tiers(&graph, &instances, &index, &request, &mut Vec::new());
            for (inst, tier) in instances.iter().zip(&tier_of) {
                if tier.is_some() {
                    self.flights.adopt(inst.key, &cancel);
                }
            }
        }
        let (tx, rx) = std::sync::mpsc::channel();
        let engine = Arc::clone(self);
        let token = cancel.clone();
        let partial: Arc<Mutex<Option<(usize, Evaluation)>>> = Arc::default();
        let slot = partial.clone();
        let handle = std::thread::Builder::new()
            .name("lightloom-eval".into())
            .spawn(move || {
                let keep = |tier: usize, evaluation: Evaluation| *slot.lock().unwrap() = Some((tier, evaluation));
                engine.evaluate_request(&graph, &request, &token, Some(&tx), &keep)
            })
            .expect("spawn evaluation thread");
        EvalJob { cancel, events: rx, handle: Some(handle), partial }
    }
}

/// A running background evaluation.
pub struct EvalJob {
    cancel: CancelToken,
    pub events: std::sync::mpsc::Receiver<EvalEvent>,
    handle: Option<std::thread::JoinHandle<Evaluation>>,
    partial: Arc<Mutex<Option<(usize, Evaluation)>>>,
}

impl EvalJob {
    /// Marks the evaluation stale: running stages stop at their next check, nothing partial is
    /// cached.
    pub fn cancel(&self) {
        self.cancel.cancel();
    }

    /// The evaluation's cancellation flag (to cancel it from elsewhere, e.g. on Ctrl+C).
    pub fn cancel_token(&self) -> CancelToken {
        self.cancel.clone()
    }

    pub fn is_finished(&self) -> bool {
        self.handle.as_ref().is_none_or(|h| h.is_finished())
    }

    /// The evaluation after the latest finished tier (not the last), once.
    pub fn take_partial(&self) -> Option<(usize, Evaluation)> {
        self.partial.lock().unwrap().take()
    }

    /// Waits for the result.
    pub fn wait(mut self) -> Evaluation {
        self.handle.take().expect("joined once").join().expect("evaluation thread panicked")
    }
}

/// Keeps at most one evaluation in flight: submitting a new graph cancels the stale one.
#[derive(Default)]
pub struct Scheduler {
    current: Option<EvalJob>,
}

impl Scheduler {
    pub fn submit(&mut self, engine: &Arc<Engine>, graph: Graph) {
        let request = Request::everything(&graph);
        self.submit_request(engine, graph, request);
    }

    pub fn submit_request(&mut self, engine: &Arc<Engine>, graph: Graph, request: Request) {
        // The new evaluation first adopts what it shares with the old one's running stages,
        // then the old one is cancelled.
        let new = engine.spawn_request(graph, request);
        if let Some(old) = self.current.replace(new) {
            old.cancel();
            // Let it wind down on its own thread; its results are discarded.
            std::thread::spawn(move || drop(old.wait()));
        }
    }

    /// The finished evaluation, if the current one is done.
    pub fn poll(&mut self) -> Option<Evaluation> {
        if self.current.as_ref().is_some_and(|j| j.is_finished()) {
            return self.current.take().map(|j| j.wait());
        }
        None
    }

    pub fn current(&self) -> Option<&EvalJob> {
        self.current.as_ref()
    }
}
