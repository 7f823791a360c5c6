//! File → Bake…: the Output's lighting baked into a folder (as `lightloom bake`), on its own
//! thread sharing the editor's engine and caches, with progress and Cancel in the status bar.

use super::EditorApp;
use eframe::egui;
use lightloom_nodes::engine::{CancelToken, EvalEvent};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// A bake in progress.
pub(super) struct BakeJob {
    pub out: PathBuf,
    pub started: std::time::Instant,
    /// What runs now and how far the whole bake is (0..1).
    pub progress: Arc<Mutex<(String, f64)>>,
    /// The evaluation's token, once the bake's thread has started it.
    cancel: Arc<Mutex<CancelToken>>,
    /// Set by Cancel, so a click before the evaluation starts, or after it ends, still counts.
    cancel_requested: Arc<AtomicBool>,
    result: std::sync::mpsc::Receiver<Result<String, String>>,
}

impl BakeJob {
    pub fn cancel(&self) {
        self.cancel_requested.store(true, Ordering::SeqCst);
        self.cancel.lock().unwrap().cancel();
    }
}

impl EditorApp {
    pub(super) fn bake_dialog(&mut self) {
        let mut dialog = egui_file_dialog::FileDialog::new()
            .title("Bake into folder")
            .initial_directory(std::path::absolute(self.doc.project_dir()).unwrap_or_default());
        dialog.pick_directory();
        self.bake_dialog = Some(dialog);
    }

    /// Bakes the project as it is now (the view as its camera) into `out`.
    pub fn bake_to(&mut self, out: PathBuf) {
        let mut project = self.doc.project.clone();
        project.view = Some(self.view.camera.to_camera("view"));
        let graph = match project.graph(&self.doc.project_dir()) {
            Ok(graph) => graph,
            Err(errors) => {
                let text: Vec<String> = errors.iter().map(ToString::to_string).collect();
                self.log_error(format!("cannot bake: {}", text.join("; ")));
                return;
            }
        };
        let output = match lightloom_nodes::kinds::output::find_output(&graph, project.render.output_node()) {
            Ok(node) => node.id.clone(),
            Err(e) => return self.log_error(format!("cannot bake: {e}")),
        };
        let camera = match project.camera(None) {
            Ok(camera) => camera,
            Err(e) => return self.log_error(format!("cannot bake: {e}")),
        };
        let engine = self.evaluator.engine.clone();
        let progress = Arc::new(Mutex::new(("starting".to_string(), 0.0)));
        let cancel = Arc::new(Mutex::new(CancelToken::default()));
        let (send, result) = std::sync::mpsc::channel();
        let cancel_requested = Arc::new(AtomicBool::new(false));
        let (shared_progress, shared_cancel, target) = (progress.clone(), cancel.clone(), out.clone());
        let requested = cancel_requested.clone();
        #[cfg(test)]
        let hold = self.bake_hold.clone();
        let spawned = std::thread::Builder::new().name("lightloom-bake".into()).spawn(move || {
            let request = lightloom_nodes::bake::bake_request(&graph, &output);
            let job = engine.spawn_request(graph.clone(), request);
            {
                let mut token = shared_cancel.lock().unwrap();
                *token = job.cancel_token();
                if requested.load(Ordering::SeqCst) {
                    token.cancel();
                }
            }
            let (mut total, mut done) = (1usize, 0usize);
            for event in job.events.iter() {
                let mut p = shared_progress.lock().unwrap();
                match event {
                    EvalEvent::Started { stages } => total = stages.max(1),
                    EvalEvent::StageStarted { node, stage } => p.0 = format!("{node}.{stage}"),
                    EvalEvent::StageFinished { .. } => done += 1,
                    EvalEvent::StageProgress { node, stage, fraction } => {
                        p.0 = format!("{node}.{stage} {:.0}%", fraction * 100.0)
                    }
                    EvalEvent::Finished => break,
                    EvalEvent::TierReady { .. } => {}
                }
                p.1 = 0.9 * done as f64 / total as f64;
            }
            let evaluation = job.wait();
            #[cfg(test)]
            if let Some(hold) = hold {
                hold.wait();
            }
            let outcome = crate::bake_command::finish(
                &evaluation,
                &graph,
                &output,
                &project,
                &camera,
                None,
                &target,
                &|what, f| *shared_progress.lock().unwrap() = (what.to_string(), 0.9 + 0.1 * f),
                &|| requested.load(Ordering::SeqCst),
            )
            .map(|baked| {
                let m = &baked.manifest;
                let lightmap =
                    m.lightmap.as_ref().map_or(String::new(), |l| format!(", lightmap {}×{}", l.width, l.height));
                format!("{} vertices{lightmap}, mode {}", m.vertices, m.mode)
            })
            .map_err(|e| format!("{e:#}"));
            let _ = send.send(outcome);
        });
        match spawned {
            Ok(_) => {
                self.log_info(format!("baking into {}", out.display()));
                self.bake = Some(BakeJob {
                    out,
                    started: std::time::Instant::now(),
                    progress,
                    cancel,
                    cancel_requested,
                    result,
                })
            }
            Err(e) => self.log_file_error(format!("cannot start baking into {}: {e}", out.display())),
        }
    }

    pub(super) fn poll_bake(&mut self, ctx: &egui::Context) {
        let Some(job) = &self.bake else { return };
        let Some(outcome) = super::files::finished(&job.result, ctx, "the bake") else { return };
        let job = self.bake.take().expect("checked above");
        let took = crate::project_commands::duration_text(job.started.elapsed().as_secs_f64());
        match outcome {
            Ok(summary) => self.log_info(format!("baked into {} in {took}: {summary}", job.out.display())),
            Err(e) => self.log_file_error(format!("bake into {} failed: {e}", job.out.display())),
        }
    }

    /// The status bar's bake progress and Cancel (at its left end, so they never move).
    pub(super) fn bake_status(&mut self, ui: &mut egui::Ui) {
        let Some(job) = &self.bake else { return };
        let (what, fraction) = job.progress.lock().unwrap().clone();
        ui.add(egui::ProgressBar::new(fraction as f32).desired_width(200.0).text(format!("baking: {what}")));
        if ui.button("Cancel bake").clicked() {
            job.cancel();
        }
        ui.separator();
    }
}
