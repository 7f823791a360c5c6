//! The wavelet modes: the local-frame triple product per vertex, and per pixel from the
//! visibility textures' texels (`nodes/src/triple_product.rs`, Ma et al. eq. 7).

use super::geometry::GeometryBuffers;
use super::{
    Draw, Pass, PassSetup, entry, linear_sampler, stage_value, storage_buffer, uniform_buffer, upload_layered, vec4,
};
use crate::{GpuContext, RenderError};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{MAX_MATERIALS, WaveletSurfaces};
use lightloom_nodes::triple_product::{LocalProducts, PHI_STEPS, THETA_STEPS, TexelIrradiance};

pub(crate) const SHADER: (&str, &str) = ("mesh_wavelet.wgsl", include_str!("../../../shaders/mesh_wavelet.wgsl"));

/// `mesh_wavelet.wgsl` `WaveletParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct WaveletParams {
    pub(crate) counts: [u32; 4],
    pub(crate) albedo: [[f32; 4]; MAX_MATERIALS],
    pub(crate) specular: [[f32; 4]; MAX_MATERIALS],
    pub(crate) texels: [u32; 4],
}

/// What is bound: the frame data's key, and the texel size when per-texel data is.
struct Bound {
    key: Key,
    texel_size: Option<u32>,
    bind_group: wgpu::BindGroup,
}

pub(crate) struct WaveletPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    sampler: wgpu::Sampler,
    bound: Option<Bound>,
}

impl WaveletPass {
    pub fn new(setup: &PassSetup) -> Self {
        use wgpu::ShaderStages as S;
        let layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("wavelet"),
            entries: &[
                entry::uniform(0, S::VERTEX_FRAGMENT),
                entry::storage(1, S::VERTEX),
                entry::storage(2, S::VERTEX),
                entry::storage(3, S::VERTEX_FRAGMENT),
                entry::texture(4, wgpu::TextureViewDimension::D2Array, true),
                entry::sampler(5),
                entry::storage(6, S::FRAGMENT),
                entry::storage(7, S::VERTEX),
            ],
        });
        Self {
            pipeline: setup.surface_pipeline(SHADER, &layout),
            params: uniform_buffer::<WaveletParams>(setup.device, "wavelet-params"),
            sampler: linear_sampler(setup.device, "texel-diffuse"),
            layout,
            bound: None,
        }
    }

    fn upload(&self, gpu: &GpuContext, data: &WaveletSurfaces) -> Result<Bound, RenderError> {
        let limit = gpu.device.limits().max_storage_buffer_binding_size;
        let p = stage_value::<LocalProducts>(&data.products)?;
        let bytes = p.values.len() as u64 / 3 * 4;
        if bytes > limit {
            return Err(RenderError::Invalid(format!(
                "the wavelet mode needs {} MiB per-vertex data ({} vertices × {} cells) but this GPU binds at \
                 most {} MiB: use 80 coefficients or fewer vertices",
                bytes >> 20,
                data.vertex_layers.len(),
                p.cells,
                limit >> 20
            )));
        }
        let texels = data.texels.as_ref().map(stage_value::<TexelIrradiance>).transpose()?;
        // P packed as RGB9E5: 4 bytes per cell instead of 12.
        let texel_packed = texels.map_or(Vec::new(), |t| crate::packing::rgb9e5_all(&t.products));
        if texel_packed.len() as u64 * 4 > limit {
            return Err(RenderError::Invalid(format!(
                "the visibility textures' per-texel data needs {} MiB but this GPU binds at most {} MiB: \
                 use a smaller visibility texture size or 80 coefficients",
                (texel_packed.len() * 4) >> 20,
                limit >> 20
            )));
        }
        let products = storage_buffer(gpu, "wavelet-products", &crate::packing::rgb9e5_all(&p.values));
        let diffuse = storage_buffer(gpu, "wavelet-diffuse", &data.diffuse_table);
        let specular = storage_buffer(gpu, "wavelet-specular", &data.specular_tables);
        let texel_view = match texels {
            Some(t) => {
                let layers = (t.texels.len() / (t.size * t.size).max(1)).max(1) as u32;
                let size = t.size as u32;
                upload_layered(gpu, "texel-diffuse", size, layers, &t.texels, wgpu::TextureViewDimension::D2Array)
            }
            None => upload_layered(gpu, "texel-diffuse", 1, 1, &[[0.0; 3]], wgpu::TextureViewDimension::D2Array),
        };
        let texel_products = storage_buffer(gpu, "wavelet-texel-products", &texel_packed);
        let layers = storage_buffer(gpu, "wavelet-vertex-layers", &data.vertex_layers);
        fn resource(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("wavelet"),
            layout: &self.layout,
            entries: &[
                resource(0, &self.params),
                resource(1, &products),
                resource(2, &diffuse),
                resource(3, &specular),
                wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&texel_view) },
                wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::Sampler(&self.sampler) },
                resource(6, &texel_products),
                resource(7, &layers),
            ],
        });
        Ok(Bound { key: data.key, texel_size: texels.map(|t| t.size as u32), bind_group })
    }
}

impl Pass for WaveletPass {
    type Data = WaveletSurfaces;

    fn prepare(&mut self, gpu: &GpuContext, data: &WaveletSurfaces) -> Result<(), RenderError> {
        if self.bound.as_ref().is_none_or(|b| b.key != data.key) {
            self.bound = None;
            self.bound = Some(self.upload(gpu, data)?);
        }
        let bound = self.bound.as_ref().expect("uploaded above");
        let cells = data.cells as u32;
        let mut params: WaveletParams = bytemuck::Zeroable::zeroed();
        params.counts =
            [cells, WaveletSurfaces::specular_stride(data.cells) as u32, THETA_STEPS as u32, PHI_STEPS as u32];
        for (dst, albedo) in params.albedo.iter_mut().zip(&data.albedo) {
            *dst = vec4(*albedo, 1.0);
        }
        for (dst, specular) in params.specular.iter_mut().zip(&data.specular) {
            *dst = specular.map_or([0.0; 4], |s| vec4(s, 1.0));
        }
        params.texels = [bound.texel_size.is_some() as u32, bound.texel_size.unwrap_or(0), 0, 0];
        gpu.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        Ok(())
    }
}

impl Draw for WaveletPass {
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, geometry: Option<&GeometryBuffers>) {
        let (Some(geometry), Some(bound)) = (geometry, &self.bound) else { return };
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(2, &bound.bind_group, &[]);
        geometry.draw(pass);
    }
}
