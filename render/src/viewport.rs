//! The viewport renderer: environment background, lit meshes, tone mapping. Used by the
//! editor's viewport and by `lightloom render` alike. GPU resources are re-uploaded only when
//! the key of the stage they come from changes.

use crate::capture::{CapturedFrame, read_texture};
use crate::{GpuContext, RenderError};
use glam::{Mat4, Vec3};
use lightloom_nodes::engine::{Key, StageType};
use lightloom_nodes::kinds::output::{FrameInputs, Keyed, MAX_LIGHTS, MAX_MATERIALS, Tonemap};
use lightloom_nodes::project::Camera;
use lightloom_nodes::sh::ShRgb;
use lightloom_nodes::single_scattering::{FoggedEnvironment, MAX_ENVIRONMENT_FOG_BANDS};
use wgpu::util::DeviceExt;

const HDR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
const LDR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Irradiance bands evaluated per pixel (`Â_l` is 0 for odd `l > 1` and `|Â_6| < 0.016 Â_0`).
const MAX_SHADER_BANDS: usize = 5;
/// SH bands of the environment's fog glow (the shader's `sh_basis` evaluates at most 8).
/// Transport bands the `sh_prt` shader evaluates (higher bands of the transport are dropped).
pub const MAX_PRT_BANDS: usize = 8;

/// The shared WGSL every scene pass includes, in order: the `Globals` uniform, the vertex
/// layout and the SH basis (`common.wgsl`), then the fog model (`fog.wgsl`, which uses them).
const SHADER_PRELUDE: [&str; 2] = [include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/fog.wgsl")];

/// The scene passes' own shaders: mesh (SH irradiance), PRT, wavelet, background.
const SCENE_SHADERS: [(&str, &str); 4] = [
    ("mesh.wgsl", include_str!("../../shaders/mesh.wgsl")),
    ("mesh_prt.wgsl", include_str!("../../shaders/mesh_prt.wgsl")),
    ("mesh_wavelet.wgsl", include_str!("../../shaders/mesh_wavelet.wgsl")),
    ("background.wgsl", include_str!("../../shaders/background.wgsl")),
];

/// A scene pass's complete WGSL: the prelude, then the pass's source. WGSL has no includes;
/// this is the one place modules are joined, and `shaders_compose_and_match_the_rust_uniforms`
/// checks that every composed shader parses and validates and that each uniform struct has
/// the Rust layout the renderer writes.
fn compose(source: &str) -> String {
    let mut out = SHADER_PRELUDE.join("\n");
    out.push('\n');
    out.push_str(source);
    out
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct PrtParams {
    counts: [u32; 4],
    albedo: [[f32; 4]; MAX_MATERIALS],
    specular: [[f32; 4]; MAX_MATERIALS],
    lobe: [[f32; 4]; 2 * MAX_MATERIALS],
    light: [[f32; 4]; MAX_PRT_BANDS * MAX_PRT_BANDS],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct WaveletParams {
    counts: [u32; 4],
    albedo: [[f32; 4]; MAX_MATERIALS],
    specular: [[f32; 4]; MAX_MATERIALS],
    texels: [u32; 4],
}

/// Per-vertex triple-product data and the material's tables on the GPU.
struct WaveletBuffers {
    keys: (Key, Key, Option<Key>),
    has_texels: bool,
    texel_size: u32,
    bind_group: wgpu::BindGroup,
    cells: u32,
}

/// Per-vertex PRT data on the GPU, keyed by the stages it came from.
struct PrtBuffers {
    keys: (Key, Key),
    bind_group: wgpu::BindGroup,
}

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
        proj * glam::camera::rh::view::look_at_mat4(self.position, self.target, Vec3::Y)
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Globals {
    view_proj: [[f32; 4]; 4],
    inv_view_proj: [[f32; 4]; 4],
    camera_pos: [f32; 4],
    flags: [f32; 4],
    albedo: [[f32; 4]; MAX_MATERIALS],
    irradiance: [[f32; 4]; MAX_SHADER_BANDS * MAX_SHADER_BANDS],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    color: [f32; 3],
    /// The local frame's tangent (as the transport stages use it).
    tangent: [f32; 3],
    uv: [f32; 2],
    /// Layer of the mesh's per-texel diffuse texture (`wavelet_pixel`), or -1.
    layer: f32,
    /// Index into the frame's materials.
    material: u32,
}

struct MeshBuffers {
    key: Key,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    bounds: ([f32; 3], [f32; 3]),
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
    layout: wgpu::BindGroupLayout,
    tone_layout: wgpu::BindGroupLayout,
    mesh_pipeline: wgpu::RenderPipeline,
    prt_layout: wgpu::BindGroupLayout,
    prt_pipeline: wgpu::RenderPipeline,
    prt_params: wgpu::Buffer,
    prt: Option<PrtBuffers>,
    wavelet_layout: wgpu::BindGroupLayout,
    wavelet_pipeline: wgpu::RenderPipeline,
    wavelet_params: wgpu::Buffer,
    wavelet: Option<WaveletBuffers>,
    background_pipeline: wgpu::RenderPipeline,
    tone_pipeline: wgpu::RenderPipeline,
    globals: wgpu::Buffer,
    tone_params: wgpu::Buffer,
    sampler: wgpu::Sampler,
    environment: (wgpu::TextureView, Option<Key>),
    fog_params: wgpu::Buffer,
    fog_tables: FogTables,
    /// The environment's fog factors and what they were computed for (β, D, phase, tables).
    bind_group: wgpu::BindGroup,
    mesh: Option<MeshBuffers>,
    targets: Option<Targets>,
    sample_count: u32,
}

impl ViewportRenderer {
    pub fn new(ctx: &GpuContext) -> Self {
        let device = &ctx.device;
        let sample_count =
            if ctx.adapter.get_texture_format_features(HDR_FORMAT).flags.sample_count_supported(4) { 4 } else { 1 };
        use wgpu::ShaderStages as Stages;
        let entry = |binding, visibility, ty| wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None };
        let uniform = |binding, visibility| {
            entry(
                binding,
                visibility,
                wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
            )
        };
        let storage = |binding, visibility| {
            entry(
                binding,
                visibility,
                wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: true },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
            )
        };
        let texture = |binding, view_dimension| {
            entry(
                binding,
                Stages::FRAGMENT,
                wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension,
                    multisampled: false,
                },
            )
        };
        let sampler =
            |binding| entry(binding, Stages::FRAGMENT, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering));
        // Single scattering tables: R32Float, read with textureLoad (interpolated in WGSL).
        let table = |binding, view_dimension| {
            entry(
                binding,
                Stages::FRAGMENT,
                wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension,
                    multisampled: false,
                },
            )
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("viewport"),
            entries: &[
                uniform(0, Stages::VERTEX_FRAGMENT),
                texture(1, wgpu::TextureViewDimension::Cube),
                sampler(2),
                uniform(3, Stages::VERTEX_FRAGMENT),
                table(4, wgpu::TextureViewDimension::D2Array),
                table(5, wgpu::TextureViewDimension::D2Array),
            ],
        });
        let prt_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("prt"),
            entries: &[uniform(0, Stages::VERTEX), storage(1, Stages::VERTEX), storage(2, Stages::VERTEX)],
        });
        let wavelet_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("wavelet"),
            entries: &[
                uniform(0, Stages::VERTEX_FRAGMENT),
                storage(1, Stages::VERTEX),
                storage(2, Stages::VERTEX),
                storage(3, Stages::VERTEX_FRAGMENT),
                texture(4, wgpu::TextureViewDimension::D2Array),
                sampler(5),
                storage(6, Stages::FRAGMENT),
            ],
        });
        let tone_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("tonemap"),
            entries: &[
                entry(
                    0,
                    Stages::FRAGMENT,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                uniform(1, Stages::FRAGMENT),
            ],
        });
        let module = |(label, source): (&str, &str)| {
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(compose(source).into()),
            })
        };
        let [mesh_module, prt_module, wavelet_module, background_module] = SCENE_SHADERS.map(module);
        let tone_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("tonemap.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../../shaders/tonemap.wgsl").into()),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("viewport"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let multisample = wgpu::MultisampleState { count: sample_count, ..Default::default() };
        let depth = |write: bool, compare| {
            Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(write),
                depth_compare: Some(compare),
                stencil: Default::default(),
                bias: Default::default(),
            })
        };
        let vertex_attributes = wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x3, 4 => Float32x2, 5 => Float32, 6 => Uint32
        ];
        let vertex_layout = [Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<Vertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &vertex_attributes,
        })];
        // Mesh passes share the vertex layout, depth test and targets; each has its own shader
        // and, beyond group 0, its own bind group.
        let mesh_pass = |label: &str, module: &wgpu::ShaderModule, extra: Option<&wgpu::BindGroupLayout>| {
            let groups: Vec<Option<&wgpu::BindGroupLayout>> =
                [Some(&layout), extra].into_iter().flatten().map(Some).collect();
            let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &groups,
                immediate_size: 0,
            });
            PipelineSpec {
                label,
                layout: &layout,
                module,
                buffers: &vertex_layout,
                depth_stencil: depth(true, wgpu::CompareFunction::Less),
                multisample,
                target: HDR_FORMAT,
            }
            .build(device)
        };
        let mesh_pipeline = mesh_pass("mesh", &mesh_module, None);
        let prt_pipeline = mesh_pass("mesh-prt", &prt_module, Some(&prt_layout));
        let wavelet_pipeline = mesh_pass("mesh-wavelet", &wavelet_module, Some(&wavelet_layout));
        let uniform_buffer = |label: &str, size: usize| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let prt_params = uniform_buffer("prt-params", std::mem::size_of::<PrtParams>());
        let wavelet_params = uniform_buffer("wavelet-params", std::mem::size_of::<WaveletParams>());
        let background_pipeline = PipelineSpec {
            label: "background",
            layout: &pipeline_layout,
            module: &background_module,
            buffers: &[],
            depth_stencil: depth(false, wgpu::CompareFunction::Always),
            multisample,
            target: HDR_FORMAT,
        }
        .build(device);
        let tone_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("tonemap"),
            bind_group_layouts: &[Some(&tone_layout)],
            immediate_size: 0,
        });
        let tone_pipeline = PipelineSpec {
            label: "tonemap",
            layout: &tone_pipeline_layout,
            module: &tone_module,
            buffers: &[],
            depth_stencil: None,
            multisample: Default::default(),
            target: LDR_FORMAT,
        }
        .build(device);
        let globals = uniform_buffer("globals", std::mem::size_of::<Globals>());
        let tone_params = uniform_buffer("tone", 16);
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("environment"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let black = upload_cube(ctx, 1, &[[0.0; 3]; 6]);
        let fog_params = uniform_buffer("fog", std::mem::size_of::<FogParams>());
        let fog_tables = FogTables {
            f: upload_tables(ctx, "f-tables", 1, &[0.0]),
            g: upload_tables(ctx, "g-table", 1, &[0.0]),
            key: None,
        };
        let bind_group = make_bind_group(device, &layout, &globals, &black, &sampler, &fog_params, &fog_tables);
        Self {
            layout,
            tone_layout,
            mesh_pipeline,
            prt_layout,
            prt_pipeline,
            prt_params,
            prt: None,
            wavelet_layout,
            wavelet_pipeline,
            wavelet_params,
            wavelet: None,
            background_pipeline,
            tone_pipeline,
            globals,
            tone_params,
            sampler,
            environment: (black, None),
            fog_params,
            fog_tables,
            bind_group,
            mesh: None,
            targets: None,
            sample_count,
        }
    }

    /// Uploads what changed and draws the frame into the offscreen targets.
    pub fn render(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameInputs,
        camera: &CameraView,
        width: u32,
        height: u32,
    ) -> Result<(), RenderError> {
        if width == 0 || height == 0 || width > 16384 || height > 16384 {
            return Err(RenderError::Invalid(format!("render size {width}x{height} must be within 1..=16384")));
        }
        self.upload_meshes(ctx, frame)?;
        self.upload_environment(ctx, frame)?;
        let environment_fog = frame.fog.as_ref().and_then(|f| f.environment.as_ref());
        self.upload_fog(ctx, frame, environment_fog)?;
        self.ensure_targets(ctx, width, height);
        let bounds = self.mesh.as_ref().map_or(([0.0; 3], [0.0; 3]), |m| m.bounds);
        let view_proj = camera.view_proj(width as f32 / height as f32, bounds);
        let mut globals = Globals {
            view_proj: view_proj.to_cols_array_2d(),
            inv_view_proj: view_proj.inverse().to_cols_array_2d(),
            camera_pos: camera.position.extend(1.0).to_array(),
            flags: [0.0, if frame.settings.background { 1.0 } else { 0.0 }, 0.0, 0.0],
            albedo: material_array(frame, |m| m.albedo.map(|a| a as f32), 1.0),
            irradiance: [[0.0; 4]; MAX_SHADER_BANDS * MAX_SHADER_BANDS],
        };
        if let Some(sh) = &frame.sh {
            let radiance = stage_value::<ShRgb>(sh)?;
            let irradiance = environment_fog.map_or(radiance, |fog| &fog.fogged).irradiance();
            let bands = irradiance.bands.min(MAX_SHADER_BANDS);
            globals.flags[0] = bands as f32;
            for (dst, src) in globals.irradiance.iter_mut().zip(&irradiance.coeffs[..bands * bands]) {
                *dst = [src[0] as f32, src[1] as f32, src[2] as f32, 0.0];
            }
        }
        let use_prt = self.upload_prt(ctx, frame, environment_fog)?;
        let use_wavelet = self.upload_wavelet(ctx, frame, environment_fog)?;
        ctx.queue.write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));
        let targets = self.targets.as_ref().unwrap();
        let mut encoder =
            ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("viewport") });
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
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_pipeline(&self.background_pipeline);
            pass.draw(0..3, 0..1);
            if let Some(mesh) = &self.mesh {
                match (&self.prt, use_prt, &self.wavelet, use_wavelet) {
                    (_, _, Some(wavelet), true) => {
                        pass.set_pipeline(&self.wavelet_pipeline);
                        pass.set_bind_group(1, &wavelet.bind_group, &[]);
                    }
                    (Some(prt), true, _, _) => {
                        pass.set_pipeline(&self.prt_pipeline);
                        pass.set_bind_group(1, &prt.bind_group, &[]);
                    }
                    _ => pass.set_pipeline(&self.mesh_pipeline),
                }
                pass.set_vertex_buffer(0, mesh.vertices.slice(..));
                pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..mesh.index_count, 0, 0..1);
            }
        }
        ctx.queue.submit(Some(encoder.finish()));
        self.tone_map(ctx, frame.settings.exposure, frame.settings.tonemap);
        Ok(())
    }

    /// Shows a linear image made on the CPU (the reference, an error map) through the same
    /// exposure and tone mapping as rendered frames.
    pub fn present(
        &mut self,
        ctx: &GpuContext,
        pixels: &[[f32; 3]],
        (width, height): (u32, u32),
        exposure: f64,
        tonemap: Tonemap,
    ) -> Result<(), RenderError> {
        if pixels.len() != width as usize * height as usize || width == 0 || height == 0 {
            return Err(RenderError::Invalid(format!("{} pixels do not make a {width}x{height} image", pixels.len())));
        }
        self.ensure_targets(ctx, width, height);
        let data = to_rgba_f16(pixels);
        let targets = self.targets.as_ref().unwrap();
        ctx.queue.write_texture(
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
        self.tone_map(ctx, exposure, tonemap);
        Ok(())
    }

    /// Tone-maps the HDR target into the LDR target.
    fn tone_map(&self, ctx: &GpuContext, exposure: f64, tonemap: Tonemap) {
        let Some(targets) = self.targets.as_ref() else { return };
        let tonemap = match tonemap {
            Tonemap::Aces => 0.0,
            Tonemap::Reinhard => 1.0,
            Tonemap::Linear => 2.0,
        };
        ctx.queue.write_buffer(
            &self.tone_params,
            0,
            bytemuck::cast_slice(&[2f32.powf(exposure as f32), tonemap, 0.0, 0.0]),
        );
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tonemap") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("tonemap"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &targets.ldr_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.tone_pipeline);
            pass.set_bind_group(0, &targets.tone_bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
        ctx.queue.submit(Some(encoder.finish()));
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
    pub fn capture(&self, ctx: &GpuContext) -> Result<CapturedFrame, RenderError> {
        let targets = self.targets.as_ref().ok_or_else(|| RenderError::Invalid("nothing rendered yet".into()))?;
        let hdr_bytes = read_texture(&ctx.device, &ctx.queue, &targets.hdr, 8)?;
        let ldr_bytes = read_texture(&ctx.device, &ctx.queue, &targets.ldr, 4)?;
        let halves: &[half::f16] = bytemuck::cast_slice(&hdr_bytes);
        let hdr = halves.chunks(4).map(|p| [p[0].to_f32(), p[1].to_f32(), p[2].to_f32(), p[3].to_f32()]).collect();
        let ldr = ldr_bytes.chunks(4).map(|p| [p[0], p[1], p[2], p[3]]).collect();
        Ok(CapturedFrame { width: targets.width, height: targets.height, hdr, ldr })
    }

    /// Renders and reads back in one call (headless rendering).
    pub fn render_offscreen(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameInputs,
        camera: &CameraView,
        width: u32,
        height: u32,
    ) -> Result<CapturedFrame, RenderError> {
        self.render(ctx, frame, camera, width, height)?;
        self.capture(ctx)
    }

    fn upload_meshes(&mut self, ctx: &GpuContext, frame: &FrameInputs) -> Result<(), RenderError> {
        // Vertices carry their mesh's texel layer, so the texel stage is part of the key.
        let assignment = frame.mesh_materials.iter().fold(0u128, |h, m| h.rotate_left(3) ^ (*m as u128 + 1));
        let key = frame.meshes.key
            ^ frame.texel_irradiance.as_ref().map_or(0, |t| t.key.rotate_left(1))
            ^ assignment.rotate_left(17);
        if self.mesh.as_ref().is_some_and(|m| m.key == key) {
            return Ok(());
        }
        let set = stage_value::<lightloom_nodes::mesh::MeshSet>(&frame.meshes)?;
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let layers = frame
            .texel_irradiance
            .as_ref()
            .and_then(|t| t.value.get::<lightloom_nodes::triple_product::TexelIrradiance>())
            .map_or(Vec::new(), |t| t.mesh_layers.clone());
        for (m, mesh) in set.meshes.iter().enumerate() {
            let base = vertices.len() as u32;
            let tangents = lightloom_nodes::mesh::vertex_tangents(mesh);
            let layer = layers.get(m).copied().unwrap_or(-1) as f32;
            let material = frame.mesh_materials.get(m).copied().unwrap_or(0);
            for i in 0..mesh.positions.len() {
                vertices.push(Vertex {
                    position: mesh.positions[i],
                    normal: mesh.normals[i],
                    color: mesh.base_color,
                    tangent: tangents[i],
                    uv: mesh.uvs.get(i).copied().unwrap_or([0.0; 2]),
                    layer,
                    material,
                });
            }
            indices.extend(mesh.indices.iter().map(|i| i + base));
        }
        if indices.is_empty() {
            self.mesh = None;
            return Ok(());
        }
        let vertices = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let index_count = indices.len() as u32;
        let indices = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        self.mesh = Some(MeshBuffers { key, vertices, indices, index_count, bounds: set.bounds() });
        Ok(())
    }

    /// For the `sh_prt` mode: uploads transfer and incident radiance when their stage keys
    /// change, and the lighting/material uniforms every frame. Returns whether to draw with it.
    fn upload_prt(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameInputs,
        fog: Option<&FoggedEnvironment>,
    ) -> Result<bool, RenderError> {
        let (Some(transport), Some(incident)) = (&frame.transport, &frame.incident) else {
            return Ok(false);
        };
        let t = stage_value::<lightloom_nodes::transport::ShTransport>(transport)?;
        let r = stage_value::<lightloom_nodes::prt::IncidentSh>(incident)?;
        let vertices: usize = frame
            .meshes
            .value
            .get::<lightloom_nodes::mesh::MeshSet>()
            .map_or(0, |m| m.meshes.iter().map(|m| m.positions.len()).sum());
        let n = t.bands * t.bands;
        if t.transfer.len() != vertices * n || (!r.coeffs.is_empty() && r.coeffs.len() != vertices * n * 3) {
            return Err(RenderError::Invalid(format!(
                "transport has {} receivers for {vertices} vertices",
                t.transfer.len() / n.max(1)
            )));
        }
        if self.prt.as_ref().is_none_or(|p| p.keys != (transport.key, incident.key)) {
            let transfer = storage_buffer(ctx, "prt-transfer", &t.transfer);
            let incident_buffer = storage_buffer(ctx, "prt-incident", &r.coeffs);
            let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("prt"),
                layout: &self.prt_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: self.prt_params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: transfer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: incident_buffer.as_entire_binding() },
                ],
            });
            self.prt = Some(PrtBuffers { keys: (transport.key, incident.key), bind_group });
        }
        let bands = t.bands.min(MAX_PRT_BANDS);
        let mut params = PrtParams {
            counts: [bands as u32, n as u32, (n * 3) as u32, !r.coeffs.is_empty() as u32],
            albedo: material_array(frame, |m| m.albedo.map(|a| a as f32), 1.0),
            specular: [[0.0; 4]; MAX_MATERIALS],
            lobe: [[0.0; 4]; 2 * MAX_MATERIALS],
            light: [[0.0; 4]; MAX_PRT_BANDS * MAX_PRT_BANDS],
        };
        for (i, m) in frame.materials.iter().enumerate().take(MAX_MATERIALS) {
            if let Some(lobe) = m.sh_lobe.as_ref().filter(|l| !l.factors.is_empty()) {
                params.specular[i] = [lobe.weight[0] as f32, lobe.weight[1] as f32, lobe.weight[2] as f32, 1.0];
                for (l, f) in lobe.factors.iter().enumerate().take(MAX_PRT_BANDS) {
                    params.lobe[2 * i + l / 4][l % 4] = *f as f32;
                }
            }
        }
        if let Some(sh) = &frame.sh {
            let light = stage_value::<ShRgb>(sh)?;
            // In fog the diffuse transfer sees the fogged environment (sec. 3.6.5); the glossy
            // lobes read per-vertex incident light computed without fog, so they get only its
            // attenuation.
            let light = fog.map_or(light, |f| &f.fogged);
            for (dst, src) in params.light.iter_mut().zip(&light.coeffs).take(bands * bands) {
                *dst = [src[0] as f32, src[1] as f32, src[2] as f32, 0.0];
            }
        }
        if let Some(fog) = fog {
            attenuate(&mut params.specular, fog.fog.attenuation);
        }
        ctx.queue.write_buffer(&self.prt_params, 0, bytemuck::bytes_of(&params));
        Ok(true)
    }

    /// For the `wavelet_vertex` mode: uploads the per-vertex products and the material's tables
    /// when their stage keys change. Returns whether to draw with them.
    fn upload_wavelet(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameInputs,
        fog: Option<&FoggedEnvironment>,
    ) -> Result<bool, RenderError> {
        let Some(products) = &frame.local_products else {
            return Ok(false);
        };
        let p = stage_value::<lightloom_nodes::triple_product::LocalProducts>(products)?;
        let mut tables = Vec::new();
        let mut table_keys: Key = 0;
        for m in &frame.materials {
            let Some(keyed) = &m.table else {
                return Err(RenderError::Invalid(format!("material `{}` has no local-frame table", m.node)));
            };
            let t = stage_value::<lightloom_nodes::triple_product::BrdfTable>(keyed)?;
            table_keys = table_keys.rotate_left(7) ^ keyed.key;
            tables.push(t);
        }
        if p.cells == 0 {
            return Ok(false);
        }
        let vertices: usize = frame
            .meshes
            .value
            .get::<lightloom_nodes::mesh::MeshSet>()
            .map_or(0, |m| m.meshes.iter().map(|m| m.positions.len()).sum());
        if p.values.len() != vertices * p.cells * 3 {
            return Err(RenderError::Invalid(format!(
                "triple-product data covers {} receivers for {vertices} vertices",
                p.values.len() / (p.cells * 3)
            )));
        }
        let bytes = p.values.len() as u64 / 3 * 4;
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        if bytes > limit {
            return Err(RenderError::Invalid(format!(
                "the wavelet mode needs {} MiB per-vertex data ({vertices} vertices × {} cells) but this GPU binds at \
                 most {} MiB: use 80 coefficients or fewer vertices",
                bytes >> 20,
                p.cells,
                limit >> 20
            )));
        }
        let texel_key = frame.texel_irradiance.as_ref().map(|t| t.key);
        let texels = frame
            .texel_irradiance
            .as_ref()
            .and_then(|t| t.value.get::<lightloom_nodes::triple_product::TexelIrradiance>())
            .filter(|t| !t.texels.is_empty());
        if self
            .wavelet
            .as_ref()
            .is_none_or(|w| w.keys != (products.key, table_keys, texel_key) || w.cells != p.cells as u32)
        {
            let coarse: Vec<_> =
                tables.iter().map(|t| t.coarsened(p.cells)).collect::<Result<_, _>>().map_err(RenderError::Invalid)?;
            // Every material gets a full specular table (zeros without a lobe): fixed stride.
            let stride =
                lightloom_nodes::triple_product::THETA_STEPS * lightloom_nodes::triple_product::PHI_STEPS * p.cells;
            let mut specular_tables = vec![0.0f32; stride * coarse.len()];
            for (i, t) in coarse.iter().enumerate() {
                if !t.specular.is_empty() {
                    specular_tables[i * stride..(i + 1) * stride].copy_from_slice(&t.specular);
                }
            }
            // P packed as RGB9E5: 4 bytes per cell instead of 12.
            let values = storage_buffer(ctx, "wavelet-products", &crate::packing::rgb9e5_all(&p.values));
            let diffuse = storage_buffer(ctx, "wavelet-diffuse", &coarse[0].diffuse);
            let specular = storage_buffer(ctx, "wavelet-specular", &specular_tables);
            let texel_view = match texels {
                Some(t) => upload_layers(ctx, t.size as u32, &t.texels),
                None => upload_layers(ctx, 1, &[[0.0; 3]]),
            };
            let texel_packed = match texels {
                Some(t) if t.cells == p.cells => crate::packing::rgb9e5_all(&t.products),
                _ => Vec::new(),
            };
            if texel_packed.len() as u64 * 4 > limit {
                return Err(RenderError::Invalid(format!(
                    "the visibility textures' per-texel data needs {} MiB but this GPU binds at most {} MiB: \
                     use a smaller visibility texture size or 80 coefficients",
                    (texel_packed.len() * 4) >> 20,
                    limit >> 20
                )));
            }
            let texel_products = storage_buffer(ctx, "wavelet-texel-products", &texel_packed);
            let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("wavelet"),
                layout: &self.wavelet_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: self.wavelet_params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: values.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: diffuse.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: specular.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&texel_view) },
                    wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::Sampler(&self.sampler) },
                    wgpu::BindGroupEntry { binding: 6, resource: texel_products.as_entire_binding() },
                ],
            });
            self.wavelet = Some(WaveletBuffers {
                keys: (products.key, table_keys, texel_key),
                has_texels: texels.is_some_and(|t| t.cells == p.cells),
                texel_size: texels.map_or(0, |t| t.size as u32),
                bind_group,
                cells: p.cells as u32,
            });
        }
        let w = self.wavelet.as_ref().unwrap();
        let stride = lightloom_nodes::triple_product::THETA_STEPS * lightloom_nodes::triple_product::PHI_STEPS;
        let mut specular = [[0.0; 4]; MAX_MATERIALS];
        for (i, t) in tables.iter().enumerate().take(MAX_MATERIALS) {
            let has = !t.specular.is_empty() as u32 as f32;
            specular[i] = [t.specular_color[0], t.specular_color[1], t.specular_color[2], has];
        }
        // In fog the all-frequency environment light reaches surfaces attenuated; fog.wgsl adds
        // the scattered part (band-limited, unshadowed).
        let mut albedo = material_array(frame, |m| m.albedo.map(|a| a as f32), 1.0);
        if let Some(fog) = fog {
            attenuate(&mut albedo, fog.fog.attenuation);
            attenuate(&mut specular, fog.fog.attenuation);
        }
        let params = WaveletParams {
            counts: [
                w.cells,
                (stride as u32) * w.cells,
                lightloom_nodes::triple_product::THETA_STEPS as u32,
                lightloom_nodes::triple_product::PHI_STEPS as u32,
            ],
            albedo,
            specular,
            texels: [w.has_texels as u32, w.texel_size, 0, 0],
        };
        ctx.queue.write_buffer(&self.wavelet_params, 0, bytemuck::bytes_of(&params));
        Ok(true)
    }

    fn upload_environment(&mut self, ctx: &GpuContext, frame: &FrameInputs) -> Result<(), RenderError> {
        let key = frame.radiance.as_ref().map(|r| r.key);
        if self.environment.1 == key {
            return Ok(());
        }
        let view = match &frame.radiance {
            Some(r) => {
                let cube = stage_value::<lightloom_nodes::cubemap::CubeMap>(r)?;
                upload_cube(ctx, cube.size as u32, &cube.texels)
            }
            None => upload_cube(ctx, 1, &[[0.0; 3]; 6]),
        };
        self.environment = (view, key);
        self.rebind(ctx);
        Ok(())
    }

    fn rebind(&mut self, ctx: &GpuContext) {
        self.bind_group = make_bind_group(
            &ctx.device,
            &self.layout,
            &self.globals,
            &self.environment.0,
            &self.sampler,
            &self.fog_params,
            &self.fog_tables,
        );
    }

    /// Point lights and the medium: uniforms every frame, tables when their stages change.
    fn upload_fog(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameInputs,
        environment_fog: Option<&FoggedEnvironment>,
    ) -> Result<(), RenderError> {
        let mut params: FogParams = bytemuck::Zeroable::zeroed();
        params.environment = [1.0, 1.0, 1.0, 0.0];
        if let Some(fog) = environment_fog {
            let a = fog.fog.attenuation;
            params.environment = [a[0] as f32, a[1] as f32, a[2] as f32, fog.fog.scattered.len() as f32];
            for (dst, src) in params.environment_scattered.iter_mut().zip(&fog.scattered.coeffs) {
                *dst = [src[0] as f32, src[1] as f32, src[2] as f32, 0.0];
            }
            // The wavelet modes cannot convolve their all-frequency light: fog.wgsl adds the
            // scattered environment's irradiance to them.
            params.counts[3] = f32::from(u8::from(frame.mode.is_wavelet()));
        }
        params.counts[0] = frame.lights.len().min(MAX_LIGHTS) as f32;
        for (i, l) in frame.lights.iter().take(MAX_LIGHTS).enumerate() {
            params.light_position[i] = [l.position[0] as f32, l.position[1] as f32, l.position[2] as f32, 1.0];
            params.light_intensity[i] = [l.intensity[0] as f32, l.intensity[1] as f32, l.intensity[2] as f32, 0.0];
        }
        for (slot, m) in params.specular.iter_mut().zip(&frame.materials) {
            if let Some((weight, exponent)) = m.phong_lobe {
                *slot = [weight[0] as f32, weight[1] as f32, weight[2] as f32, exponent as f32];
            }
        }
        if let Some(fog) = &frame.fog {
            params.beta = [fog.beta[0] as f32, fog.beta[1] as f32, fog.beta[2] as f32, 1.0];
            for (k, w) in fog.phase.iter().take(3).enumerate() {
                params.phase[k] = *w as f32;
            }
            params.phase[3] = fog.phase.len().min(3) as f32;
            let f = stage_value::<Vec<lightloom_nodes::single_scattering::FTable>>(&fog.f_tables)?;
            let g = stage_value::<lightloom_nodes::single_scattering::PhongGTables>(&fog.g_tables)?;
            params.counts[1] = g.tables.len() as f32;
            params.counts[2] = lightloom_nodes::single_scattering::PHONG_STEPS_PER_OCTAVE as f32;
            let key = Some(fog.f_tables.key ^ fog.g_tables.key.rotate_left(7));
            if self.fog_tables.key != key {
                let layers = |tables: &mut dyn Iterator<Item = &lightloom_nodes::single_scattering::Table2>| {
                    tables.flat_map(|t| t.values.iter().copied()).collect::<Vec<f32>>()
                };
                let f_size = f.first().map_or(1, |t| t.table.width) as u32;
                let g_size = g.tables.first().map_or(1, |t| t.table.width) as u32;
                self.fog_tables = FogTables {
                    f: upload_tables(ctx, "f-tables", f_size, &layers(&mut f.iter().map(|t| &t.table))),
                    g: upload_tables(ctx, "g-tables", g_size, &layers(&mut g.tables.iter().map(|t| &t.table))),
                    key,
                };
                self.rebind(ctx);
            }
        }
        ctx.queue.write_buffer(&self.fog_params, 0, bytemuck::bytes_of(&params));
        Ok(())
    }

    fn ensure_targets(&mut self, ctx: &GpuContext, width: u32, height: u32) {
        if self.targets.as_ref().is_some_and(|t| t.width == width && t.height == height) {
            return;
        }
        let device = &ctx.device;
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
        let tone_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("tonemap"),
            layout: &self.tone_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&hdr_view) },
                wgpu::BindGroupEntry { binding: 1, resource: self.tone_params.as_entire_binding() },
            ],
        });
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

/// A render pipeline with `vs_main`/`fs_main` entry points and one colour target.
struct PipelineSpec<'a> {
    label: &'a str,
    layout: &'a wgpu::PipelineLayout,
    module: &'a wgpu::ShaderModule,
    buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    depth_stencil: Option<wgpu::DepthStencilState>,
    multisample: wgpu::MultisampleState,
    target: wgpu::TextureFormat,
}

impl PipelineSpec<'_> {
    fn build(self, device: &wgpu::Device) -> wgpu::RenderPipeline {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(self.label),
            layout: Some(self.layout),
            vertex: wgpu::VertexState {
                module: self.module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: self.buffers,
            },
            primitive: Default::default(),
            depth_stencil: self.depth_stencil,
            multisample: self.multisample,
            fragment: Some(wgpu::FragmentState {
                module: self.module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(self.target.into())],
            }),
            multiview_mask: None,
            cache: None,
        })
    }
}

fn make_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    globals: &wgpu::Buffer,
    environment: &wgpu::TextureView,
    sampler: &wgpu::Sampler,
    fog_params: &wgpu::Buffer,
    fog: &FogTables,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("viewport"),
        layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: globals.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(environment) },
            wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(sampler) },
            wgpu::BindGroupEntry { binding: 3, resource: fog_params.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&fog.f) },
            wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::TextureView(&fog.g) },
        ],
    })
}

/// Square R32Float tables, `values.len() / size²` layers, as a 2D array view.
fn upload_tables(ctx: &GpuContext, label: &str, size: u32, values: &[f32]) -> wgpu::TextureView {
    let layers = (values.len() / (size * size).max(1) as usize).max(1) as u32;
    let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: layers },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    ctx.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        bytemuck::cast_slice(values),
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(size * 4), rows_per_image: Some(size) },
        wgpu::Extent3d { width: size, height: size, depth_or_array_layers: layers },
    );
    texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    })
}

/// The fog uniforms (`fog.wgsl` `Fog`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FogParams {
    /// rgb: β per channel (1/m); w: 1 when a medium is linked.
    beta: [f32; 4],
    /// Phase polynomial weights `W_0..W_2`; w: how many.
    phase: [f32; 4],
    /// x: point light count; y: `G_n` ladder layers; z: layers per octave of exponent; w: 1
    /// when the shader adds the scattered environment's irradiance to surfaces.
    counts: [f32; 4],
    /// rgb: the environment's attenuation `e^{-βD}`; w: bands of `environment_scattered`.
    environment: [f32; 4],
    /// SH coefficients of the light fog scatters from the environment (eq. 3.35).
    environment_scattered: [[f32; 4]; MAX_ENVIRONMENT_FOG_BANDS * MAX_ENVIRONMENT_FOG_BANDS],
    /// Per material: Phong-equivalent lobe weight (rgb) and exponent (w; 0 = no lobe).
    specular: [[f32; 4]; MAX_MATERIALS],
    light_position: [[f32; 4]; MAX_LIGHTS],
    light_intensity: [[f32; 4]; MAX_LIGHTS],
}

struct FogTables {
    f: wgpu::TextureView,
    g: wgpu::TextureView,
    key: Option<Key>,
}

/// Scales the rgb of every material slot by the environment's attenuation `e^{-βD}`.
fn attenuate(slots: &mut [[f32; 4]], attenuation: [f64; 3]) {
    for slot in slots {
        for (v, a) in slot.iter_mut().zip(attenuation) {
            *v *= a as f32;
        }
    }
}

/// One vec4 per material slot: `rgb` from the material, `w`.
fn material_array(
    frame: &FrameInputs,
    rgb: impl Fn(&lightloom_nodes::kinds::brdf::Material) -> [f32; 3],
    w: f32,
) -> [[f32; 4]; MAX_MATERIALS] {
    let mut out = [[0.0; 4]; MAX_MATERIALS];
    for (o, m) in out.iter_mut().zip(&frame.materials) {
        let c = rgb(&m.material);
        *o = [c[0], c[1], c[2], w];
    }
    out
}

/// Uploads `size²` layers (layer-major) as a filterable half-float 2D array texture.
fn upload_layers(ctx: &GpuContext, size: u32, texels: &[[f32; 3]]) -> wgpu::TextureView {
    let layers = (texels.len() / (size * size) as usize).max(1) as u32;
    upload_layered(ctx, "texel-diffuse", size, layers, texels, wgpu::TextureViewDimension::D2Array)
}

/// Uploads six `size²` faces (Vulkan order) as a half-float cube texture.
fn upload_cube(ctx: &GpuContext, size: u32, texels: &[[f32; 3]]) -> wgpu::TextureView {
    upload_layered(ctx, "environment", size, 6, texels, wgpu::TextureViewDimension::Cube)
}

/// Uploads linear RGB as `layers` half-float `size²` layers and views them as `dimension`.
fn upload_layered(
    ctx: &GpuContext,
    label: &str,
    size: u32,
    layers: u32,
    texels: &[[f32; 3]],
    dimension: wgpu::TextureViewDimension,
) -> wgpu::TextureView {
    let texture = ctx.device.create_texture_with_data(
        &ctx.queue,
        &wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: layers },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: HDR_FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(&to_rgba_f16(texels)),
    );
    texture.create_view(&wgpu::TextureViewDescriptor { dimension: Some(dimension), ..Default::default() })
}

/// Linear RGB to RGBA half floats, clamped to the finite non-negative half range.
fn to_rgba_f16(pixels: &[[f32; 3]]) -> Vec<half::f16> {
    pixels.iter().flat_map(|p| [p[0], p[1], p[2], 1.0]).map(|v| half::f16::from_f32(v.clamp(0.0, 65000.0))).collect()
}

/// A read-only storage buffer (never empty: bindings must have a size).
fn storage_buffer<T: bytemuck::Pod + Default>(ctx: &GpuContext, label: &str, data: &[T]) -> wgpu::Buffer {
    let fallback = [T::default()];
    let data = if data.is_empty() { &fallback[..] } else { data };
    ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(data),
        usage: wgpu::BufferUsages::STORAGE,
    })
}

/// A gathered stage's value as `T`, or an error naming what it holds instead.
fn stage_value<T: StageType>(keyed: &Keyed) -> Result<&T, RenderError> {
    keyed.value.expect::<T>().map_err(|e| RenderError::Invalid(e.to_string()))
}

#[cfg(test)]
mod layout_tests {
    use super::*;
    use wgpu::naga;

    /// The WGSL struct `name`: its size and `(member, offset)` list.
    fn wgsl_struct(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
        let ty = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(name)).map(|(_, t)| t);
        match ty.map(|t| &t.inner) {
            Some(naga::TypeInner::Struct { members, span }) => {
                (*span, members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect())
            }
            _ => panic!("no struct {name} in the shader"),
        }
    }

    #[test]
    fn shaders_compose_and_match_the_rust_uniforms() {
        use std::mem::{offset_of, size_of};
        let mut modules = Vec::new();
        for (label, source) in SCENE_SHADERS {
            let module = naga::front::wgsl::parse_str(&compose(source))
                .unwrap_or_else(|e| panic!("{label}: {}", e.emit_to_string(&compose(source))));
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
                .validate(&module)
                .unwrap_or_else(|e| panic!("{label} does not validate: {e:?}"));
            modules.push((label, module));
        }
        // Each uniform struct, in the shader that declares it, against the Rust struct the
        // renderer writes with bytemuck: the same size and every member at the same offset.
        macro_rules! check {
            ($module:expr, $wgsl:literal, $rust:ty, [$($field:ident),+ $(,)?]) => {{
                let (span, members) = wgsl_struct($module, $wgsl);
                assert_eq!(span as usize, size_of::<$rust>(), "{} size", $wgsl);
                let rust: Vec<(String, u32)> = vec![$((stringify!($field).to_string(), offset_of!($rust, $field) as u32)),+];
                assert_eq!(members, rust, "{} members and offsets", $wgsl);
            }};
        }
        let (mesh, prt, wavelet) = (&modules[0].1, &modules[1].1, &modules[2].1);
        check!(mesh, "Globals", Globals, [view_proj, inv_view_proj, camera_pos, flags, albedo, irradiance]);
        check!(
            mesh,
            "Fog",
            FogParams,
            [beta, phase, counts, environment, environment_scattered, specular, light_position, light_intensity]
        );
        check!(prt, "PrtParams", PrtParams, [counts, albedo, specular, lobe, light]);
        check!(wavelet, "WaveletParams", WaveletParams, [counts, albedo, specular, texels]);
    }
}
