//! `common.wgsl`'s functions run on the device against the Rust they mirror.

use super::entry;
use crate::GpuContext;
use glam::Vec3;
use wgpu::util::DeviceExt;

/// `frame_tangent(n, t)` for each `(n, t)` pair, computed by a compute shader.
fn frame_tangents_on_device(gpu: &GpuContext, pairs: &[(Vec3, Vec3)]) -> Vec<Vec3> {
    let kernel = "
#import lightloom::common::frame_tangent
@group(1) @binding(0) var<storage, read> pairs: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read_write> tangents: array<vec4<f32>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x < arrayLength(&tangents)) {
        tangents[id.x] = vec4<f32>(frame_tangent(pairs[2u * id.x].xyz, pairs[2u * id.x + 1u].xyz), 0.0);
    }
}";
    let device = &gpu.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("frame_tangent"),
        source: wgpu::ShaderSource::Naga(std::borrow::Cow::Owned(
            crate::shaders::compose_source(kernel).unwrap_or_else(|e| panic!("{e}")),
        )),
    });
    let compute = wgpu::ShaderStages::COMPUTE;
    let globals = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("globals"),
        entries: &[entry::uniform(0, compute)],
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("frame_tangent"),
        entries: &[entry::storage(0, compute), entry::storage_read_write(1, compute)],
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("frame_tangent"),
        layout: Some(&device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("frame_tangent"),
            bind_group_layouts: &[Some(&globals), Some(&layout)],
            immediate_size: 0,
        })),
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let words: Vec<[f32; 4]> =
        pairs.iter().flat_map(|(n, t)| [n.extend(0.0).to_array(), t.extend(0.0).to_array()]).collect();
    let storage = |label, contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
    };
    let input = storage("pairs", bytemuck::cast_slice(&words), wgpu::BufferUsages::STORAGE);
    let size = (pairs.len() * 16) as u64;
    let output = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("tangents"),
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let camera = storage("globals", &[0u8; 160], wgpu::BufferUsages::UNIFORM);
    let group = |layout, buffers: &[&wgpu::Buffer]| {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout, entries: &entries })
    };
    let (globals_group, group) = (group(&globals, &[&camera]), group(&layout, &[&input, &output]));
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &globals_group, &[]);
        pass.set_bind_group(1, &group, &[]);
        pass.dispatch_workgroups(pairs.len().div_ceil(64) as u32, 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &readback, 0, size);
    gpu.queue.submit([encoder.finish()]);
    crate::capture::read_mapped(device, &readback, |bytes| {
        bytemuck::cast_slice::<u8, [f32; 4]>(bytes).iter().map(|v| Vec3::new(v[0], v[1], v[2])).collect()
    })
    .expect("the tangents read back")
}

/// The viewport's shading tangent is the CPU shading's (`shading_frame`: `(t - n n·t)`
/// normalised, else glam's `any_orthonormal_vector(n)`, as the Monte Carlo reference takes
/// it): for ordinary tangents and zero ones (interpolated tangents that cancel), at normals with
/// z of either sign, -0 included.
#[test]
fn the_shading_tangent_falls_back_as_the_reference_does() {
    let gpu = GpuContext::headless().expect("a wgpu device (lavapipe on machines without a GPU)");
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut random = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    };
    let mut normals: Vec<Vec3> =
        (0..200).map(|_| Vec3::new(random(), random(), random()).normalize_or(Vec3::Y)).collect();
    normals.extend([Vec3::X, Vec3::Y, Vec3::Z, -Vec3::Z, Vec3::new(0.6, 0.8, -0.0), Vec3::new(0.6, -0.8, 0.0)]);
    let mut pairs = Vec::new();
    for &n in &normals {
        pairs.push((n, Vec3::new(random(), random(), random())));
        pairs.push((n, Vec3::ZERO));
    }
    let device = frame_tangents_on_device(&gpu, &pairs);
    for (&(n, t), got) in pairs.iter().zip(&device) {
        let expected = lightloom_nodes::rsl::shade::shading_frame(n.as_dvec3(), t.as_dvec3()).x_axis;
        assert!(
            (got.as_dvec3() - expected).length() < 1e-4,
            "n {n}, t {t}: the device gives {got}, the reference {expected}"
        );
    }
}
