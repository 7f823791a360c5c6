//! Group 0 of every scene pass: the camera (`common.wgsl` `Globals`).

use super::{entry, uniform_buffer, write_uniform};
use crate::GpuContext;
use glam::{Mat4, Vec3};

#[derive(encase::ShaderType)]
pub(crate) struct Globals {
    pub view_proj: glam::Mat4,
    pub inv_view_proj: glam::Mat4,
    pub camera_pos: glam::Vec3,
    /// 1 when the background is drawn.
    pub background: u32,
}

pub(crate) struct CameraBinding {
    pub layout: wgpu::BindGroupLayout,
    buffer: wgpu::Buffer,
    pub bind_group: wgpu::BindGroup,
}

impl CameraBinding {
    pub fn new(device: &wgpu::Device) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("camera"),
            entries: &[entry::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
        });
        let buffer = uniform_buffer::<Globals>(device, "camera");
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("camera"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: buffer.as_entire_binding() }],
        });
        Self { layout, buffer, bind_group }
    }

    pub fn write(&self, gpu: &GpuContext, view_proj: Mat4, position: Vec3, background: bool) {
        let globals = Globals {
            view_proj,
            inv_view_proj: view_proj.inverse(),
            camera_pos: position,
            background: u32::from(background),
        };
        write_uniform(&gpu.queue, &self.buffer, &globals);
    }
}
