//! The environment's sun, lit per pixel apart from the mode's transport (`sun.wgsl`, group 3 of
//! every scene pass): one orthographic shadow map per direction over the disc
//! ([`lightloom_nodes::frame::SunFrame`]), re-rendered only when the sun turns or the geometry
//! changes. Shaded in the same fragment as each surface (`fog.wgsl` `fog_shade`), so this pass
//! draws nothing into the scene itself.

use super::geometry::GeometryBuffers;
use super::{entry, uniform_buffer, write_uniform};
use crate::GpuContext;
use crate::shaders::Shader;
use glam::{Mat4, Vec3};
use lightloom_nodes::brdf::Lobe;
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{FrameMaterial, MAX_MATERIALS, SunFrame};

/// `sun.wgsl` `MAX_SUN_DIRECTIONS`.
pub(crate) const MAX_DIRECTIONS: usize = 32;
// Every direction of a disc is drawn (the rim ones are the last).
const _: () = assert!(lightloom_nodes::sun::DISC_SAMPLES <= MAX_DIRECTIONS);
/// Texels per side of each shadow map.
pub(crate) const SHADOW_MAP_SIZE: u32 = 1024;
const SHADOW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth16Unorm;
/// GPU memory of the shadow maps of a sun with the most directions.
pub const SHADOW_MAP_BYTES: usize = MAX_DIRECTIONS * (SHADOW_MAP_SIZE * SHADOW_MAP_SIZE) as usize * 2;
/// Normal offset against self-shadowing, in shadow-map texels.
const NORMAL_OFFSET_TEXELS: f32 = 1.5;

pub(crate) const SHADER: Shader = Shader::file("sun-depth", crate::shaders::source!("sun_depth.wgsl"));

/// `common.wgsl` `SpecularLobe`: a material's lobe ([`FrameMaterial::lobe`]).
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct SpecularLobe {
    /// 0 none, 1 Phong, 2 Blinn-Phong, 3 GGX, 4 Ward.
    pub(crate) model: u32,
    /// The exponent (the Phong models) or α along the tangent.
    pub(crate) sharpness: f32,
    /// Fresnel at normal incidence.
    pub(crate) reflectance: f32,
    /// α along the bitangent.
    pub(crate) alpha_y: f32,
    pub(crate) colour: Vec3,
}

impl SpecularLobe {
    fn of(material: &FrameMaterial) -> Self {
        let lightloom_nodes::frame::SpecularLobe { lobe, f0, colour } = material.lobe();
        let (model, sharpness, alpha_y) = match lobe {
            Lobe::None => (0, 0.0, 0.0),
            Lobe::Phong { exponent } => (1, exponent, 0.0),
            Lobe::BlinnPhong { exponent } => (2, exponent, 0.0),
            Lobe::Ggx { alpha_x, alpha_y } => (3, alpha_x, alpha_y),
            Lobe::Ward { alpha_x, alpha_y } => (4, alpha_x, alpha_y),
        };
        Self {
            model,
            sharpness: sharpness as f32,
            reflectance: f0 as f32,
            alpha_y: alpha_y as f32,
            colour: glam::DVec3::from(colour).as_vec3(),
        }
    }
}

/// `sun.wgsl` `Sun`.
#[derive(Clone, Default, encase::ShaderType)]
pub(crate) struct SunParams {
    /// Radiance × solid angle ÷ direction count.
    pub(crate) irradiance: Vec3,
    /// 0 without a separate sun.
    pub(crate) direction_count: u32,
    /// Offset along the normal against self-shadowing (world units).
    pub(crate) normal_offset: f32,
    /// How many of the last directions lie on the rim.
    pub(crate) rim_directions: u32,
    /// The disc's axis and the cosine of its angular radius.
    pub(crate) axis: Vec3,
    pub(crate) cos_radius: f32,
    pub(crate) directions: [Vec3; MAX_DIRECTIONS],
    pub(crate) view_proj: [Mat4; MAX_DIRECTIONS],
    /// Per material.
    pub(crate) lobes: [SpecularLobe; MAX_MATERIALS],
}

pub(crate) struct SunPass {
    pub layout: wgpu::BindGroupLayout,
    pub bind_group: wgpu::BindGroup,
    params: wgpu::Buffer,
    matrices: wgpu::Buffer,
    depth_bind_group: wgpu::BindGroup,
    depth_pipeline: wgpu::RenderPipeline,
    /// One layer per direction.
    shadow_maps: wgpu::Texture,
    /// The directions and geometry the maps were drawn for.
    drawn: Option<(Vec<[f32; 3]>, Key)>,
    /// The uniforms last written.
    written: SunParams,
}

impl SunPass {
    pub fn new(gpu: &GpuContext) -> Self {
        let device = &gpu.device;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("sun"),
            entries: &[
                entry::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                    count: None,
                },
            ],
        });
        let params = uniform_buffer::<SunParams>(device, "sun");
        write_uniform(&gpu.queue, &params, &SunParams::default());
        let matrices = uniform_buffer::<[Mat4; MAX_DIRECTIONS]>(device, "sun-depth");
        let shadow_maps = Self::shadow_maps(device, 1, 1);
        let bind_group = Self::bind(device, &layout, &params, &shadow_maps);
        let depth_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("sun-depth"),
            entries: &[entry::uniform(0, wgpu::ShaderStages::VERTEX)],
        });
        let depth_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("sun-depth"),
            layout: &depth_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: matrices.as_entire_binding() }],
        });
        let depth_pipeline = Self::depth_pipeline(device, &depth_layout);
        Self {
            layout,
            bind_group,
            params,
            matrices,
            depth_bind_group,
            depth_pipeline,
            shadow_maps,
            drawn: None,
            written: SunParams::default(),
        }
    }

    fn shadow_maps(device: &wgpu::Device, size: u32, layers: u32) -> wgpu::Texture {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some("sun-shadow-maps"),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: layers },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: SHADOW_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
    }

    fn bind(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
        shadow_maps: &wgpu::Texture,
    ) -> wgpu::BindGroup {
        let view = shadow_maps.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("sun-shadow"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("sun"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&sampler) },
            ],
        })
    }

    fn depth_pipeline(device: &wgpu::Device, layout: &wgpu::BindGroupLayout) -> wgpu::RenderPipeline {
        let module = SHADER.module(device, false);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(SHADER.label),
            bind_group_layouts: &[Some(layout)],
            immediate_size: 0,
        });
        let position = [wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x3, offset: 0, shader_location: 0 }];
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(SHADER.label),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<super::geometry::Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &position,
                })],
            },
            primitive: Default::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: SHADOW_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: wgpu::DepthBiasState { constant: 2, slope_scale: 1.5, clamp: 0.0 },
            }),
            multisample: Default::default(),
            fragment: None,
            multiview_mask: None,
            cache: None,
        })
    }

    /// Uploads the sun's uniforms and redraws its shadow maps when it turned or the geometry
    /// changed; without a sun (or geometry) the scene passes add nothing.
    pub fn prepare(
        &mut self,
        gpu: &GpuContext,
        sun: Option<&SunFrame>,
        materials: &[FrameMaterial],
        geometry: Option<&GeometryBuffers>,
    ) {
        let (Some(sun), Some(geometry)) = (sun, geometry) else {
            if self.drawn.take().is_some() {
                self.written = SunParams::default();
                write_uniform(&gpu.queue, &self.params, &self.written);
            }
            return;
        };
        let directions: Vec<[f32; 3]> = sun.directions.iter().take(MAX_DIRECTIONS).copied().collect();
        let (lo, hi) = (Vec3::from(geometry.bounds.0), Vec3::from(geometry.bounds.1));
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let share = sun.solid_angle / directions.len().max(1) as f64;
        let mut params = SunParams {
            irradiance: glam::DVec3::from(sun.radiance.map(|l| l * share)).as_vec3(),
            direction_count: directions.len() as u32,
            normal_offset: NORMAL_OFFSET_TEXELS * 2.0 * radius / SHADOW_MAP_SIZE as f32,
            rim_directions: sun.rim_directions as u32,
            axis: Vec3::from(sun.axis),
            cos_radius: sun.cos_radius as f32,
            ..SunParams::default()
        };
        for (k, d) in directions.iter().enumerate() {
            params.directions[k] = Vec3::from(*d);
            params.view_proj[k] = light_view_proj(params.directions[k], centre, radius);
        }
        for (slot, material) in params.lobes.iter_mut().zip(materials) {
            *slot = SpecularLobe::of(material);
        }
        // The radiance changes without the disc moving (exposure, tint, intensity): the uniforms
        // are written every frame, the maps only when the disc or the geometry changed.
        write_uniform(&gpu.queue, &self.params, &params);
        self.written = params;
        if self.drawn.as_ref().is_some_and(|(d, key)| *d == directions && *key == geometry.key()) {
            return;
        }
        write_uniform(&gpu.queue, &self.matrices, &self.written.view_proj);
        let layers = directions.len().max(1) as u32;
        if self.shadow_maps.depth_or_array_layers() != layers || self.shadow_maps.width() != SHADOW_MAP_SIZE {
            self.shadow_maps = Self::shadow_maps(&gpu.device, SHADOW_MAP_SIZE, layers);
            self.bind_group = Self::bind(&gpu.device, &self.layout, &self.params, &self.shadow_maps);
        }
        let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("sun") });
        for k in 0..directions.len() as u32 {
            let view = self.shadow_maps.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: k,
                array_layer_count: Some(1),
                ..Default::default()
            });
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("sun-shadow-map"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.depth_pipeline);
            pass.set_bind_group(0, &self.depth_bind_group, &[]);
            geometry.draw_instance(&mut pass, k);
        }
        gpu.queue.submit(Some(encoder.finish()));
        self.drawn = Some((directions, geometry.key()));
    }
}

/// World to clip space of an orthographic view along `-towards_sun` framing the sphere
/// (`centre`, `radius`), depth in [0, 1] front to back.
pub(crate) fn light_view_proj(towards_sun: Vec3, centre: Vec3, radius: f32) -> Mat4 {
    let eye = centre + towards_sun * (radius * 2.0);
    let up = if towards_sun.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
    let view = glam::camera::rh::view::look_at_mat4(eye, centre, up);
    glam::camera::rh::proj::directx::orthographic(-radius, radius, -radius, radius, radius * 0.5, radius * 3.5) * view
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightloom_nodes::engine::StageValue;
    use lightloom_nodes::frame::{Geometry, Keyed};
    use std::sync::Arc;

    /// A change of the sun's radiance alone (exposure, tint, intensity: the disc does not
    /// move) reaches the shader, and only a moved disc redraws the maps.
    #[test]
    fn a_brighter_sun_that_did_not_move_is_drawn_brighter() {
        let gpu = GpuContext::headless().expect("a wgpu device (lavapipe on machines without a GPU)");
        let meshes = lightloom_nodes::mesh::MeshSet { meshes: vec![lightloom_nodes::mesh::sphere(1.0, 8)] };
        let geometry =
            Geometry::of_meshes(Keyed { key: 1, value: Arc::new(StageValue::new(meshes)) }, vec![0]).unwrap();
        let mut buffers = None;
        GeometryBuffers::prepare(&mut buffers, &gpu, &geometry).unwrap();
        let disc = lightloom_nodes::sun::Sun { direction: [0.3, 0.8, -0.2], radius: 0.02, radiance: [100.0; 3] };
        let mut pass = SunPass::new(&gpu);
        pass.prepare(&gpu, Some(&SunFrame::new(&disc)), &[], buffers.as_ref());
        let before = pass.written.irradiance;
        let drawn = pass.drawn.clone();
        let brighter = lightloom_nodes::sun::Sun { radiance: [200.0; 3], ..disc };
        pass.prepare(&gpu, Some(&SunFrame::new(&brighter)), &[], buffers.as_ref());
        assert_eq!(pass.written.irradiance.x, 2.0 * before.x, "the radiance reaches the uniforms");
        assert_eq!(pass.drawn, drawn, "the maps are not redrawn for a brightness change");
        pass.prepare(&gpu, None, &[], buffers.as_ref());
        assert_eq!(pass.written.direction_count, 0, "no sun, no directions");
    }
}
