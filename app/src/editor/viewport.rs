//! The 3D viewport's GPU side: draws frames with the renderer crate and hands the tone-mapped
//! image to egui. In the editor window it shares eframe's wgpu device and shows the render
//! target directly; where there is no window device (UI tests) it renders on a headless
//! device and uploads the read-back pixels.

use eframe::egui;
use eframe::egui_wgpu;
use lightloom_nodes::kinds::output::{FrameInputs, Tonemap};
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use std::sync::Arc;
use std::time::Instant;

enum Display {
    /// eframe's renderer shows our target texture (same device).
    Native { renderer: Arc<egui::mutex::RwLock<egui_wgpu::Renderer>>, id: Option<egui::TextureId>, size: (u32, u32) },
    /// Read back to the CPU and uploaded as an egui texture.
    Uploaded(Option<egui::TextureHandle>),
}

pub struct ViewportHost {
    gpu: GpuContext,
    renderer: ViewportRenderer,
    display: Display,
    /// Size of the image on screen now.
    pub size: (u32, u32),
    /// Milliseconds the last draw took on the UI thread (submit, and readback when uploading).
    pub last_draw_ms: f64,
}

impl ViewportHost {
    pub fn new(render_state: Option<&egui_wgpu::RenderState>) -> Result<Self, String> {
        let (gpu, display) = match render_state {
            Some(rs) => (
                GpuContext::from_parts(rs.instance.clone(), rs.adapter.clone(), rs.device.clone(), rs.queue.clone()),
                Display::Native { renderer: rs.renderer.clone(), id: None, size: (0, 0) },
            ),
            None => (GpuContext::headless().map_err(|e| e.to_string())?, Display::Uploaded(None)),
        };
        let renderer = ViewportRenderer::new(&gpu);
        Ok(Self { gpu, renderer, display, size: (0, 0), last_draw_ms: 0.0 })
    }

    /// "adapter (backend, type)".
    pub fn describe(&self) -> String {
        self.gpu.describe()
    }

    /// Software rasteriser (lavapipe, llvmpipe)? The editor then renders at a lower resolution.
    pub fn is_cpu(&self) -> bool {
        self.gpu.adapter.get_info().device_type == eframe::wgpu::DeviceType::Cpu
    }

    /// Draws a frame of the approximation.
    pub fn render(
        &mut self,
        ctx: &egui::Context,
        frame: &FrameInputs,
        camera: &CameraView,
        size: (u32, u32),
    ) -> Result<(), String> {
        let start = Instant::now();
        self.renderer.render(&self.gpu, frame, camera, size.0, size.1).map_err(|e| e.to_string())?;
        self.size = size;
        self.publish(ctx)?;
        self.last_draw_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Shows a CPU image (the reference, an error map) through the same tone mapping.
    pub fn present(
        &mut self,
        ctx: &egui::Context,
        pixels: &[[f32; 3]],
        size: (u32, u32),
        exposure: f64,
        tonemap: Tonemap,
    ) -> Result<(), String> {
        self.renderer.present(&self.gpu, pixels, size, exposure, tonemap).map_err(|e| e.to_string())?;
        self.size = size;
        self.publish(ctx)
    }

    fn publish(&mut self, ctx: &egui::Context) -> Result<(), String> {
        match &mut self.display {
            Display::Native { renderer, id, size } => {
                let view = self.renderer.display_view().ok_or("nothing rendered")?;
                let mut r = renderer.write();
                match id {
                    Some(_) if *size == self.size => {}
                    Some(id) => {
                        r.update_egui_texture_from_wgpu_texture(
                            &self.gpu.device,
                            view,
                            eframe::wgpu::FilterMode::Linear,
                            *id,
                        );
                        *size = self.size;
                    }
                    None => {
                        *id = Some(r.register_native_texture(&self.gpu.device, view, eframe::wgpu::FilterMode::Linear));
                        *size = self.size;
                    }
                }
            }
            Display::Uploaded(handle) => {
                let captured = self.renderer.capture(&self.gpu).map_err(|e| e.to_string())?;
                let image = egui::ColorImage::from_rgba_unmultiplied(
                    [captured.width as usize, captured.height as usize],
                    captured.ldr.as_flattened(),
                );
                match handle {
                    Some(h) => h.set(image, egui::TextureOptions::LINEAR),
                    None => *handle = Some(ctx.load_texture("viewport", image, egui::TextureOptions::LINEAR)),
                }
            }
        }
        Ok(())
    }

    /// Linear radiance of the last rendered frame (for comparisons with the reference).
    pub fn capture_hdr(&self) -> Result<Vec<[f32; 3]>, String> {
        let captured = self.renderer.capture(&self.gpu).map_err(|e| e.to_string())?;
        Ok(captured.hdr.iter().map(|p| [p[0], p[1], p[2]]).collect())
    }

    /// The tone-mapped pixels of the last frame (sRGB bytes), as the renderer wrote them.
    #[cfg(test)]
    pub fn capture_ldr(&self) -> Result<Vec<[u8; 4]>, String> {
        Ok(self.renderer.capture(&self.gpu).map_err(|e| e.to_string())?.ldr)
    }

    /// The texture egui draws, once something was rendered.
    pub fn texture_id(&self) -> Option<egui::TextureId> {
        match &self.display {
            Display::Native { id, .. } => *id,
            Display::Uploaded(h) => h.as_ref().map(|h| h.id()),
        }
    }
}
