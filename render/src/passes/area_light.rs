//! Painted area lights: their per-vertex diffuse light and glossy highlights
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
}

pub(crate) struct AreaLightPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    /// The per-vertex irradiance and highlights, and the stage keys they came from.
    bound: Option<((Key, Option<Key>), wgpu::BindGroup)>,
}

impl AreaLightPass {
    pub fn new(setup: &PassSetup) -> Self {
        use wgpu::ShaderStages as S;
        let layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("area-lights"),
            entries: &[entry::uniform(0, S::VERTEX), entry::storage(1, S::VERTEX), entry::storage(2, S::VERTEX)],
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
        let keys = (data.irradiance.key, data.highlights.as_ref().map(|h| h.key));
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
            let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("area-lights"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: irradiance.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: highlights.as_entire_binding() },
                ],
            });
            self.bound = Some((keys, bind_group));
        }
        write_uniform(&gpu.queue, &self.params, &AreaLightParams { albedo: vec3s(&data.albedo) });
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
