//! Tone mapping: the HDR target through exposure and a display curve into the LDR target.

use super::{LDR_FORMAT, entry, pipeline, uniform_buffer, write_uniform};
use crate::GpuContext;
use crate::shaders::Shader;
use lightloom_nodes::kinds::output::Tonemap;

pub(crate) const SHADER: Shader = Shader::file("tonemap", crate::shaders::source!("tonemap.wgsl"));

/// `tonemap.wgsl` `ToneParams`.
#[derive(encase::ShaderType)]
pub(crate) struct ToneParams {
    /// `2^EV`.
    pub(crate) exposure_scale: f32,
    /// 0 ACES, 1 Reinhard, 2 linear clamp.
    pub(crate) curve: u32,
}

pub(crate) struct TonemapPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
}

impl TonemapPass {
    pub fn new(device: &wgpu::Device) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("tonemap"),
            entries: &[
                entry::texture(0, wgpu::TextureViewDimension::D2, false),
                entry::uniform(1, wgpu::ShaderStages::FRAGMENT),
            ],
        });
        let module = SHADER.module(device, false);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("tonemap"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline =
            pipeline(device, "tonemap", &pipeline_layout, &module, &[], None, Default::default(), LDR_FORMAT);
        Self { layout, pipeline, params: uniform_buffer::<ToneParams>(device, "tone") }
    }

    /// The bind group reading `hdr` (made once per target size).
    pub fn bind(&self, device: &wgpu::Device, hdr: &wgpu::TextureView) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("tonemap"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(hdr) },
                wgpu::BindGroupEntry { binding: 1, resource: self.params.as_entire_binding() },
            ],
        })
    }

    /// Tone-maps through `bind_group` (from [`Self::bind`]) into `ldr`.
    pub fn run(
        &self,
        gpu: &GpuContext,
        bind_group: &wgpu::BindGroup,
        ldr: &wgpu::TextureView,
        exposure: f64,
        tonemap: Tonemap,
    ) {
        let curve = match tonemap {
            Tonemap::Aces => 0,
            Tonemap::Reinhard => 1,
            Tonemap::Linear => 2,
        };
        let params = ToneParams { exposure_scale: 2f32.powf(exposure as f32), curve };
        write_uniform(&gpu.queue, &self.params, &params);
        let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("tonemap") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("tonemap"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: ldr,
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
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
        gpu.queue.submit(Some(encoder.finish()));
    }
}
