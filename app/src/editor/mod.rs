//! The editor: node graph, 3D viewport, inspector, problems/log and timings, with undo/redo,
//! saves, autosave and recovery. Evaluation and reference renders run off the UI thread.
//!
//! Layout: menu bar on top; status bar (evaluation progress, Cancel, frame time) at the
//! bottom with the problems/log/timings panel above it; inspector on the right; graph on
//! the left; viewport in the centre.

pub mod document;
pub mod edits;
pub mod graph_editor;
pub mod inspector;
pub mod jobs;
pub mod orbit;
pub mod previews;
pub mod viewport;

#[cfg(test)]
mod ui_tests;

use document::Document;
use eframe::egui::{self, Color32};
use graph_editor::{GraphAction, GraphEditor, PendingLink};
use jobs::{Evaluator, NodeStatus, ReferenceJob};
use lightloom_nodes::engine::{Engine, EngineConfig, Evaluation};
use lightloom_nodes::graph::ParamValue;
use lightloom_nodes::kinds::output::{FrameInputs, find_output};
use lightloom_nodes::project::{Project, default_project};
use lightloom_nodes::reference::{self, HdrImage, ImageError};
use orbit::OrbitCamera;
use previews::Previews;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};
use viewport::ViewportHost;

/// How the editor was started.
#[derive(Clone, Debug, Default)]
pub struct EditorOptions {
    /// Project to open; `None` opens the built-in default project.
    pub project: Option<PathBuf>,
    /// Save a screenshot of the window here once the first evaluation is shown, then quit.
    pub screenshot: Option<PathBuf>,
    /// Disk cache for expensive stages (`None`: the default folder).
    pub cache_dir: Option<PathBuf>,
    pub no_disk_cache: bool,
    /// Print UI frame-time statistics when the editor closes.
    pub frame_stats: bool,
}

/// How often unsaved work is written to the recovery file.
const AUTOSAVE_INTERVAL: Duration = Duration::from_secs(20);

#[derive(Clone, Copy, PartialEq, Eq)]
enum BottomTab {
    Problems,
    Log,
    Timings,
}

/// What the inspector shows.
#[derive(Clone, Debug, PartialEq)]
pub enum Selection {
    None,
    Node(String),
}

#[derive(Clone, Debug)]
enum FileAction {
    Open,
    SaveAs { then_close: bool },
    Browse { node: String, param: String },
}

/// A question that needs an answer before going on.
#[derive(Clone, Debug)]
enum Pending {
    /// Unsaved changes, and the user asked to do this.
    Close,
    Open(PathBuf),
    New,
    /// A recovery file from a session that did not close cleanly.
    Recover(PathBuf, SystemTime),
    Rename {
        node: String,
        text: String,
    },
}

struct LogLine {
    at: SystemTime,
    error: bool,
    text: String,
}

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
    fn record(&mut self, sample: FrameSample) {
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

/// The viewport's view of the output: what it last drew and what it needs.
struct ViewState {
    camera: OrbitCamera,
    /// Project camera the orbit started from.
    camera_name: String,
    frame: Option<Arc<FrameInputs>>,
    frame_error: Option<String>,
    /// Signature of what is on screen; redraw when it changes.
    drawn: u64,
    resolution_scale: f32,
    reference: Option<ReferenceJob>,
    /// The finished reference for a signature, and the approximation's error against it.
    reference_image: Option<(u64, Arc<HdrImage>)>,
    error: Option<ImageError>,
    selected_object: Option<usize>,
}

pub struct EditorApp {
    pub doc: Document,
    pub evaluator: Evaluator,
    pub graph: GraphEditor,
    pub selection: Selection,
    previews: Previews,
    view: ViewState,
    host: Option<ViewportHost>,
    host_error: Option<String>,
    graph_errors: Vec<String>,
    /// Hash of what evaluation reads (nodes, parameters, links): positions and labels excluded.
    eval_signature: u64,
    log: Vec<LogLine>,
    bottom_tab: BottomTab,
    clipboard: Option<edits::Clipboard>,
    file_dialog: egui_file_dialog::FileDialog,
    file_action: Option<FileAction>,
    pending: Option<Pending>,
    close_confirmed: bool,
    title: String,
    pub stats: FrameStats,
    options: EditorOptions,
    last_frame: Option<Instant>,
    screenshot_state: ScreenshotState,
    /// Text for the system clipboard (copied nodes), handed to egui at the end of the frame.
    copy_request: Option<String>,
    /// Where the viewport image and the graph were drawn last frame.
    pub viewport_rect: egui::Rect,
    pub graph_rect: egui::Rect,
    last_cpu_ms: Option<f64>,
}

#[derive(PartialEq, Eq)]
enum ScreenshotState {
    None,
    Waiting,
    Requested,
    Done,
}

/// Runs the editor window.
pub fn run(options: EditorOptions) -> anyhow::Result<()> {
    let mut wgpu_options = eframe::egui_wgpu::WgpuConfiguration::default();
    if let eframe::egui_wgpu::WgpuSetup::CreateNew(create) = &mut wgpu_options.wgpu_setup {
        create.device_descriptor = Arc::new(lightloom_render::device_descriptor);
    }
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1600.0, 900.0]).with_title("Lightloom"),
        renderer: eframe::Renderer::Wgpu,
        wgpu_options,
        ..Default::default()
    };
    let stats_wanted = options.frame_stats;
    let stats = Arc::new(std::sync::Mutex::new(None));
    let stats_out = stats.clone();
    eframe::run_native(
        "Lightloom",
        native,
        Box::new(move |cc| {
            let app = EditorApp::new(&cc.egui_ctx, cc.wgpu_render_state.as_ref(), options)?;
            Ok(Box::new(AppWithStats { app, out: stats_out }))
        }),
    )
    .map_err(|e| anyhow::anyhow!("the editor window could not start: {e}"))?;
    if stats_wanted && let Some(text) = stats.lock().ok().and_then(|mut s| s.take()) {
        println!("{text}");
    }
    Ok(())
}

/// Hands the frame statistics out when the window closes.
struct AppWithStats {
    app: EditorApp,
    out: Arc<std::sync::Mutex<Option<String>>>,
}

impl eframe::App for AppWithStats {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        eframe::App::ui(&mut self.app, ui, frame);
    }

    fn on_exit(&mut self) {
        if let Ok(mut out) = self.out.lock() {
            *out = Some(self.app.stats_report());
        }
        self.app.on_exit();
    }
}

impl eframe::App for EditorApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.last_cpu_ms = frame.info().cpu_usage.map(|s| f64::from(s) * 1e3);
        self.frame(ui, frame.wgpu_render_state());
    }

    fn on_exit(&mut self) {
        EditorApp::on_exit(self);
    }
}

fn eval_signature(project: &Project) -> u64 {
    let mut stripped = project.clone();
    stripped.cameras.clear();
    stripped.name.clear();
    for n in &mut stripped.nodes {
        n.position = [0.0; 2];
        n.label.clear();
    }
    xxhash_rust::xxh3::xxh3_64(stripped.to_ron().as_bytes())
}

impl EditorApp {
    /// An editor on `options.project` (or the default project). `render_state` is eframe's
    /// wgpu device; without one the viewport renders on its own headless device.
    pub fn new(
        ctx: &egui::Context,
        render_state: Option<&eframe::egui_wgpu::RenderState>,
        options: EditorOptions,
    ) -> anyhow::Result<Self> {
        let (doc, open_error) = match &options.project {
            Some(path) => match Document::open(path) {
                Ok(doc) => (doc, None),
                Err(e) => (Document::new(default_project(), None), Some(format!("{e:#}"))),
            },
            None => (Document::new(default_project(), None), None),
        };
        let disk_cache = if options.no_disk_cache {
            None
        } else {
            Some(options.cache_dir.clone().unwrap_or_else(lightloom_nodes::engine::cache::DiskCache::default_dir))
        };
        let engine = Arc::new(Engine::new(EngineConfig { disk_cache, ..Default::default() }));
        let (host, host_error) = match ViewportHost::new(render_state) {
            Ok(h) => (Some(h), None),
            Err(e) => (None, Some(e)),
        };
        let cpu = host.as_ref().is_some_and(ViewportHost::is_cpu);
        let camera = doc.project.camera(None).unwrap_or_else(|_| default_project().cameras[0].clone());
        let mut app = Self {
            evaluator: Evaluator::new(engine),
            graph: GraphEditor::default(),
            selection: Selection::None,
            previews: Previews::default(),
            view: ViewState {
                camera: OrbitCamera::from_camera(&camera),
                camera_name: camera.name.clone(),
                frame: None,
                frame_error: None,
                drawn: 0,
                resolution_scale: if cpu { 0.5 } else { 1.0 },
                reference: None,
                reference_image: None,
                error: None,
                selected_object: None,
            },
            host,
            host_error: host_error.clone(),
            graph_errors: Vec::new(),
            eval_signature: 0,
            log: Vec::new(),
            bottom_tab: BottomTab::Problems,
            clipboard: None,
            file_dialog: egui_file_dialog::FileDialog::new()
                .add_file_filter_extensions("Lightloom projects", vec!["ron"])
                .default_file_filter("Lightloom projects")
                .add_save_extension("Lightloom project", "ron")
                .default_save_extension("Lightloom project"),
            file_action: None,
            pending: None,
            close_confirmed: false,
            title: String::new(),
            stats: FrameStats::default(),
            screenshot_state: if options.screenshot.is_some() {
                ScreenshotState::Waiting
            } else {
                ScreenshotState::None
            },
            options,
            last_frame: None,
            copy_request: None,
            viewport_rect: egui::Rect::NOTHING,
            graph_rect: egui::Rect::NOTHING,
            last_cpu_ms: None,
            doc,
        };
        if let Some(e) = open_error {
            app.log_error(format!("{e}; opened the built-in default project instead"));
        }
        if let Some(e) = host_error {
            app.log_error(format!("viewport: {e}"));
        } else if let Some(h) = &app.host {
            app.log_info(format!("viewport renders on {}", h.describe()));
        }
        // Start with the Output selected: the inspector shows what the viewport draws.
        if let Some(output) = app.doc.project.nodes.iter().find(|n| n.kind == "Output") {
            app.selection = Selection::Node(output.id.clone());
        }
        if let Some((path, at)) = document::pending_recovery(app.doc.path.as_deref()) {
            app.pending = Some(Pending::Recover(path, at));
        }
        if let Some(p) = app.doc.path.clone() {
            document::remember_recent(&p);
        }
        app.graph.sync(&app.doc.project);
        ctx.request_repaint();
        Ok(app)
    }

    fn log_info(&mut self, text: impl Into<String>) {
        self.log.push(LogLine { at: SystemTime::now(), error: false, text: text.into() });
    }

    fn log_error(&mut self, text: impl Into<String>) {
        self.log.push(LogLine { at: SystemTime::now(), error: true, text: text.into() });
        self.bottom_tab = BottomTab::Problems;
    }

    /// One frame of the editor (public so UI tests can drive it through a harness).
    pub fn frame(&mut self, ui: &mut egui::Ui, render_state: Option<&eframe::egui_wgpu::RenderState>) {
        let start = Instant::now();
        let ctx = ui.ctx().clone();
        let _ = render_state;
        let revision = self.doc.revision();
        self.shortcuts(&ctx);
        self.poll_jobs(&ctx);
        self.submit_if_changed();

        egui::Panel::top("menu").show(ui, |ui| self.menu_bar(ui));
        egui::Panel::bottom("status").resizable(false).show(ui, |ui| self.status_bar(ui));
        egui::Panel::bottom("problems").resizable(true).default_size(150.0).show(ui, |ui| self.bottom_panel(ui));
        egui::Panel::right("inspector").resizable(true).default_size(340.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| self.inspector(ui));
        });
        egui::Panel::left("graph")
            .resizable(true)
            .default_size(ui.available_width() * 0.36)
            .show(ui, |ui| self.graph_panel(ui));
        egui::CentralPanel::default().show(ui, |ui| self.viewport_panel(ui));

        self.dialogs(&ctx);
        if !ctx.input(|i| i.pointer.any_down()) {
            self.doc.seal();
        }
        if self.doc.revision() != revision {
            self.graph.sync(&self.doc.project);
        }
        self.handle_close(&ctx);
        self.autosave();
        let title = self.doc.title();
        if title != self.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.title = title;
        }
        self.screenshot(&ctx);
        if let Some(text) = self.copy_request.take() {
            ctx.copy_text(text);
        }
        let busy = self.evaluator.is_running() || self.view.reference.is_some();
        if busy {
            ctx.request_repaint_after(Duration::from_millis(50));
        }
        let now = Instant::now();
        if let Some(last) = self.last_frame {
            // Time between frames while the UI is being redrawn continuously.
            let gap_ms = now.duration_since(last).as_secs_f64() * 1e3;
            let ui_ms = now.duration_since(start).as_secs_f64() * 1e3;
            self.stats.record(FrameSample { ui_ms, cpu_ms: self.last_cpu_ms, gap_ms, busy });
        }
        self.last_frame = Some(now);
    }

    pub fn on_exit(&mut self) {
        self.evaluator.cancel();
        if let Some(job) = &self.view.reference {
            job.cancel();
        }
        if !self.doc.is_dirty() {
            self.doc.discard_recovery();
        }
    }

    /// UI frame times, idle and while background work runs: the ui pass, eframe's CPU time
    /// per frame, and the interval between frames (a blocked UI thread shows as long gaps).
    pub fn stats_report(&self) -> String {
        let fmt = |v: Option<(usize, f64, f64, f64)>| match v {
            Some((n, mean, p95, max)) => format!("{n} frames, mean {mean:.1} / p95 {p95:.1} / max {max:.1} ms"),
            None => "no frames".into(),
        };
        let mut out = String::from("UI frame times");
        for (busy, name) in [(false, "idle"), (true, "while evaluating or rendering a reference")] {
            out += &format!(
                "\n  {name}:\n    ui pass: {}\n    eframe CPU per frame: {}\n    interval between frames: {}",
                fmt(self.stats.summary(busy, |f| Some(f.ui_ms))),
                fmt(self.stats.summary(busy, |f| f.cpu_ms)),
                fmt(self.stats.summary(busy, |f| Some(f.gap_ms))),
            );
        }
        out
    }

    // ----- evaluation -----

    fn submit_if_changed(&mut self) {
        let signature = eval_signature(&self.doc.project);
        if signature == self.eval_signature {
            return;
        }
        self.eval_signature = signature;
        let dir = self.doc.project_dir();
        let scratch = dir.join("project.ron");
        match self.doc.project.graph(&scratch) {
            Ok(graph) => {
                self.graph_errors.clear();
                self.evaluator.submit(graph, self.doc.revision());
            }
            Err(errors) => {
                self.graph_errors = errors.iter().map(|e| e.to_string()).collect();
                for e in &errors {
                    if let Some(node) = &e.node {
                        self.evaluator.status.insert(node.clone(), NodeStatus::Error(e.message.clone()));
                    }
                }
            }
        }
    }

    fn poll_jobs(&mut self, ctx: &egui::Context) {
        if let Some(evaluation) = self.evaluator.poll() {
            self.on_evaluated(&evaluation);
        }
        if let Some(job) = &mut self.view.reference
            && let Some(result) = job.poll()
        {
            let (signature, seconds) = (job.signature, job.started.elapsed().as_secs_f64());
            self.view.reference = None;
            match result {
                Ok(image) => {
                    self.log_info(format!("reference rendered in {seconds:.1} s ({}x{})", image.width, image.height));
                    self.view.reference_image = Some((signature, Arc::new(image)));
                    self.view.drawn = 0;
                }
                Err(e) if e.contains("cancel") => self.log_info("reference render cancelled"),
                Err(e) => self.log_error(format!("reference render: {e}")),
            }
            ctx.request_repaint();
        }
    }

    fn on_evaluated(&mut self, evaluation: &Evaluation) {
        let Some((_, graph)) = self.evaluator.last.clone() else { return };
        for note in &evaluation.report.notes {
            self.log.push(LogLine { at: SystemTime::now(), error: false, text: note.clone() });
        }
        let failed: Vec<String> = evaluation
            .report
            .failed()
            .iter()
            .filter(|s| s.error.is_some())
            .map(|s| format!("{}.{}: {}", s.node, s.stage, s.error.as_deref().unwrap_or("failed")))
            .collect();
        for f in failed {
            self.log_error(f);
        }
        let output = if self.doc.project.render.output.is_empty() {
            None
        } else {
            Some(self.doc.project.render.output.as_str())
        };
        let gathered = find_output(&graph, output).and_then(|o| FrameInputs::gather(evaluation, &graph, &o.id));
        match gathered {
            Ok(frame) => {
                for note in &frame.ignored_inputs {
                    self.log_info(format!("output: {note}"));
                }
                self.view.frame = Some(Arc::new(frame));
                self.view.frame_error = None;
            }
            Err(e) => self.view.frame_error = Some(e),
        }
        self.view.drawn = 0;
    }

    // ----- shortcuts and menus -----

    fn shortcuts(&mut self, ctx: &egui::Context) {
        use egui::{Key, KeyboardShortcut, Modifiers};
        let typing = ctx.egui_wants_keyboard_input();
        let pressed = |m: Modifiers, k: Key| ctx.input_mut(|i| i.consume_shortcut(&KeyboardShortcut::new(m, k)));
        if pressed(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z) || pressed(Modifiers::COMMAND, Key::Y) {
            self.redo();
        } else if !typing && pressed(Modifiers::COMMAND, Key::Z) {
            self.undo();
        }
        if pressed(Modifiers::COMMAND | Modifiers::SHIFT, Key::S) {
            self.save_as_dialog(false);
        } else if pressed(Modifiers::COMMAND, Key::S) {
            self.save();
        }
        if pressed(Modifiers::COMMAND, Key::O) {
            self.file_action = Some(FileAction::Open);
            self.file_dialog.pick_file();
        }
        if pressed(Modifiers::COMMAND, Key::N) {
            self.request(Pending::New);
        }
        if !typing && pressed(Modifiers::NONE, Key::F5) {
            self.eval_signature = 0;
        }
        if !typing
            && let Some(text) = ctx.input(|i| {
                i.events.iter().find_map(|e| if let egui::Event::Paste(t) = e { Some(t.clone()) } else { None })
            })
        {
            self.paste(Some(&text));
        }
    }

    fn undo(&mut self) {
        if let Some(label) = self.doc.undo_label().map(String::from)
            && self.doc.undo()
        {
            self.log_info(format!("undo: {label}"));
        }
    }

    fn redo(&mut self) {
        if let Some(label) = self.doc.redo_label().map(String::from)
            && self.doc.redo()
        {
            self.log_info(format!("redo: {label}"));
        }
    }

    fn menu_bar(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("New  (Ctrl+N)").clicked() {
                    self.request(Pending::New);
                    ui.close();
                }
                if ui.button("Open…  (Ctrl+O)").clicked() {
                    self.file_action = Some(FileAction::Open);
                    self.file_dialog.pick_file();
                    ui.close();
                }
                ui.menu_button("Open recent", |ui| {
                    let recent = document::recent_files();
                    if recent.is_empty() {
                        ui.weak("no recent projects");
                    }
                    for path in recent {
                        if ui.button(path.display().to_string()).clicked() {
                            self.request(Pending::Open(path));
                            ui.close();
                        }
                    }
                });
                ui.separator();
                if ui.button("Save  (Ctrl+S)").clicked() {
                    self.save();
                    ui.close();
                }
                if ui.button("Save As…  (Ctrl+Shift+S)").clicked() {
                    self.save_as_dialog(false);
                    ui.close();
                }
                ui.separator();
                if ui.button("Quit").clicked() {
                    ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
                    ui.close();
                }
            });
            ui.menu_button("Edit", |ui| {
                let undo = self.doc.undo_label().map_or("Undo".to_string(), |l| format!("Undo {l}"));
                if ui
                    .add_enabled(self.doc.undo_label().is_some(), egui::Button::new(format!("{undo}  (Ctrl+Z)")))
                    .clicked()
                {
                    self.undo();
                    ui.close();
                }
                let redo = self.doc.redo_label().map_or("Redo".to_string(), |l| format!("Redo {l}"));
                if ui
                    .add_enabled(self.doc.redo_label().is_some(), egui::Button::new(format!("{redo}  (Ctrl+Shift+Z)")))
                    .clicked()
                {
                    self.redo();
                    ui.close();
                }
                ui.separator();
                let selected = self.graph.selected.clone();
                let any = !selected.is_empty();
                if ui.add_enabled(any, egui::Button::new("Copy  (Ctrl+C)")).clicked() {
                    self.apply(vec![GraphAction::Copy(selected.clone())]);
                    ui.close();
                }
                if ui.add_enabled(self.clipboard.is_some(), egui::Button::new("Paste  (Ctrl+V)")).clicked() {
                    self.paste(None);
                    ui.close();
                }
                if ui.add_enabled(any, egui::Button::new("Duplicate  (Shift+D)")).clicked() {
                    self.apply(vec![GraphAction::Duplicate(selected.clone())]);
                    ui.close();
                }
                if ui.add_enabled(any, egui::Button::new("Delete  (X)")).clicked() {
                    self.apply(vec![GraphAction::Remove(selected.clone())]);
                    ui.close();
                }
                if ui.add_enabled(selected.len() == 1, egui::Button::new("Rename…  (F2)")).clicked() {
                    self.apply(vec![GraphAction::Rename(selected[0].clone())]);
                    ui.close();
                }
            });
            ui.menu_button("Add", |ui| {
                let mut query = String::new();
                if let Some(kind) = graph_editor::add_list(ui, &mut query, None) {
                    let n = self.doc.project.nodes.len() as f32;
                    self.apply(vec![GraphAction::Add {
                        kind,
                        position: [40.0 + 20.0 * n, 40.0 + 20.0 * n],
                        link: None,
                    }]);
                    ui.close();
                }
            });
            ui.menu_button("Evaluate", |ui| {
                if ui.button("Re-evaluate  (F5)").clicked() {
                    self.eval_signature = 0;
                    ui.close();
                }
                if ui.add_enabled(self.evaluator.is_running(), egui::Button::new("Cancel evaluation")).clicked() {
                    self.evaluator.cancel();
                    ui.close();
                }
            });
        });
    }

    fn status_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            if let Some(p) = &self.evaluator.progress {
                let fraction = if p.total > 0 { p.done as f32 / p.total as f32 } else { 0.0 };
                let running: Vec<String> =
                    p.running.iter().map(|(n, s, f)| format!("{n}.{s} {:.0}%", f * 100.0)).collect();
                ui.add(egui::ProgressBar::new(fraction).desired_width(260.0).text(format!(
                    "evaluating {}/{} {}",
                    p.done,
                    p.total,
                    running.join(", ")
                )));
                ui.label(format!("{:.1} s", p.started.elapsed().as_secs_f64()));
                if ui.button("Cancel").clicked() {
                    self.evaluator.cancel();
                }
            } else if self.evaluator.cancelled_revision.is_some() {
                ui.label("evaluation cancelled — F5 re-evaluates");
            } else if let Some((evaluation, _)) = &self.evaluator.last {
                ui.label(format!("evaluated in {:.0} ms", evaluation.report.total_ms));
            }
            if let Some(job) = &self.view.reference {
                ui.separator();
                ui.add(
                    egui::ProgressBar::new(job.fraction())
                        .desired_width(200.0)
                        .text(format!("reference {}x{}", job.size.0, job.size.1)),
                );
                if ui.button("Cancel reference").clicked() {
                    job.cancel();
                }
            }
            ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                let ui_ms = self.stats.frames.last().map_or(0.0, |f| f.ui_ms);
                let draw_ms = self.host.as_ref().map_or(0.0, |h| h.last_draw_ms);
                ui.weak(format!("UI {ui_ms:.1} ms · viewport draw {draw_ms:.0} ms"));
                if self.doc.is_dirty() {
                    ui.colored_label(Color32::from_rgb(230, 180, 60), "unsaved changes");
                }
            });
        });
    }

    fn bottom_panel(&mut self, ui: &mut egui::Ui) {
        let problems = self.problems();
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.bottom_tab, BottomTab::Problems, format!("Problems ({})", problems.len()));
            ui.selectable_value(&mut self.bottom_tab, BottomTab::Log, "Log");
            ui.selectable_value(&mut self.bottom_tab, BottomTab::Timings, "Stage timings");
        });
        ui.separator();
        egui::ScrollArea::vertical().stick_to_bottom(self.bottom_tab == BottomTab::Log).show(ui, |ui| {
            match self.bottom_tab {
                BottomTab::Problems => {
                    if problems.is_empty() {
                        ui.weak("no problems");
                    }
                    for p in problems {
                        ui.colored_label(Color32::from_rgb(235, 90, 80), p);
                    }
                }
                BottomTab::Log => {
                    for line in &self.log {
                        let at = line.at.duration_since(SystemTime::UNIX_EPOCH).map_or(0, |d| d.as_secs());
                        let text = format!("{:02}:{:02}:{:02}  {}", at / 3600 % 24, at / 60 % 60, at % 60, line.text);
                        if line.error {
                            ui.colored_label(Color32::from_rgb(235, 90, 80), text);
                        } else {
                            ui.label(text);
                        }
                    }
                }
                BottomTab::Timings => self.timings(ui),
            }
        });
    }

    fn problems(&self) -> Vec<String> {
        let mut out = self.graph_errors.clone();
        if let Some(e) = &self.host_error {
            out.push(format!("viewport: {e}"));
        }
        if let Some(e) = &self.view.frame_error {
            out.push(format!("viewport: {e}"));
        }
        if let Some((evaluation, _)) = &self.evaluator.last {
            for s in evaluation.report.failed() {
                out.push(format!(
                    "{}.{}: {}",
                    s.node,
                    s.stage,
                    s.error.as_deref().unwrap_or("blocked by a failed input")
                ));
            }
            for s in &evaluation.report.stages {
                for w in &s.warnings {
                    out.push(format!("{}.{}: warning: {w}", s.node, s.stage));
                }
            }
        }
        for (node, _, path) in self.missing_assets() {
            out.push(format!("node `{node}`: file {} does not exist", path.display()));
        }
        out
    }

    fn missing_assets(&self) -> Vec<(String, String, PathBuf)> {
        match self.doc.project.graph(&self.doc.project_dir().join("project.ron")) {
            Ok(g) => self.doc.project.missing_assets(&g),
            Err(_) => Vec::new(),
        }
    }

    fn timings(&self, ui: &mut egui::Ui) {
        let Some((evaluation, _)) = &self.evaluator.last else {
            ui.weak("nothing evaluated yet");
            return;
        };
        let report = &evaluation.report;
        ui.label(format!(
            "last evaluation: {:.1} ms, memory cache {:.1} MB",
            report.total_ms,
            report.memory_cache_bytes as f64 / 1e6
        ));
        egui::Grid::new("timings").striped(true).show(ui, |ui| {
            ui.strong("node");
            ui.strong("stage");
            ui.strong("status");
            ui.strong("ms");
            ui.strong("why");
            ui.end_row();
            let mut stages: Vec<_> = report.stages.iter().collect();
            stages.sort_by(|a, b| b.ms.total_cmp(&a.ms));
            for s in stages {
                ui.label(&s.node);
                ui.label(s.stage.as_ref());
                ui.label(format!("{:?}", s.status).to_lowercase());
                ui.label(format!("{:.2}", s.ms));
                ui.label(s.reasons.join("; "));
                ui.end_row();
            }
        });
    }

    // ----- graph -----

    fn graph_panel(&mut self, ui: &mut egui::Ui) {
        self.graph_rect = ui.max_rect();
        let evaluation = self.evaluator.last.as_ref().map(|(e, _)| e.clone());
        let actions =
            self.graph.show(ui, &self.doc.project, &self.evaluator.status, evaluation.as_deref(), &mut self.previews);
        if let [id] = self.graph.selected.as_slice()
            && self.selection != Selection::Node(id.clone())
        {
            self.selection = Selection::Node(id.clone());
            self.view.selected_object = None;
        }
        if ui.input(|i| i.key_pressed(egui::Key::F2))
            && !ui.ctx().egui_wants_keyboard_input()
            && let [id] = self.graph.selected.as_slice()
        {
            self.pending = Some(Pending::Rename { node: id.clone(), text: id.clone() });
        }
        self.apply(actions);
    }

    /// Applies graph actions to the document (each an undoable edit).
    pub fn apply(&mut self, actions: Vec<GraphAction>) {
        for action in actions {
            let result: Result<(), String> = match action {
                GraphAction::Add { kind, position, link } => {
                    let result = self.doc.edit(format!("Add {kind}"), None, |p| {
                        let id = edits::add_node(p, &kind, position)?;
                        let spec = edits::kind_of(p, &id).expect("just added");
                        match link {
                            Some(PendingLink::FromOutput(node, port)) => {
                                let ty = edits::kind_of(p, &node).and_then(|k| k.output(&port)).map(|o| o.ty);
                                if let Some(input) = spec.inputs.iter().find(|i| Some(i.ty) == ty) {
                                    edits::connect(p, &(node, port), &(id.clone(), input.name.into()))?;
                                }
                            }
                            Some(PendingLink::ToInput(node, port)) => {
                                let ty = edits::kind_of(p, &node).and_then(|k| k.input(&port)).map(|o| o.ty);
                                if let Some(output) = spec.outputs.iter().find(|o| Some(o.ty) == ty) {
                                    edits::connect(p, &(id.clone(), output.name.into()), &(node, port))?;
                                }
                            }
                            None => {}
                        }
                        Ok(id)
                    });
                    result.map(|id| {
                        self.selection = Selection::Node(id);
                    })
                }
                GraphAction::Connect { from, to } => {
                    self.doc.edit(format!("Link {}.{} → {}.{}", from.0, from.1, to.0, to.1), None, |p| {
                        edits::connect(p, &from, &to)
                    })
                }
                GraphAction::Disconnect { from, to } => {
                    self.doc.edit(format!("Unlink {}.{} → {}.{}", from.0, from.1, to.0, to.1), None, |p| {
                        edits::disconnect(p, &from, &to);
                        Ok(())
                    })
                }
                GraphAction::DisconnectPort { port, input } => {
                    self.doc.edit(format!("Unlink {}.{}", port.0, port.1), None, |p| {
                        edits::disconnect_port(p, &port, input);
                        Ok(())
                    })
                }
                GraphAction::Remove(ids) => {
                    if ids.iter().any(|id| matches!(&self.selection, Selection::Node(s) if s == id)) {
                        self.selection = Selection::None;
                    }
                    self.doc.edit(format!("Delete {}", ids.join(", ")), None, |p| {
                        edits::remove_nodes(p, &ids);
                        Ok(())
                    })
                }
                GraphAction::Duplicate(ids) => {
                    let clipboard = edits::Clipboard::copy(&self.doc.project, &ids);
                    self.doc
                        .edit(format!("Duplicate {}", ids.join(", ")), None, |p| {
                            edits::paste(p, &clipboard, [40.0, 40.0])
                        })
                        .map(|_| ())
                }
                GraphAction::Copy(ids) => {
                    let clipboard = edits::Clipboard::copy(&self.doc.project, &ids);
                    self.graph_copy_text(&clipboard);
                    self.clipboard = Some(clipboard);
                    Ok(())
                }
                GraphAction::Rename(id) => {
                    let text = edits::node(&self.doc.project, &id).map(|n| n.label.clone()).unwrap_or_default();
                    self.pending = Some(Pending::Rename { node: id, text });
                    Ok(())
                }
                GraphAction::Move(moves) => self.doc.edit("Move nodes", Some("move nodes"), |p| {
                    for (id, pos) in &moves {
                        if let Some(n) = p.nodes.iter_mut().find(|n| &n.id == id) {
                            n.position = *pos;
                        }
                    }
                    Ok(())
                }),
                GraphAction::Refused(reason) => Err(reason),
            };
            if let Err(e) = result {
                self.graph.notice = Some((e.clone(), Instant::now()));
                self.log_error(e);
            }
        }
    }

    fn graph_copy_text(&mut self, clipboard: &edits::Clipboard) {
        self.copy_request = Some(clipboard.to_text());
    }

    fn paste(&mut self, text: Option<&str>) {
        let clipboard = text.and_then(edits::Clipboard::from_text).or_else(|| self.clipboard.clone());
        let Some(clipboard) = clipboard else { return };
        let result = self.doc.edit("Paste nodes", None, |p| edits::paste(p, &clipboard, [60.0, 60.0]));
        if let Err(e) = result {
            self.log_error(e);
        }
    }

    // ----- inspector -----

    fn inspector(&mut self, ui: &mut egui::Ui) {
        let Selection::Node(id) = self.selection.clone() else {
            ui.weak("Select a node to edit it, or click an object in the viewport.");
            return;
        };
        if edits::node(&self.doc.project, &id).is_none() {
            self.selection = Selection::None;
            return;
        }
        let report = self.evaluator.last.as_ref().map(|(e, _)| e.report.clone());
        let mut inspector = inspector::Inspector {
            doc: &mut self.doc,
            status: self.evaluator.status.get(&id),
            report: report.as_ref(),
            selected_object: &mut self.view.selected_object,
            requests: Vec::new(),
            errors: Vec::new(),
        };
        inspector.show(ui, &id);
        let (requests, errors) = (inspector.requests, inspector.errors);
        for e in errors {
            self.log_error(e);
        }
        for r in requests {
            let inspector::InspectorRequest::Browse { node, param, extensions } = r;
            self.file_action = Some(FileAction::Browse { node, param });
            self.file_dialog.config_mut().file_filters.clear();
            let _ = extensions;
            self.file_dialog.pick_file();
        }
    }

    // ----- viewport -----

    fn viewport_panel(&mut self, ui: &mut egui::Ui) {
        self.viewport_toolbar(ui);
        let available = ui.available_size();
        let (rect, response) = ui.allocate_exact_size(available, egui::Sense::click_and_drag());
        self.viewport_rect = rect;
        self.navigate(ui, &response, rect);
        let scale = self.view.resolution_scale * ui.ctx().pixels_per_point();
        let size = (((rect.width() * scale) as u32).clamp(16, 4096), ((rect.height() * scale) as u32).clamp(16, 4096));
        self.draw_viewport(ui.ctx(), size);
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::from_gray(20));
        if let Some(id) = self.host.as_ref().and_then(ViewportHost::texture_id) {
            painter.image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                Color32::WHITE,
            );
        }
        self.selection_overlay(&painter, rect);
        let message = if let Some(e) = &self.host_error {
            Some(format!("viewport unavailable: {e}"))
        } else if let Some(e) = &self.view.frame_error {
            Some(e.clone())
        } else if self.view.frame.is_none() {
            Some("evaluating…".into())
        } else {
            None
        };
        if let Some(m) = message {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                m,
                egui::FontId::proportional(16.0),
                Color32::LIGHT_GRAY,
            );
        }
        if let Some(error) = &self.view.error {
            painter.text(
                rect.left_top() + egui::vec2(8.0, 8.0),
                egui::Align2::LEFT_TOP,
                format!(
                    "error vs reference: RMSE {:.4}, relative {:.1}%, PSNR {:.1} dB",
                    error.rmse,
                    error.relative_rmse * 100.0,
                    error.psnr_db
                ),
                egui::FontId::monospace(12.0),
                Color32::WHITE,
            );
        }
        if response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            self.pick(pos, rect);
        }
    }

    fn viewport_toolbar(&mut self, ui: &mut egui::Ui) {
        let Some(output) = self.doc.project.nodes.iter().find(|n| n.kind == "Output").map(|n| n.id.clone()) else {
            ui.weak("no Output node: add one to see the scene");
            return;
        };
        let spec = lightloom_nodes::kinds::kind("Output").expect("Output kind");
        let value = |doc: &Document, name: &str| {
            inspector::param_value(&doc.project, &output, spec.param(name).expect("param"))
        };
        let mut changes: Vec<(&str, ParamValue)> = Vec::new();
        ui.horizontal_wrapped(|ui| {
            for (name, label) in [("view", "View"), ("mode", "Mode"), ("tonemap", "Tone map")] {
                let ParamValue::Choice(current) = value(&self.doc, name) else { continue };
                let lightloom_nodes::graph::ParamKind::Choice { options, .. } = &spec.param(name).expect("param").kind
                else {
                    continue;
                };
                let l = ui.label(label);
                let mut chosen = current.clone();
                egui::ComboBox::from_id_salt(("viewport", name))
                    .selected_text(current.as_str())
                    .show_ui(ui, |ui| {
                        for o in options.iter() {
                            ui.selectable_value(&mut chosen, o.to_string(), *o);
                        }
                    })
                    .response
                    .labelled_by(l.id);
                if chosen != current {
                    changes.push((name, ParamValue::Choice(chosen)));
                }
            }
            if let ParamValue::Float(mut exposure) = value(&self.doc, "exposure") {
                let l = ui.label("Exposure");
                if ui
                    .add(egui::DragValue::new(&mut exposure).range(-20.0..=20.0).speed(0.05).suffix(" EV"))
                    .labelled_by(l.id)
                    .changed()
                {
                    changes.push(("exposure", ParamValue::Float(exposure)));
                }
            }
            ui.separator();
            ui.label("Resolution");
            egui::ComboBox::from_id_salt("resolution")
                .selected_text(format!("{:.0}%", self.view.resolution_scale * 100.0))
                .show_ui(ui, |ui| {
                    for s in [0.25f32, 0.5, 0.75, 1.0] {
                        ui.selectable_value(&mut self.view.resolution_scale, s, format!("{:.0}%", s * 100.0));
                    }
                });
            if ui.button("Frame all").on_hover_text("Home").clicked() || ui.input(|i| i.key_pressed(egui::Key::Home)) {
                self.frame_all();
            }
            if ui.button("Reset view").on_hover_text("back to the project's camera").clicked() {
                let camera =
                    self.doc.project.camera(Some(&self.view.camera_name)).or_else(|_| self.doc.project.camera(None));
                if let Ok(c) = camera {
                    self.view.camera = OrbitCamera::from_camera(&c);
                }
            }
            if ui.button("Save view to camera").on_hover_text("store this view in the project's camera").clicked() {
                let camera = self.view.camera.to_camera(&self.view.camera_name);
                let result = self.doc.edit("Save view to camera", None, |p| {
                    match p.cameras.iter_mut().find(|c| c.name == camera.name) {
                        Some(c) => *c = camera.clone(),
                        None => p.cameras.insert(0, camera.clone()),
                    }
                    Ok(())
                });
                if let Err(e) = result {
                    self.log_error(e);
                }
            }
        });
        for (name, v) in changes {
            if let Err(e) = inspector::set_param(&mut self.doc, &output, name, v) {
                self.log_error(e);
            }
        }
    }

    fn frame_all(&mut self) {
        if let Some(frame) = &self.view.frame
            && let lightloom_nodes::engine::StageValue::Meshes(m) = frame.meshes.value.as_ref()
        {
            self.view.camera.frame(mesh_bounds(m.meshes.iter()));
        }
    }

    /// Blender-style: middle drag orbits, Shift+middle pans, Ctrl+middle or the wheel zooms;
    /// for trackpads, Alt+left drag orbits, Alt+Shift+left pans, pinch zooms; right drag
    /// also orbits.
    fn navigate(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        let (delta, shift, ctrl, alt) =
            ui.input(|i| (i.pointer.delta(), i.modifiers.shift, i.modifiers.command, i.modifiers.alt));
        let delta = (f64::from(delta.x), f64::from(delta.y));
        let height = f64::from(rect.height());
        let middle = response.dragged_by(egui::PointerButton::Middle);
        let left_alt = response.dragged_by(egui::PointerButton::Primary) && alt;
        let right = response.dragged_by(egui::PointerButton::Secondary);
        if middle || left_alt || right {
            if shift {
                self.view.camera.pan(delta, height);
            } else if ctrl && middle {
                self.view.camera.zoom((delta.1 * 0.01).exp());
            } else {
                self.view.camera.orbit(delta, height);
            }
        }
        if response.hovered() {
            let (scroll, zoom) = ui.input(|i| (i.smooth_scroll_delta.y, i.zoom_delta()));
            if scroll != 0.0 {
                self.view.camera.zoom((-f64::from(scroll) * 0.002).exp());
            }
            if zoom != 1.0 {
                self.view.camera.zoom(1.0 / f64::from(zoom));
            }
        }
    }

    fn pick(&mut self, pos: egui::Pos2, rect: egui::Rect) {
        let Some(frame) = &self.view.frame else { return };
        let local = pos - rect.min;
        let size = (rect.width().max(1.0) as usize, rect.height().max(1.0) as usize);
        let camera = self.view.camera.pinhole();
        let Some(mesh) = frame.pick(&camera, (f64::from(local.x), f64::from(local.y)), size) else {
            self.view.selected_object = None;
            return;
        };
        let lightloom_nodes::engine::StageValue::Meshes(meshes) = frame.meshes.value.as_ref() else { return };
        let name = meshes.meshes[mesh].name.split('/').next().unwrap_or_default().to_string();
        // The Scene node feeding the output, and the object with that name.
        let Some((_, graph)) = &self.evaluator.last else { return };
        let Some(output) = graph.nodes.iter().find(|n| n.kind.name == "Output") else { return };
        let Some(scene) = graph.upstream(&output.id, "scene") else { return };
        let Some(ParamValue::Objects(objects)) = scene.params.get("objects") else { return };
        if let Some(index) = objects.iter().position(|o| o.name == name) {
            self.selection = Selection::Node(scene.id.clone());
            self.view.selected_object = Some(index);
            self.log_info(format!("selected object `{name}` of {}", scene.id));
        } else {
            self.selection = Selection::Node(scene.id.clone());
            self.view.selected_object = None;
            self.log_info(format!("`{}` comes from the scene's file", meshes.meshes[mesh].name));
        }
    }

    /// Outlines the selected object's bounding box.
    fn selection_overlay(&self, painter: &egui::Painter, rect: egui::Rect) {
        let (Some(index), Some(frame)) = (self.view.selected_object, &self.view.frame) else { return };
        let Selection::Node(scene_id) = &self.selection else { return };
        let Some(ParamValue::Objects(objects)) =
            edits::node(&self.doc.project, scene_id).and_then(|n| n.params.get("objects"))
        else {
            return;
        };
        let Some(object) = objects.get(index) else { return };
        let lightloom_nodes::engine::StageValue::Meshes(m) = frame.meshes.value.as_ref() else { return };
        let prefix = format!("{}/", object.name);
        let parts: Vec<_> = m.meshes.iter().filter(|x| x.name == object.name || x.name.starts_with(&prefix)).collect();
        if parts.is_empty() {
            return;
        }
        let (lo, hi) = mesh_bounds(parts.into_iter());
        let all = mesh_bounds(m.meshes.iter());
        let view_proj = self.view.camera.view().view_proj(rect.width() / rect.height().max(1.0), all);
        let corner = |i: usize| {
            glam::Vec3::new(
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            )
        };
        let project = |p: glam::Vec3| {
            let c = view_proj * p.extend(1.0);
            (c.w > 1e-4).then(|| {
                egui::pos2(
                    rect.left() + (c.x / c.w * 0.5 + 0.5) * rect.width(),
                    rect.top() + (0.5 - c.y / c.w * 0.5) * rect.height(),
                )
            })
        };
        let stroke = egui::Stroke::new(1.5, Color32::from_rgb(255, 200, 80));
        for (a, b) in [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)] {
            if let (Some(p), Some(q)) = (project(corner(a)), project(corner(b))) {
                painter.line_segment([p, q], stroke);
            }
        }
    }

    /// Redraws when the frame, camera, size or view changed; starts or shows reference renders.
    fn draw_viewport(&mut self, ctx: &egui::Context, size: (u32, u32)) {
        let (Some(host), Some(frame)) = (self.host.as_mut(), self.view.frame.clone()) else { return };
        let settings = &frame.settings;
        let camera = self.view.camera;
        let mut h = std::hash::DefaultHasher::new();
        use std::hash::{Hash, Hasher};
        (Arc::as_ptr(&frame) as usize).hash(&mut h);
        format!("{camera:?}").hash(&mut h);
        size.hash(&mut h);
        let signature = h.finish();
        if settings.view == "approximation" {
            if let Some(job) = self.view.reference.take() {
                job.cancel();
            }
            self.view.error = None;
            if signature != self.view.drawn {
                match host.render(ctx, &frame, &camera.view(), size) {
                    Ok(()) => self.view.drawn = signature,
                    Err(e) => {
                        self.view.frame_error = Some(format!("render failed: {e}"));
                        self.view.drawn = signature;
                    }
                }
            }
            return;
        }
        // Reference and error views: the reference is rendered in the background at the
        // viewport size; meanwhile the approximation stays on screen.
        let have = self.view.reference_image.as_ref().is_some_and(|(s, _)| *s == signature);
        let running = self.view.reference.as_ref().is_some_and(|j| j.signature == signature);
        if !have && !running {
            if let Some(old) = self.view.reference.take() {
                old.cancel();
            }
            self.view.reference = Some(ReferenceJob::spawn(frame.clone(), camera.pinhole(), size, signature));
            let _ = host.render(ctx, &frame, &camera.view(), size);
            self.view.drawn = 0;
            return;
        }
        let Some((_, reference)) = self.view.reference_image.clone().filter(|(s, _)| *s == signature) else { return };
        let view_signature = signature
            ^ xxhash_rust::xxh3::xxh3_64(
                format!("{}{}{}", settings.view, settings.exposure, settings.tonemap).as_bytes(),
            );
        if view_signature == self.view.drawn {
            return;
        }
        self.view.drawn = view_signature;
        // The approximation at the same size, read back for the comparison.
        if let Err(e) = host.render(ctx, &frame, &camera.view(), size) {
            self.view.frame_error = Some(e);
            return;
        }
        let approximation = match host.capture_hdr() {
            Ok(a) => a,
            Err(e) => {
                self.view.frame_error = Some(e);
                return;
            }
        };
        let mask = reference.surface_mask();
        self.view.error = reference::compare(&approximation, &reference.pixels, Some(&mask)).ok();
        let result = if settings.view == "reference" {
            host.present(ctx, &reference.pixels, size, settings.exposure, &settings.tonemap)
        } else {
            let mean = reference.pixels.iter().map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0).sum::<f64>()
                / reference.pixels.len().max(1) as f64;
            let map = reference::error_heat_map(&approximation, &reference.pixels, Some(&mask), (mean * 0.5).max(1e-6));
            host.present(ctx, &map, size, 0.0, "linear")
        };
        if let Err(e) = result {
            self.view.frame_error = Some(e);
        }
    }

    // ----- files -----

    fn save(&mut self) {
        match self.doc.path.clone() {
            Some(path) => self.save_to(&path),
            None => self.save_as_dialog(false),
        }
    }

    fn save_as_dialog(&mut self, then_close: bool) {
        self.file_action = Some(FileAction::SaveAs { then_close });
        self.file_dialog.save_file();
    }

    /// Saves to `path` (atomic, with a `.bak` of the previous file).
    pub fn save_to(&mut self, path: &std::path::Path) {
        match self.doc.save_as(path) {
            Ok(()) => {
                document::remember_recent(path);
                self.log_info(format!("saved {}", path.display()));
            }
            Err(e) => self.log_error(format!("{e:#}")),
        }
    }

    /// Asks first when there are unsaved changes.
    fn request(&mut self, what: Pending) {
        if self.doc.is_dirty() {
            self.pending = Some(what);
        } else {
            self.perform(what);
        }
    }

    fn perform(&mut self, what: Pending) {
        match what {
            Pending::Open(path) => self.open(&path),
            Pending::New => {
                self.doc.discard_recovery();
                self.replace_document(Document::new(default_project(), None));
            }
            Pending::Close => {
                self.close_confirmed = true;
            }
            Pending::Recover(..) | Pending::Rename { .. } => {}
        }
    }

    /// Opens a project file (errors go to the log; the current document stays).
    pub fn open(&mut self, path: &std::path::Path) {
        match Document::open(path) {
            Ok(doc) => {
                self.doc.discard_recovery();
                document::remember_recent(path);
                self.log_info(format!("opened {}", path.display()));
                self.replace_document(doc);
                if let Some((p, at)) = document::pending_recovery(self.doc.path.as_deref()) {
                    self.pending = Some(Pending::Recover(p, at));
                }
            }
            Err(e) => self.log_error(format!("{e:#}")),
        }
    }

    fn replace_document(&mut self, doc: Document) {
        self.doc = doc;
        self.selection = Selection::None;
        self.view.selected_object = None;
        self.view.frame = None;
        self.view.reference_image = None;
        if let Ok(c) = self.doc.project.camera(None) {
            self.view.camera = OrbitCamera::from_camera(&c);
            self.view.camera_name = c.name;
        }
        self.eval_signature = 0;
        self.graph = GraphEditor::default();
        self.graph.sync(&self.doc.project);
    }

    fn dialogs(&mut self, ctx: &egui::Context) {
        self.file_dialog.update(ctx);
        if let Some(path) = self.file_dialog.take_picked() {
            match self.file_action.take() {
                Some(FileAction::Open) => self.request(Pending::Open(path)),
                Some(FileAction::SaveAs { then_close }) => {
                    self.save_to(&path);
                    if then_close && !self.doc.is_dirty() {
                        self.close_confirmed = true;
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                }
                Some(FileAction::Browse { node, param }) => {
                    let dir = std::path::absolute(self.doc.project_dir()).unwrap_or_default();
                    let value = path.strip_prefix(&dir).map_or(path.clone(), PathBuf::from).display().to_string();
                    if let Err(e) = inspector::set_param(&mut self.doc, &node, &param, ParamValue::Path(value)) {
                        self.log_error(e);
                    }
                    self.doc.seal();
                }
                None => {}
            }
        }
        let Some(pending) = self.pending.clone() else { return };
        let modal = egui::Modal::new(egui::Id::new("pending")).show(ctx, |ui| {
            ui.set_max_width(420.0);
            match &pending {
                Pending::Recover(path, at) => {
                    let age = at.elapsed().map_or(0, |d| d.as_secs());
                    ui.heading("Recover unsaved work?");
                    ui.label(format!(
                        "Lightloom did not close cleanly. Autosaved changes from {} minute(s) ago are in {}.",
                        age / 60,
                        path.display()
                    ));
                    ui.horizontal(|ui| {
                        if ui.button("Recover").clicked() {
                            match Document::open(path) {
                                Ok(recovered) => {
                                    let project = recovered.project;
                                    let _ = self.doc.edit("Recover autosaved changes", None, |p| {
                                        *p = project;
                                        Ok(())
                                    });
                                    self.log_info(format!("recovered {}", path.display()));
                                }
                                Err(e) => self.log_error(format!("{e:#}")),
                            }
                            self.pending = None;
                        }
                        if ui.button("Discard").clicked() {
                            let _ = std::fs::remove_file(path);
                            self.pending = None;
                        }
                    });
                }
                Pending::Rename { node, text } => {
                    ui.heading(format!("Rename {node}"));
                    let mut text = text.clone();
                    let r = ui.text_edit_singleline(&mut text);
                    r.request_focus();
                    let done = ui.input(|i| i.key_pressed(egui::Key::Enter));
                    self.pending = Some(Pending::Rename { node: node.clone(), text: text.clone() });
                    ui.horizontal(|ui| {
                        if ui.button("Rename").clicked() || done {
                            let node = node.clone();
                            let result = self.doc.edit(format!("Rename {node}"), None, |p| {
                                let n = p.nodes.iter_mut().find(|n| n.id == node).ok_or("node vanished")?;
                                n.label = text.trim().to_string();
                                Ok(())
                            });
                            if let Err(e) = result {
                                self.log_error(e);
                            }
                            self.pending = None;
                        }
                        if ui.button("Cancel").clicked() {
                            self.pending = None;
                        }
                    });
                }
                what => {
                    ui.heading("Save changes?");
                    ui.label(format!(
                        "{} has unsaved changes.",
                        self.doc.path.as_ref().map_or("This project".into(), |p| p.display().to_string())
                    ));
                    ui.horizontal(|ui| {
                        if ui.button("Save").clicked() {
                            self.pending = None;
                            match self.doc.path.clone() {
                                Some(p) => {
                                    self.save_to(&p);
                                    if !self.doc.is_dirty() {
                                        self.perform(what.clone());
                                    }
                                }
                                None => self.save_as_dialog(matches!(what, Pending::Close)),
                            }
                        }
                        if ui.button("Discard changes").clicked() {
                            self.pending = None;
                            self.doc.discard_recovery();
                            self.perform(what.clone());
                        }
                        if ui.button("Cancel").clicked() {
                            self.pending = None;
                        }
                    });
                }
            }
        });
        if modal.should_close() && !matches!(pending, Pending::Recover(..)) {
            self.pending = None;
        }
        if self.close_confirmed && matches!(pending, Pending::Close) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }

    fn handle_close(&mut self, ctx: &egui::Context) {
        if ctx.input(|i| i.viewport().close_requested()) && !self.close_confirmed && self.doc.is_dirty() {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.pending = Some(Pending::Close);
        }
    }

    fn autosave(&mut self) {
        if self.close_confirmed {
            return;
        }
        match self.doc.autosave(AUTOSAVE_INTERVAL) {
            Ok(Some(path)) => self.log_info(format!("autosaved to {}", path.display())),
            Ok(None) => {}
            Err(e) => self.log_error(format!("autosave failed: {e:#}")),
        }
    }

    /// With `--screenshot`: once the first evaluation is on screen, capture the window, save
    /// it, and close.
    fn screenshot(&mut self, ctx: &egui::Context) {
        match self.screenshot_state {
            ScreenshotState::Waiting
                if self.view.frame.is_some() && self.view.drawn != 0 && !self.evaluator.is_running() =>
            {
                ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(egui::UserData::default()));
                self.screenshot_state = ScreenshotState::Requested;
            }
            ScreenshotState::Requested => {
                let image = ctx.input(|i| {
                    i.events.iter().find_map(|e| match e {
                        egui::Event::Screenshot { image, .. } => Some(image.clone()),
                        _ => None,
                    })
                });
                if let Some(image) = image {
                    let path = self.options.screenshot.clone().expect("screenshot path");
                    let saved =
                        image::RgbaImage::from_raw(image.size[0] as u32, image.size[1] as u32, image.as_raw().to_vec())
                            .ok_or_else(|| "bad screenshot size".to_string())
                            .and_then(|img| img.save(&path).map_err(|e| e.to_string()));
                    let ppp = ctx.pixels_per_point();
                    let px = |r: egui::Rect| {
                        format!(
                            "{:.0},{:.0},{:.0},{:.0}",
                            r.left() * ppp,
                            r.top() * ppp,
                            r.right() * ppp,
                            r.bottom() * ppp
                        )
                    };
                    match saved {
                        Ok(()) => println!(
                            "screenshot: {} ({}x{}); graph {}; viewport {}",
                            path.display(),
                            image.size[0],
                            image.size[1],
                            px(self.graph_rect),
                            px(self.viewport_rect)
                        ),
                        Err(e) => eprintln!("screenshot failed: {e}"),
                    }
                    self.screenshot_state = ScreenshotState::Done;
                    self.close_confirmed = true;
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
                ctx.request_repaint();
            }
            ScreenshotState::Waiting => ctx.request_repaint_after(Duration::from_millis(100)),
            _ => {}
        }
    }
}

/// Axis-aligned bounds of meshes.
fn mesh_bounds<'a>(meshes: impl Iterator<Item = &'a lightloom_nodes::mesh::Mesh>) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for m in meshes {
        for p in &m.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    (lo, hi)
}
