//! The editor: node graph, 3D viewport, inspector, problems/log and timings, with undo/redo,
//! saves, autosave and recovery. Evaluation and reference renders run off the UI thread.
//!
//! Layout: menu bar on top; status bar (evaluation progress, Cancel, frame time) at the
//! bottom with the problems/log/timings panel above it; inspector on the right; graph on
//! the left; viewport in the centre.

mod bake;
pub mod document;
pub mod edits;
mod files;
mod frame_stats;
mod gizmos;
mod graph_actions;
pub mod graph_editor;
pub mod inspector;
pub mod jobs;
mod menus;
pub mod orbit;
pub mod paint_canvas;
pub mod previews;
pub mod viewport;
mod viewport_panel;

#[cfg(test)]
mod ui_tests;

use document::Document;
use eframe::egui::{self, Color32};
pub use frame_stats::{FrameSample, FrameStats};
use graph_editor::{GraphAction, GraphEditor, PendingLink};
use jobs::{Evaluator, NodeStatus, ReferenceJob};
use lightloom_nodes::engine::spec::ParamValue;
use lightloom_nodes::engine::{Engine, EngineConfig, Evaluation};
use lightloom_nodes::frame::FrameInputs;
use lightloom_nodes::kinds::output::{View, find_output};
use lightloom_nodes::project::{Project, default_project};
use lightloom_nodes::reference::{HdrImage, ImageError};
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
    /// Delays every viewport frame (tests of a slow adapter).
    pub viewport_slow_down: Duration,
    /// Disk cache for expensive stages (`None`: the default folder).
    pub cache_dir: Option<PathBuf>,
    pub no_disk_cache: bool,
    /// Print UI frame-time statistics when the editor closes.
    pub frame_stats: bool,
    /// Append a line here whenever the view settles or the project is saved.
    pub status_file: Option<PathBuf>,
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
    Browse { node: String, target: inspector::FileTarget },
}

/// A question that needs an answer before going on.
#[derive(Clone, Debug)]
enum Pending {
    /// Unsaved changes, and the user asked to do this.
    Close,
    Open(PathBuf),
    /// Open a copy of the built-in sample with this file stem (untitled, so saving never
    /// changes the sample).
    OpenSample(String),
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

/// Where the viewport starts on a project: its saved view (else its render camera), and the
/// name of the camera "Save view to camera" writes.
fn initial_view(project: &Project) -> (OrbitCamera, String) {
    let camera = project.camera(None).unwrap_or_else(|_| default_project().cameras[0].clone());
    let name = Some(project.render.camera.clone())
        .filter(|n| !n.is_empty())
        .or_else(|| project.cameras.first().map(|c| c.name.clone()))
        .unwrap_or_else(|| "main".into());
    (OrbitCamera::from_camera(&camera), name)
}

/// The viewport's view of the output: what it last drew and what it needs.
struct ViewState {
    camera: OrbitCamera,
    /// Project camera the orbit started from.
    camera_name: String,
    frame: Option<Arc<FrameInputs>>,
    /// Counts the frames gathered, so a new frame always has a new draw signature.
    frame_generation: u64,
    frame_error: Option<String>,
    /// Signature of what is on screen; redraw when it changes.
    drawn: u64,
    resolution_scale: f32,
    reference: Option<ReferenceJob>,
    /// The finished reference for a signature, and the approximation's error against it.
    reference_image: Option<(u64, Arc<HdrImage>)>,
    error: Option<ImageError>,
    /// The error view's scale (the radiance difference of its top colour).
    error_scale: Option<f64>,
    selected_object: Option<usize>,
    /// The gizmo (light or blocker sphere) being dragged.
    dragging_gizmo: Option<gizmos::GizmoId>,
    /// The Scene node and the name of the object being dragged in the viewport.
    dragging_object: Option<(String, String)>,
}

pub struct EditorApp {
    pub doc: Document,
    pub evaluator: Evaluator,
    pub graph: GraphEditor,
    pub selection: Selection,
    previews: Previews,
    paint_canvas: paint_canvas::PaintCanvas,
    /// Per area light: its painted texture as the viewport previews it, and the stage key.
    light_previews: std::collections::HashMap<String, (lightloom_nodes::engine::Key, egui::TextureHandle)>,
    view: ViewState,
    host: Option<ViewportHost>,
    host_error: Option<String>,
    graph_errors: Vec<String>,
    /// Hash of what evaluation reads (nodes, parameters, links): positions and labels excluded.
    eval_signature: u64,
    /// The view area-light highlights are computed for: the viewport camera's position once it
    /// has rested, and where and since when the camera was last seen moving.
    highlight_eye: Option<[f64; 3]>,
    camera_seen: ([f64; 3], std::time::Instant),
    /// The document revision and folder last checked for changes, and the graph built from
    /// them (valid projects only): both are per edit, not per frame.
    checked_revision: Option<(u64, PathBuf)>,
    built_graph: Option<lightloom_nodes::engine::Graph>,
    log: Vec<LogLine>,
    /// Errors of the user's own actions, listed with the problems: a failed save or open
    /// (`None`) until the next successful one, others while the document is at the revision
    /// they happened in (an undo takes them away with the state they were about).
    action_errors: Vec<(Option<u64>, String)>,
    /// The document revision the graph widget last matched: it is brought up to date just
    /// before it is shown (an undo must reach the widget before it reads node positions back,
    /// or it would redo the move it shows). `u64::MAX` forces a sync.
    graph_revision: u64,
    bottom_tab: BottomTab,
    clipboard: Option<edits::Clipboard>,
    file_dialog: egui_file_dialog::FileDialog,
    /// The Browse… dialog of a file parameter, while open.
    asset_dialog: Option<egui_file_dialog::FileDialog>,
    /// The Render image… dialog, while open.
    image_dialog: Option<egui_file_dialog::FileDialog>,
    /// A render of the view to an image file, while it runs.
    image_render: Option<files::ImageRender>,
    /// The Bake… folder dialog, while open.
    bake_dialog: Option<egui_file_dialog::FileDialog>,
    /// Tests: the bake's thread waits here between its evaluation and its files.
    #[cfg(test)]
    bake_hold: Option<std::sync::Arc<std::sync::Barrier>>,
    /// A bake, while it runs.
    bake: Option<bake::BakeJob>,
    file_action: Option<FileAction>,
    pending: Option<Pending>,
    close_confirmed: bool,
    title: String,
    pub stats: FrameStats,
    options: EditorOptions,
    /// When the editor started (status lines).
    started: Instant,
    /// The last `--status-file` state written.
    last_status: String,
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
            let app = EditorApp::new(&cc.egui_ctx, options)?;
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
        self.frame(ui);
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
    /// An editor on `options.project` (a copy of the sample it names if `sample:NAME`, or the
    /// default project). The viewport renders on its own device on a render thread (see
    /// `viewport.rs`).
    pub fn new(ctx: &egui::Context, options: EditorOptions) -> anyhow::Result<Self> {
        let opened = match &options.project {
            Some(arg) => match crate::samples::named(arg) {
                Some(stem) => files::sample_copy(stem).map(|(copy, _)| copy),
                None => Document::open(arg),
            }
            .map(Some),
            None => Ok(None),
        };
        let (doc, open_error) = match opened {
            Ok(doc) => (doc.unwrap_or_else(|| Document::new(default_project(), None)), None),
            Err(e) => (Document::new(default_project(), None), Some(format!("{e:#}"))),
        };
        let disk_cache = if options.no_disk_cache {
            None
        } else {
            Some(options.cache_dir.clone().unwrap_or_else(lightloom_nodes::engine::cache::DiskCache::default_dir))
        };
        let engine = Arc::new(Engine::new(EngineConfig { disk_cache, ..Default::default() }));
        let (host, host_error) = match ViewportHost::new(ctx, options.viewport_slow_down) {
            Ok(h) => (Some(h), None),
            Err(e) => (None, Some(e)),
        };
        let cpu = host.as_ref().is_some_and(ViewportHost::is_cpu);
        let (camera, camera_name) = initial_view(&doc.project);
        let mut app = Self {
            evaluator: Evaluator::new(engine),
            graph: GraphEditor::default(),
            selection: Selection::None,
            previews: Previews::default(),
            paint_canvas: Default::default(),
            light_previews: Default::default(),
            view: ViewState {
                camera,
                camera_name,
                frame: None,
                frame_generation: 0,
                frame_error: None,
                drawn: 0,
                resolution_scale: if cpu { 0.5 } else { 1.0 },
                reference: None,
                reference_image: None,
                error: None,
                error_scale: None,
                selected_object: None,
                dragging_gizmo: None,
                dragging_object: None,
            },
            host,
            host_error: host_error.clone(),
            graph_errors: Vec::new(),
            eval_signature: 0,
            highlight_eye: None,
            camera_seen: ([f64::NAN; 3], std::time::Instant::now()),
            checked_revision: None,
            built_graph: None,
            log: Vec::new(),
            action_errors: Vec::new(),
            graph_revision: u64::MAX,
            bottom_tab: BottomTab::Problems,
            clipboard: None,
            file_dialog: egui_file_dialog::FileDialog::new()
                .add_file_filter_extensions("Lightloom projects", vec!["ron"])
                .default_file_filter("Lightloom projects")
                .add_save_extension("Lightloom project", "ron")
                .default_save_extension("Lightloom project"),
            asset_dialog: None,
            image_dialog: None,
            image_render: None,
            bake_dialog: None,
            #[cfg(test)]
            bake_hold: None,
            bake: None,
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
            started: Instant::now(),
            last_status: String::new(),
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
        ctx.request_repaint();
        Ok(app)
    }

    fn log_info(&mut self, text: impl Into<String>) {
        self.log.push(LogLine { at: SystemTime::now(), error: false, text: text.into() });
    }

    fn log_error(&mut self, text: impl Into<String>) {
        self.log_action_error(Some(self.doc.revision()), text.into());
    }

    /// A failed save or open: listed until the next successful one.
    fn log_file_error(&mut self, text: impl Into<String>) {
        self.log_action_error(None, text.into());
    }

    fn log_action_error(&mut self, revision: Option<u64>, text: String) {
        self.action_errors.push((revision, text.clone()));
        if self.action_errors.len() > 5 {
            self.action_errors.remove(0);
        }
        self.log.push(LogLine { at: SystemTime::now(), error: true, text });
        self.bottom_tab = BottomTab::Problems;
    }

    /// One frame of the editor (public so UI tests can drive it through a harness).
    pub fn frame(&mut self, ui: &mut egui::Ui) {
        let start = Instant::now();
        let ctx = ui.ctx().clone();
        self.shortcuts(&ctx);
        self.poll_jobs(&ctx);
        self.follow_view_for_highlights(&ctx);
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
        self.poll_image_render(&ctx);
        self.poll_bake(&ctx);
        if !ctx.input(|i| i.pointer.any_down()) {
            self.doc.seal();
        }
        self.handle_close(&ctx);
        self.autosave();
        let title = self.doc.title();
        if title != self.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.title = title;
        }
        self.screenshot(&ctx);
        self.report_status(&ctx);
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

    /// Evaluates again even if nothing changed (F5, a new document).
    pub(super) fn request_evaluation(&mut self) {
        self.eval_signature = 0;
        self.checked_revision = None;
    }

    /// Area-light highlights hold for one viewpoint (a glossy transport per view): once the
    /// viewport camera rests somewhere new, they are recomputed for it.
    fn follow_view_for_highlights(&mut self, ctx: &egui::Context) {
        const REST: std::time::Duration = std::time::Duration::from_millis(400);
        if !self.doc.project.nodes.iter().any(|n| n.kind == "AreaLightPainter") {
            return;
        }
        let eye = self.view.camera.to_camera("").position;
        if eye != self.camera_seen.0 {
            self.camera_seen = (eye, std::time::Instant::now());
            ctx.request_repaint_after(REST);
        } else if self.highlight_eye != Some(eye) {
            if self.camera_seen.1.elapsed() >= REST {
                self.highlight_eye = Some(eye);
                self.checked_revision = None;
            } else {
                ctx.request_repaint_after(REST);
            }
        }
    }

    fn submit_if_changed(&mut self) {
        // Relative asset paths resolve against the project's folder, which Save As can change.
        let dir = self.doc.project_dir();
        let checked = Some((self.doc.revision(), dir.clone()));
        if self.checked_revision == checked {
            return;
        }
        self.checked_revision = checked;
        let eye: Vec<u8> = self.highlight_eye.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let signature = eval_signature(&self.doc.project)
            ^ xxhash_rust::xxh3::xxh3_64(dir.as_os_str().as_encoded_bytes())
            ^ xxhash_rust::xxh3::xxh3_64(&eye);
        if signature == self.eval_signature {
            return;
        }
        self.eval_signature = signature;
        let scratch = dir.join("project.ron");
        match self.doc.project.graph_seen_from(&scratch, self.highlight_eye) {
            Ok(graph) => {
                self.graph_errors = graph.warnings.iter().map(|w| format!("warning: {w}")).collect();
                self.built_graph = Some(graph.clone());
                let request = self.evaluation_request(&graph);
                self.evaluator.submit(graph, request, self.doc.revision());
            }
            Err(errors) => {
                self.built_graph = None;
                self.graph_errors = errors.iter().map(|e| e.to_string()).collect();
                for e in &errors {
                    if let Some(node) = &e.node {
                        self.evaluator.status.insert(node.clone(), NodeStatus::Error(e.message.clone()));
                    }
                }
            }
        }
    }

    /// What the editor needs evaluated: the Output's mode and view (with the BVH for picking),
    /// then the previews of nodes that show one.
    fn evaluation_request(&self, graph: &lightloom_nodes::engine::Graph) -> lightloom_nodes::engine::Request {
        let output = self.doc.project.render.output_node();
        let request = match find_output(graph, output) {
            Ok(o) => {
                // A viewport relighting on the CPU has the engine relight the wavelet modes.
                let relight_on_cpu = self.host.as_ref().is_some_and(ViewportHost::relights_on_cpu);
                let needs = lightloom_nodes::frame::FrameNeeds { picking: true, relight_on_cpu };
                lightloom_nodes::frame::frame_request_for(graph, &o.id, needs)
            }
            Err(_) => lightloom_nodes::engine::Request::default(),
        };
        let previews: Vec<_> = graph
            .nodes
            .iter()
            .flat_map(|n| {
                previews::preview_stages(n.kind).map(|s| lightloom_nodes::engine::StageRef::new(n.id.clone(), s))
            })
            .collect();
        request.with_first("node previews", previews)
    }

    fn poll_jobs(&mut self, ctx: &egui::Context) {
        if let Some(evaluation) = self.evaluator.poll() {
            // A preview tier's notes and failures come again with the final evaluation.
            let log = !self.evaluator.is_running();
            self.on_evaluated(&evaluation, log);
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

    fn on_evaluated(&mut self, evaluation: &Evaluation, log: bool) {
        let Some((_, graph)) = self.evaluator.last.clone() else { return };
        let notes = if log { evaluation.report.notes.as_slice() } else { &[] };
        for note in notes {
            self.log.push(LogLine { at: SystemTime::now(), error: false, text: note.clone() });
        }
        let failed: Vec<String> = evaluation
            .report
            .failed()
            .iter()
            .filter(|s| log && s.error.is_some())
            .map(|s| format!("{}.{}: {}", s.node, s.stage, s.error.as_deref().unwrap_or("failed")))
            .collect();
        for f in failed {
            self.log_error(f);
        }
        let output = self.doc.project.render.output_node();
        let gathered = find_output(&graph, output).and_then(|o| FrameInputs::gather(evaluation, &graph, &o.id));
        match gathered {
            Ok(frame) => {
                for note in frame.ignored_inputs.iter().filter(|_| log) {
                    self.log_info(format!("output: {note}"));
                }
                self.view.frame = Some(Arc::new(frame));
                self.view.frame_generation += 1;
                self.view.frame_error = None;
            }
            Err(e) => self.view.frame_error = Some(e),
        }
        self.view.drawn = 0;
    }
}
