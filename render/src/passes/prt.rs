//! `sh_prt`: shadowed diffuse transfer and glossy lobes on the shadowed incident radiance, per
//! vertex (`nodes/src/prt.rs`).

use super::geometry::GeometryBuffers;
use super::{Draw, Pass, PassSetup, entry, stage_value, storage_buffer, uniform_buffer, vec4};
use crate::shaders::Shader;
use crate::{GpuContext, RenderError};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{MAX_MATERIALS, PrtSurfaces};

pub(crate) const SHADER: Shader = Shader::mesh("mesh_prt", "PRT");

/// Transport bands the shader evaluates (higher bands of the transport are dropped).
pub const MAX_PRT_BANDS: usize = 12;

/// `mesh_prt.wgsl` `PrtParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PrtParams {
    pub(crate) counts: [u32; 4],
    pub(crate) albedo: [[f32; 4]; MAX_MATERIALS],
    pub(crate) specular: [[f32; 4]; MAX_MATERIALS],
    pub(crate) lobe: [[f32; 4]; 3 * MAX_MATERIALS],
    pub(crate) light: [[f32; 4]; MAX_PRT_BANDS * MAX_PRT_BANDS],
}

pub(crate) struct PrtPass {
    layout: wgpu::BindGroupLayout,
    pipeline: super::SurfacePipelines,
    params: wgpu::Buffer,
    /// The per-vertex buffers and the transport and incident stages they came from.
    bound: Option<((Key, Key), wgpu::BindGroup)>,
}

impl PrtPass {
    pub fn new(setup: &PassSetup) -> Self {
        use wgpu::ShaderStages as S;
        let layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("prt"),
            entries: &[
                entry::uniform(0, S::VERTEX_FRAGMENT),
                entry::storage(1, S::VERTEX),
                entry::storage(2, S::VERTEX),
            ],
        });
        Self {
            pipeline: setup.surface_pipeline(SHADER, &layout),
            params: uniform_buffer::<PrtParams>(setup.device, "prt-params"),
            layout,
            bound: None,
        }
    }
}

impl Pass for PrtPass {
    type Data = PrtSurfaces;

    fn of(frame: &lightloom_nodes::frame::FrameInputs) -> Option<&Self::Data> {
        match &frame.surfaces {
            lightloom_nodes::frame::Surfaces::Prt(data) => Some(data),
            _ => None,
        }
    }

    fn prepare(&mut self, gpu: &GpuContext, data: &PrtSurfaces) -> Result<(), RenderError> {
        let t = stage_value::<lightloom_nodes::transport::ShTransport>(&data.transport)?;
        let r = lightloom_nodes::frame::incident_sh(&data.incident.value).map_err(RenderError::Invalid)?;
        let keys = (data.transport.key, data.incident.key);
        if self.bound.as_ref().is_none_or(|(k, _)| *k != keys) {
            let limit = gpu.device.limits().max_storage_buffer_binding_size;
            let bytes = (r.coeffs.len() as u64 * 4).max(t.transfer.len() as u64 * 4);
            if bytes > limit {
                return Err(RenderError::Invalid(format!(
                    "the SH modes need {} MiB of per-vertex coefficients here ({} bands), but this GPU binds at most \
                     {} MiB: lower the SH level or bands, or the tessellation",
                    bytes >> 20,
                    r.bands.max(t.bands),
                    limit >> 20
                )));
            }
            let transfer = storage_buffer(gpu, "prt-transfer", &t.transfer);
            let incident = storage_buffer(gpu, "prt-incident", &r.coeffs);
            let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("prt"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: transfer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: incident.as_entire_binding() },
                ],
            });
            self.bound = Some((keys, bind_group));
        }
        let n = t.bands * t.bands;
        let bands = t.bands.min(MAX_PRT_BANDS);
        let mut params: PrtParams = bytemuck::Zeroable::zeroed();
        let glossy_bands = if r.coeffs.is_empty() { 0 } else { r.bands.min(MAX_PRT_BANDS) };
        params.counts = [bands as u32, n as u32, (r.bands * r.bands * 3) as u32, glossy_bands as u32];
        for (dst, albedo) in params.albedo.iter_mut().zip(&data.albedo) {
            *dst = vec4(*albedo, 1.0);
        }
        for (i, lobe) in data.glossy.iter().enumerate().take(MAX_MATERIALS) {
            if let Some(lobe) = lobe {
                params.specular[i] = vec4(lobe.weight, 1.0);
                for (l, f) in lobe.factors.iter().enumerate().take(MAX_PRT_BANDS) {
                    params.lobe[3 * i + l / 4][l % 4] = *f as f32;
                }
            }
        }
        if let Some(light) = &data.light {
            for (dst, src) in params.light.iter_mut().zip(&light.coeffs).take(bands * bands) {
                *dst = vec4(*src, 0.0);
            }
        }
        gpu.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        Ok(())
    }
}

impl Draw for PrtPass {
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, geometry: Option<&GeometryBuffers>, normal_maps: bool) {
        let (Some(geometry), Some((_, bind_group))) = (geometry, &self.bound) else { return };
        pass.set_pipeline(self.pipeline.get(normal_maps));
        pass.set_bind_group(2, bind_group, &[]);
        geometry.draw(pass);
    }
}
