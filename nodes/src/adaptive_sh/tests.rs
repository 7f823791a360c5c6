use super::*;
use crate::mesh::{Mesh, MeshSet};
use crate::quadrature::SphereQuadrature;
use crate::sh::{ShBasis, rotation::ShRotation};
use crate::transport::{Receivers, ShTransport};
use glam::{DMat3, DMat4, DVec3};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// An environment with a sun over a sky, about 1 in radiance (Lee's display-referred scale).
fn sun_and_sky(bands: usize, sun: DVec3) -> ShRgb {
    let sun = sun.normalize();
    let f = |scale: [f64; 2]| {
        crate::sh::project_fn(bands, 24, move |d| {
            scale[0] * 2.0 * (12.0 * (d.dot(sun) - 1.0)).exp() + scale[1] * (0.3 + 0.3 * d.y).max(0.0)
        })
    };
    let (r, g, b) = (f([1.0, 0.4]), f([0.9, 0.5]), f([0.7, 0.8]));
    ShRgb::from_channels([&r, &g, &b])
}

/// A floor with a sphere and a torus over it: shadows with sharp and soft edges.
fn scene(bands: usize, rays: usize) -> (MeshSet, ShTransport) {
    let lift = |m: Mesh, t: DVec3| m.transformed(DMat4::from_translation(t));
    let meshes = MeshSet {
        meshes: vec![
            crate::mesh::plane(4.0, 30),
            lift(crate::mesh::sphere(0.6, 10), DVec3::new(-0.8, 0.7, 0.0)),
            lift(crate::mesh::torus(0.5, 0.15, 12), DVec3::new(0.9, 0.5, 0.4)),
        ],
    };
    let ray_scene = crate::raycast::RayScene::build(&meshes);
    let receivers = Receivers::from_meshes(&meshes);
    let transport =
        crate::transport::sh_transport(&ray_scene, &receivers, bands, rays, &CancelToken::default(), &|_| {}).unwrap();
    (meshes, transport)
}

struct Fixture {
    products: LightProducts,
    transport: ShTransport,
    lobe_of: Vec<Option<u16>>,
    weights: Vec<ShadingWeights>,
    adjacency: Adjacency,
}

impl Fixture {
    fn new(bands: usize) -> Self {
        let (meshes, transport) = scene(bands, 400);
        let adjacency =
            Adjacency::from_triangles(meshes.meshes.iter().map(|m| (m.positions.len(), m.indices.as_slice())));
        let lobe = crate::brdf::Brdf::phong_zonal(20.0, bands);
        let weights = vec![ShadingWeights::new(&crate::prt::lobe_factors(&lobe), [0.3, 0.3, 0.3], bands)];
        let count = adjacency.offsets.len() - 1;
        Self {
            products: LightProducts::new(&sun_and_sky(bands, DVec3::new(0.4, 1.0, 0.3)), bands),
            transport,
            lobe_of: vec![Some(0); count],
            weights,
            adjacency,
        }
    }

    fn inputs(&self) -> AdaptiveInputs<'_> {
        AdaptiveInputs {
            products: &self.products,
            visibility: &self.transport.visibility,
            stride: self.transport.bands * self.transport.bands,
            lobe_of: &self.lobe_of,
            weights: &self.weights,
            adjacency: &self.adjacency,
            previous_levels: None,
        }
    }

    fn settings(&self, threshold: f64) -> AdaptiveSettings {
        AdaptiveSettings { threshold, level: self.products.bands - 1, refine: true, smooth: true, hysteresis: 1.0 }
    }
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

/// Lee's incremental product (the notes' corrected Algorithm 3) equals the independent Gaunt
/// product of the truncated factors at every level (notes B6.7; the printed equation fails this).
#[test]
fn raising_level_by_level_equals_the_truncated_product_at_every_level() {
    let bands = 7;
    let mut rng = SmallRng::seed_from_u64(7);
    let light = ShRgb {
        bands,
        coeffs: (0..bands * bands).map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0))).collect(),
    };
    let v: Vec<f32> = (0..bands * bands).map(|_| rng.random_range(-1.0..1.0)).collect();
    let products = LightProducts::new(&light, bands);
    let n = bands * bands;
    let (mut planar_r, mut d, mut change) = (planar(n), planar(n), planar(n));
    let mut r = vec![0.0f32; n * 3];
    for level in 0..bands {
        if level == 0 {
            products.increment(0, &v, &mut planar_r);
        } else {
            products.raise(level - 1, level, &v, &mut planar_r, &mut d, &mut change);
        }
        interleave(&planar_r, n, &mut r);
        let k = (level + 1) * (level + 1);
        // Lee's L̂ keeps every band of the light; the factors truncated are V and the result.
        let table = GauntTable::new(bands, level + 1, level + 1);
        let vk: Vec<f64> = v[..k].iter().map(|x| *x as f64).collect();
        for c in 0..3 {
            let expected = table.multiply(&light.channel(c), &vk);
            for i in 0..n {
                let want = if i < k { expected[i] } else { 0.0 };
                assert!((r[i * 3 + c] as f64 - want).abs() < 1e-4, "level {level} coefficient {i} channel {c}");
            }
        }
    }
    let mut full = vec![0.0f32; n * 3];
    products.full(&v, &mut full);
    assert!(max_abs_diff(&full, &r) < 1e-4);
}

/// The view-averaged RMS is the mean square over mirror directions of the glossy exit
/// radiance difference `w Σ f_l ΔR_lm Y_lm(r)`, by quadrature.
#[test]
fn the_view_averaged_rms_matches_quadrature_over_mirror_directions() {
    let bands = 6;
    let mut rng = SmallRng::seed_from_u64(3);
    let lobe = crate::prt::lobe_factors(&crate::brdf::Brdf::phong_zonal(25.0, bands));
    let weight = [0.3, 0.6, 0.9];
    let weights = ShadingWeights::new(&lobe, weight, bands);
    let a: Vec<f32> = (0..bands * bands * 3).map(|_| rng.random_range(-1.0..1.0)).collect();
    let b: Vec<f32> = (0..bands * bands * 3).map(|_| rng.random_range(-1.0..1.0)).collect();
    let basis = ShBasis::new(bands);
    let quad = SphereQuadrature::exact_for_degree(2 * bands);
    let mean_square = |c: usize| {
        quad.integrate(|r| {
            let y = basis.eval_vec(r);
            let s: f64 = (0..bands * bands)
                .map(|i| weight[c] * lobe[band_of(i)] * (a[i * 3 + c] - b[i * 3 + c]) as f64 * y[i])
                .sum();
            s * s
        }) / (4.0 * std::f64::consts::PI)
    };
    let expected = (0..3).map(mean_square).fold(0.0, f64::max).sqrt();
    let got = weights.rms(&a, &b);
    assert!((got - expected).abs() < 1e-5 * expected, "{got} against {expected}");
}

#[test]
fn adjacency_of_two_triangles() {
    let a = Adjacency::from_triangles([(4usize, &[0u32, 1, 2, 0, 2, 3][..]), (3, &[0, 1, 2][..])]);
    assert_eq!(a.of(0), &[1, 2, 3]);
    assert_eq!(a.of(1), &[0, 2]);
    assert_eq!(a.of(2), &[0, 1, 3]);
    assert_eq!(a.of(4), &[5, 6], "the second mesh's vertices follow the first's");
    assert!(a.of(99).is_empty());
}

/// Notes B6.8: threshold 0 is the full image, threshold ∞ the base image.
#[test]
fn threshold_zero_is_the_full_product_and_infinity_the_base() {
    let f = Fixture::new(9);
    let cancel = CancelToken::default();
    let full = full_incident(&f.inputs(), &cancel).unwrap();
    let zero = adaptive_incident(&f.inputs(), &f.settings(0.0), &cancel).unwrap();
    assert!(max_abs_diff(&zero.incident.coeffs, &full.coeffs) < 1e-4);
    assert_eq!(zero.stats.roi, zero.stats.glossy);
    assert_eq!(zero.stats.macs, zero.stats.full_macs, "every level of every vertex once");
    let infinite = adaptive_incident(&f.inputs(), &f.settings(f64::INFINITY), &cancel).unwrap();
    assert_eq!(infinite.stats.roi, 0);
    let n = 81;
    let base = GauntTable::new(9, 3, 3);
    for v in [0usize, 500, 1000] {
        let vis: Vec<f64> = f.transport.visibility[v * n..v * n + 9].iter().map(|x| *x as f64).collect();
        let light = sun_and_sky(9, DVec3::new(0.4, 1.0, 0.3));
        for c in 0..3 {
            let expected = base.multiply(&light.channel(c), &vis);
            for i in 0..n {
                let got = infinite.incident.coeffs[(v * n + i) * 3 + c] as f64;
                let want = if i < 9 { expected[i] } else { 0.0 };
                assert!((got - want).abs() < 1e-4 * (1.0 + want.abs()), "vertex {v} coefficient {i}");
            }
        }
    }
}

/// Notes B6.8: the PSNR against the full product does not rise and the work does not grow as
/// the threshold rises; the work falls well below the full product's.
#[test]
fn psnr_and_work_fall_as_the_threshold_rises() {
    let f = Fixture::new(9);
    let cancel = CancelToken::default();
    let full = full_incident(&f.inputs(), &cancel).unwrap();
    let mut last: Option<(f64, u64)> = None;
    for threshold in [0.0, 1e-3, 3e-3, 1e-2, 2e-2, 5e-2, 0.1, f64::INFINITY] {
        let a = adaptive_incident(&f.inputs(), &f.settings(threshold), &cancel).unwrap();
        let psnr = view_psnr(view_mse(&a.incident, &full, &f.lobe_of, &f.weights), 1.0);
        if let Some((p, m)) = last {
            assert!(psnr <= p + 0.05, "PSNR rose from {p:.2} to {psnr:.2} dB at threshold {threshold}");
            // Refinement recomputes some vertices, so the work may rise slightly.
            assert!(
                a.stats.macs as f64 <= m as f64 * 1.02,
                "work rose from {m} to {} at threshold {threshold}",
                a.stats.macs
            );
        }
        last = Some((psnr, a.stats.macs));
    }
    let moderate = adaptive_incident(&f.inputs(), &f.settings(1e-2), &cancel).unwrap();
    let psnr = view_psnr(view_mse(&moderate.incident, &full, &f.lobe_of, &f.weights), 1.0);
    assert!(moderate.stats.macs * 5 < moderate.stats.full_macs * 2, "{:?}", moderate.stats);
    assert!(psnr > 38.0, "{psnr:.1} dB");
    assert!(moderate.stats.per_level.iter().filter(|&&c| c > 0).count() >= 4, "graded orders: {:?}", moderate.stats);
}

/// Mean jump of the error across the edges between vertices of different levels: the seams
/// Lee's smoothing is for (§5.2.2).
fn seam(f: &Fixture, a: &AdaptiveIncident, full: &IncidentSh) -> f64 {
    let n = full.bands * full.bands * 3;
    let error =
        |v: usize| -> Vec<f32> { (0..n).map(|k| a.incident.coeffs[v * n + k] - full.coeffs[v * n + k]).collect() };
    let (mut sum, mut edges) = (0.0, 0);
    for v in 0..a.levels.len() {
        for &u in f.adjacency.of(v) {
            let u = u as usize;
            if u > v && a.levels[u] != a.levels[v] {
                sum += f.weights[0].rms(&error(u), &error(v));
                edges += 1;
            }
        }
    }
    sum / edges.max(1) as f64
}

/// Refinement brings the adaptive image closer to the full one for a little more work;
/// smoothing lowers the seams where the level changes.
#[test]
fn refinement_lowers_the_error_and_smoothing_the_seams() {
    let f = Fixture::new(9);
    let cancel = CancelToken::default();
    let full = full_incident(&f.inputs(), &cancel).unwrap();
    let run = |refine: bool, smooth: bool| {
        let settings = AdaptiveSettings { refine, smooth, ..f.settings(5e-3) };
        adaptive_incident(&f.inputs(), &settings, &cancel).unwrap()
    };
    let mse = |a: &AdaptiveIncident| view_mse(&a.incident, &full, &f.lobe_of, &f.weights);
    let (plain, refined, smoothed) = (run(false, false), run(true, false), run(true, true));
    assert!(refined.stats.refined > 0);
    assert!(mse(&refined) < 0.9 * mse(&plain), "refinement: {} against {}", mse(&refined), mse(&plain));
    assert!(refined.stats.macs < plain.stats.macs * 11 / 10, "{:?}", refined.stats);
    assert!(smoothed.stats.smoothed > 0);
    let (with, without) = (seam(&f, &smoothed, &full), seam(&f, &refined, &full));
    assert!(with < without, "seams: {with} with smoothing, {without} without");
}

/// Notes B6.11: under a slow environment rotation, hysteresis lowers the level flips per frame.
#[test]
fn hysteresis_lowers_level_flips_under_a_slow_rotation() {
    let mut f = Fixture::new(9);
    let cancel = CancelToken::default();
    let light = sun_and_sky(9, DVec3::new(0.4, 1.0, 0.3));
    let flips = |f: &mut Fixture, hysteresis: f64| {
        let mut previous: Option<Vec<u8>> = None;
        let mut total = 0;
        for frame in 0..6 {
            let turn = ShRotation::new(9, DMat3::from_rotation_y(0.05 * frame as f64));
            f.products = LightProducts::new(&turn.apply_rgb(&light), 9);
            let settings = AdaptiveSettings { hysteresis, ..f.settings(5e-3) };
            let inputs = AdaptiveInputs { previous_levels: previous.as_deref(), ..f.inputs() };
            let a = adaptive_incident(&inputs, &settings, &cancel).unwrap();
            total += a.stats.flips.unwrap_or(0);
            previous = Some(a.levels);
        }
        total
    };
    let (without, with) = (flips(&mut f, 1.0), flips(&mut f, 0.5));
    eprintln!("level changes over 5 turns of 0.05 rad: {without} without hysteresis, {with} with 0.5");
    assert!(without > 0, "the levels should move under rotation");
    assert!(with * 2 <= without, "flips with hysteresis {with}, without {without}");
}
