//! `sh_irradiance`: unshadowed diffuse light per pixel from the irradiance SH (Sun 2008 eq.
//! 2.20); the coefficients arrive convolved ([`IrradianceSurfaces`]).

use super::geometry::GeometryBuffers;
use super::{Draw, Pass, PassSetup, entry, uniform_buffer, vec3s, write_uniform};
use crate::shaders::Shader;
use crate::{GpuContext, RenderError};
use lightloom_nodes::frame::{IRRADIANCE_BANDS, IrradianceSurfaces, MAX_MATERIALS};

pub(crate) const SHADER: Shader = Shader::mesh("mesh_irradiance", "IRRADIANCE");

/// `mesh_irradiance.wgsl` `Irradiance`.
#[derive(encase::ShaderType)]
pub(crate) struct IrradianceParams {
    /// SH bands (0 without an environment).
    pub(crate) bands: u32,
    pub(crate) albedo: [glam::Vec3; MAX_MATERIALS],
    pub(crate) coeffs: [glam::Vec3; IRRADIANCE_BANDS * IRRADIANCE_BANDS],
}

pub(crate) struct IrradiancePass {
    pipeline: super::SurfacePipelines,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl IrradiancePass {
    pub fn new(setup: &PassSetup) -> Self {
        let layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("irradiance"),
            entries: &[entry::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
        });
        let params = uniform_buffer::<IrradianceParams>(setup.device, "irradiance");
        let bind_group = setup.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("irradiance"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() }],
        });
        Self { pipeline: setup.surface_pipeline(SHADER, &layout), params, bind_group }
    }
}

impl Pass for IrradiancePass {
    type Data = IrradianceSurfaces;

    fn of(frame: &lightloom_nodes::frame::FrameInputs) -> Option<&Self::Data> {
        match &frame.surfaces {
            lightloom_nodes::frame::Surfaces::Irradiance(data) => Some(data),
            _ => None,
        }
    }

    fn prepare(&mut self, gpu: &GpuContext, data: &IrradianceSurfaces) -> Result<(), RenderError> {
        let bands = data.irradiance.as_ref().map_or(0, |e| e.bands.min(IRRADIANCE_BANDS));
        let coeffs = data.irradiance.as_ref().map_or(&[][..], |e| &e.coeffs[..bands * bands]);
        let params = IrradianceParams { bands: bands as u32, albedo: vec3s(&data.albedo), coeffs: vec3s(coeffs) };
        write_uniform(&gpu.queue, &self.params, &params);
        Ok(())
    }
}

impl Draw for IrradiancePass {
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, geometry: Option<&GeometryBuffers>, normal_maps: bool) {
        let Some(geometry) = geometry else { return };
        pass.set_pipeline(self.pipeline.get(normal_maps));
        pass.set_bind_group(2, &self.bind_group, &[]);
        geometry.draw(pass);
    }
}
