//! Group 0 of every scene pass: the camera (`common.wgsl` `Globals`).

use super::{entry, uniform_buffer};
use crate::GpuContext;
use glam::{Mat4, Vec3};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Globals {
    pub view_proj: [[f32; 4]; 4],
    pub inv_view_proj: [[f32; 4]; 4],
    pub camera_pos: [f32; 4],
    /// y: 1 when the background is drawn.
    pub flags: [f32; 4],
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
            view_proj: view_proj.to_cols_array_2d(),
            inv_view_proj: view_proj.inverse().to_cols_array_2d(),
            camera_pos: position.extend(1.0).to_array(),
            flags: [0.0, if background { 1.0 } else { 0.0 }, 0.0, 0.0],
        };
        gpu.queue.write_buffer(&self.buffer, 0, bytemuck::bytes_of(&globals));
    }
}
