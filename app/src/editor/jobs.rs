//! Work off the UI thread: graph evaluation (through the engine's scheduler, which cancels a
//! stale evaluation when a newer graph arrives) and Monte Carlo reference renders. The UI
//! polls them each frame and shows progress; both can be cancelled.

use lightloom_nodes::engine::{CancelToken, Engine, EvalEvent, Evaluation, Graph, Request, Scheduler, StageStatus};
use lightloom_nodes::frame::FrameInputs;
use lightloom_nodes::reference::{HdrImage, PinholeCamera};
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Instant;

/// What a node shows in its header.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeStatus {
    UpToDate,
    /// Waiting for an evaluation to reach it.
    Dirty,
    /// A stage is running: `(stage, fraction done)`.
    Running(String, f32),
    Error(String),
}

/// The running evaluation, as seen through its events.
pub struct Progress {
    pub started: Instant,
    pub total: usize,
    pub done: usize,
    /// Stages running now: node, stage, fraction done, when it started.
    pub running: Vec<(String, String, f32, Instant)>,
}

impl Progress {
    /// The running stages as "node.stage 43% (about 12 s left)".
    pub fn describe(&self) -> String {
        let parts: Vec<String> = self
            .running
            .iter()
            .map(|(n, s, f, started)| {
                let elapsed = started.elapsed().as_secs_f64();
                let f = f64::from(*f);
                if f > 0.02 && elapsed > 0.5 {
                    format!("{n}.{s} {:.0}% (about {:.0} s left)", f * 100.0, elapsed * (1.0 - f) / f)
                } else {
                    format!("{n}.{s} {:.0}%", f * 100.0)
                }
            })
            .collect();
        parts.join(", ")
    }
}

/// Background evaluation of the document's graph.
pub struct Evaluator {
    pub engine: Arc<Engine>,
    scheduler: Scheduler,
    /// Document revision of the graph submitted last (evaluated or in flight).
    pub submitted_revision: u64,
    pub progress: Option<Progress>,
    /// The last evaluation that finished (not cancelled), and the graph it evaluated.
    pub last: Option<(Arc<Evaluation>, Graph)>,
    pub status: HashMap<String, NodeStatus>,
    /// The user cancelled: do not resubmit until the next edit.
    pub cancelled_revision: Option<u64>,
    pending_graph: Option<Graph>,
    /// The latest finished tier, until the evaluation has run long enough to show it.
    held: Option<(usize, Evaluation)>,
}

/// How long an evaluation runs before its finished tiers are shown.
const PARTIAL_AFTER: std::time::Duration = std::time::Duration::from_millis(150);

impl Evaluator {
    pub fn new(engine: Arc<Engine>) -> Self {
        Self {
            engine,
            scheduler: Scheduler::default(),
            submitted_revision: 0,
            progress: None,
            last: None,
            status: HashMap::new(),
            cancelled_revision: None,
            pending_graph: None,
            held: None,
        }
    }

    /// Evaluates what `request` needs (the Output's mode and view, previews on screen).
    pub fn submit(&mut self, graph: Graph, request: Request, revision: u64) {
        for n in &graph.nodes {
            self.status.insert(n.id.clone(), NodeStatus::Dirty);
        }
        self.status.retain(|id, _| graph.node(id).is_some());
        self.scheduler.submit_request(&self.engine, graph.clone(), request);
        self.submitted_revision = revision;
        self.cancelled_revision = None;
        self.progress = Some(Progress { started: Instant::now(), total: 0, done: 0, running: Vec::new() });
        self.pending_graph = Some(graph);
        self.held = None;
    }

    pub fn is_running(&self) -> bool {
        self.progress.is_some()
    }

    /// Stops the running evaluation; nothing partial is cached.
    pub fn cancel(&mut self) {
        if let Some(job) = self.scheduler.current() {
            job.cancel();
            self.cancelled_revision = Some(self.submitted_revision);
        }
    }

    /// Drains events; returns the evaluation when one has just finished.
    pub fn poll(&mut self) -> Option<Arc<Evaluation>> {
        if let (Some(job), Some(progress)) = (self.scheduler.current(), self.progress.as_mut()) {
            while let Ok(event) = job.events.try_recv() {
                match event {
                    EvalEvent::Started { stages } => progress.total = stages,
                    EvalEvent::StageStarted { node, stage } => {
                        self.status.insert(node.clone(), NodeStatus::Running(stage.clone(), 0.0));
                        progress.running.push((node, stage, 0.0, Instant::now()));
                    }
                    EvalEvent::StageProgress { node, stage, fraction } => {
                        self.status.insert(node.clone(), NodeStatus::Running(stage.clone(), fraction as f32));
                        if let Some(r) = progress.running.iter_mut().find(|r| r.0 == node && r.1 == stage) {
                            r.2 = fraction as f32;
                        }
                    }
                    EvalEvent::StageFinished { node, stage, status, .. } => {
                        progress.done += 1;
                        progress.running.retain(|r| !(r.0 == node && r.1 == stage));
                        if !progress.running.iter().any(|r| r.0 == node) {
                            let s = if matches!(status, StageStatus::Failed | StageStatus::KnownFailure) {
                                NodeStatus::Error(format!("{stage} failed"))
                            } else {
                                NodeStatus::Dirty
                            };
                            self.status.insert(node, s);
                        }
                    }
                    EvalEvent::TierReady { .. } | EvalEvent::Finished => {}
                }
            }
            // A finished tier (an unshadowed preview while transport computes) is shown once
            // the evaluation has run for PARTIAL_AFTER: a quick edit (a stroke) goes straight to
            // its final frame instead of flashing its preview tiers first.
            if let Some(partial) = job.take_partial() {
                self.held = Some(partial);
            }
            if progress.started.elapsed() >= PARTIAL_AFTER
                && let Some(graph) = self.pending_graph.clone()
                && let Some((_, partial)) = self.held.take()
            {
                let partial = Arc::new(partial);
                self.last = Some((partial.clone(), graph));
                return Some(partial);
            }
        }
        let evaluation = self.scheduler.poll()?;
        self.progress = None;
        self.held = None;
        let graph = self.pending_graph.take()?;
        let cancelled = evaluation.report.stages.iter().any(|s| s.status == StageStatus::Cancelled);
        for n in &graph.nodes {
            let failed = evaluation.report.stages.iter().find(|s| {
                s.node == n.id
                    && matches!(s.status, StageStatus::Failed | StageStatus::KnownFailure | StageStatus::Blocked)
            });
            let status = match failed {
                Some(s) if s.status == StageStatus::Blocked => {
                    NodeStatus::Error(format!("{}: blocked by a failed input", s.stage))
                }
                Some(s) => NodeStatus::Error(format!("{}: {}", s.stage, s.error.as_deref().unwrap_or("failed"))),
                None if cancelled => NodeStatus::Dirty,
                None => NodeStatus::UpToDate,
            };
            self.status.insert(n.id.clone(), status);
        }
        if cancelled {
            return None;
        }
        let evaluation = Arc::new(evaluation);
        self.last = Some((evaluation.clone(), graph));
        Some(evaluation)
    }
}

/// A Monte Carlo reference render on its own thread.
pub struct ReferenceJob {
    cancel: CancelToken,
    progress: Arc<AtomicU32>,
    handle: Option<std::thread::JoinHandle<Result<HdrImage, String>>>,
    pub started: Instant,
    /// What it renders: `(frame keys, camera, size, samples)` hashed, to know when it is stale.
    pub signature: u64,
    pub size: (u32, u32),
}

impl ReferenceJob {
    pub fn spawn(frame: Arc<FrameInputs>, camera: PinholeCamera, size: (u32, u32), signature: u64) -> Self {
        let cancel = CancelToken::default();
        let progress = Arc::new(AtomicU32::new(0));
        let (token, counter) = (cancel.clone(), progress.clone());
        let handle = std::thread::Builder::new()
            .name("lightloom-reference".into())
            .spawn(move || {
                let report = |f: f64| counter.store((f.clamp(0.0, 1.0) * 1e6) as u32, Ordering::Relaxed);
                frame.render_reference(&camera, (size.0 as usize, size.1 as usize), 1, &token, &report)
            })
            .expect("spawn reference thread");
        Self { cancel, progress, handle: Some(handle), started: Instant::now(), signature, size }
    }

    pub fn fraction(&self) -> f32 {
        self.progress.load(Ordering::Relaxed) as f32 / 1e6
    }

    pub fn cancel(&self) {
        self.cancel.cancel();
    }

    /// The finished image (or why it failed), once.
    pub fn poll(&mut self) -> Option<Result<HdrImage, String>> {
        if !self.handle.as_ref()?.is_finished() {
            return None;
        }
        let result = self.handle.take()?.join().unwrap_or_else(|_| Err("the reference render panicked".into()));
        Some(result)
    }
}

impl Drop for ReferenceJob {
    fn drop(&mut self) {
        self.cancel.cancel();
    }
}
