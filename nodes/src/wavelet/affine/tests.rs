use super::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// `Φ_k(w)` pointwise (0 outside `[0, 1)`).
fn basis(k: usize, w: f64) -> f64 {
    if !(0.0..1.0).contains(&w) {
        return 0.0;
    }
    match level_offset(k) {
        None => 1.0,
        Some((l, t)) => {
            let x = w * f64::from(1u32 << l) - f64::from(t);
            let sign = if (0.0..0.5).contains(&x) {
                1.0
            } else if (0.5..1.0).contains(&x) {
                -1.0
            } else {
                0.0
            };
            sign * f64::from(1u32 << l).sqrt()
        }
    }
}

/// Where `Φ_k` jumps, on `[0, 1)`.
fn jumps(k: usize) -> Vec<f64> {
    match level_offset(k) {
        None => vec![0.0, 1.0],
        Some((l, t)) => {
            let w = 1.0 / f64::from(1u32 << l);
            vec![f64::from(t) * w, (f64::from(t) + 0.5) * w, f64::from(t + 1) * w]
        }
    }
}

/// `∫₀¹ Π f(v) dv` for piecewise-constant factors, exactly: midpoint values times lengths
/// between all their jumps (`breaks` in v).
fn integrate(mut breaks: Vec<f64>, f: impl Fn(f64) -> f64) -> f64 {
    breaks.extend([0.0, 1.0]);
    breaks.retain(|b| (0.0..=1.0).contains(b));
    breaks.sort_by(f64::total_cmp);
    breaks.windows(2).map(|w| (w[1] - w[0]) * f(0.5 * (w[0] + w[1]))).sum()
}

/// `D_ij(s, o)` by exact segment integration.
fn exact_coupling(i: usize, j: usize, map: Affine) -> f64 {
    let mut breaks: Vec<f64> = jumps(i).iter().map(|b| (b - map.o) / map.s).collect();
    breaks.extend(jumps(j));
    integrate(breaks, |v| basis(i, map.s * v + map.o) * basis(j, v))
}

/// `D_ijk(s, o)` by exact segment integration.
fn exact_tripling(i: usize, j: usize, k: usize, map: Affine) -> f64 {
    let mut breaks: Vec<f64> = jumps(i).iter().map(|b| (b - map.o) / map.s).collect();
    breaks.extend(jumps(j));
    breaks.extend(jumps(k));
    integrate(breaks, |v| basis(i, map.s * v + map.o) * basis(j, v) * basis(k, v))
}

/// `M(r, c)` by exact segment integration of `α(u) ψ(u)`.
fn exact_m(r: f64, c: f64) -> f64 {
    let alpha = |u: f64| {
        if (c - r..c).contains(&u) {
            1.0
        } else if (c..c + r).contains(&u) {
            -1.0
        } else {
            0.0
        }
    };
    let psi = |u: f64| basis(1, u);
    // ψ lives on [0, 1); integrate over it.
    integrate(vec![c - r, c, c + r, 0.5], |u| alpha(u) * psi(u))
}

fn random_map(rng: &mut SmallRng) -> Affine {
    Affine { s: 10f64.powf(rng.random_range(-1.0..1.0)), o: rng.random_range(-1.5..1.5) }
}

/// Notes §5.1: the closed form, the restored case analysis and exact integration agree to
/// 1e-12 over log-uniform r ∈ [1e-3, 1e3], c ∈ (−r − 2, r + 3); with sparsity, both
/// symmetries, the bounds and the slope sets.
#[test]
fn canonical_coupling_closed_form_cases_and_integration_agree() {
    let mut rng = SmallRng::seed_from_u64(1);
    let (mut c_slopes, mut r_slopes) = (std::collections::BTreeSet::new(), std::collections::BTreeSet::new());
    for _ in 0..20_000 {
        let r = 10f64.powf(rng.random_range(-3.0..3.0));
        let c = rng.random_range(-r - 2.0..r + 3.0);
        let m = canonical_coupling(r, c);
        assert!((m - canonical_coupling_by_cases(r, c)).abs() < 1e-12, "cases at r {r} c {c}");
        assert!((m - exact_m(r, c)).abs() < 1e-12, "integration at r {r} c {c}: {m} vs {}", exact_m(r, c));
        if (c - 0.5).abs() > r + 0.5 {
            assert_eq!(m, 0.0, "sparsity (4.24)");
        }
        assert!((m - canonical_coupling(r, 1.0 - c)).abs() < 1e-12, "c-symmetry (4.27)");
        let mirrored = 2.0 * r * canonical_coupling(1.0 / (4.0 * r), 0.5 + 1.0 / (4.0 * r) - c / (2.0 * r));
        assert!((m - mirrored).abs() < 1e-9 * (1.0 + r), "r-symmetry (4.28) at r {r} c {c}");
        assert!(m >= -r.min(0.5) - 1e-12 && m <= 2.0 * r.min(0.5) + 1e-12, "bounds");
        // Piecewise linear: slopes away from kinks (4.25, 4.26).
        let h = 1e-7 * r.min(1.0);
        let dc = (canonical_coupling(r, c + h) - canonical_coupling(r, c - h)) / (2.0 * h);
        let dr = (canonical_coupling(r + h, c) - canonical_coupling(r - h, c)) / (2.0 * h);
        for (slope, set) in [(dc, &mut c_slopes), (dr, &mut r_slopes)] {
            if (slope - slope.round()).abs() < 1e-4 {
                set.insert(slope.round() as i64);
            }
        }
    }
    assert!(c_slopes.iter().all(|s| s.abs() <= 3), "∂M/∂c in {{0, ±1, ±2, ±3}}: {c_slopes:?}");
    assert_eq!(r_slopes.into_iter().collect::<Vec<_>>(), vec![-1, 0, 1, 2], "∂M/∂r (the printed −2 never occurs)");
}

/// Notes §5.2: the ACC (Eq. 4.21, corrected 4.23, scaling cases) against exact integration,
/// with its identities and bounds; and the printed Eq. 4.23 fails.
#[test]
fn affine_coupling_matches_integration_and_its_identities() {
    let mut rng = SmallRng::seed_from_u64(2);
    let n = 32;
    for _ in 0..60 {
        let map = random_map(&mut rng);
        let mut column_squares = vec![0.0; n];
        for i in 0..n {
            let mut row_squares = 0.0;
            for j in 0..n {
                let d = map.coupling(i, j);
                assert!((d - exact_coupling(i, j, map)).abs() < 1e-12, "D_{i}{j} at {map:?}");
                assert!(d.abs() <= map.s.powf(-0.5) + 1e-12, "|D| ≤ s^-1/2");
                // Reciprocity (4.13): D_ij(s, o) = s⁻¹ D_ji(1/s, −o/s).
                let inverse = Affine { s: 1.0 / map.s, o: -map.o / map.s };
                assert!((d - inverse.coupling(j, i) / map.s).abs() < 1e-12, "reciprocity");
                row_squares += d * d;
                column_squares[j] += d * d;
            }
            assert!(row_squares <= 1.0 / map.s + 1e-9, "Bessel on a row");
        }
        assert!(column_squares.iter().all(|c| *c <= 1.0 / map.s + 1e-9), "Bessel on a column");
    }
    let identity = Affine { s: 1.0, o: 0.0 };
    for i in 0..n {
        for j in 0..n {
            assert!((identity.coupling(i, j) - f64::from(u8::from(i == j))).abs() < 1e-12, "D(1, 0) = I");
        }
    }
    // The printed Eq. 4.23 (2^{l_i} o in c) disagrees with integration: keep it out.
    let printed = |i: usize, j: usize, map: Affine| {
        let ((li, ti), (lj, tj)) = (level_offset(i).unwrap(), level_offset(j).unwrap());
        let (li, lj) = (f64::from(li), f64::from(lj));
        let ratio = (lj - li).exp2();
        let c = (ratio * f64::from(ti) - li.exp2() * map.o + 0.5 * ratio) / map.s - f64::from(tj);
        ((li - lj) / 2.0).exp2() * canonical_coupling(0.5 * ratio / map.s, c)
    };
    let map = Affine { s: 0.7, o: 0.3 };
    let worst = (1..n)
        .flat_map(|i| (1..n).map(move |j| (i, j)))
        .map(|(i, j)| (printed(i, j, map) - exact_coupling(i, j, map)).abs())
        .fold(0.0, f64::max);
    assert!(worst > 0.1, "the printed Eq. 4.23 should fail, worst error {worst}");
}

/// Notes §5.3: the ATC by Property 2 with σ (and the j = k and scaling cases) against exact
/// integration and against Lemma 1, `D_ijk = Σ_l D_il C_ljk` (Eq. 4.14).
#[test]
fn affine_tripling_matches_integration_and_lemma_1() {
    let mut rng = SmallRng::seed_from_u64(3);
    let n = 16;
    let identity = Affine { s: 1.0, o: 0.0 };
    for _ in 0..20 {
        let map = random_map(&mut rng);
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let d = map.tripling(i, j, k);
                    assert!((d - exact_tripling(i, j, k, map)).abs() < 1e-12, "D_{i}{j}{k} at {map:?}");
                    let lemma: f64 = (0..n).map(|l| map.coupling(i, l) * exact_tripling(l, j, k, identity)).sum();
                    assert!((d - lemma).abs() < 1e-12, "Lemma 1 at {i} {j} {k}");
                }
            }
        }
    }
    // Without σ Property 2 would be wrong where ψ_n is negative on ψ_m's support.
    let map = Affine { s: 0.8, o: 0.1 };
    let (j, k) = (1, 3); // ψ_{0,0} is −1 on supp ψ_{1,1}
    let i = (2..n).find(|&i| map.coupling(i, k).abs() > 1e-3).unwrap();
    assert!(map.tripling(i, j, k) * map.coupling(i, k) < 0.0, "σ = −1 flips the sign");
}

/// Notes §5.5: the fan-out holds every nonzero coupling, at most 3 per level (2L + 1 for a
/// scaling source), and the total stays under the corrected bound; a DC-only light has at
/// most (2L + 1)² nonzero 2D predictions.
#[test]
fn breakpoint_fan_out_covers_every_nonzero_coupling() {
    let mut rng = SmallRng::seed_from_u64(4);
    let mut targets = Vec::new();
    for n in [16usize, 32, 64] {
        let levels = n.ilog2() as usize;
        for _ in 0..40 {
            let map = random_map(&mut rng);
            let mut wavelet_block = 0;
            for i in 0..n {
                map.targets(i, n, &mut targets);
                let limit = if i == 0 { 2 * levels + 1 } else { 3 * levels + 1 };
                assert!(targets.len() <= limit, "fan-out {} > {limit}", targets.len());
                for j in 0..n {
                    if map.coupling(i, j).abs() > 1e-14 {
                        assert!(targets.contains(&j), "D_{i}{j} = {} but {j} is not a target", map.coupling(i, j));
                        wavelet_block += usize::from(i > 0 && j > 0);
                    }
                }
            }
            let bound = (map.s.min(1.0 / map.s) + 2.0) * levels as f64 * (n - 1) as f64;
            assert!(wavelet_block as f64 <= bound, "{wavelet_block} nonzeros > {bound}");
            let dc = propagate_2d(&[((0, 0), 1.0)], [map, random_map(&mut rng)], n);
            let nonzero = dc.iter().filter(|v| v.abs() > 1e-14).count();
            assert!(nonzero <= (2 * levels + 1).pow(2), "{nonzero} DC predictions");
        }
    }
}

/// `∫ F̂(s v + o) Ĝ(v) dv` over `[0, 1)` for cell values `f`, `g` (exact overlaps).
fn pixel_product_1d(f: &[f64], g: &[f64], map: Affine) -> f64 {
    let (nf, ng) = (f.len() as f64, g.len() as f64);
    let mut total = 0.0;
    for (a, fa) in f.iter().enumerate() {
        let (w0, w1) = (a as f64 / nf, (a + 1) as f64 / nf);
        let (v0, v1) = ((w0 - map.o) / map.s, (w1 - map.o) / map.s);
        for (b, gb) in g.iter().enumerate() {
            let overlap = (v1.min((b + 1) as f64 / ng) - v0.max(b as f64 / ng)).max(0.0);
            total += fa * gb * overlap;
        }
    }
    total
}

/// Length of `{v ∈ [b/n, (b+1)/n): s v + o ∈ [a/n, (a+1)/n)}`.
fn overlap(a: usize, b: usize, n: f64, map: Affine) -> f64 {
    let (v0, v1) = ((a as f64 / n - map.o) / map.s, ((a + 1) as f64 / n - map.o) / map.s);
    (v1.min((b + 1) as f64 / n) - v0.max(b as f64 / n)).max(0.0)
}

/// Notes §5.4: in 1D and 2D the affine double product in Haar equals the pixel-domain
/// integral with exact overlaps; two-step separable = naive four-index = pixel; and the
/// inverse transform of the propagated light is the transformed texture's cell averages.
#[test]
fn affine_products_equal_the_pixel_domain_integral() {
    let mut rng = SmallRng::seed_from_u64(5);
    let n = 16;
    for _ in 0..20 {
        let map = random_map(&mut rng);
        let f: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..2.0)).collect();
        let g: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..2.0)).collect();
        let (mut fh, mut gh) = (f.clone(), g.clone());
        haar_forward(&mut fh);
        haar_forward(&mut gh);
        let wavelet: f64 =
            (0..n).flat_map(|i| (0..n).map(move |j| (i, j))).map(|(i, j)| fh[i] * gh[j] * map.coupling(i, j)).sum();
        let pixel = pixel_product_1d(&f, &g, map);
        assert!((wavelet - pixel).abs() < 1e-12, "1D: {wavelet} vs {pixel}");
        let source: Vec<(usize, f64)> = fh.iter().copied().enumerate().collect();
        let light = propagate_1d(&source, map, n);
        let fanned: f64 = light.iter().zip(&gh).map(|(l, g)| l * g).sum();
        assert!((fanned - pixel).abs() < 1e-12, "1D over the fan-out");
    }
    let n = 8;
    let nf = n as f64;
    for _ in 0..6 {
        let maps = [random_map(&mut rng), random_map(&mut rng)];
        let f: Vec<f64> = (0..n * n).map(|_| rng.random_range(0.0..2.0)).collect();
        let g: Vec<f64> = (0..n * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let (mut fh, mut gh) = (f.clone(), g.clone());
        haar_forward_2d(&mut fh, n);
        haar_forward_2d(&mut gh, n);
        let source: Vec<((usize, usize), f64)> = (0..n * n).map(|k| ((k % n, k / n), fh[k])).collect();
        let light = propagate_2d(&source, maps, n);
        let two_step: f64 = light.iter().zip(&gh).map(|(l, g)| l * g).sum();
        let mut naive = 0.0;
        for i in 0..n * n {
            for j in 0..n * n {
                naive += fh[i] * gh[j] * maps[0].coupling(i % n, j % n) * maps[1].coupling(i / n, j / n);
            }
        }
        let mut pixel = 0.0;
        for a in 0..n * n {
            for b in 0..n * n {
                pixel += f[a] * g[b] * overlap(a % n, b % n, nf, maps[0]) * overlap(a / n, b / n, nf, maps[1]);
            }
        }
        assert!((two_step - naive).abs() < 1e-12 && (naive - pixel).abs() < 1e-12, "2D: {two_step} {naive} {pixel}");
        // The propagated light, back in cells: each cell's average of F(s v + o).
        let mut cells = light.clone();
        haar_inverse_2d(&mut cells, n);
        for b in 0..n * n {
            let average: f64 = (0..n * n)
                .map(|a| f[a] * overlap(a % n, b % n, nf, maps[0]) * overlap(a / n, b / n, nf, maps[1]))
                .sum::<f64>()
                * nf
                * nf;
            assert!((cells[b] - average).abs() < 1e-12, "cell {b}: {} vs {average}", cells[b]);
        }
    }
}

/// The transforms are orthonormal on functions: round trip, and Parseval against the cell
/// values' integral of the square.
#[test]
fn haar_transforms_round_trip_and_keep_energy() {
    let mut rng = SmallRng::seed_from_u64(6);
    let n = 32;
    let image: Vec<f64> = (0..n * n).map(|_| rng.random_range(-1.0..1.0)).collect();
    let mut coefficients = image.clone();
    haar_forward_2d(&mut coefficients, n);
    let energy: f64 = coefficients.iter().map(|c| c * c).sum();
    let integral: f64 = image.iter().map(|v| v * v).sum::<f64>() / (n * n) as f64;
    assert!((energy - integral).abs() < 1e-12);
    // Coefficient (i₁, i₂) is ∫∫ F Φ_{i₁}(x) Φ_{i₂}(y).
    let (i1, i2) = (5, 2);
    let direct: f64 = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f64 + 0.5, (k / n) as f64 + 0.5);
            image[k] * basis(i1, x / n as f64) * basis(i2, y / n as f64)
        })
        .sum::<f64>()
        / (n * n) as f64;
    assert!((coefficients[i2 * n + i1] - direct).abs() < 1e-12);
    haar_inverse_2d(&mut coefficients, n);
    assert!(coefficients.iter().zip(&image).all(|(a, b)| (a - b).abs() < 1e-12));
}

/// The coupling grid: a snapped map lies within half a step of the map (in the footprint's
/// position and in octaves of scale), a map on the grid stays put, and the couplings taken at
/// the snapped map approach the exact ones as the grid refines (relative L² over the first 16
/// indices of 300 random maps; the couplings are piecewise linear in `(s, o)`, so the error
/// falls about as fast as the step).
#[test]
fn coupling_grid_error_falls_with_its_step() {
    let mut rng = SmallRng::seed_from_u64(11);
    let maps: Vec<Affine> = (0..300).map(|_| random_map(&mut rng)).collect();
    let mut worst = Vec::new();
    for steps in [16u32, 64, 256, 1024] {
        let grid = CouplingGrid { steps };
        let (mut error2, mut norm2) = (0.0, 0.0);
        for &map in &maps {
            let snapped = grid.snap(map);
            let position = |m: Affine| (m.o + m.s) / (1.0 + m.s);
            assert!((position(snapped) - position(map)).abs() <= 0.5 / f64::from(steps) + 1e-12);
            assert!((snapped.s.log2() - map.s.log2()).abs() <= 1.0 / f64::from(steps) + 1e-12);
            let again = grid.snap(snapped);
            assert!((again.s - snapped.s).abs() < 1e-12 && (again.o - snapped.o).abs() < 1e-12);
            for i in 0..16 {
                for k in 0..16 {
                    let exact = map.coupling(i, k);
                    error2 += (exact - snapped.coupling(i, k)).powi(2);
                    norm2 += exact * exact;
                }
            }
        }
        worst.push((error2 / norm2).sqrt());
    }
    eprintln!("relative coupling error per grid (16, 64, 256, 1024 steps): {worst:?}");
    assert!(worst.windows(2).all(|w| w[1] < 0.5 * w[0]), "{worst:?}");
    assert!(worst[3] < 0.02, "{worst:?}");
}
