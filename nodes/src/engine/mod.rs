//! The evaluation engine: stages, keys and dirty propagation (see `ARCHITECTURE.md`).
//!
//! Every stage of every node gets a key, the hash of exactly the parameters, own stages and
//! upstream stages it reads. A stage runs only when no cache holds its key. Stages run in
//! parallel in dependency waves, can be cancelled, report progress, and every evaluation
//! produces a [`Report`] of what ran and why.

pub mod cache;
mod context;
mod flight;
pub mod graph;
mod job;
pub mod key;
mod report;
pub mod request;
pub mod spec;
pub mod value;

pub use context::StageContext;
pub use graph::{Graph, GraphError, GraphNode, Link};
pub use job::{EvalJob, Scheduler};
pub use key::Key;
pub use report::{Evaluation, Report, StageReport, StageResult, StageStatus};
pub use request::{Request, StageRef, Tier};
pub use value::{Codec, Persisted, StageType, StageValue};

use crate::engine::spec::{ParamValue, StageSpec};
use cache::{DiskCache, DiskLookup, MemoryCache};
use rustc_hash::FxHashMap as HashMap;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Why a stage failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StageError {
    #[error("cancelled")]
    Cancelled,
    #[error("{0}")]
    Failed(String),
    #[error("upstream stage {0} failed")]
    Upstream(String),
    #[error("internal error: {0}")]
    Internal(String),
}

/// A shared cancellation flag; stages poll it in their loops. A stage computed for several
/// evaluations (see `flight`) gets a token that is cancelled once all of theirs are.
#[derive(Clone, Debug, Default)]
pub struct CancelToken {
    flag: Arc<AtomicBool>,
    /// When set: cancelled once every one of these is.
    all_of: Option<Arc<Mutex<Vec<CancelToken>>>>,
}

impl CancelToken {
    pub fn cancel(&self) {
        self.flag.store(true, Ordering::SeqCst);
    }

    pub fn is_cancelled(&self) -> bool {
        if self.flag.load(Ordering::SeqCst) {
            return true;
        }
        let Some(all) = &self.all_of else { return false };
        let all_cancelled = all.lock().unwrap().iter().all(CancelToken::is_cancelled);
        if all_cancelled {
            self.flag.store(true, Ordering::SeqCst);
        }
        all_cancelled
    }

    /// A token cancelled once `first` and every token added with
    /// [`CancelToken::also_wanted_by`] are.
    fn wanted_by(first: &CancelToken) -> Self {
        Self { flag: Arc::default(), all_of: Some(Arc::new(Mutex::new(vec![first.clone()]))) }
    }

    fn also_wanted_by(&self, other: &CancelToken) {
        if let Some(all) = &self.all_of {
            let mut all = all.lock().unwrap();
            all.retain(|t| !t.is_cancelled());
            all.push(other.clone());
        }
    }

    pub fn check(&self) -> Result<(), StageError> {
        if self.is_cancelled() { Err(StageError::Cancelled) } else { Ok(()) }
    }
}

/// Progress events, sent while an evaluation runs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum EvalEvent {
    Started {
        stages: usize,
    },
    StageStarted {
        node: String,
        stage: String,
    },
    StageProgress {
        node: String,
        stage: String,
        fraction: f64,
    },
    StageFinished {
        node: String,
        stage: String,
        status: StageStatus,
        ms: f64,
    },
    /// Every stage of request tier `tier` is done; [`EvalJob::take_partial`] holds its results.
    TierReady {
        tier: usize,
        label: String,
    },
    Finished,
}

/// A memoised part of a stage's work (see [`StageContext::memo`]): a shared `T`.
#[derive(Clone, Debug)]
pub struct Memo<T> {
    value: Arc<StageValue>,
    _type: std::marker::PhantomData<fn() -> T>,
}

impl<T: StageType> Memo<T> {
    fn new(value: Arc<StageValue>) -> Self {
        debug_assert!(value.get::<T>().is_some());
        Self { value, _type: std::marker::PhantomData }
    }
}

impl<T: StageType> std::ops::Deref for Memo<T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.value.get::<T>().expect("memo holds its type")
    }
}

/// Engine settings.
#[derive(Clone, Debug)]
pub struct EngineConfig {
    pub memory_budget_bytes: usize,
    /// `None` disables the disk cache.
    pub disk_cache: Option<PathBuf>,
    /// The disk cache's least recently used entries beyond this are removed.
    pub disk_budget_bytes: u64,
}

impl Default for EngineConfig {
    fn default() -> Self {
        Self {
            memory_budget_bytes: 2 << 30,
            disk_cache: Some(DiskCache::default_dir()),
            disk_budget_bytes: cache::DEFAULT_DISK_BUDGET_BYTES,
        }
    }
}

#[derive(Clone, Debug)]
struct StageRecord {
    key: Key,
    components: Vec<(key::Component, u64)>,
}

/// The evaluation engine: caches and the memory of the previous keys (for "why" reports).
pub struct Engine {
    memory: Mutex<MemoryCache>,
    disk: Option<DiskCache>,
    /// Last successful key per `(node, stage)` (hashed), for "why" reports.
    last: Mutex<HashMap<u64, StageRecord>>,
    /// Keys whose computation failed (deterministic failures are not retried).
    failures: Mutex<HashMap<Key, StageError>>,
    file_hashes: Mutex<HashMap<PathBuf, (std::time::SystemTime, u64, u64)>>,
    /// Warnings of computed stages by key, repeated whenever the result is reused.
    stage_warnings: Mutex<HashMap<Key, Vec<String>>>,
    /// Information lines of computed stages by key.
    stage_info: Mutex<HashMap<Key, Vec<String>>>,
    /// Stages being computed, shared with newer evaluations that need the same key.
    flights: flight::Flights,
}

/// A stage instance scheduled in one evaluation.
struct Instance<'g> {
    node: &'g GraphNode,
    spec: &'g StageSpec,
    /// Indices of the instances it reads, with the label they are read under.
    deps: Vec<(usize, DepLabel<'g>)>,
    key: Key,
    components: Vec<(key::Component, u64)>,
}

/// `(node id, stage name)` → index of its instance in one evaluation.
type StageIndex<'g> = HashMap<(&'g str, &'g str), usize>;

/// A hash of `(node id, stage name)` identifying a stage across evaluations.
fn stage_slot(node: &str, stage: &str) -> u64 {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(node.as_bytes());
    h.update(&[0]);
    h.update(stage.as_bytes());
    h.digest()
}

/// A finished instance: its value or error, how it was obtained, milliseconds, reasons.
type Outcome = (Result<Arc<StageValue>, StageError>, StageStatus, f64, Vec<String>);

#[derive(Clone, Copy)]
enum DepLabel<'g> {
    Own(&'static str),
    /// Port, stage and the upstream node.
    Input(&'static str, &'static str, &'g str),
}

impl Engine {
    pub fn new(config: EngineConfig) -> Self {
        Self {
            memory: Mutex::new(MemoryCache::new(config.memory_budget_bytes)),
            disk: config.disk_cache.map(|dir| DiskCache::with_budget(dir, config.disk_budget_bytes)),
            last: Mutex::new(HashMap::default()),
            failures: Mutex::new(HashMap::default()),
            file_hashes: Mutex::new(HashMap::default()),
            stage_warnings: Mutex::new(HashMap::default()),
            stage_info: Mutex::new(HashMap::default()),
            flights: flight::Flights::default(),
        }
    }

    /// An engine with no disk cache (tests, one-off runs).
    pub fn in_memory() -> Self {
        Self::new(EngineConfig { disk_cache: None, ..Default::default() })
    }

    pub fn disk_cache(&self) -> Option<&DiskCache> {
        self.disk.as_ref()
    }

    /// Evaluates every stage of `graph` (blocking; stages run in parallel on the rayon pool).
    pub fn evaluate(&self, graph: &Graph, cancel: &CancelToken, events: Option<&Sender<EvalEvent>>) -> Evaluation {
        self.evaluate_request(graph, &Request::everything(graph), cancel, events, &|_, _| {})
    }

    /// Evaluates what `request` needs, tier by tier (blocking). After each tier but the last,
    /// `on_tier` gets the evaluation so far (every stage that tier needs is in it).
    pub fn evaluate_request(
        &self,
        graph: &Graph,
        request: &Request,
        cancel: &CancelToken,
        events: Option<&Sender<EvalEvent>>,
        on_tier: &dyn Fn(usize, Evaluation),
    ) -> Evaluation {
        let start = Instant::now();
        let (instances, index) = self.schedule(graph);
        let mut notes = Vec::new();
        let tier_of = request::needed_tiers(graph, &instances, &index, request, &mut notes);
        if let Some(tx) = events {
            let _ = tx.send(EvalEvent::Started { stages: tier_of.iter().flatten().count() });
        }
        let mut results: Vec<Option<Outcome>> = (0..instances.len()).map(|_| None).collect();
        for (tier, spec) in request.tiers.iter().enumerate() {
            // Waves: every instance of this tier (or an earlier one) whose dependencies are done.
            loop {
                let ready: Vec<usize> = (0..instances.len())
                    .filter(|&i| {
                        results[i].is_none()
                            && tier_of[i].is_some_and(|t| t <= tier)
                            && instances[i].deps.iter().all(|(d, _)| results[*d].is_some())
                    })
                    .collect();
                if ready.is_empty() {
                    break;
                }
                // Cache hits resolve inline; only real work goes to the thread pool.
                let (cached, work): (Vec<usize>, Vec<usize>) = {
                    let memory = self.memory.lock().unwrap();
                    ready.iter().partition(|&&i| memory.contains(instances[i].key))
                };
                // Stages another evaluation is computing are waited for on this thread (not a
                // pool worker), after this wave's own work.
                let (joined, work): (Vec<usize>, Vec<usize>) =
                    work.into_iter().partition(|&i| self.flights.is_live(instances[i].key));
                let mut done: Vec<(usize, _)> = cached
                    .iter()
                    .map(|&i| (i, self.run_instance(graph, &instances, i, &results, cancel, events)))
                    .collect();
                if work.len() == 1 {
                    done.push((work[0], self.run_instance(graph, &instances, work[0], &results, cancel, events)));
                } else {
                    use rayon::prelude::*;
                    done.par_extend(
                        work.par_iter()
                            .map(|&i| (i, self.run_instance(graph, &instances, i, &results, cancel, events))),
                    );
                }
                for &i in &joined {
                    done.push((i, self.run_instance(graph, &instances, i, &results, cancel, events)));
                }
                for (i, (outcome, note)) in done {
                    if let Some(n) = note {
                        notes.push(n);
                    }
                    results[i] = Some(outcome);
                }
            }
            if tier + 1 < request.tiers.len() && !cancel.is_cancelled() {
                on_tier(tier, self.assemble(&instances, &results, None, notes.clone(), start, false));
                if let Some(tx) = events {
                    let _ = tx.send(EvalEvent::TierReady { tier, label: spec.label.clone() });
                }
            }
        }
        let evaluation = self.assemble(&instances, &results, Some(request), notes, start, true);
        if let Some(tx) = events {
            let _ = tx.send(EvalEvent::Finished);
        }
        evaluation
    }

    /// The evaluation of the finished instances. With `request`, stages it did not need are
    /// reported as such; `commit` records keys for the next evaluation's "why" reasons.
    fn assemble(
        &self,
        instances: &[Instance],
        results: &[Option<Outcome>],
        request: Option<&Request>,
        mut notes: Vec<String>,
        start: Instant,
        commit: bool,
    ) -> Evaluation {
        let mut last = self.last.lock().unwrap();
        let mut report = Report { stages: Vec::with_capacity(instances.len()), ..Default::default() };
        let mut out = Vec::with_capacity(instances.len());
        let mut index = HashMap::with_capacity_and_hasher(instances.len(), Default::default());
        for (inst, result) in instances.iter().zip(results) {
            let Some((value, status, ms, reasons)) = result.clone() else {
                if let Some(request) = request {
                    report.stages.push(StageReport {
                        node: inst.node.id.clone(),
                        kind: Cow::Borrowed(inst.node.kind.name),
                        stage: Cow::Borrowed(inst.spec.name),
                        key: inst.key,
                        status: StageStatus::NotNeeded,
                        reasons: vec![format!("not read by what was requested ({})", request.describe())],
                        ms: 0.0,
                        error: None,
                        warnings: Vec::new(),
                        info: Vec::new(),
                    });
                }
                continue;
            };
            let slot = stage_slot(&inst.node.id, inst.spec.name);
            if commit && value.is_ok() && last.get(&slot).is_none_or(|r| r.key != inst.key) {
                last.insert(slot, StageRecord { key: inst.key, components: inst.components.clone() });
            }
            let warnings = if value.is_ok() {
                self.stage_warnings.lock().unwrap().get(&inst.key).cloned().unwrap_or_default()
            } else {
                Vec::new()
            };
            notes.extend(warnings.iter().map(|w| format!("{}.{}: {w}", inst.node.id, inst.spec.name)));
            let info = if value.is_ok() {
                self.stage_info.lock().unwrap().get(&inst.key).cloned().unwrap_or_default()
            } else {
                Vec::new()
            };
            report.stages.push(StageReport {
                warnings,
                info,
                node: inst.node.id.clone(),
                kind: Cow::Borrowed(inst.node.kind.name),
                stage: Cow::Borrowed(inst.spec.name),
                key: inst.key,
                status,
                reasons,
                ms,
                error: value.as_ref().err().map(|e| e.to_string()),
            });
            index.insert(slot, out.len());
            out.push(StageResult { key: inst.key, value });
        }
        report.total_ms = start.elapsed().as_secs_f64() * 1e3;
        report.memory_cache_bytes = self.memory.lock().unwrap().used_bytes();
        report.notes = notes;
        Evaluation { results: out, index, report }
    }

    /// Builds stage instances in topological order and computes their keys.
    /// Also returns the `(node, stage)` → instance index it built.
    fn schedule<'g>(&self, graph: &'g Graph) -> (Vec<Instance<'g>>, StageIndex<'g>) {
        let count: usize = graph.nodes.iter().map(|n| n.kind.stages.len()).sum();
        let mut instances: Vec<Instance<'g>> = Vec::with_capacity(count);
        let mut index: HashMap<(&str, &str), usize> = HashMap::with_capacity_and_hasher(count, Default::default());
        let mut buffer = Vec::new();
        for node in graph.topological_order() {
            for spec in &node.kind.stages {
                let mut builder = key::KeyBuilder::new(node.kind.name, spec.name, spec.version);
                for &param in spec.params {
                    if param == crate::engine::spec::NODE_ID {
                        builder.add(key::Component::Param(param), node.id.as_bytes());
                        continue;
                    }
                    let value = &node.params[param];
                    self.param_bytes(graph, node.kind, value, &mut buffer);
                    builder.add(key::Component::Param(param), &buffer);
                }
                let mut deps = Vec::new();
                for &own in spec.stages {
                    let d = index[&(node.id.as_str(), own)];
                    builder.add(key::Component::Stage(own), &instances[d].key.to_le_bytes());
                    deps.push((d, DepLabel::Own(own)));
                }
                for &(port, stage) in spec.inputs {
                    let many = node.kind.inputs.iter().any(|p| p.name == port && p.many);
                    let upstream = if many {
                        graph.upstream_all(&node.id, port)
                    } else {
                        Vec::from_iter(graph.upstream(&node.id, port))
                    };
                    if upstream.is_empty() {
                        builder.add(key::Component::Input(port, stage), b"unconnected");
                    }
                    let mut bytes = Vec::new();
                    for up in upstream {
                        let d = index[&(up.id.as_str(), stage)];
                        bytes.clear();
                        bytes.extend_from_slice(&instances[d].key.to_le_bytes());
                        // Which node a value came from matters where many are linked.
                        if many {
                            bytes.extend_from_slice(up.id.as_bytes());
                        }
                        builder.add(key::Component::Input(port, stage), &bytes);
                        deps.push((d, DepLabel::Input(port, stage, up.id.as_str())));
                    }
                }
                let (key, components) = builder.finish();
                index.insert((node.id.as_str(), spec.name), instances.len());
                instances.push(Instance { node, spec, deps, key, components });
            }
        }
        (instances, index)
    }

    /// Canonical bytes of a parameter value; file paths also hash the file's content.
    fn param_bytes(&self, graph: &Graph, kind: &spec::NodeKindSpec, value: &ParamValue, bytes: &mut Vec<u8>) {
        bytes.clear();
        let taken = std::mem::take(bytes);
        *bytes = postcard::to_extend(value, taken).unwrap_or_default();
        for p in value.files() {
            let path = graph.project_dir.join(p);
            bytes.extend_from_slice(&self.file_hash(&path).to_le_bytes());
            for sidecar in (kind.referenced_files)(&path) {
                bytes.extend_from_slice(&self.file_hash(&sidecar).to_le_bytes());
            }
        }
    }

    /// Content hash of a file, memoised on (mtime, size); 0 when unreadable.
    fn file_hash(&self, path: &Path) -> u64 {
        let Ok(meta) = std::fs::metadata(path) else { return 0 };
        let mtime = meta.modified().unwrap_or(std::time::UNIX_EPOCH);
        if let Some((t, size, hash)) = self.file_hashes.lock().unwrap().get(path)
            && *t == mtime
            && *size == meta.len()
        {
            return *hash;
        }
        let hash = std::fs::read(path).map(|b| xxhash_rust::xxh3::xxh3_64(&b)).unwrap_or(0);
        self.file_hashes.lock().unwrap().insert(path.to_path_buf(), (mtime, meta.len(), hash));
        hash
    }

    fn run_instance(
        &self,
        graph: &Graph,
        instances: &[Instance],
        i: usize,
        results: &[Option<Outcome>],
        cancel: &CancelToken,
        events: Option<&Sender<EvalEvent>>,
    ) -> (Outcome, Option<String>) {
        let inst = &instances[i];
        let start = Instant::now();
        let node_id = inst.node.id.clone();
        let stage_name = inst.spec.name.to_string();
        let finish = |value: Result<Arc<StageValue>, StageError>, status: StageStatus, reasons: Vec<String>| {
            let ms = start.elapsed().as_secs_f64() * 1e3;
            if let Some(tx) = events {
                let _ =
                    tx.send(EvalEvent::StageFinished { node: node_id.clone(), stage: stage_name.clone(), status, ms });
            }
            (value, status, ms, reasons)
        };
        // Upstream failures propagate without running.
        for (d, _) in &inst.deps {
            if let Some((Err(e), ..)) = &results[*d] {
                let what = format!("{}.{}", instances[*d].node.id, instances[*d].spec.name);
                let err = if *e == StageError::Cancelled { StageError::Cancelled } else { StageError::Upstream(what) };
                let status = if err == StageError::Cancelled { StageStatus::Cancelled } else { StageStatus::Blocked };
                return (finish(Err(err), status, vec![]), None);
            }
        }
        if let Some(value) = self.memory.lock().unwrap().get(inst.key) {
            return (finish(Ok(value), StageStatus::MemoryHit, vec![]), None);
        }
        if let Some(error) = self.failures.lock().unwrap().get(&inst.key) {
            return (finish(Err(error.clone()), StageStatus::KnownFailure, vec![]), None);
        }
        if cancel.is_cancelled() {
            return (finish(Err(StageError::Cancelled), StageStatus::Cancelled, vec![]), None);
        }
        let mut reasons = self.reasons(inst);
        let mut note = None;
        if let Some(codec) = &inst.spec.persist
            && let Some(disk) = &self.disk
        {
            match disk.load(inst.key, codec) {
                DiskLookup::Hit(value) => {
                    let value = Arc::new(value);
                    self.memory.lock().unwrap().insert(inst.key, value.clone());
                    return (finish(Ok(value), StageStatus::DiskHit, reasons), None);
                }
                DiskLookup::Corrupt(why) => {
                    reasons.push(format!("corrupt disk cache entry recomputed ({why})"));
                    note = Some(format!(
                        "{}.{}: corrupt disk cache entry recomputed: {why}",
                        inst.node.id, inst.spec.name
                    ));
                }
                DiskLookup::Miss => {}
            }
        }
        if let Some(tx) = events {
            let _ = tx.send(EvalEvent::StageStarted { node: inst.node.id.clone(), stage: inst.spec.name.to_string() });
        }
        // Another evaluation may be computing this very key (an edit cancelled it, and this
        // newer evaluation needs the same result): wait for it rather than start over. Only
        // off the rayon pool (see `flight`); a worker computes on its own instead.
        let may_wait = rayon::current_thread_index().is_none();
        let flight = loop {
            match self.flights.join(inst.key, cancel, may_wait) {
                flight::Role::Lead(flight) => break flight,
                flight::Role::Wait(flight) => {
                    let progress = |fraction| {
                        if let Some(tx) = events {
                            let _ = tx.send(EvalEvent::StageProgress {
                                node: inst.node.id.clone(),
                                stage: inst.spec.name.to_string(),
                                fraction,
                            });
                        }
                    };
                    match flight.wait(cancel, progress) {
                        None => return (finish(Err(StageError::Cancelled), StageStatus::Cancelled, reasons), note),
                        // Its other evaluations were all cancelled first: compute it here.
                        Some(Err(StageError::Cancelled)) => continue,
                        Some(Ok(value)) => {
                            reasons.push("joined the computation an earlier evaluation had started".into());
                            return (finish(Ok(value), StageStatus::Computed, reasons), note);
                        }
                        Some(Err(e)) => return (finish(Err(e), StageStatus::Failed, reasons), note),
                    }
                }
            }
        };
        let mut guard = flight::FinishOnUnwind { flights: &self.flights, key: inst.key, flight: &flight, done: false };
        let (outcome, note) = self.compute_instance(graph, inst, results, &flight, events, reasons, note, finish);
        let shared = match &outcome.0 {
            Ok(value) => Ok(value.clone()),
            Err(e) => Err(e.clone()),
        };
        self.flights.finish(inst.key, &flight, shared);
        guard.done = true;
        (outcome, note)
    }

    /// Runs an instance's computation (its flight's leader) and caches the result.
    #[allow(clippy::too_many_arguments)]
    fn compute_instance(
        &self,
        graph: &Graph,
        inst: &Instance,
        results: &[Option<Outcome>],
        flight: &flight::Flight,
        events: Option<&Sender<EvalEvent>>,
        mut reasons: Vec<String>,
        mut note: Option<String>,
        finish: impl Fn(Result<Arc<StageValue>, StageError>, StageStatus, Vec<String>) -> Outcome,
    ) -> (Outcome, Option<String>) {
        let cancel = &flight.token;
        let mut ctx = StageContext {
            node_id: &inst.node.id,
            stage: inst.spec.name,
            params: inst
                .spec
                .params
                .iter()
                .filter(|p| **p != crate::engine::spec::NODE_ID)
                .map(|p| (*p, &inst.node.params[*p]))
                .collect(),
            stages: HashMap::default(),
            inputs: HashMap::default(),
            project_dir: &graph.project_dir,
            cancel,
            events,
            flight: Some(flight),
            engine: self,
            persist: inst.spec.persist,
            memo_hits: Default::default(),
            memo_misses: Default::default(),
            warnings: Default::default(),
            info: Default::default(),
        };
        for (d, label) in &inst.deps {
            let value = results[*d].as_ref().unwrap().0.as_ref().unwrap().clone();
            match label {
                DepLabel::Own(name) => {
                    ctx.stages.insert(name, value);
                }
                DepLabel::Input(port, stage, from) => {
                    ctx.inputs.entry((port, stage)).or_default().push((from, value));
                }
            }
        }
        let outcome = (inst.spec.compute)(&ctx);
        let mut warnings = ctx.warnings.into_inner().unwrap();
        if let Ok(value) = &outcome {
            let absurd = value.absurd_numbers();
            if absurd > 0 {
                warnings.push(format!(
                    "{absurd} value(s) of its {} are NaN, infinite or beyond ±1e30: check this node's inputs and \
                     parameters",
                    value.type_name()
                ));
            }
        }
        if outcome.is_ok() && !warnings.is_empty() {
            self.stage_warnings.lock().unwrap().insert(inst.key, warnings);
        }
        let info = ctx.info.into_inner().unwrap();
        if outcome.is_ok() && !info.is_empty() {
            self.stage_info.lock().unwrap().insert(inst.key, info);
        }
        let (hits, misses) = (ctx.memo_hits.into_inner(), ctx.memo_misses.into_inner());
        if hits + misses > 0 {
            reasons.push(format!("{misses} part(s) computed, {hits} reused"));
        }
        // A result computed after every evaluation that wanted it was cancelled is still
        // correct for its key, but we drop it to keep cancellation prompt and simple.
        match outcome {
            Ok(value) if !cancel.is_cancelled() => {
                let value = Arc::new(value);
                if let Some(codec) = &inst.spec.persist
                    && let Some(disk) = &self.disk
                    && let Err(e) = disk.store(inst.key, &value, codec)
                {
                    note = Some(format!("{}.{}: could not write the disk cache: {e}", inst.node.id, inst.spec.name));
                }
                self.memory.lock().unwrap().insert(inst.key, value.clone());
                (finish(Ok(value), StageStatus::Computed, reasons), note)
            }
            Ok(_) | Err(StageError::Cancelled) => {
                (finish(Err(StageError::Cancelled), StageStatus::Cancelled, reasons), note)
            }
            Err(e) => {
                let mut failures = self.failures.lock().unwrap();
                if failures.len() > 10_000 {
                    failures.clear();
                }
                failures.insert(inst.key, e.clone());
                (finish(Err(e), StageStatus::Failed, reasons), note)
            }
        }
    }

    /// Why an instance must run, compared with the last successful evaluation of the same stage.
    fn reasons(&self, inst: &Instance) -> Vec<String> {
        let last = self.last.lock().unwrap();
        match last.get(&stage_slot(&inst.node.id, inst.spec.name)) {
            None => vec!["first evaluation".into()],
            Some(prev) if prev.key == inst.key => vec!["not in the memory cache".into()],
            Some(prev) => {
                // A port with many links contributes one component per link: compare them
                // together, once per label.
                let per_label = |components: &[(key::Component, u64)]| {
                    let mut out: Vec<(key::Component, u64)> = Vec::new();
                    for &(label, hash) in components {
                        match out.iter_mut().find(|(l, _)| *l == label) {
                            Some(entry) => entry.1 = entry.1.rotate_left(7) ^ hash,
                            None => out.push((label, hash)),
                        }
                    }
                    out
                };
                let old: HashMap<key::Component, u64> = per_label(&prev.components).into_iter().collect();
                let changed: Vec<String> = per_label(&inst.components)
                    .iter()
                    .filter(|(label, hash)| old.get(label) != Some(hash))
                    .map(|(label, _)| format!("{label} changed"))
                    .collect();
                if changed.is_empty() { vec!["stage definition changed".into()] } else { changed }
            }
        }
    }
}

#[cfg(test)]
mod tests;
