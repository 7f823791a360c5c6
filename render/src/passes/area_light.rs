//! Painted area lights: their diffuse light (per vertex, or per texel on meshes with a
//! visibility texture) and per-vertex glossy highlights
//! (`nodes/src/near_field.rs`, Sun 2008 §4.5 and §4.9) drawn additively over whichever mode
//! drew the surfaces ([`AreaLightFrame`]).

use super::geometry::GeometryBuffers;
use super::{Draw, Pass, PassSetup, entry, stage_value, storage_buffer, uniform_buffer, vec3s, write_uniform};
use crate::shaders::Shader;
use crate::{GpuContext, RenderError};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{AreaLightFrame, MAX_MATERIALS};
use lightloom_nodes::kinds::output::area::{AreaHighlights, AreaIrradiance};

pub(crate) const SHADER: Shader = Shader::mesh("mesh_area", "AREA");

/// `mesh_area.wgsl` `AreaLights`.
#[derive(encase::ShaderType)]
pub(crate) struct AreaLightParams {
    pub(crate) albedo: [glam::Vec3; MAX_MATERIALS],
    /// 1 when per-texel irradiance is bound, and its layers' side.
    pub(crate) texels_bound: u32,
    pub(crate) texel_size: u32,
}

/// The keys of the per-vertex irradiance, the highlights and the per-texel irradiance.
type BoundKeys = (Key, Option<Key>, Option<Key>);

pub(crate) struct AreaLightPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    /// The per-vertex irradiance and highlights and the per-texel irradiance, and the keys they
    /// came from.
    bound: Option<(BoundKeys, wgpu::BindGroup)>,
}

impl AreaLightPass {
    pub fn new(setup: &PassSetup) -> Self {
        use wgpu::ShaderStages as S;
        let layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("area-lights"),
            entries: &[
                entry::uniform(0, S::VERTEX_FRAGMENT),
                entry::storage(1, S::VERTEX),
                entry::storage(2, S::VERTEX),
                entry::storage(3, S::FRAGMENT),
                entry::storage(4, S::VERTEX),
            ],
        });
        Self {
            pipeline: setup.additive_surface_pipeline(SHADER, &layout),
            params: uniform_buffer::<AreaLightParams>(setup.device, "area-light-params"),
            layout,
            bound: None,
        }
    }

    /// Forgets the last frame's lights (a frame without area lights draws nothing here).
    pub fn clear(&mut self) {
        self.bound = None;
    }
}

impl Pass for AreaLightPass {
    type Data = AreaLightFrame;

    fn of(frame: &lightloom_nodes::frame::FrameInputs) -> Option<&Self::Data> {
        frame.area_lights.as_ref()
    }

    fn absent(&mut self) {
        self.clear();
    }

    fn prepare(&mut self, gpu: &GpuContext, data: &AreaLightFrame) -> Result<(), RenderError> {
        let keys = (data.irradiance.key, data.highlights.as_ref().map(|h| h.key), data.texels.as_ref().map(|t| t.key));
        if self.bound.as_ref().is_none_or(|(k, _)| *k != keys) {
            let e = stage_value::<AreaIrradiance>(&data.irradiance)?;
            let rgba: Vec<[f32; 4]> = e.irradiance.iter().map(|c| [c[0], c[1], c[2], 0.0]).collect();
            let irradiance = storage_buffer(gpu, "area-irradiance", &rgba);
            // Without highlights (no glossy material, or not yet computed for this view): zeros.
            let highlights = match &data.highlights {
                Some(h) => stage_value::<AreaHighlights>(h)?.radiance.iter().map(|c| [c[0], c[1], c[2], 0.0]).collect(),
                None => Vec::new(),
            };
            let highlights =
                if highlights.len() == rgba.len() { highlights } else { vec![[0.0f32; 4]; rgba.len().max(1)] };
            let highlights = storage_buffer(gpu, "area-highlights", &highlights);
            // Without texels: one unused slot each.
            let (texel_values, vertex_layers) = match &data.texels {
                Some(t) => (t.irradiance.as_slice(), t.vertex_layers.as_slice()),
                None => (&[][..], &[][..]),
            };
            let texel_irradiance = storage_buffer(gpu, "area-texel-irradiance", texel_values);
            let vertex_layers = storage_buffer(gpu, "area-vertex-layers", vertex_layers);
            let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("area-lights"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: irradiance.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: highlights.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: texel_irradiance.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: vertex_layers.as_entire_binding() },
                ],
            });
            self.bound = Some((keys, bind_group));
        }
        let params = AreaLightParams {
            albedo: vec3s(&data.albedo),
            texels_bound: u32::from(data.texels.is_some()),
            texel_size: data.texels.as_ref().map_or(0, |t| t.size as u32),
        };
        write_uniform(&gpu.queue, &self.params, &params);
        Ok(())
    }
}

impl Draw for AreaLightPass {
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, geometry: Option<&GeometryBuffers>, _: bool) {
        let (Some(geometry), Some((_, bind_group))) = (geometry, &self.bound) else { return };
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(2, bind_group, &[]);
        geometry.draw(pass);
    }
}
