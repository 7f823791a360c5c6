//! The viewport renderer: draws a frame's features with one pass each (`crate::passes`) into
//! its own offscreen targets, then tone-maps. Used by the editor's viewport and by
//! `lightloom render` alike. GPU resources are re-uploaded only when the key of the stage they
//! come from changes.

use crate::capture::{CapturedFrame, read_texture};
use crate::passes::background::BackgroundPass;
use crate::passes::camera::CameraBinding;
use crate::passes::geometry::GeometryBuffers;
use crate::passes::medium::MediumPass;
use crate::passes::sun::SunPass;
use crate::passes::tonemap::TonemapPass;
use crate::passes::{
    DEPTH_FORMAT, Draw, HDR_FORMAT, LDR_FORMAT, Pass, PassSetup, ScenePass, scene_passes, to_rgba_f16,
};
use crate::{GpuContext, RenderError};
use glam::{Mat4, Vec3};
use lightloom_nodes::frame::FrameInputs;
use lightloom_nodes::kinds::output::Tonemap;
use lightloom_nodes::project::Camera;

/// A perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraView {
    pub position: Vec3,
    pub target: Vec3,
    pub fov_y_deg: f32,
}

impl CameraView {
    pub fn from_project(camera: &Camera) -> Self {
        Self {
            position: glam::DVec3::from(camera.position).as_vec3(),
            target: glam::DVec3::from(camera.target).as_vec3(),
            fov_y_deg: camera.fov_y_deg as f32,
        }
    }

    /// View-projection for an aspect ratio, with clip planes fitted to the scene bounds.
    pub fn view_proj(&self, aspect: f32, bounds: ([f32; 3], [f32; 3])) -> Mat4 {
        let (lo, hi) = (Vec3::from(bounds.0), Vec3::from(bounds.1));
        let radius = if lo.x <= hi.x { (hi - lo).length() * 0.5 } else { 1.0 };
        let centre = if lo.x <= hi.x { (hi + lo) * 0.5 } else { Vec3::ZERO };
        let far = (self.position - centre).length() + radius * 2.0 + 1.0;
        let near = (far / 5000.0).max(0.001);
        // wgpu clip space: right-handed view, depth in [0, 1], NDC y up (the "directx" form).
        let proj = glam::camera::rh::proj::directx::perspective(self.fov_y_deg.to_radians(), aspect, near, far);
        // The reference's frame, so looking straight down still has an up direction.
        let forward = (self.target - self.position).as_dvec3().normalize_or(glam::DVec3::NEG_Z);
        let (_, up) = lightloom_nodes::reference::camera_basis(forward);
        proj * glam::camera::rh::view::look_at_mat4(self.position, self.target, up.as_vec3())
    }
}

struct Targets {
    width: u32,
    height: u32,
    msaa: Option<wgpu::TextureView>,
    hdr: wgpu::Texture,
    hdr_view: wgpu::TextureView,
    depth: wgpu::TextureView,
    ldr: wgpu::Texture,
    ldr_view: wgpu::TextureView,
    /// The same texels viewed as Rgba8Unorm (sRGB-encoded bytes, no decoding on read).
    ldr_encoded_view: wgpu::TextureView,
    tone_bind_group: wgpu::BindGroup,
}

/// Draws frames into its own offscreen targets.
pub struct ViewportRenderer {
    camera: CameraBinding,
    medium: MediumPass,
    sun: SunPass,
    normal_maps: crate::passes::normal_map::NormalMapPass,
    background: BackgroundPass,
    /// The passes over the background ([`scene_passes`]), and which drew the last frame.
    passes: Vec<Box<dyn ScenePass>>,
    drawn: Vec<bool>,
    tonemap: TonemapPass,
    geometry: Option<GeometryBuffers>,
    targets: Option<Targets>,
    sample_count: u32,
}

impl ViewportRenderer {
    pub fn new(gpu: &GpuContext) -> Self {
        let sample_count =
            if gpu.adapter.get_texture_format_features(HDR_FORMAT).flags.sample_count_supported(4) { 4 } else { 1 };
        let camera = CameraBinding::new(&gpu.device);
        let medium = MediumPass::new(gpu);
        let sun = SunPass::new(gpu);
        let normal_maps = crate::passes::normal_map::NormalMapPass::new(gpu);
        let setup = PassSetup {
            device: &gpu.device,
            camera_layout: &camera.layout,
            medium_layout: &medium.layout,
            sun_layout: &sun.layout,
            normal_map_layout: &normal_maps.layout,
            sample_count,
        };
        let mut passes = scene_passes(&setup);
        let relight_on = crate::RelightOn::from_env();
        for pass in &mut passes {
            pass.relight_on(relight_on);
        }
        Self {
            background: BackgroundPass::new(gpu, &setup),
            drawn: vec![false; passes.len()],
            passes,
            tonemap: TonemapPass::new(&gpu.device),
            camera,
            medium,
            sun,
            normal_maps,
            geometry: None,
            targets: None,
            sample_count,
        }
    }

    /// Where the wavelet modes rebuild their products after a lighting change (by default the
    /// GPU's compute kernel, or the CPU on a CPU adapter).
    pub fn set_relight_on(&mut self, on: crate::RelightOn) {
        for pass in &mut self.passes {
            pass.relight_on(on);
        }
    }

    /// Uploads what changed and draws the frame into the offscreen targets.
    pub fn render(
        &mut self,
        gpu: &GpuContext,
        frame: &FrameInputs,
        camera: &CameraView,
        width: u32,
        height: u32,
    ) -> Result<(), RenderError> {
        self.check_size(gpu, width, height)?;
        GeometryBuffers::prepare(&mut self.geometry, gpu, &frame.geometry)?;
        self.medium.prepare(gpu, &frame.medium)?;
        self.normal_maps.prepare(gpu, &frame.normal_maps)?;
        self.sun.prepare(gpu, frame.sun.as_ref(), &frame.materials, self.geometry.as_ref());
        self.background.prepare(gpu, &frame.background)?;
        for (pass, drawn) in self.passes.iter_mut().zip(&mut self.drawn) {
            *drawn = pass.prepare_frame(gpu, frame)?;
        }
        self.ensure_targets(gpu, width, height);
        let bounds = self.geometry.as_ref().map_or(([0.0; 3], [0.0; 3]), |m| m.bounds);
        let view_proj = camera.view_proj(width as f32 / height as f32, bounds);
        self.camera.write(gpu, view_proj, camera.position, frame.background.visible);
        let targets = self.targets.as_ref().expect("made above");
        let mut encoder =
            gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("viewport") });
        {
            let (view, resolve) = match &targets.msaa {
                Some(msaa) => (msaa, Some(&targets.hdr_view)),
                None => (&targets.hdr_view, None),
            };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("scene"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: resolve,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.camera.bind_group, &[]);
            pass.set_bind_group(1, &self.medium.bind_group, &[]);
            pass.set_bind_group(3, &self.sun.bind_group, &[]);
            pass.set_bind_group(4, &self.normal_maps.bind_group, &[]);
            let mapped = frame.normal_maps.shaded();
            self.background.draw(&mut pass, None, mapped);
            for (scene_pass, _) in self.passes.iter().zip(&self.drawn).filter(|(_, drawn)| **drawn) {
                scene_pass.draw(&mut pass, self.geometry.as_ref(), mapped);
            }
        }
        gpu.queue.submit(Some(encoder.finish()));
        self.tone_map(gpu, frame.settings.exposure, frame.settings.tonemap);
        Ok(())
    }

    /// Shows a linear image made on the CPU (the reference, an error map) through the same
    /// exposure and tone mapping as rendered frames.
    pub fn present(
        &mut self,
        gpu: &GpuContext,
        pixels: &[[f32; 3]],
        (width, height): (u32, u32),
        exposure: f64,
        tonemap: Tonemap,
    ) -> Result<(), RenderError> {
        if pixels.len() != width as usize * height as usize || width == 0 || height == 0 {
            return Err(RenderError::Invalid(format!("{} pixels do not make a {width}x{height} image", pixels.len())));
        }
        self.check_size(gpu, width, height)?;
        self.ensure_targets(gpu, width, height);
        let data = to_rgba_f16(pixels);
        let targets = self.targets.as_ref().unwrap();
        gpu.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &targets.hdr,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(&data),
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(width * 8), rows_per_image: Some(height) },
            wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        );
        self.tone_map(gpu, exposure, tonemap);
        Ok(())
    }

    /// Refuses sizes the adapter cannot hold or that would need more than
    /// [`lightloom_nodes::limits::MAX_RENDER_TARGET_BYTES`] for targets and readback.
    fn check_size(&self, gpu: &GpuContext, width: u32, height: u32) -> Result<(), RenderError> {
        let max = gpu.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::Invalid(format!(
                "render size {width}x{height}: this GPU draws 1 to {max} pixels per side"
            )));
        }
        // Per pixel: MSAA colour and depth, resolved HDR, LDR, their readback and CPU copies.
        let per_pixel = 12 * self.sample_count as u64 + 8 + 4 + 12 + 20;
        let bytes = width as u64 * height as u64 * per_pixel;
        let limit = lightloom_nodes::limits::MAX_RENDER_TARGET_BYTES;
        if bytes > limit {
            return Err(RenderError::Invalid(format!(
                "render size {width}x{height} needs about {} MiB for its targets; the limit is {} MiB \
                 (about {} megapixels)",
                bytes >> 20,
                limit >> 20,
                limit / per_pixel / 1_000_000
            )));
        }
        Ok(())
    }

    /// Tone-maps the HDR target into the LDR target.
    fn tone_map(&self, gpu: &GpuContext, exposure: f64, tonemap: Tonemap) {
        if let Some(targets) = &self.targets {
            self.tonemap.run(gpu, &targets.tone_bind_group, &targets.ldr_view, exposure, tonemap);
        }
    }

    /// The tone-mapped target, sRGB-decoding on read.
    pub fn ldr_view(&self) -> Option<&wgpu::TextureView> {
        self.targets.as_ref().map(|t| &t.ldr_view)
    }

    /// The tone-mapped target as Rgba8Unorm: its sRGB-encoded bytes, for UIs that blend in
    /// gamma space (egui's `register_native_texture` expects this).
    pub fn display_view(&self) -> Option<&wgpu::TextureView> {
        self.targets.as_ref().map(|t| &t.ldr_encoded_view)
    }

    /// Reads the last rendered frame back to the CPU.
    pub fn capture(&self, gpu: &GpuContext) -> Result<CapturedFrame, RenderError> {
        let targets = self.targets.as_ref().ok_or_else(|| RenderError::Invalid("nothing rendered yet".into()))?;
        let hdr_bytes = read_texture(&gpu.device, &gpu.queue, &targets.hdr, 8)?;
        let ldr_bytes = read_texture(&gpu.device, &gpu.queue, &targets.ldr, 4)?;
        let halves: &[half::f16] = bytemuck::cast_slice(&hdr_bytes);
        let hdr = halves.chunks(4).map(|p| [p[0].to_f32(), p[1].to_f32(), p[2].to_f32(), p[3].to_f32()]).collect();
        let ldr = ldr_bytes.chunks(4).map(|p| [p[0], p[1], p[2], p[3]]).collect();
        Ok(CapturedFrame { width: targets.width, height: targets.height, hdr, ldr })
    }

    /// Renders and reads back in one call (headless rendering).
    pub fn render_offscreen(
        &mut self,
        gpu: &GpuContext,
        frame: &FrameInputs,
        camera: &CameraView,
        width: u32,
        height: u32,
    ) -> Result<CapturedFrame, RenderError> {
        self.render(gpu, frame, camera, width, height)?;
        self.capture(gpu)
    }

    fn ensure_targets(&mut self, gpu: &GpuContext, width: u32, height: u32) {
        if self.targets.as_ref().is_some_and(|t| t.width == width && t.height == height) {
            return;
        }
        let device = &gpu.device;
        let size = wgpu::Extent3d { width, height, depth_or_array_layers: 1 };
        let texture = |label, format, usage, samples| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        use wgpu::TextureUsages as U;
        let msaa = (self.sample_count > 1).then(|| {
            texture("hdr-msaa", HDR_FORMAT, U::RENDER_ATTACHMENT, self.sample_count).create_view(&Default::default())
        });
        let hdr = texture("hdr", HDR_FORMAT, U::RENDER_ATTACHMENT | U::TEXTURE_BINDING | U::COPY_SRC | U::COPY_DST, 1);
        let hdr_view = hdr.create_view(&Default::default());
        let depth =
            texture("depth", DEPTH_FORMAT, U::RENDER_ATTACHMENT, self.sample_count).create_view(&Default::default());
        // The tone-mapped target also has a plain Rgba8Unorm view: UIs that composite in gamma
        // space (egui) read the sRGB-encoded bytes as they are.
        let ldr = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("ldr"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: LDR_FORMAT,
            usage: U::RENDER_ATTACHMENT | U::TEXTURE_BINDING | U::COPY_SRC,
            view_formats: &[wgpu::TextureFormat::Rgba8Unorm],
        });
        let ldr_view = ldr.create_view(&Default::default());
        let ldr_encoded_view = ldr.create_view(&wgpu::TextureViewDescriptor {
            format: Some(wgpu::TextureFormat::Rgba8Unorm),
            ..Default::default()
        });
        let tone_bind_group = self.tonemap.bind(device, &hdr_view);
        self.targets = Some(Targets {
            width,
            height,
            msaa,
            hdr,
            hdr_view,
            depth,
            ldr,
            ldr_view,
            ldr_encoded_view,
            tone_bind_group,
        });
    }
}
