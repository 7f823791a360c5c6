//! The `rsl` mode: square lights per vertex (`nodes/src/rsl/`, Xu et al. 2006 eq. 5). The
//! shader sums each light's energy times its visibility (from the CPU) and the BRDF's means
//! over its square (summed-area tables).

use super::geometry::GeometryBuffers;
use super::{Draw, Pass, PassSetup, entry, stage_value, storage_buffer, uniform_buffer, vec3s, write_uniform};
use crate::shaders::Shader;
use crate::{GpuContext, RenderError};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{MAX_MATERIALS, RslSurfaces};
use lightloom_nodes::rsl::shade::LightVisibility;

pub(crate) const SHADER: Shader = Shader::mesh("mesh_rsl", "RSL");

/// `mesh_rsl.wgsl` `RslParams`.
#[derive(encase::ShaderType)]
pub(crate) struct RslParams {
    pub(crate) lights: u32,
    /// Texels per side of every table.
    pub(crate) table_size: u32,
    pub(crate) albedo: [glam::Vec3; MAX_MATERIALS],
    pub(crate) specular: [glam::Vec3; MAX_MATERIALS],
    pub(crate) layouts: [RslLayout; MAX_MATERIALS],
}

/// `mesh_rsl.wgsl` `RslLayout`: where a material's tables start and how they are sliced.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct RslLayout {
    /// Its first float in the tables (16-byte aligned: a uniform array's elements are 16
    /// bytes apart).
    #[shader(align(16))]
    pub(crate) first: u32,
    /// 0 no lobe, 1 isotropic, 2 anisotropic.
    pub(crate) view_grid: u32,
    /// θ₀ slices, or view slices per side.
    pub(crate) slices: u32,
}

struct Bound {
    key: Key,
    bind_group: wgpu::BindGroup,
}

pub(crate) struct RslPass {
    layout: wgpu::BindGroupLayout,
    pipeline: super::SurfacePipelines,
    params: wgpu::Buffer,
    bound: Option<Bound>,
}

impl RslPass {
    pub fn new(setup: &PassSetup) -> Self {
        use wgpu::ShaderStages as S;
        let layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("rsl"),
            entries: &[
                entry::uniform(0, S::VERTEX_FRAGMENT),
                entry::storage(1, S::VERTEX),
                entry::storage(2, S::VERTEX),
                entry::storage(3, S::VERTEX),
            ],
        });
        Self {
            pipeline: setup.surface_pipeline(SHADER, &layout),
            params: uniform_buffer::<RslParams>(setup.device, "rsl-params"),
            layout,
            bound: None,
        }
    }

    fn upload(&self, gpu: &GpuContext, data: &RslSurfaces) -> Result<Bound, RenderError> {
        let limit = gpu.device.limits().max_storage_buffer_binding_size;
        let visibility = stage_value::<LightVisibility>(&data.visibility)?;
        let bytes = visibility.values.len() as u64 * 4;
        if bytes > limit || data.tables.len() as u64 * 4 > limit {
            return Err(RenderError::Invalid(format!(
                "the rsl mode needs {} MiB of per-vertex visibility ({} vertices × {} lights) and {} MiB of BRDF \
                 tables, but this GPU binds at most {} MiB: use fewer lights or vertices",
                bytes >> 20,
                visibility.vertices,
                visibility.lights,
                (data.tables.len() * 4) >> 20,
                limit >> 20
            )));
        }
        let lights: Vec<f32> = data.lights.iter().flatten().copied().collect();
        let lights = storage_buffer(gpu, "rsl-lights", &lights);
        let values = storage_buffer(gpu, "rsl-visibility", &visibility.values);
        let tables = storage_buffer(gpu, "rsl-tables", &data.tables);
        fn resource(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("rsl"),
            layout: &self.layout,
            entries: &[resource(0, &self.params), resource(1, &lights), resource(2, &values), resource(3, &tables)],
        });
        Ok(Bound { key: data.key, bind_group })
    }
}

impl Pass for RslPass {
    type Data = RslSurfaces;

    fn of(frame: &lightloom_nodes::frame::FrameInputs) -> Option<&Self::Data> {
        match &frame.surfaces {
            lightloom_nodes::frame::Surfaces::Rsl(data) => Some(data),
            _ => None,
        }
    }

    fn prepare(&mut self, gpu: &GpuContext, data: &RslSurfaces) -> Result<(), RenderError> {
        if self.bound.as_ref().is_none_or(|b| b.key != data.key) {
            self.bound = None;
            self.bound = Some(self.upload(gpu, data)?);
        }
        let layouts = std::array::from_fn(|m| {
            data.layouts.get(m).map_or_else(RslLayout::default, |l| RslLayout {
                first: l[0],
                view_grid: l[1],
                slices: l[2],
            })
        });
        let params = RslParams {
            lights: data.lights.len() as u32,
            table_size: data.table_size as u32,
            albedo: vec3s(&data.albedo),
            specular: vec3s(&data.specular),
            layouts,
        };
        write_uniform(&gpu.queue, &self.params, &params);
        Ok(())
    }
}

impl Draw for RslPass {
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, geometry: Option<&GeometryBuffers>, normal_maps: bool) {
        let (Some(geometry), Some(bound)) = (geometry, &self.bound) else { return };
        pass.set_pipeline(self.pipeline.get(normal_maps));
        pass.set_bind_group(2, &bound.bind_group, &[]);
        geometry.draw(pass);
    }
}
