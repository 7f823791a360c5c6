//! The scene's meshes on the GPU: one vertex and index buffer shared by every surface pass.

use super::stage_value;
use crate::{GpuContext, RenderError};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::Geometry;
use wgpu::util::DeviceExt;

/// `common.wgsl` `MeshVertex`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    color: [f32; 3],
    /// The local frame's tangent (as the transport stages use it) and, in w, the sign of the
    /// normal map's bitangent `w · n × t` ([`lightloom_nodes::mesh::VertexFrames`]).
    tangent: [f32; 4],
    uv: [f32; 2],
    /// Index into the frame's materials.
    material: u32,
}

pub(crate) const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 6] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x4, 4 => Float32x2, 5 => Uint32
];

pub(crate) struct GeometryBuffers {
    key: Key,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    pub bounds: ([f32; 3], [f32; 3]),
}

impl GeometryBuffers {
    /// Re-uploads `geometry` into `slot` when its meshes or material assignment changed.
    pub fn prepare(slot: &mut Option<Self>, gpu: &GpuContext, geometry: &Geometry) -> Result<(), RenderError> {
        let assignment = geometry.mesh_materials.iter().fold(0u128, |h, m| h.rotate_left(3) ^ (*m as u128 + 1));
        let key = geometry.meshes.key ^ assignment.rotate_left(17) ^ geometry.frames.key.rotate_left(41);
        if slot.as_ref().is_some_and(|m| m.key == key) {
            return Ok(());
        }
        let set = stage_value::<lightloom_nodes::mesh::MeshSet>(&geometry.meshes)?;
        let frames = &stage_value::<lightloom_nodes::mesh::VertexFrames>(&geometry.frames)?.tangents;
        let vertex_count: usize = set.meshes.iter().map(|m| m.positions.len()).sum();
        if frames.len() != vertex_count {
            return Err(RenderError::Invalid(format!(
                "the scene's tangent frames cover {} of its {vertex_count} vertices",
                frames.len()
            )));
        }
        let mut frames = frames.iter();
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        for (m, mesh) in set.meshes.iter().enumerate() {
            let base = vertices.len() as u32;
            let material = geometry.mesh_materials.get(m).copied().unwrap_or(0);
            for i in 0..mesh.positions.len() {
                vertices.push(Vertex {
                    position: mesh.positions[i],
                    normal: mesh.normals[i],
                    color: mesh.base_color,
                    tangent: *frames.next().expect("one frame per vertex, checked above"),
                    uv: mesh.uvs.get(i).copied().unwrap_or([0.0; 2]),
                    material,
                });
            }
            indices.extend(mesh.indices.iter().map(|i| i + base));
        }
        if indices.is_empty() {
            *slot = None;
            return Ok(());
        }
        let buffer = |label, contents: &[u8], usage| {
            gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        *slot = Some(Self {
            key,
            vertices: buffer("vertices", bytemuck::cast_slice(&vertices), wgpu::BufferUsages::VERTEX),
            indices: buffer("indices", bytemuck::cast_slice(&indices), wgpu::BufferUsages::INDEX),
            index_count: indices.len() as u32,
            bounds: set.bounds(),
        });
        Ok(())
    }

    /// Draws every mesh with the pipeline and groups already set.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        self.draw_instance(pass, 0);
    }

    /// [`Self::draw`] as instance `instance` (a shader's index into per-draw data).
    pub fn draw_instance(&self, pass: &mut wgpu::RenderPass<'_>, instance: u32) {
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.index_count, 0, instance..instance + 1);
    }

    /// The meshes and material assignment these buffers hold.
    pub fn key(&self) -> Key {
        self.key
    }
}
