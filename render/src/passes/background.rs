//! The environment behind the scene (seen through the medium, `fog.wgsl` `fog_background`).

use super::geometry::GeometryBuffers;
use super::{Draw, Pass, PassSetup, entry, linear_sampler, stage_value, upload_layered};
use crate::shaders::Shader;
use crate::{GpuContext, RenderError};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::Background;

pub(crate) const SHADER: Shader = Shader::file("background", crate::shaders::source!("background.wgsl"));

pub(crate) struct BackgroundPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    sampler: wgpu::Sampler,
    bind_group: wgpu::BindGroup,
    /// The radiance stage the bound cube map came from.
    key: Option<Option<Key>>,
}

impl BackgroundPass {
    pub fn new(gpu: &GpuContext, setup: &PassSetup) -> Self {
        let layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("background"),
            entries: &[entry::texture(0, wgpu::TextureViewDimension::Cube, true), entry::sampler(1)],
        });
        let pipeline = setup.fullscreen_pipeline(SHADER, &layout);
        let sampler = linear_sampler(setup.device, "environment");
        let bind_group = Self::bind(gpu, &layout, &sampler, 1, &[[0.0; 3]; 6]);
        Self { layout, pipeline, sampler, bind_group, key: None }
    }

    fn bind(
        gpu: &GpuContext,
        layout: &wgpu::BindGroupLayout,
        sampler: &wgpu::Sampler,
        size: u32,
        texels: &[[f32; 3]],
    ) -> wgpu::BindGroup {
        let cube = upload_layered(gpu, "environment", (size, 1), 6, texels, wgpu::TextureViewDimension::Cube);
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("background"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&cube) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(sampler) },
            ],
        })
    }
}

impl Pass for BackgroundPass {
    type Data = Background;

    fn of(frame: &lightloom_nodes::frame::FrameInputs) -> Option<&Self::Data> {
        Some(&frame.background)
    }

    fn prepare(&mut self, gpu: &GpuContext, background: &Background) -> Result<(), RenderError> {
        let key = background.radiance.as_ref().map(|r| r.key);
        if self.key == Some(key) {
            return Ok(());
        }
        self.bind_group = match &background.radiance {
            Some(r) => {
                let cube = stage_value::<lightloom_nodes::cubemap::CubeMap>(r)?;
                Self::bind(gpu, &self.layout, &self.sampler, cube.size as u32, &cube.texels)
            }
            None => Self::bind(gpu, &self.layout, &self.sampler, 1, &[[0.0; 3]; 6]),
        };
        self.key = Some(key);
        Ok(())
    }
}

impl Draw for BackgroundPass {
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, _: Option<&GeometryBuffers>, _: bool) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(2, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
