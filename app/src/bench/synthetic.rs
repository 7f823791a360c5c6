//! A synthetic sphere of `--vertices` vertices: the CPU cost of a lighting change per mode and
//! the GPU frame, beside the memory-bandwidth bound.

use super::common::*;
use anyhow::{Result, anyhow};
use lightloom_nodes::engine::{CancelToken, StageValue};
use lightloom_nodes::frame::{
    Background, FrameInputs, FrameMaterial, Geometry, IrradianceSurfaces, Keyed, MediumFrame, PrtSurfaces, RelitSets,
    Surfaces, WaveletLighting, WaveletSurfaces,
};
use lightloom_nodes::kinds::output::{Mode, Tonemap, View};
use lightloom_nodes::transport::{Receivers, ShTransport, SphericalTransport};
use lightloom_nodes::wavelet::SparseVector;
use lightloom_render::{GpuContext, ViewportRenderer};
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use std::time::Instant;

pub(super) fn synthetic_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    let segments = ((args.vertices as f64 / 2.0).sqrt()).round().max(4.0) as usize;
    let mesh = lightloom_nodes::mesh::sphere(1.0, segments);
    let meshes = lightloom_nodes::mesh::MeshSet { meshes: vec![mesh] };
    let n = meshes.meshes[0].positions.len();
    let receivers = Receivers::from_meshes(&meshes);
    let bandwidth = super::anchors::copy_bandwidth();
    println!(
        "\nsynthetic sphere: {n} vertices, 1280x720; memory bandwidth {:.1} GB/s (parallel copy, read + write); \
         \"bound\": the least time to read and write a relight's bytes per vertex at that bandwidth",
        bandwidth / 1e9
    );
    println!("{:<24} {:>22} {:>14}  against the anchors", "mode", "lighting change ms", "frame ms");
    let mut rng = rand::rngs::SmallRng::seed_from_u64(7);
    let view = bench_view();
    let environment = lightloom_nodes::cubemap::CubeMap::from_fn(64, 1, |d| [1.0 + d.y, 0.8, 0.5 + d.x.abs()]);
    let light = lightloom_nodes::sh::project_samples(8, environment.samples());
    let keyed = |key: u128, value: StageValue| Keyed { key, value: Arc::new(value) };
    let base_settings = lightloom_nodes::kinds::output::OutputSettings {
        mode: Mode::ShIrradiance,
        exposure: 0.0,
        tonemap: Tonemap::Aces,
        background: true,
        view: View::Approximation,
        reference_samples: 1,
        separate_sun: false,
        wavelet_details: 0,
    };
    let material = lightloom_nodes::brdf::Material {
        model: lightloom_nodes::brdf::Model::Phong,
        exponent: 20.0,
        f0: 0.3,
        ..Default::default()
    };
    let materials = vec![FrameMaterial::new("bench", material.clone(), None)];
    let geometry =
        Geometry::of_meshes(keyed(1, StageValue::new(meshes.clone())), vec![0]).map_err(|e| anyhow::anyhow!(e))?;
    let frame_with = |mode: Mode, surfaces: Surfaces| FrameInputs {
        geometry: geometry.clone(),
        ray_scene: None,
        mode,
        pending: None,
        settings: lightloom_nodes::kinds::output::OutputSettings { mode, ..base_settings.clone() },
        ignored_inputs: Vec::new(),
        lobe_limits: Vec::new(),
        materials: materials.clone(),
        background: Background { radiance: Some(keyed(4, StageValue::new(environment.clone()))), visible: true },
        surfaces,
        medium: MediumFrame::new(Vec::new(), &materials, None),
        area_lights: None,
        blockers: None,
        sun: None,
        normal_maps: Default::default(),
    };
    let mut renderer = ViewportRenderer::new(gpu);
    let frame_times = |renderer: &mut ViewportRenderer, frame: &FrameInputs| -> Result<f64> {
        timed_frame(gpu, renderer, frame, &view, (1280, 720))?;
        let times: Vec<f64> =
            (0..args.frames).map(|_| timed_frame(gpu, renderer, frame, &view, (1280, 720))).collect::<Result<_>>()?;
        Ok(median(times))
    };
    let irradiance = IrradianceSurfaces::new(Some(&light), None, &materials);
    let frame = frame_with(Mode::ShIrradiance, Surfaces::Irradiance(irradiance));
    println!("{:<24} {:>22} {:>14.1}", "sh_irradiance", "-", frame_times(&mut renderer, &frame)?);
    let sphere = Sphere {
        gpu,
        n,
        bandwidth,
        light: &light,
        material: &material,
        materials: &materials,
        geometry: &geometry,
        environment: &environment,
        receivers: &receivers,
        view: &view,
        frame_with: &frame_with,
        frame_times: &frame_times,
    };
    sh_prt_rows(&sphere, &mut renderer, &mut rng)?;
    let table = {
        let grid = lightloom_nodes::triple_product::CellGrid::for_coefficients(320).map_err(|e| anyhow!(e))?;
        let brdf = lightloom_nodes::brdf::Brdf::from_material(&material);
        let start = Instant::now();
        let table = lightloom_nodes::triple_product::tabulate_brdf(&brdf, grid, &CancelToken::default())
            .map_err(|e| anyhow!("{e}"))?;
        println!(
            "(BRDF table, 320 cells and their two finer levels × {} outgoing directions: {:.1} ms)",
            lightloom_nodes::triple_product::THETA_STEPS * lightloom_nodes::triple_product::PHI_STEPS,
            start.elapsed().as_secs_f64() * 1e3
        );
        table
    };
    for terms in [80usize, 320] {
        wavelet_rows(&sphere, &mut renderer, &mut rng, &table, terms)?;
    }
    Ok(())
}

/// What the synthetic sphere's rows share.
struct Sphere<'a> {
    gpu: &'a GpuContext,
    /// Vertices.
    n: usize,
    /// Host memory's copy bandwidth, bytes per second.
    bandwidth: f64,
    light: &'a lightloom_nodes::sh::ShRgb,
    material: &'a lightloom_nodes::brdf::Material,
    materials: &'a [FrameMaterial],
    geometry: &'a Geometry,
    environment: &'a lightloom_nodes::cubemap::CubeMap,
    receivers: &'a Receivers,
    view: &'a lightloom_render::CameraView,
    /// A frame of the sphere in `mode` with these surfaces.
    frame_with: &'a dyn Fn(Mode, Surfaces) -> FrameInputs,
    /// The median steady frame time of a frame, ms.
    frame_times: &'a dyn Fn(&mut ViewportRenderer, &FrameInputs) -> Result<f64>,
}

/// `sh_prt` at 6 and 8 bands: the incident radiance's CPU cost against the bandwidth bound,
/// and the frame.
fn sh_prt_rows(sphere: &Sphere, renderer: &mut ViewportRenderer, rng: &mut rand::rngs::SmallRng) -> Result<()> {
    let (n, bandwidth, light, material, materials) =
        (sphere.n, sphere.bandwidth, sphere.light, sphere.material, sphere.materials);
    let (frame_with, frame_times) = (sphere.frame_with, sphere.frame_times);
    let keyed = |key: u128, value: StageValue| Keyed { key, value: Arc::new(value) };
    for bands in [6usize, 8] {
        let count = n * bands * bands;
        let random = |rng: &mut rand::rngs::SmallRng| (0..count).map(|_| rng.random::<f32>() * 0.1).collect::<Vec<_>>();
        let transport = ShTransport { bands, rays: 0, visibility: random(rng), transfer: random(rng) };
        let start = Instant::now();
        let incident = lightloom_nodes::prt::incident_radiance(light, &transport, &CancelToken::default())
            .map_err(|e| anyhow!("{e}"))?;
        let change_ms = start.elapsed().as_secs_f64() * 1e3;
        let surfaces = PrtSurfaces::new(
            keyed(10 + bands as u128, StageValue::new(transport)),
            keyed(20 + bands as u128, StageValue::new(incident)),
            Some(light),
            None,
            materials,
            vec![lightloom_nodes::prt::glossy_lobe(material, lightloom_nodes::prt::LOBE_BANDS)],
            n,
        )
        .map_err(|e| anyhow!(e))?;
        let frame = frame_with(Mode::ShPrt, Surfaces::Prt(surfaces));
        let ms = frame_times(renderer, &frame)?;
        // The relight reads each vertex's visibility and writes its RGB incident radiance (f32).
        let bytes = 4 * bands * bands * 4;
        let bound = super::anchors::bandwidth_bound_ms(n, bytes, bandwidth);
        println!(
            "{:<24} {:>22.1} {:>14.1}  {:.1}× the bandwidth bound ({bound:.1} ms for {bytes} B per vertex)",
            format!("sh_prt {bands} bands"),
            change_ms,
            ms,
            change_ms / bound
        );
    }
    Ok(())
}

/// `wavelet_vertex` with `terms` cells, relit on the CPU and on the GPU, top-only and with 32
/// detail terms: a new environment's and a rotation's cost, the steady frame, beside Ma et
/// al.'s rate and the bandwidth bound.
fn wavelet_rows(
    sphere: &Sphere,
    renderer: &mut ViewportRenderer,
    rng: &mut rand::rngs::SmallRng,
    table: &lightloom_nodes::triple_product::BrdfTable,
    terms: usize,
) -> Result<()> {
    let (n, bandwidth, materials) = (sphere.n, sphere.bandwidth, sphere.materials);
    let (frame_with, frame_times) = (sphere.frame_with, sphere.frame_times);
    let keyed = |key: u128, value: StageValue| Keyed { key, value: Arc::new(value) };
    let (gpu, view, geometry, environment, receivers) =
        (sphere.gpu, sphere.view, sphere.geometry, sphere.environment, sphere.receivers);
    let depth = if terms == 80 { 2 } else { 3 };
    let cells = 20usize << (2 * depth);
    let basis = lightloom_nodes::wavelet::spherical::SphericalHaar::new(depth);
    let visibility = (0..n)
        .map(|_| {
            let dense: Vec<f64> = (0..cells).map(|_| if rng.random::<f64>() < 0.7 { 1.0 } else { 0.0 }).collect();
            SparseVector::largest(&basis.forward(&dense), terms, |_| 1.0)
        })
        .collect();
    let transport = SphericalTransport { depth, keep: terms, visibility };
    let grid = lightloom_nodes::triple_product::CellGrid::for_coefficients(terms).map_err(|e| anyhow!(e))?;
    let cell_visibility = lightloom_nodes::triple_product::local_visibility(grid, &transport, &CancelToken::default())
        .map_err(|e| anyhow!("{e}"))?;
    let visibility = keyed(30 + terms as u128, StageValue::new(cell_visibility));
    let receivers_keyed = keyed(3, StageValue::new(receivers.clone()));
    // A new environment: prefiltering on the CPU, then the relight kernel in the next frame.
    let start = Instant::now();
    let prefiltered = lightloom_nodes::triple_product::prefiltered(environment, grid);
    let prefilter_ms = start.elapsed().as_secs_f64() * 1e3;
    let surfaces = |rotation: glam::DMat3, environment_key: u128, details: usize| -> Result<WaveletSurfaces> {
        let lighting = WaveletLighting {
            visibility: visibility.clone(),
            receivers: receivers_keyed.clone(),
            environment: keyed(environment_key, StageValue::new(prefiltered.clone())),
            rotation,
        };
        WaveletSurfaces::new(
            lighting,
            &[keyed(40, StageValue::new(table.clone()))],
            None,
            None,
            geometry,
            materials,
            details,
        )
        .map_err(|e| anyhow!(e))
    };
    // The first frame after a change rebuilds P and E (on the GPU, or on the CPU and
    // uploaded); the rebuild's cost is that frame's excess over a steady frame.
    // Ma's top-only products (the anchor), then with 32 detail terms per vertex.
    for (on, details) in [
        (lightloom_render::RelightOn::Cpu, 0),
        (lightloom_render::RelightOn::Gpu, 0),
        (lightloom_render::RelightOn::Cpu, 32),
        (lightloom_render::RelightOn::Gpu, 32),
    ] {
        renderer.set_relight_on(on);
        let label = format!(
            "wavelet_vertex {terms}{} ({})",
            if details > 0 { format!("+{details}") } else { String::new() },
            if on == lightloom_render::RelightOn::Cpu { "CPU" } else { "GPU" }
        );
        let key = |k: u128| 100_000 * details as u128 + 1000 * (on as u128 + 1) + 10 * terms as u128 + k;
        let first = frame_with(
            Mode::WaveletVertex,
            Surfaces::Wavelet(Box::new(surfaces(glam::DMat3::IDENTITY, key(1), details)?)),
        );
        let steady = match frame_times(renderer, &first) {
            Ok(ms) => ms,
            Err(e) => {
                println!("{label:<24} {:>22}   not drawn: {e}", "-");
                continue;
            }
        };
        // On the CPU the engine relights (the Output's `wavelet_relit` stage, run here as it
        // runs it: the frame table built once per environment) and the renderer uploads.
        let mut table: Option<(u128, Option<lightloom_nodes::triple_product::FrameTable>)> = None;
        let mut changed = |rotation: glam::DMat3, environment_key: u128| -> Result<f64> {
            let mut surfaces = surfaces(rotation, environment_key, details)?;
            let mut relight_ms = 0.0;
            if on == lightloom_render::RelightOn::Cpu {
                let start = Instant::now();
                if table.as_ref().is_none_or(|(k, _)| *k != environment_key) {
                    table =
                        Some((environment_key, surfaces.frame_table_for(&surfaces.vertices).map_err(|e| anyhow!(e))?));
                }
                let table = table.as_ref().and_then(|(_, t)| t.as_ref());
                let set = &surfaces.vertices;
                let relit = surfaces
                    .relight(|r| {
                        r.packed(set.receivers()?, set.cells()?, table, &CancelToken::default())
                            .map_err(|e| e.to_string())
                    })
                    .map_err(|e| anyhow!(e))?;
                let key = environment_key ^ u128::from(rotation.x_axis.z.to_bits()).rotate_left(64);
                surfaces.relit = Some(RelitSets { vertices: keyed(key, StageValue::new(relit)), texels: None });
                relight_ms = start.elapsed().as_secs_f64() * 1e3;
            }
            let frame = frame_with(Mode::WaveletVertex, Surfaces::Wavelet(Box::new(surfaces)));
            Ok(timed_frame(gpu, renderer, &frame, view, (1280, 720))? - steady + relight_ms)
        };
        let new_environment = changed(glam::DMat3::IDENTITY, key(2))? + prefilter_ms;
        let rotation = changed(glam::DMat3::from_rotation_y(0.7), key(2))?;
        // Ma recomputes every product every frame: its fps is a rotation's edit-to-frame rate.
        let rate = n as f64 / (rotation + steady) / 1e3;
        let ma = match details {
            0 => super::anchors::ma_interpolated(terms).map_or(String::new(), |a| a.beside(rate)),
            _ => "(no anchor: Ma keeps top-only coefficients)".to_string(),
        };
        // The relight reads each vertex's frame (32 B) and f16 visibility cells and writes its
        // RGB9E5 products and diffuse transfer (16 B), and its detail terms (20 B each), as the
        // GPU kernel stores them. The bound is host memory's: it says nothing of the kernel on
        // a GPU's own memory.
        let bound = if on == lightloom_render::RelightOn::Cpu {
            let bytes = 32 + 2 * terms + 4 * terms + 16 + 20 * details;
            let ms = super::anchors::bandwidth_bound_ms(n, bytes, bandwidth);
            format!("rotation {:.1}× the bandwidth bound ({ms:.1} ms for {bytes} B per vertex); ", rotation / ms)
        } else {
            String::new()
        };
        println!(
            "{label:<24} {:>22} {steady:>14.1}  {bound}rotation to frame {rate:.2} M vertices/s = {ma}",
            format!("{new_environment:.1} (rotation {rotation:.0})"),
        );
    }
    Ok(())
}
