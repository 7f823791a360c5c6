//! `sh_prt`: shadowed diffuse transfer and glossy lobes on the shadowed incident radiance, per
//! vertex (`nodes/src/prt.rs`).

use super::geometry::GeometryBuffers;
use super::{Draw, Pass, PassSetup, entry, stage_value, storage_buffer, uniform_buffer, vec3s, write_uniform};
use crate::shaders::Shader;
use crate::{GpuContext, RenderError};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{MAX_MATERIALS, PrtSurfaces};

pub(crate) const SHADER: Shader = Shader::mesh("mesh_prt", "PRT");

/// Transport bands the shader evaluates (higher bands of the transport are dropped).
pub const MAX_PRT_BANDS: usize = 12;

/// `mesh_prt.wgsl` `PrtParams`.
#[derive(encase::ShaderType)]
pub(crate) struct PrtParams {
    /// Bands of the diffuse transfer read (at most [`MAX_PRT_BANDS`]).
    pub(crate) diffuse_bands: u32,
    /// Floats per vertex of the transfer and of the incident radiance.
    pub(crate) transfer_stride: u32,
    pub(crate) incident_stride: u32,
    /// Bands of the incident radiance `R` (0 when none is bound).
    pub(crate) incident_bands: u32,
    pub(crate) materials: [PrtMaterial; MAX_MATERIALS],
    /// The lighting `L_k`, index `l(l+1)+m`.
    pub(crate) light: [glam::Vec3; MAX_PRT_BANDS * MAX_PRT_BANDS],
}

/// `mesh_prt.wgsl` `PrtMaterial`.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct PrtMaterial {
    pub(crate) albedo: glam::Vec3,
    /// 1 with a glossy lobe.
    pub(crate) glossy: u32,
    /// The lobe's weight.
    pub(crate) weight: glam::Vec3,
    /// Its per-band factors `f_l`, `l` at `[l / 4][l % 4]` (a uniform array's elements are 16
    /// bytes apart).
    pub(crate) factors: [glam::Vec4; 3],
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
        let glossy_bands = if r.coeffs.is_empty() { 0 } else { r.bands.min(MAX_PRT_BANDS) };
        let albedo: [glam::Vec3; MAX_MATERIALS] = vec3s(&data.albedo);
        let materials = std::array::from_fn(|i| {
            let mut material = PrtMaterial { albedo: albedo[i], ..Default::default() };
            if let Some(Some(lobe)) = data.glossy.get(i) {
                material.glossy = 1;
                material.weight = glam::DVec3::from(lobe.weight).as_vec3();
                for (l, f) in lobe.factors.iter().enumerate().take(MAX_PRT_BANDS) {
                    material.factors[l / 4][l % 4] = *f as f32;
                }
            }
            material
        });
        let light = data.light.as_ref().map_or(&[][..], |l| &l.coeffs[..(bands * bands).min(l.coeffs.len())]);
        let params = PrtParams {
            diffuse_bands: bands as u32,
            transfer_stride: n as u32,
            incident_stride: (r.bands * r.bands * 3) as u32,
            incident_bands: glossy_bands as u32,
            materials,
            light: vec3s(light),
        };
        write_uniform(&gpu.queue, &self.params, &params);
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
