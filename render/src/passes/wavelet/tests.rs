use super::*;
use crate::passes::camera::CameraBinding;
use crate::passes::medium::MediumPass;
use lightloom_nodes::engine::{CancelToken, StageValue};
use lightloom_nodes::frame::{FrameMaterial, Geometry, Keyed, WaveletLighting};
use lightloom_nodes::mesh::{MeshSet, sphere};
use lightloom_nodes::transport::Receivers;
use lightloom_nodes::triple_product::{CellGrid, LocalVisibility, diffuse_transfer, prefiltered, tabulate_brdf};
use std::sync::Arc;

/// A deterministic stream in [0, 1).
fn uniform(state: &mut u64) -> f64 {
    *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 53) as f64
}

fn keyed(key: u128, value: StageValue) -> Keyed {
    Keyed { key, value: Arc::new(value) }
}

/// A sphere's vertices with random visibility cells (a third of them blocked), under a random
/// environment with a bright sun, rotated arbitrarily.
fn surfaces(cells: usize, rotation: glam::DMat3) -> WaveletSurfaces {
    surfaces_of(cells, rotation, lightloom_nodes::brdf::Material::default(), 0)
}

fn surfaces_of(
    cells: usize,
    rotation: glam::DMat3,
    material: lightloom_nodes::brdf::Material,
    details: usize,
) -> WaveletSurfaces {
    let mut state = 9;
    let meshes = MeshSet { meshes: vec![sphere(1.0, 12)] };
    let receivers = Receivers::from_meshes(&meshes);
    let values = (0..receivers.len() * cells)
        .map(|_| {
            let u = uniform(&mut state);
            if u < 0.33 { 0.0 } else { u as f32 }
        })
        .collect();
    let grid = CellGrid::for_coefficients(cells).unwrap();
    let sun = glam::DVec3::new(0.3, 0.8, -0.5).normalize();
    let environment = lightloom_nodes::cubemap::CubeMap::from_fn(64, 1, |d| {
        let glow = if d.dot(sun) > 0.995 { 500.0 } else { 0.0 };
        [0.2 + glow + d.x.abs(), 0.4 + 0.5 * glow * d.y.max(0.0), 0.6 + 0.3 * d.z + glow]
    });
    let table =
        tabulate_brdf(&lightloom_nodes::brdf::Brdf::from_material(&material), grid, &CancelToken::default()).unwrap();
    let lighting = WaveletLighting {
        visibility: keyed(1, StageValue::new(LocalVisibility { cells, values })),
        receivers: keyed(2, StageValue::new(receivers)),
        environment: keyed(3, StageValue::new(prefiltered(&environment, grid))),
        rotation,
    };
    let geometry = Geometry::of_meshes(keyed(4, StageValue::new(meshes)), vec![0]).unwrap();
    let materials = [FrameMaterial::new("m", material, None)];
    WaveletSurfaces::new(lighting, &[keyed(5, StageValue::new(table))], None, None, &geometry, &materials, details)
        .unwrap()
}

fn read(gpu: &GpuContext, buffer: &wgpu::Buffer) -> Vec<u8> {
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: buffer.size(),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, buffer.size());
    gpu.queue.submit([encoder.finish()]);
    crate::capture::read_mapped(&gpu.device, &staging, |bytes| bytes.to_vec()).unwrap()
}

/// A wavelet pass that relights with the kernel, whatever the adapter.
fn kernel_pass(gpu: &GpuContext) -> WaveletPass {
    let camera = CameraBinding::new(&gpu.device);
    let medium = MediumPass::new(gpu);
    let sun = crate::passes::sun::SunPass::new(gpu);
    let normal_maps = crate::passes::normal_map::NormalMapPass::new(gpu);
    let setup = PassSetup {
        device: &gpu.device,
        camera_layout: &camera.layout,
        medium_layout: &medium.layout,
        sun_layout: &sun.layout,
        normal_map_layout: &normal_maps.layout,
        sample_count: 1,
    };
    let mut pass = WaveletPass::new(&setup);
    pass.set_relight_on(RelightOn::Gpu);
    pass
}

/// The relight kernel (`wavelet_relight.wgsl`) against its CPU twin (`local_products` in f64,
/// then `diffuse_transfer`) on random frames, visibility and a sunlit environment: every
/// product but one in a thousand within RGB9E5's precision plus half-float visibility (2⁻⁸ of
/// the largest channel), all within 2%, and every diffuse transfer within 0.2%.
#[test]
fn the_relight_kernel_matches_the_cpu_twin() {
    let gpu = GpuContext::headless().expect("a wgpu device (lavapipe on machines without a GPU)");
    let mut pass = kernel_pass(&gpu);
    for (cells, rotation) in
        [(80, glam::DMat3::IDENTITY), (320, glam::DMat3::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 2.1))]
    {
        let data = surfaces(cells, rotation);
        pass.prepare(&gpu, &data).unwrap();
        let buffers = &pass.receivers.as_ref().unwrap().vertices;
        let products: Vec<u32> = bytemuck::cast_slice(&read(&gpu, &buffers.products)).to_vec();
        let irradiance: Vec<[f32; 4]> = bytemuck::cast_slice(&read(&gpu, &buffers.irradiance)).to_vec();

        let (cpu, _) = data.cpu_products_of(&data.vertices, None, &Default::default()).unwrap();
        let cpu_irradiance = diffuse_transfer(&cpu, &data.diffuse_table);
        assert_eq!(irradiance.len(), cpu_irradiance.len());
        let (mut worst, mut beyond): (f32, usize) = (0.0, 0);
        for (g, c) in products.iter().zip(cpu.values.chunks_exact(3)) {
            let g = lightloom_nodes::triple_product::packing::rgb9e5_decode(*g);
            let max = c[0].max(c[1]).max(c[2]);
            let error = (0..3).map(|k| (g[k] - c[k]).abs()).fold(0.0, f32::max) / max.max(1e-6);
            // f32 directions on the GPU pick a neighbouring cube face for a sample that lies
            // within rounding of a face edge, now and then.
            assert!(error <= 0.02, "{cells} cells: kernel {g:?}, twin {c:?}");
            beyond += usize::from(error > 1.0 / 256.0);
            worst = worst.max(error);
        }
        assert!(
            beyond * 1000 <= products.len(),
            "{cells} cells: {beyond} of {} products off by more than 2⁻⁸",
            products.len()
        );
        for (g, c) in irradiance.iter().zip(&cpu_irradiance) {
            for k in 0..3 {
                assert!((g[k] - c[k]).abs() <= 2e-3 * c[k].abs() + 1e-5, "{cells} cells: E {g:?} against {c:?}");
            }
        }
        // The sun must reach the products, or the comparison proves little.
        assert!(cpu.values.iter().cloned().fold(0.0, f32::max) > 5.0);
        eprintln!("{cells} cells: worst product error {worst:.4} of its largest channel, {beyond} beyond 2⁻⁸");
    }
}

/// The kernel's kept detail terms against the CPU twin's, through what the shader makes of
/// them: for a glossy material, each vertex's detail glossy sum at several views within 2% of
/// the twin's plus 1% of the whole glossy sum there. Nodes whose bounds tie within float
/// rounding may swap between the two, so terms are compared summed, not one by one.
#[test]
fn the_relight_kernel_keeps_the_twins_detail_terms() {
    use lightloom_nodes::triple_product::details::{LocalDetails, detail_glossy};
    use lightloom_nodes::triple_product::{BrdfTable, shade};
    let gpu = GpuContext::headless().expect("a wgpu device (lavapipe on machines without a GPU)");
    let mut pass = kernel_pass(&gpu);
    let material = lightloom_nodes::brdf::Material {
        model: lightloom_nodes::brdf::Model::Ggx,
        roughness: 0.3,
        f0: 1.0,
        specular: [0.5; 3],
        ..Default::default()
    };
    let kept = 24;
    let data = surfaces_of(320, glam::DMat3::from_euler(glam::EulerRot::YXZ, 0.3, 0.9, -1.2), material.clone(), kept);
    assert_eq!(data.details.kept, kept);
    pass.prepare(&gpu, &data).unwrap();
    let buffers = &pass.receivers.as_ref().unwrap().vertices;
    let words: Vec<u32> = bytemuck::cast_slice(&read(&gpu, &buffers.details)).to_vec();
    let (nodes, values): (Vec<u32>, Vec<[f32; 9]>) =
        words.chunks_exact(5).map(lightloom_nodes::triple_product::packing::detail_decode).unzip();
    let kernel = LocalDetails { kept, nodes, values };
    let (products, twin) = data.cpu_products_of(&data.vertices, None, &Default::default()).unwrap();
    assert_eq!(kernel.nodes.len(), twin.nodes.len());
    let grid = CellGrid::for_coefficients(320).unwrap();
    let table: BrdfTable =
        tabulate_brdf(&lightloom_nodes::brdf::Brdf::from_material(&material), grid, &CancelToken::default()).unwrap();
    let receivers = data.vertices.receivers().unwrap();
    let glossy = |d: &LocalDetails, i: usize, wo: glam::DVec3| -> glam::DVec3 {
        (i * kept..(i + 1) * kept)
            .take_while(|j| d.nodes[*j] != lightloom_nodes::triple_product::details::NO_NODE)
            .map(|j| detail_glossy(&table, d.nodes[j], &d.values[j], wo))
            .sum()
    };
    let (mut state, mut same_nodes, mut largest) = (4u64, 0usize, 0.0f64);
    for i in 0..receivers.len() {
        let frame = receivers.frame(i);
        same_nodes += (i * kept..(i + 1) * kept).filter(|j| kernel.nodes[*j] == twin.nodes[*j]).count();
        for _ in 0..4 {
            let (theta, phi) = (uniform(&mut state) * 1.4, uniform(&mut state) * std::f64::consts::TAU);
            let wo = glam::DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            let whole = shade(&products, &table, i, frame, frame * wo) + glossy(&twin, i, wo);
            let (a, b) = (glossy(&kernel, i, wo), glossy(&twin, i, wo));
            largest = largest.max(b.abs().max_element());
            for k in 0..3 {
                assert!(
                    (a[k] - b[k]).abs() <= 0.02 * b[k].abs() + 0.01 * whole[k].abs() + 1e-6,
                    "vertex {i}: kernel's detail terms {a}, twin's {b}, glossy sum {whole}"
                );
            }
        }
    }
    // The terms must matter, and the two must mostly keep the same nodes.
    assert!(largest > 0.05, "the detail terms are at most {largest}");
    assert!(
        same_nodes * 10 >= kernel.nodes.len() * 9,
        "{same_nodes} of {} slots keep the same node",
        kernel.nodes.len()
    );
    eprintln!(
        "{same_nodes} of {} slots keep the same node; largest detail glossy term {largest:.3}",
        kernel.nodes.len()
    );
}

/// A viewport relighting on the CPU uploads the engine's relight as the frame brings it (here
/// a pattern the kernel never writes), one on the GPU runs its kernel over it, and a relight
/// of the wrong size is refused, naming what does not fit.
#[test]
fn a_cpu_viewport_uploads_the_engines_relight() {
    use lightloom_nodes::frame::RelitSets;
    use lightloom_nodes::triple_product::relight::RelitReceivers;
    let gpu = GpuContext::headless().expect("a wgpu device (lavapipe on machines without a GPU)");
    let mut data = surfaces(80, glam::DMat3::IDENTITY);
    let receivers = data.vertices.frames.len() / 2;
    let pattern = lightloom_nodes::triple_product::packing::rgb9e5([1.0, 2.0, 3.0]);
    let relit = |receivers: usize| RelitReceivers {
        products: Arc::new(vec![pattern; receivers * 80]),
        irradiance: Arc::new(vec![[4.0, 5.0, 6.0, 0.0]; receivers]),
        details: Arc::default(),
    };
    data.relit = Some(RelitSets { vertices: keyed(7, StageValue::new(relit(receivers))), texels: None });
    let products = |pass: &WaveletPass| -> Vec<u32> {
        bytemuck::cast_slice(&read(&gpu, &pass.receivers.as_ref().unwrap().vertices.products)).to_vec()
    };
    let mut cpu = kernel_pass(&gpu);
    cpu.set_relight_on(RelightOn::Cpu);
    cpu.prepare(&gpu, &data).unwrap();
    assert!(products(&cpu).iter().all(|p| *p == pattern), "the CPU viewport uploads the engine's products");
    let irradiance: Vec<[f32; 4]> =
        bytemuck::cast_slice(&read(&gpu, &cpu.receivers.as_ref().unwrap().vertices.irradiance)).to_vec();
    assert!(irradiance.iter().all(|e| *e == [4.0, 5.0, 6.0, 0.0]));
    let mut gpu_pass = kernel_pass(&gpu);
    gpu_pass.prepare(&gpu, &data).unwrap();
    assert!(products(&gpu_pass).iter().any(|p| *p != pattern), "the GPU viewport runs its kernel");
    data.relit = Some(RelitSets { vertices: keyed(8, StageValue::new(relit(receivers - 1))), texels: None });
    data.rotation = glam::DMat3::from_rotation_y(0.5);
    let error = cpu.prepare(&gpu, &data).unwrap_err().to_string();
    assert!(error.contains("relit products"), "{error}");
}
