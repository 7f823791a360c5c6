//! The viewport's passes, one per feature. Each owns its pipeline, its bind group layout and
//! uniforms, and reads only its feature's frame data ([`lightloom_nodes::frame`]); none does
//! lighting math.
//!
//! Bind groups of the scene passes: 0 the camera ([`camera::CameraBinding`]), 1 the medium and
//! point lights ([`medium::MediumPass`], shaded in the same fragment as every surface because
//! they depend on its normal and material), 2 the pass's own, 3 the sun ([`sun::SunPass`]), 4
//! the materials' normal maps ([`normal_map::NormalMapPass`]). A new drawing feature adds one
//! module here with its shader in `shaders/`.

pub mod area_light;
pub mod background;
pub mod camera;
pub mod geometry;
pub mod irradiance;
pub mod medium;
pub mod normal_map;
pub mod prt;
pub mod rsl;
pub mod sun;
pub mod tonemap;
pub mod wavelet;

use crate::shaders::Shader;
use crate::{GpuContext, RenderError};
use geometry::GeometryBuffers;
use lightloom_nodes::engine::StageType;
use lightloom_nodes::frame::{FrameInputs, Keyed};
use wgpu::util::DeviceExt;

pub(crate) const HDR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
pub(crate) const LDR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// One feature's GPU side: uploads its frame data, then draws.
pub(crate) trait Pass: Draw {
    /// The frame data of the feature this pass draws.
    type Data: ?Sized;
    /// This pass's part of `frame` (`None`: it draws nothing in this frame).
    fn of(frame: &FrameInputs) -> Option<&Self::Data>
    where
        Self: Sized;
    /// Uploads what changed since the last frame.
    fn prepare(&mut self, gpu: &GpuContext, data: &Self::Data) -> Result<(), RenderError>;
    /// A frame without this pass's part (drop what was uploaded for the last one).
    fn absent(&mut self) {}
    /// Where the pass rebuilds its lighting after a change, for passes with a choice.
    fn set_relight_on(&mut self, _on: crate::RelightOn) {}
}

/// A scene pass as the viewport holds it: it finds its part of the frame, uploads what
/// changed, and says whether it draws.
pub(crate) trait ScenePass: Draw {
    /// Prepares this pass's part of `frame`; whether it draws in it.
    fn prepare_frame(&mut self, gpu: &GpuContext, frame: &FrameInputs) -> Result<bool, RenderError>;
    fn relight_on(&mut self, on: crate::RelightOn);
}

impl<P: Pass> ScenePass for P {
    fn prepare_frame(&mut self, gpu: &GpuContext, frame: &FrameInputs) -> Result<bool, RenderError> {
        match P::of(frame) {
            Some(data) => self.prepare(gpu, data).map(|()| true),
            None => {
                self.absent();
                Ok(false)
            }
        }
    }

    fn relight_on(&mut self, on: crate::RelightOn) {
        self.set_relight_on(on);
    }
}

/// The passes drawn over the background, in order: the surfaces of each relighting mode (one
/// of them draws a frame) and what adds onto them. A new pass is one line here.
pub(crate) fn scene_passes(setup: &PassSetup) -> Vec<Box<dyn ScenePass>> {
    vec![
        Box::new(irradiance::IrradiancePass::new(setup)),
        Box::new(prt::PrtPass::new(setup)),
        Box::new(wavelet::WaveletPass::new(setup)),
        Box::new(rsl::RslPass::new(setup)),
        Box::new(area_light::AreaLightPass::new(setup)),
    ]
}

pub(crate) trait Draw {
    /// Records the pass's draws into the scene pass (groups 0, 1, 3 and 4 bound), with the
    /// pipelines that shade normal maps when `normal_maps` (a material of the frame has one).
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, geometry: Option<&GeometryBuffers>, normal_maps: bool);
}

/// A surface pass's two pipelines: one shading normal maps, one composed without them (every
/// normal-map path folded away, for frames without a mapped material).
pub(crate) struct SurfacePipelines {
    mapped: wgpu::RenderPipeline,
    plain: wgpu::RenderPipeline,
}

impl SurfacePipelines {
    pub fn get(&self, normal_maps: bool) -> &wgpu::RenderPipeline {
        if normal_maps { &self.mapped } else { &self.plain }
    }
}

/// What every scene pass's pipeline shares: the device, the shared bind group layouts, the
/// vertex layout and the target's sample count.
pub(crate) struct PassSetup<'a> {
    pub device: &'a wgpu::Device,
    pub camera_layout: &'a wgpu::BindGroupLayout,
    pub medium_layout: &'a wgpu::BindGroupLayout,
    pub sun_layout: &'a wgpu::BindGroupLayout,
    pub normal_map_layout: &'a wgpu::BindGroupLayout,
    pub sample_count: u32,
}

impl PassSetup<'_> {
    /// A pipeline drawing the scene's meshes with `shader` (composed with the modules it imports), its own
    /// bind group `own` as group 2, depth-tested.
    pub fn surface_pipeline(&self, shader: Shader, own: &wgpu::BindGroupLayout) -> SurfacePipelines {
        SurfacePipelines {
            mapped: self.mesh_pipeline(shader, own, Depth::Write, None, true),
            plain: self.mesh_pipeline(shader, own, Depth::Write, None, false),
        }
    }

    /// A pipeline adding `shader`'s output onto the surfaces already drawn (same meshes, depth
    /// tested equal-or-nearer, not written).
    pub fn additive_surface_pipeline(&self, shader: Shader, own: &wgpu::BindGroupLayout) -> wgpu::RenderPipeline {
        let add = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::One,
            operation: wgpu::BlendOperation::Add,
        };
        self.mesh_pipeline(shader, own, Depth::Equal, Some(wgpu::BlendState { color: add, alpha: add }), true)
    }

    /// A pipeline over the shared mesh vertex buffer.
    fn mesh_pipeline(
        &self,
        shader: Shader,
        own: &wgpu::BindGroupLayout,
        depth: Depth,
        blend: Option<wgpu::BlendState>,
        normal_maps: bool,
    ) -> wgpu::RenderPipeline {
        let attributes = geometry::VERTEX_ATTRIBUTES;
        let buffers = [Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<geometry::Vertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &attributes,
        })];
        self.pipeline(shader, own, &buffers, depth, blend, normal_maps)
    }

    /// A pipeline drawing one screen-covering triangle behind everything.
    pub fn fullscreen_pipeline(&self, shader: Shader, own: &wgpu::BindGroupLayout) -> wgpu::RenderPipeline {
        self.pipeline(shader, own, &[], Depth::Behind, None, true)
    }

    fn pipeline(
        &self,
        shader: Shader,
        own: &wgpu::BindGroupLayout,
        buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
        depth: Depth,
        blend: Option<wgpu::BlendState>,
        normal_maps: bool,
    ) -> wgpu::RenderPipeline {
        let label = shader.label;
        let module = shader.module(self.device, normal_maps);
        let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[
                Some(self.camera_layout),
                Some(self.medium_layout),
                Some(own),
                Some(self.sun_layout),
                Some(self.normal_map_layout),
            ],
            immediate_size: 0,
        });
        let (write, compare) = match depth {
            Depth::Write => (true, wgpu::CompareFunction::Less),
            Depth::Equal => (false, wgpu::CompareFunction::LessEqual),
            Depth::Behind => (false, wgpu::CompareFunction::Always),
        };
        let depth = wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(write),
            depth_compare: Some(compare),
            stencil: Default::default(),
            bias: Default::default(),
        };
        pipeline(
            self.device,
            label,
            &layout,
            &module,
            buffers,
            Some(depth),
            wgpu::MultisampleState { count: self.sample_count, ..Default::default() },
            wgpu::ColorTargetState { format: HDR_FORMAT, blend, write_mask: wgpu::ColorWrites::ALL },
        )
    }
}

/// How a scene pass uses the depth buffer.
enum Depth {
    /// Nearest surface wins and is recorded.
    Write,
    /// Only where the surfaces already drawn are (adding light to them).
    Equal,
    /// Behind everything, not recorded (the background).
    Behind,
}

/// Every scene pass's shader (checked by `shaders_compose_and_match_the_rust_uniforms`).
#[cfg(test)]
const SCENE_SHADERS: [Shader; 6] =
    [irradiance::SHADER, prt::SHADER, wavelet::SHADER, background::SHADER, rsl::SHADER, area_light::SHADER];

/// A render pipeline with `vs_main`/`fs_main` entry points and one colour target.
#[allow(clippy::too_many_arguments)]
pub(crate) fn pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
    depth_stencil: Option<wgpu::DepthStencilState>,
    multisample: wgpu::MultisampleState,
    target: impl Into<wgpu::ColorTargetState>,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers,
        },
        primitive: Default::default(),
        depth_stencil,
        multisample,
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(target.into())],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Bind group layout entries.
pub(crate) mod entry {
    use wgpu::ShaderStages;

    fn entry(binding: u32, visibility: ShaderStages, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
        wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None }
    }

    pub fn uniform(binding: u32, visibility: ShaderStages) -> wgpu::BindGroupLayoutEntry {
        let ty = wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        entry(binding, visibility, ty)
    }

    pub fn storage(binding: u32, visibility: ShaderStages) -> wgpu::BindGroupLayoutEntry {
        storage_buffer(binding, visibility, true)
    }

    /// A storage buffer a compute pass writes.
    pub fn storage_read_write(binding: u32, visibility: ShaderStages) -> wgpu::BindGroupLayoutEntry {
        storage_buffer(binding, visibility, false)
    }

    fn storage_buffer(binding: u32, visibility: ShaderStages, read_only: bool) -> wgpu::BindGroupLayoutEntry {
        let ty = wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        entry(binding, visibility, ty)
    }

    /// A fragment-stage texture; `filterable: false` for tables read with `textureLoad`.
    pub fn texture(
        binding: u32,
        view_dimension: wgpu::TextureViewDimension,
        filterable: bool,
    ) -> wgpu::BindGroupLayoutEntry {
        let ty = wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable },
            view_dimension,
            multisampled: false,
        };
        entry(binding, ShaderStages::FRAGMENT, ty)
    }

    pub fn sampler(binding: u32) -> wgpu::BindGroupLayoutEntry {
        entry(binding, ShaderStages::FRAGMENT, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering))
    }
}

/// A uniform buffer for `T`, laid out as WGSL lays it out (`encase`).
pub(crate) fn uniform_buffer<T: encase::ShaderType>(device: &wgpu::Device, label: &str) -> wgpu::Buffer {
    sized_uniform_buffer(device, label, T::min_size().get())
}

fn sized_uniform_buffer(device: &wgpu::Device, label: &str, size: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Writes `value` into `buffer` laid out as WGSL lays out `T`.
pub(crate) fn write_uniform<T: encase::ShaderType + encase::internal::WriteInto>(
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    value: &T,
) {
    queue.write_buffer(buffer, 0, &uniform_bytes(value));
}

/// `value` laid out as WGSL lays out `T` in a uniform.
pub(crate) fn uniform_bytes<T: encase::ShaderType + encase::internal::WriteInto>(value: &T) -> Vec<u8> {
    let mut bytes = encase::UniformBuffer::new(Vec::<u8>::new());
    bytes.write(value).expect("a Vec grows to any uniform");
    bytes.into_inner()
}

pub(crate) fn linear_sampler(device: &wgpu::Device, label: &str) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some(label),
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    })
}

/// A read-only storage buffer (never empty: bindings must have a size).
pub(crate) fn storage_buffer<T: bytemuck::Pod + Default>(gpu: &GpuContext, label: &str, data: &[T]) -> wgpu::Buffer {
    let fallback = [T::default()];
    let data = if data.is_empty() { &fallback[..] } else { data };
    gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(data),
        usage: wgpu::BufferUsages::STORAGE,
    })
}

/// Square R32Float tables, `values.len() / size²` layers, as a 2D array view.
pub(crate) fn upload_tables(gpu: &GpuContext, label: &str, size: u32, values: &[f32]) -> wgpu::TextureView {
    upload_table_layers(gpu, label, (size, size), values)
}

/// Uploads `width × height` `R32Float` layers (as many as `values` holds) as a 2D array.
pub(crate) fn upload_table_layers(
    gpu: &GpuContext,
    label: &str,
    (width, height): (u32, u32),
    values: &[f32],
) -> wgpu::TextureView {
    let layers = (values.len() / (width * height).max(1) as usize).max(1) as u32;
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: layers },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    gpu.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        bytemuck::cast_slice(values),
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(width * 4), rows_per_image: Some(height) },
        wgpu::Extent3d { width, height, depth_or_array_layers: layers },
    );
    texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    })
}

/// Uploads linear RGB as `layers` half-float `size²` layers of `mips` levels each (`texels`
/// layer by layer, each layer's levels in turn, level `m` of side `size >> m`) and views them
/// as `dimension`.
pub(crate) fn upload_layered(
    gpu: &GpuContext,
    label: &str,
    (size, mips): (u32, u32),
    layers: u32,
    texels: &[[f32; 3]],
    dimension: wgpu::TextureViewDimension,
) -> wgpu::TextureView {
    let texture = gpu.device.create_texture_with_data(
        &gpu.queue,
        &wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: layers },
            mip_level_count: mips,
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
pub(crate) fn to_rgba_f16(pixels: &[[f32; 3]]) -> Vec<half::f16> {
    pixels.iter().flat_map(|p| [p[0], p[1], p[2], 1.0]).map(|v| half::f16::from_f32(v.clamp(0.0, 65000.0))).collect()
}

/// The first `N` of `values` as `vec3`s, zeros after them (a uniform's per-material array).
pub(crate) fn vec3s<const N: usize>(values: &[[f64; 3]]) -> [glam::Vec3; N] {
    std::array::from_fn(|i| values.get(i).map_or(glam::Vec3::ZERO, |v| glam::DVec3::from(*v).as_vec3()))
}

/// A gathered stage's value as `T`, or an error naming what it holds instead.
pub(crate) fn stage_value<T: StageType>(keyed: &Keyed) -> Result<&T, RenderError> {
    keyed.value.expect::<T>().map_err(|e| RenderError::Invalid(e.to_string()))
}

#[cfg(test)]
mod common_tests;

#[cfg(test)]
mod layout_tests {
    use super::*;
    use wgpu::naga;

    /// The WGSL type a Rust uniform field is written as (by encase's rules).
    trait Wgsl {
        fn wgsl() -> String;
    }

    macro_rules! wgsl {
        ($($rust:ty => $wgsl:expr),+ $(,)?) => {$(
            impl Wgsl for $rust {
                fn wgsl() -> String {
                    $wgsl.to_string()
                }
            }
        )+};
    }

    wgsl! {
        u32 => "u32",
        f32 => "f32",
        glam::Vec3 => "vec3<f32>",
        glam::Vec4 => "vec4<f32>",
        glam::Mat3 => "mat3x3<f32>",
        glam::Mat4 => "mat4x4<f32>",
        medium::FogLight => "FogLight",
        medium::SurfaceLobe => "SurfaceLobe",
        sun::SpecularLobe => "SpecularLobe",
        normal_map::NormalMapMaterial => "NormalMapMaterial",
        normal_map::VmfLevel => "VmfLevel",
        normal_map::HighlightLobe => "HighlightLobe",
        prt::PrtMaterial => "PrtMaterial",
        wavelet::WaveletMaterial => "WaveletMaterial",
        rsl::RslLayout => "RslLayout",
    }

    impl<T: Wgsl, const N: usize> Wgsl for [T; N] {
        fn wgsl() -> String {
            format!("array<{}, {N}>", T::wgsl())
        }
    }

    /// The WGSL type of the field `field` picks (its type inferred).
    fn field_type<S, T: Wgsl>(_field: fn(&S) -> &T) -> String {
        T::wgsl()
    }

    /// A naga type written as WGSL (a struct by its own name, without naga_oil's module suffix).
    fn naga_type(module: &naga::Module, ty: naga::Handle<naga::Type>) -> String {
        let scalar = |s: naga::Scalar| match (s.kind, s.width) {
            (naga::ScalarKind::Uint, 4) => "u32".to_string(),
            (naga::ScalarKind::Sint, 4) => "i32".to_string(),
            (naga::ScalarKind::Float, 4) => "f32".to_string(),
            other => format!("{other:?}"),
        };
        let t = &module.types[ty];
        match &t.inner {
            naga::TypeInner::Scalar(s) => scalar(*s),
            naga::TypeInner::Vector { size, scalar: s } => format!("vec{}<{}>", *size as u8, scalar(*s)),
            naga::TypeInner::Matrix { columns, rows, scalar: s } => {
                format!("mat{}x{}<{}>", *columns as u8, *rows as u8, scalar(*s))
            }
            naga::TypeInner::Array { base, size: naga::ArraySize::Constant(n), .. } => {
                format!("array<{}, {n}>", naga_type(module, *base))
            }
            naga::TypeInner::Struct { .. } => {
                let name = t.name.clone().unwrap_or_default();
                name.split("X_naga_oil_mod_X").next().unwrap_or_default().to_string()
            }
            other => format!("{other:?}"),
        }
    }

    /// The WGSL struct `name`: its size and `(member, type)` list.
    fn wgsl_struct(module: &naga::Module, name: &str) -> (u32, Vec<(String, String)>) {
        // A struct of an imported module carries the module's name after its own.
        let named = |t: &naga::Type| {
            t.name
                .as_deref()
                .is_some_and(|n| n == name || n.strip_prefix(name).is_some_and(|r| r.starts_with("X_naga_oil_mod_X")))
        };
        let ty = module.types.iter().find(|(_, t)| named(t)).map(|(_, t)| t);
        match ty.map(|t| &t.inner) {
            Some(naga::TypeInner::Struct { members, span }) => {
                let members = members.iter().map(|m| (m.name.clone().unwrap_or_default(), naga_type(module, m.ty)));
                (*span, members.collect())
            }
            _ => panic!("no struct {name} in the shader"),
        }
    }

    #[test]
    fn shaders_compose_and_match_the_rust_uniforms() {
        let validate = |shader: Shader, normal_maps: bool| {
            let module = shader.compose(normal_maps).unwrap_or_else(|e| panic!("{e}"));
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
                .validate(&module)
                .unwrap_or_else(|e| panic!("{} does not validate: {e:?}", shader.label));
            module
        };
        // Each scene shader without normal maps too (its pipelines for frames without one).
        for shader in SCENE_SHADERS {
            validate(shader, false);
        }
        let modules: Vec<naga::Module> =
            SCENE_SHADERS.into_iter().chain([tonemap::SHADER]).map(|s| validate(s, true)).collect();
        // Each uniform struct, in the shader that declares it, against the Rust struct its pass
        // writes. `encase` lays a Rust struct out by WGSL's rules from its field types: the
        // same size and the same members in order, each of the same type.
        macro_rules! layout {
            ($module:expr, $wgsl:literal, $rust:ty, [$($field:ident),+ $(,)?]) => {{
                let (span, members) = wgsl_struct($module, $wgsl);
                <$rust as encase::ShaderType>::assert_uniform_compat();
                assert_eq!(u64::from(span), <$rust as encase::ShaderType>::min_size().get(), "{} size", $wgsl);
                let rust = [$((stringify!($field).to_string(), field_type(|s: &$rust| &s.$field))),+];
                assert_eq!(members, rust, "{} members and their types", $wgsl);
            }};
        }
        let [irr, prt, wavelet, _background, rsl, area, tone] = [0, 1, 2, 3, 4, 5, 6].map(|i| &modules[i]);
        layout!(irr, "Globals", camera::Globals, [view_proj, inv_view_proj, camera_pos, background]);
        layout!(irr, "Irradiance", irradiance::IrradianceParams, [bands, albedo, coeffs]);
        layout!(
            irr,
            "Fog",
            medium::FogParams,
            [
                beta,
                linked,
                phase,
                phase_terms,
                light_count,
                g_layers,
                g_layers_per_octave,
                scatter_onto_surfaces,
                attenuation,
                scattered_bands,
                environment_scattered,
                lobes,
                lights
            ]
        );
        layout!(irr, "FogLight", medium::FogLight, [position, profiled, intensity, axis, x_axis]);
        layout!(irr, "SurfaceLobe", medium::SurfaceLobe, [weight, exponent]);
        layout!(
            irr,
            "Sun",
            sun::SunParams,
            [
                irradiance,
                direction_count,
                normal_offset,
                rim_directions,
                axis,
                cos_radius,
                directions,
                view_proj,
                lobes
            ]
        );
        layout!(irr, "SpecularLobe", sun::SpecularLobe, [model, sharpness, reflectance, alpha_y, colour]);
        layout!(
            irr,
            "NormalMaps",
            normal_map::NormalParams,
            [
                materials,
                scale_vertex_diffuse,
                vertex_highlights,
                irradiance,
                vmf_levels,
                highlight_radiance,
                highlight_factors,
                highlight_lobes,
                highlight_cube_levels,
                reflected_lobe
            ]
        );
        layout!(irr, "NormalMapMaterial", normal_map::NormalMapMaterial, [filter_kind, tiling, fitted_levels, layer]);
        layout!(irr, "VmfLevel", normal_map::VmfLevel, [first, width, height, texel_span, count, pad_a, pad_b, pad_c]);
        layout!(irr, "HighlightLobe", normal_map::HighlightLobe, [weight, glossy, alpha]);
        validate(sun::SHADER, false);
        layout!(
            prt,
            "PrtParams",
            prt::PrtParams,
            [diffuse_bands, transfer_stride, incident_stride, incident_bands, materials, light]
        );
        layout!(prt, "PrtMaterial", prt::PrtMaterial, [albedo, glossy, weight, factors]);
        layout!(
            wavelet,
            "WaveletParams",
            wavelet::WaveletParams,
            [cells, specular_stride, theta_steps, phi_steps, texels_bound, texel_size, details_kept, materials]
        );
        layout!(wavelet, "WaveletMaterial", wavelet::WaveletMaterial, [albedo, glossy, specular, fine_offset]);
        // The relight kernel is a compute shader on its own.
        let relight = validate(wavelet::RELIGHT_SHADER, false);
        layout!(
            &relight,
            "RelightParams",
            wavelet::RelightParams,
            [inverse_rotation, receivers, cells, samples_per_cell, face_size, row_width, details_kept]
        );
        layout!(rsl, "RslParams", rsl::RslParams, [lights, table_size, albedo, specular, layouts]);
        layout!(rsl, "RslLayout", rsl::RslLayout, [first, view_grid, slices]);
        layout!(area, "AreaLights", area_light::AreaLightParams, [albedo, texels_bound, texel_size]);
        layout!(tone, "ToneParams", tonemap::ToneParams, [exposure_scale, curve]);
        // The blocker kernel is a compute shader importing common.wgsl alone.
        let shexp = validate(crate::shexp::SHADER, false);
        layout!(
            &shexp,
            "ShexpParams",
            crate::shexp::ShexpParams,
            [
                receivers,
                bands_b,
                bands_t,
                vectors_per_receiver,
                series_degree,
                table_entries,
                ol_bins,
                gaunt_bb_count,
                gaunt_tb_count,
                offset_blockers,
                offset_parts,
                offset_log,
                offset_ol,
                offset_gaunt_bb,
                offset_gaunt_tb,
                row_stride,
                strength,
                ol_max_norm,
                ol_halving,
                min_sin
            ]
        );
    }
}
