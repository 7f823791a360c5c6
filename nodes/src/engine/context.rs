//! What a stage's computation sees ([`StageContext`]): its declared parameters, own stages and
//! inputs, cancellation, progress, memoised parts, its previous value and its report lines.

use super::*;

/// An upstream node's id and the value of one of its stages.
type Upstream<'a> = (&'a str, Arc<StageValue>);

/// What a stage's computation sees: only what it declared it reads.
pub struct StageContext<'a> {
    pub node_id: &'a str,
    pub stage: &'static str,
    pub(super) params: BTreeMap<&'static str, &'a ParamValue>,
    pub(super) stages: HashMap<&'static str, Arc<StageValue>>,
    /// Per `(port, stage)`: the upstream nodes' values in link order (one unless the port
    /// takes many links).
    pub(super) inputs: HashMap<(&'static str, &'static str), Vec<Upstream<'a>>>,
    pub(super) project_dir: &'a Path,
    pub(super) cancel: &'a CancelToken,
    pub(super) events: Option<&'a Sender<EvalEvent>>,
    /// Where this computation's progress is shared with evaluations that joined it.
    pub(super) flight: Option<&'a flight::Flight>,
    pub(super) engine: &'a Engine,
    pub(super) persist: Option<Codec>,
    pub(super) memo_hits: std::sync::atomic::AtomicUsize,
    pub(super) memo_misses: std::sync::atomic::AtomicUsize,
    pub(super) warnings: Mutex<Vec<String>>,
    pub(super) info: Mutex<Vec<String>>,
}

impl StageContext<'_> {
    /// Tells the user about something repaired or adjusted (NaN pixels zeroed, an image
    /// downsampled): shown in the stage's report for as long as its result is used.
    pub fn warn(&self, message: impl Into<String>) {
        self.warnings.lock().unwrap().push(message.into());
    }

    /// A plain statement about the result (how accurate, how much work), shown beside the node.
    pub fn inform(&self, message: impl Into<String>) {
        self.info.lock().unwrap().push(message.into());
    }

    /// Caches a part of this stage's work under `key`, a hash of everything that part depends
    /// on (so a stage over many items recomputes only the items that changed). Memoised parts
    /// share the engine's memory cache, and its disk cache when the stage persists.
    pub fn memo<T: Persisted>(
        &self,
        key: Key,
        compute: impl FnOnce() -> Result<T, StageError>,
    ) -> Result<Memo<T>, StageError> {
        use std::sync::atomic::Ordering::Relaxed;
        let codec = Codec::of::<T>();
        let cached = self.engine.memory.lock().unwrap().get(key).filter(|v| v.get::<T>().is_some());
        if let Some(v) = cached {
            self.memo_hits.fetch_add(1, Relaxed);
            return Ok(Memo::new(v));
        }
        if self.persist.is_some()
            && let Some(disk) = &self.engine.disk
        {
            match disk.load(key, &codec) {
                DiskLookup::Hit(v) => {
                    let v = Arc::new(v);
                    self.engine.memory.lock().unwrap().insert(key, v.clone());
                    self.memo_hits.fetch_add(1, Relaxed);
                    return Ok(Memo::new(v));
                }
                // Reported, then recomputed and written again below.
                DiskLookup::Corrupt(why) => {
                    self.warn(format!("disk cache entry of a part was bad ({why}); recomputed"))
                }
                DiskLookup::Miss => {}
            }
        }
        let v = Arc::new(StageValue::new(compute()?));
        self.cancel.check()?;
        self.memo_misses.fetch_add(1, Relaxed);
        if self.persist.is_some()
            && let Some(disk) = &self.engine.disk
        {
            let _ = disk.store(key, &v, &codec);
        }
        self.engine.memory.lock().unwrap().insert(key, v.clone());
        Ok(Memo::new(v))
    }

    /// The part memoised under `key` if the memory cache holds it (counted as a hit), without
    /// computing it: for stages that compute their missing parts together.
    pub fn memo_cached<T: Persisted>(&self, key: Key) -> Option<Memo<T>> {
        let cached = self.engine.memory.lock().unwrap().get(key).filter(|v| v.get::<T>().is_some())?;
        self.memo_hits.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Some(Memo::new(cached))
    }

    fn param(&self, name: &str) -> Result<&ParamValue, StageError> {
        self.params.get(name).copied().ok_or_else(|| {
            StageError::Internal(format!("stage `{}` read parameter `{name}` it did not declare", self.stage))
        })
    }

    pub fn float(&self, name: &str) -> Result<f64, StageError> {
        match self.param(name)? {
            ParamValue::Float(v) => Ok(*v),
            ParamValue::Int(v) => Ok(*v as f64),
            other => Err(StageError::Internal(format!("parameter `{name}` is {}, not Float", other.type_name()))),
        }
    }

    pub fn int(&self, name: &str) -> Result<i64, StageError> {
        match self.param(name)? {
            ParamValue::Int(v) => Ok(*v),
            other => Err(StageError::Internal(format!("parameter `{name}` is {}, not Int", other.type_name()))),
        }
    }

    pub fn boolean(&self, name: &str) -> Result<bool, StageError> {
        match self.param(name)? {
            ParamValue::Bool(v) => Ok(*v),
            other => Err(StageError::Internal(format!("parameter `{name}` is {}, not Bool", other.type_name()))),
        }
    }

    pub fn vec3(&self, name: &str) -> Result<[f64; 3], StageError> {
        match self.param(name)? {
            ParamValue::Vec3(v) | ParamValue::Color(v) => Ok(*v),
            other => Err(StageError::Internal(format!("parameter `{name}` is {}, not Vec3", other.type_name()))),
        }
    }

    pub fn choice(&self, name: &str) -> Result<&str, StageError> {
        match self.param(name)? {
            ParamValue::Choice(v) => Ok(v),
            other => Err(StageError::Internal(format!("parameter `{name}` is {}, not Choice", other.type_name()))),
        }
    }

    /// A `Choice` parameter as its Rust enum (see [`crate::choice_enum`]).
    pub fn option<T: std::str::FromStr<Err = String>>(&self, name: &str) -> Result<T, StageError> {
        self.choice(name)?.parse().map_err(|e| StageError::Internal(format!("parameter `{name}`: {e}")))
    }

    /// A path parameter resolved against the project directory (`None` when empty).
    /// The folder relative file names resolve against.
    pub fn project_dir(&self) -> &Path {
        self.project_dir
    }

    pub fn path(&self, name: &str) -> Result<Option<PathBuf>, StageError> {
        match self.param(name)? {
            ParamValue::Path(p) if p.is_empty() => Ok(None),
            ParamValue::Path(p) => Ok(Some(self.project_dir.join(p))),
            other => Err(StageError::Internal(format!("parameter `{name}` is {}, not Path", other.type_name()))),
        }
    }

    pub fn value(&self, name: &str) -> Result<&ParamValue, StageError> {
        self.param(name)
    }

    /// An earlier stage of this node, as its type; a wrong type is an error naming both.
    pub fn stage<T: StageType>(&self, name: &str) -> Result<&T, StageError> {
        let value = self.stages.get(name).ok_or_else(|| {
            StageError::Internal(format!("stage `{}` read stage `{name}` it did not declare", self.stage))
        })?;
        value.expect::<T>().map_err(|e| StageError::Internal(format!("stage `{name}`: {e}")))
    }

    /// An upstream stage through an input port, as its type; `None` when the port is
    /// unconnected.
    pub fn input<T: StageType>(&self, port: &str, stage: &str) -> Result<Option<&T>, StageError> {
        Ok(self.inputs_all::<T>(port, stage)?.into_iter().next().map(|(_, v)| v))
    }

    /// Every upstream node's stage through a port that takes many links, in link order, with
    /// the upstream node's id.
    pub fn inputs_all<T: StageType>(&self, port: &str, stage: &str) -> Result<Vec<(&str, &T)>, StageError> {
        let Some((_, values)) = self.inputs.iter().find(|((p, s), _)| *p == port && *s == stage) else {
            return Ok(Vec::new());
        };
        values
            .iter()
            .map(|(id, value)| {
                value
                    .expect::<T>()
                    .map(|v| (*id, v))
                    .map_err(|e| StageError::Internal(format!("input `{port}.{stage}`: {e}")))
            })
            .collect()
    }

    /// The value this stage last produced for this node in a finished evaluation (under any
    /// key), while the memory cache still holds it: for results meant to be stable from one
    /// edit to the next (hysteresis). `None` on the first evaluation.
    pub fn previous<T: StageType>(&self) -> Option<Arc<StageValue>> {
        let key = self.engine.last.lock().unwrap().get(&stage_slot(self.node_id, self.stage))?.key;
        self.engine.memory.lock().unwrap().get(key).filter(|v| v.get::<T>().is_some())
    }

    /// Like [`StageContext::input`], for inputs the node cannot work without.
    pub fn required_input<T: StageType>(&self, port: &str, stage: &str) -> Result<&T, StageError> {
        self.input::<T>(port, stage)?.ok_or_else(|| StageError::Failed(format!("the `{port}` input is not connected")))
    }

    pub fn check_cancel(&self) -> Result<(), StageError> {
        self.cancel.check()
    }

    pub fn cancel_token(&self) -> &CancelToken {
        self.cancel
    }

    /// Reports progress in `[0, 1]` (throttling is the receiver's business).
    pub fn progress(&self, fraction: f64) {
        if let Some(flight) = self.flight {
            flight.set_progress(fraction);
        }
        if let Some(tx) = self.events {
            let _ = tx.send(EvalEvent::StageProgress {
                node: self.node_id.to_string(),
                stage: self.stage.to_string(),
                fraction,
            });
        }
    }
}
