//! What an evaluation returns: each stage's result, and the report of what ran and why.

use super::*;

/// How a stage's value was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StageStatus {
    Computed,
    MemoryHit,
    DiskHit,
    Failed,
    /// Failed before with the same key; not retried until something it reads changes.
    KnownFailure,
    /// Not run because a stage it reads failed.
    Blocked,
    Cancelled,
    /// Not run: no requested output reads it (the reasons say what was requested).
    NotNeeded,
}

/// One line of the evaluation report.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageReport {
    pub node: String,
    pub kind: Cow<'static, str>,
    pub stage: Cow<'static, str>,
    /// The stage key (hex in JSON).
    #[serde(with = "key::hex")]
    pub key: Key,
    pub status: StageStatus,
    /// Why it ran: "first evaluation", "parameter `x` changed", "input `p.s` changed", ...
    pub reasons: Vec<String>,
    pub ms: f64,
    pub error: Option<String>,
    /// Repairs and adjustments the stage made (also listed in the report's notes).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// What the stage says about its result (accuracy, work done).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub info: Vec<String>,
}

/// What an evaluation did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub stages: Vec<StageReport>,
    pub total_ms: f64,
    pub memory_cache_bytes: usize,
    pub notes: Vec<String>,
}

impl Report {
    /// `(node, stage)` of every stage that was computed.
    pub fn computed(&self) -> Vec<(String, String)> {
        self.stages
            .iter()
            .filter(|s| s.status == StageStatus::Computed)
            .map(|s| (s.node.clone(), s.stage.to_string()))
            .collect()
    }

    pub fn failed(&self) -> Vec<&StageReport> {
        self.stages
            .iter()
            .filter(|s| matches!(s.status, StageStatus::Failed | StageStatus::KnownFailure | StageStatus::Blocked))
            .collect()
    }
}

/// The result of one stage in an evaluation.
#[derive(Clone, Debug)]
pub struct StageResult {
    pub key: Key,
    pub value: Result<Arc<StageValue>, StageError>,
}

/// The outcome of evaluating a graph.
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// Every stage's result, in report order.
    pub results: Vec<StageResult>,
    /// `stage_slot(node, stage)` → index into `results`.
    pub(super) index: HashMap<u64, usize>,
    pub report: Report,
}

impl Evaluation {
    pub fn get(&self, node: &str, stage: &str) -> Option<&StageResult> {
        self.index.get(&stage_slot(node, stage)).map(|&i| &self.results[i])
    }

    pub fn value(&self, node: &str, stage: &str) -> Result<Arc<StageValue>, StageError> {
        match self.get(node, stage) {
            Some(r) => r.value.clone(),
            None => Err(StageError::Internal(format!("no stage `{stage}` on node `{node}`"))),
        }
    }
}
