//! The 3D viewport's GPU side, off the UI thread. A render thread owns the renderer on its own
//! wgpu device (on a software rasteriser a shared queue would make every UI frame wait for the
//! viewport), draws the newest job, reads the tone-mapped image back and hands it to the UI,
//! which shows the last finished frame while the next one renders.

use eframe::egui;
use lightloom_nodes::frame::FrameInputs;
use lightloom_nodes::kinds::output::{Tonemap, View};
use lightloom_nodes::reference::{self, HdrImage, ImageError};
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError};
use std::time::{Duration, Instant};

/// What to draw.
pub enum Job {
    /// The approximation.
    Render { frame: Arc<FrameInputs>, camera: CameraView, size: (u32, u32) },
    /// The reference, or the error heat map of the approximation against it, through the
    /// frame's exposure and tone mapping.
    Compare { frame: Arc<FrameInputs>, camera: CameraView, size: (u32, u32), reference: Arc<HdrImage>, view: View },
}

/// A finished job.
pub struct Finished {
    /// The caller's signature of the job.
    pub signature: u64,
    pub size: (u32, u32),
    /// Tone-mapped sRGB bytes (moved into the host once shown).
    pub ldr: Vec<[u8; 4]>,
    /// For [`Job::Compare`]: the approximation's error against the reference.
    pub error: Option<ImageError>,
    /// For the error view: the radiance difference the heat map's top colour stands for.
    pub error_scale: Option<f64>,
    pub draw_ms: f64,
}

pub struct ViewportHost {
    /// `None` once dropping: the render thread then finishes its job and exits.
    jobs: Option<Sender<(u64, Job)>>,
    thread: Option<std::thread::JoinHandle<()>>,
    finished: Receiver<Result<Finished, (u64, String)>>,
    texture: Option<egui::TextureHandle>,
    description: String,
    cpu: bool,
    /// Whether its renderer relights the wavelet modes on the CPU (the frames it is sent then
    /// bring them relit by the engine).
    relights_on_cpu: bool,
    /// Signature of the newest job sent, and of the frame on screen.
    pub requested: Option<u64>,
    pub shown: Option<u64>,
    /// Size of the image on screen now.
    pub size: (u32, u32),
    /// Milliseconds the last frame took on the render thread.
    pub last_draw_ms: f64,
    /// The tone-mapped pixels on screen (what the renderer wrote).
    last_ldr: Vec<[u8; 4]>,
}

impl ViewportHost {
    /// Starts the render thread on its own device. `slow_down` delays every job (tests of a
    /// slow adapter).
    pub fn new(ctx: &egui::Context, slow_down: Duration) -> Result<Self, String> {
        let gpu = GpuContext::headless().map_err(|e| e.to_string())?;
        let description = gpu.describe();
        let cpu = gpu.adapter.get_info().device_type == eframe::wgpu::DeviceType::Cpu;
        let relights_on_cpu = lightloom_render::RelightOn::from_env().on_cpu(&gpu);
        let (jobs, job_rx) = std::sync::mpsc::channel::<(u64, Job)>();
        let (done_tx, finished) = std::sync::mpsc::channel();
        let repaint = ctx.clone();
        let thread = std::thread::Builder::new()
            .name("lightloom-viewport".into())
            .spawn(move || render_thread(gpu, job_rx, done_tx, &repaint, slow_down))
            .map_err(|e| format!("cannot start the viewport thread: {e}"))?;
        Ok(Self {
            jobs: Some(jobs),
            thread: Some(thread),
            finished,
            texture: None,
            description,
            cpu,
            relights_on_cpu,
            requested: None,
            shown: None,
            size: (0, 0),
            last_draw_ms: 0.0,
            last_ldr: Vec::new(),
        })
    }

    /// "adapter (backend, type)".
    pub fn describe(&self) -> String {
        self.description.clone()
    }

    /// Software rasteriser (lavapipe, llvmpipe)? The editor then renders at a lower resolution.
    pub fn is_cpu(&self) -> bool {
        self.cpu
    }

    /// Whether frames for it should bring the wavelet modes relit by the engine.
    pub fn relights_on_cpu(&self) -> bool {
        self.relights_on_cpu
    }

    /// Queues a job unless it is the one already requested; the render thread skips to the
    /// newest job, so a stream of camera moves never queues up.
    pub fn request(&mut self, signature: u64, job: Job) {
        if self.requested == Some(signature) {
            return;
        }
        self.requested = Some(signature);
        if let Some(jobs) = &self.jobs {
            let _ = jobs.send((signature, job));
        }
    }

    /// Whether a requested frame is still rendering.
    pub fn is_busy(&self) -> bool {
        self.requested.is_some() && self.requested != self.shown
    }

    /// Shows frames that finished since the last call; returns the newest, or its error.
    pub fn poll(&mut self, ctx: &egui::Context) -> Option<Result<Finished, String>> {
        let mut newest = None;
        loop {
            match self.finished.try_recv() {
                Ok(result) => newest = Some(result),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    // Reported once; afterwards nothing is requested or polled.
                    self.jobs.take()?;
                    self.requested = self.shown;
                    return Some(Err("the viewport thread stopped; restart the editor to draw again".into()));
                }
            }
        }
        match newest? {
            Ok(mut done) => {
                let image = egui::ColorImage::from_rgba_unmultiplied(
                    [done.size.0 as usize, done.size.1 as usize],
                    done.ldr.as_flattened(),
                );
                match &mut self.texture {
                    Some(h) => h.set(image, egui::TextureOptions::LINEAR),
                    None => self.texture = Some(ctx.load_texture("viewport", image, egui::TextureOptions::LINEAR)),
                }
                self.shown = Some(done.signature);
                self.size = done.size;
                self.last_draw_ms = done.draw_ms;
                self.last_ldr = std::mem::take(&mut done.ldr);
                Some(Ok(done))
            }
            Err((signature, e)) => {
                self.shown = Some(signature);
                Some(Err(e))
            }
        }
    }

    /// The tone-mapped pixels on screen (sRGB bytes), as the renderer wrote them.
    #[cfg(test)]
    pub fn capture_ldr(&self) -> Result<Vec<[u8; 4]>, String> {
        Ok(self.last_ldr.clone())
    }

    /// The texture egui draws, once something was rendered.
    pub fn texture_id(&self) -> Option<egui::TextureId> {
        self.texture.as_ref().map(|h| h.id())
    }
}

impl Drop for ViewportHost {
    /// Stops the render thread and waits for it, so its device is torn down before the
    /// process exits (a GPU driver still rendering at exit can crash).
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

fn render_thread(
    gpu: GpuContext,
    jobs: Receiver<(u64, Job)>,
    done: Sender<Result<Finished, (u64, String)>>,
    repaint: &egui::Context,
    slow_down: Duration,
) {
    let mut renderer = ViewportRenderer::new(&gpu);
    while let Ok(mut job) = jobs.recv() {
        // Only the newest job matters.
        while let Ok(newer) = jobs.try_recv() {
            job = newer;
        }
        let (signature, job) = job;
        let start = Instant::now();
        std::thread::sleep(slow_down);
        let result = run(&gpu, &mut renderer, job).map(|(size, ldr, error, error_scale)| Finished {
            signature,
            size,
            ldr,
            error,
            error_scale,
            draw_ms: start.elapsed().as_secs_f64() * 1e3,
        });
        if done.send(result.map_err(|e| (signature, e))).is_err() {
            return;
        }
        // The UI may be idle (no input, no evaluation): wake it to show the frame.
        repaint.request_repaint();
    }
}

type Drawn = ((u32, u32), Vec<[u8; 4]>, Option<ImageError>, Option<f64>);

fn run(gpu: &GpuContext, renderer: &mut ViewportRenderer, job: Job) -> Result<Drawn, String> {
    let text = |e: lightloom_render::RenderError| e.to_string();
    match job {
        Job::Render { frame, camera, size } => {
            renderer.render(gpu, &frame, &camera, size.0, size.1).map_err(|e| format!("render failed: {e}"))?;
            Ok((size, renderer.capture(gpu).map_err(text)?.ldr, None, None))
        }
        Job::Compare { frame, camera, size, reference, view } => {
            // The approximation at the reference's size, read back for the comparison.
            renderer.render(gpu, &frame, &camera, size.0, size.1).map_err(|e| format!("render failed: {e}"))?;
            let approximation: Vec<[f32; 3]> =
                renderer.capture(gpu).map_err(text)?.hdr.iter().map(|p| [p[0], p[1], p[2]]).collect();
            let mask = reference.surface_mask();
            let error = reference::compare(&approximation, &reference.pixels, Some(&mask)).ok();
            let settings = &frame.settings;
            let mut error_scale = None;
            if view == View::Reference {
                renderer.present(gpu, &reference.pixels, size, settings.exposure, settings.tonemap).map_err(text)?;
            } else {
                let scale = reference::error_map_scale(&reference.pixels);
                let map = reference::error_heat_map(&approximation, &reference.pixels, Some(&mask), scale);
                renderer.present(gpu, &map, size, 0.0, Tonemap::Linear).map_err(text)?;
                error_scale = Some(scale);
            }
            Ok((size, renderer.capture(gpu).map_err(text)?.ldr, error, error_scale))
        }
    }
}
