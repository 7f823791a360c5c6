//! UI frame times, split by whether background work was running (`--stats`, the benches).

/// One UI frame's cost.
#[derive(Clone, Copy, Debug)]
pub struct FrameSample {
    /// The editor's ui pass on the UI thread.
    pub ui_ms: f64,
    /// eframe's CPU time for the previous whole frame (ui, tessellation, paint submission).
    pub cpu_ms: Option<f64>,
    /// Time since the previous frame started.
    pub gap_ms: f64,
    /// An evaluation or a reference render was running.
    pub busy: bool,
}

/// UI frame times, split by whether background work was running.
#[derive(Default)]
pub struct FrameStats {
    pub frames: Vec<FrameSample>,
}

fn percentiles(mut v: Vec<f64>) -> Option<(usize, f64, f64, f64)> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    Some((v.len(), mean, v[(v.len() * 95 / 100).min(v.len() - 1)], v[v.len() - 1]))
}

impl FrameStats {
    pub(super) fn record(&mut self, sample: FrameSample) {
        self.frames.push(sample);
        if self.frames.len() > 20_000 {
            self.frames.drain(..10_000);
        }
    }

    /// `(count, mean, p95, max)` in ms of one measure over the frames with `busy`.
    pub fn summary(&self, busy: bool, measure: impl Fn(&FrameSample) -> Option<f64>) -> Option<(usize, f64, f64, f64)> {
        percentiles(self.frames.iter().filter(|f| f.busy == busy).filter_map(measure).collect())
    }
}
