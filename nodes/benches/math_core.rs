//! Math-core benchmarks: SH projection and rotation, Haar transforms, triple products.
//! Run with `cargo bench -p lightloom-nodes`.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use lightloom_nodes::cubemap::Equirect;
use lightloom_nodes::sampling::{random_rotation, test_rng};
use lightloom_nodes::sh::{self, ShRotation};
use lightloom_nodes::sky::ProceduralSky;
use lightloom_nodes::wavelet::SparseVector;
use lightloom_nodes::wavelet::cube_haar::CubeHaar;
use lightloom_nodes::wavelet::spherical::SphericalHaar;
use rand::Rng;
use std::hint::black_box;

fn sh_projection(c: &mut Criterion) {
    let sky = ProceduralSky::default();
    let image = Equirect::from_fn(1024, 512, 1, |d| sky.radiance(d));
    let mut group = c.benchmark_group("sh_project_1024x512");
    group.sample_size(10);
    for bands in [3, 8, 16] {
        group.bench_with_input(BenchmarkId::from_parameter(bands), &bands, |b, &bands| {
            b.iter(|| sh::project_equirect(black_box(&image), bands))
        });
    }
    group.finish();
}

fn sh_rotation(c: &mut Criterion) {
    let mut rng = test_rng(1);
    let mut group = c.benchmark_group("sh_rotate");
    for bands in [8, 16] {
        let coeffs: Vec<f64> = (0..bands * bands).map(|_| rng.random_range(-1.0..1.0)).collect();
        let rotation = random_rotation(&mut rng);
        group.bench_with_input(BenchmarkId::new("build_and_apply", bands), &bands, |b, &bands| {
            b.iter(|| ShRotation::new(bands, black_box(rotation)).apply(black_box(&coeffs)))
        });
        let prepared = ShRotation::new(bands, rotation);
        group.bench_with_input(BenchmarkId::new("apply", bands), &bands, |b, _| {
            b.iter(|| prepared.apply(black_box(&coeffs)))
        });
    }
    group.finish();
}

fn haar(c: &mut Criterion) {
    let mut rng = test_rng(2);
    let haar = CubeHaar::new(128);
    let values: Vec<f64> = (0..haar.len()).map(|_| rng.random_range(0.0..1.0)).collect();
    c.bench_function("haar_forward_6x128x128", |b| b.iter(|| haar.forward(black_box(&values))));
    let coeffs = haar.forward(&values);
    c.bench_function("haar_inverse_6x128x128", |b| b.iter(|| haar.inverse(black_box(&coeffs))));
}

fn triple_products(c: &mut Criterion) {
    let mut rng = test_rng(3);
    let mut group = c.benchmark_group("triple_product");
    let haar = CubeHaar::new(32);
    let spherical = SphericalHaar::new(5);
    for keep in [64, 256] {
        // Smooth-plus-noise signals, so the kept coefficients overlap as real lighting does.
        let cube: Vec<SparseVector> = (0..3)
            .map(|_| {
                let v: Vec<f64> =
                    (0..haar.len()).map(|i| 1.0 + (i as f64 * 0.01).sin() + rng.random_range(0.0..0.2)).collect();
                haar.approximate(&v, keep)
            })
            .collect();
        group.bench_with_input(BenchmarkId::new("cube_haar_6x32x32", keep), &keep, |b, _| {
            b.iter(|| haar.triple_product(black_box(&cube[0]), black_box(&cube[1]), black_box(&cube[2])))
        });
        let sph: Vec<SparseVector> = (0..3)
            .map(|_| {
                let v: Vec<f64> =
                    (0..spherical.len()).map(|i| 1.0 + (i as f64 * 0.01).sin() + rng.random_range(0.0..0.2)).collect();
                spherical.approximate(&v, keep)
            })
            .collect();
        group.bench_with_input(BenchmarkId::new("spherical_haar_depth5", keep), &keep, |b, _| {
            b.iter(|| spherical.triple_product(black_box(&sph[0]), black_box(&sph[1]), black_box(&sph[2])))
        });
    }
    group.finish();
}

criterion_group!(benches, sh_projection, sh_rotation, haar, triple_products);
criterion_main!(benches);
