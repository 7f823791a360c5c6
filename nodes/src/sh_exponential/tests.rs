use super::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// A fine product grid on the sphere: Gauss–Legendre in `z`, trapezoid in `φ`, with the
/// basis values at each node (the oracle for projections of discontinuous functions).
struct Grid {
    dirs: Vec<DVec3>,
    weights: Vec<f64>,
    basis: Vec<Vec<f64>>,
}

impl Grid {
    fn new(bands: usize, nz: usize, nphi: usize) -> Self {
        let (zs, ws) = crate::quadrature::gauss_legendre(nz);
        let b = ShBasis::new(bands);
        let (mut dirs, mut weights, mut basis) = (Vec::new(), Vec::new(), Vec::new());
        for (z, w) in zs.iter().zip(&ws) {
            let r = (1.0 - z * z).max(0.0).sqrt();
            for k in 0..nphi {
                let phi = (k as f64 + 0.5) * 2.0 * PI / nphi as f64;
                let d = DVec3::new(r * phi.cos(), r * phi.sin(), *z);
                dirs.push(d);
                weights.push(w * 2.0 * PI / nphi as f64);
                basis.push(b.eval_vec(d));
            }
        }
        Self { dirs, weights, basis }
    }

    fn project(&self, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
        let mut out = vec![0.0; self.basis[0].len()];
        for ((d, w), y) in self.dirs.iter().zip(&self.weights).zip(&self.basis) {
            let v = f(*d) * w;
            if v != 0.0 {
                out.iter_mut().zip(y).for_each(|(o, y)| *o += v * y);
            }
        }
        out
    }
}

fn relative_l2(a: &[f64], b: &[f64]) -> f64 {
    let diff: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    (diff / b.iter().map(|y| y * y).sum::<f64>()).sqrt()
}

/// A random direction in the upper (+Z) hemisphere.
fn upper_direction(rng: &mut SmallRng) -> DVec3 {
    let z: f64 = rng.random_range(0.05..1.0);
    let phi: f64 = rng.random_range(0.0..2.0 * PI);
    let r = (1.0 - z * z).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// The closed-form cap coefficients equal Gauss–Legendre quadrature of `Y_l0` over the
/// visible part `z < cos θ` (a polynomial there, so the quadrature is exact).
#[test]
fn cap_coefficients_match_quadrature() {
    let bands = 8;
    let basis = ShBasis::new(bands);
    for theta in [0.05, 0.3, 0.7, 1.2, FRAC_PI_2, 2.5] {
        let x = f64::cos(theta);
        let (nodes, weights) = crate::quadrature::gauss_legendre(24);
        let mut expected = vec![0.0; bands];
        for (t, w) in nodes.iter().zip(&weights) {
            // Map [-1, 1] to [-1, x].
            let z = -1.0 + (t + 1.0) * (x + 1.0) / 2.0;
            let y = basis.eval_vec(DVec3::new((1.0 - z * z).max(0.0).sqrt(), 0.0, z));
            for (l, e) in expected.iter_mut().enumerate() {
                *e += w * (x + 1.0) / 2.0 * 2.0 * PI * y[sh::index(l, 0)];
            }
        }
        let closed = cap_zonal(bands, x);
        for l in 0..bands {
            assert!((closed[l] - expected[l]).abs() < 1e-12, "θ={theta} l={l}: {} vs {}", closed[l], expected[l]);
        }
    }
}

/// Γ's entries allowed by the selection rules number 1, 10, 83, 359, 1164, 2961 for orders
/// 1–6 (the thesis prints 369 for order 4: a typo); the numerically non-zero ones, which the
/// Gaunt table keeps, are fewer (accidental zeros): 1, 10, 83, 353, 1158, 2907 (notes §3.1).
#[test]
fn gaunt_nonzero_counts_per_order() {
    let m_of = |i: usize| i as i64 - (sh::band_of(i) * (sh::band_of(i) + 1)) as i64;
    for (bands, allowed, nonzero) in
        [(1, 1, 1), (2, 10, 10), (3, 83, 83), (4, 359, 353), (5, 1164, 1158), (6, 2961, 2907)]
    {
        let n = bands * bands;
        let mut count = 0;
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let (l1, l2, l3) = (sh::band_of(i), sh::band_of(j), sh::band_of(k));
                    let (m1, m2, m3) = (m_of(i), m_of(j), m_of(k));
                    let triangle = l3 >= l1.abs_diff(l2) && l3 <= l1 + l2 && (l1 + l2 + l3) % 2 == 0;
                    let (a1, a2, a3) = (m1.abs(), m2.abs(), m3.abs());
                    let m_sum = a3 == a1 + a2 || a3 == (a1 - a2).abs() || a1 == a2 + a3 || a2 == a1 + a3;
                    let negatives = [m1, m2, m3].iter().filter(|m| **m < 0).count();
                    if triangle && m_sum && negatives % 2 == 0 {
                        count += 1;
                    }
                }
            }
        }
        assert_eq!(count, allowed, "order {bands}: allowed by the selection rules");
        assert_eq!(GauntTable::new(bands, bands, bands).len(), nonzero, "order {bands}: numerically non-zero");
    }
}

/// The truncated product, the product matrix and the exact series agree with their
/// definitions: `M_f g = f * g`, `M_f` symmetric, and the eigen-summed series equals PS-p for
/// a small `f` as `p` grows, and PS*-8 (whose squarings truncate) within 1e-4 of it.
#[test]
fn products_and_the_exact_series_agree_with_their_definitions() {
    let shexp = ShExp::new(4);
    let mut rng = SmallRng::seed_from_u64(5);
    let f: Vec<f64> = (0..16).map(|_| rng.random_range(-0.3..0.3)).collect();
    let g: Vec<f64> = (0..16).map(|_| rng.random_range(-0.3..0.3)).collect();
    let m = shexp.matrix(&f);
    assert!((&m - m.transpose()).abs().max() < 1e-12);
    let mg = &m * DVector::from_column_slice(&g);
    let fg = shexp.product(&f, &g);
    assert!(mg.iter().zip(&fg).all(|(a, b)| (a - b).abs() < 1e-12));
    let exact = shexp.exp_exact(&f);
    assert!(relative_l2(&shexp.exp_series(&f, 20), &exact) < 1e-12);
    // PS* squares truncated products, so it differs from the exact series by truncation.
    let ps_star = relative_l2(&shexp.exp_ps_star(&f, 8), &exact);
    assert!(ps_star < 1e-4, "PS*-8 against the exact series: {ps_star:e}");
}

/// `exp_*(log g)` gives back a single cap: PS*-8 within 1e-4 up to θ = 0.5 (the notes'
/// 3e-10 and 2.9e-5) and within 1% at θ = 0.8 (2.3e-3); plain PS-8 fails on large caps
/// where PS* holds (θ = 1.2: 0.69 against 0.058).
#[test]
fn exp_of_log_gives_back_a_single_cap() {
    let shexp = ShExp::new(4);
    for (theta, tolerance) in [(0.1, 1e-8), (0.5, 1e-4), (0.8, 1e-2), (1.2, 0.1)] {
        let cap = zonal_to_full(&cap_zonal(4, f64::cos(theta)));
        let log = shexp.log_eigen(&cap, LOG_CLIP_RELATIVE);
        let error = relative_l2(&shexp.exp_ps_star(&log, 8), &cap);
        assert!(error < tolerance, "θ={theta}: PS*-8 round trip {error}");
        if theta >= 1.2 {
            let plain = relative_l2(&shexp.exp_series(&log, 8), &cap);
            assert!(plain > 5.0 * error, "θ={theta}: PS-8 {plain} against PS*-8 {error}");
        }
    }
}

/// Random caps (angular radius 0.1–0.5, upper hemisphere), 12 trials each: summing the logs
/// and exponentiating once with PS*-8 is within 10% (relative) of the O(n⁵) product chain's
/// error against the fine-grid projection of the exact visibility, both limited by order-4
/// truncation (notes §3.6: chain 0.7 / 4.2 / 8.4 / 12.9% for 2 / 8 / 16 / 32 blockers; here
/// 0.24 / 4.3 / 6.8 / 14.6%, log space 0.26 / 4.6 / 7.2 / 14.9%).
#[test]
fn many_blockers_in_log_space_match_the_product_chain() {
    let bands = 4;
    let shexp = ShExp::new(bands);
    let grid = Grid::new(bands, 300, 600);
    // The grid's own error on one cap: far below the errors compared.
    let cap_dir = DVec3::new(0.3, 0.2, 0.9).normalize();
    let projected = grid.project(|d| if d.dot(cap_dir) >= f64::cos(0.3) { 0.0 } else { 1.0 });
    let basis = ShBasis::new(bands);
    let mut closed = vec![0.0; bands * bands];
    let mut y = vec![0.0; bands * bands];
    add_rotated_zonal(&basis, &cap_zonal(bands, f64::cos(0.3)), cap_dir, 1.0, &mut y, &mut closed);
    let floor = relative_l2(&projected, &closed);
    assert!(floor < 1e-3, "grid error {floor}");
    let table = LogCapTable::new(&shexp, 512, LOG_CLIP_RELATIVE);
    let mut rng = SmallRng::seed_from_u64(17);
    for (count, chain_expected) in [(2, 0.007), (8, 0.042), (16, 0.084), (32, 0.129)] {
        let (mut chain_sum, mut log_sum) = (0.0, 0.0);
        let trials = 12;
        for _ in 0..trials {
            let caps: Vec<(DVec3, f64)> =
                (0..count).map(|_| (upper_direction(&mut rng), rng.random_range(0.1..0.5))).collect();
            let truth = grid.project(|d| if caps.iter().any(|(c, t)| d.dot(*c) >= t.cos()) { 0.0 } else { 1.0 });
            let mut chain = shexp.one();
            let mut log = vec![0.0; bands * bands];
            let mut zonal = vec![0.0; bands];
            for (c, t) in &caps {
                let mut g = vec![0.0; bands * bands];
                add_rotated_zonal(&basis, &cap_zonal(bands, t.cos()), *c, 1.0, &mut y, &mut g);
                chain = shexp.product(&chain, &g);
                table.lookup(*t, &mut zonal);
                add_rotated_zonal(&basis, &zonal, *c, 1.0, &mut y, &mut log);
            }
            chain_sum += relative_l2(&chain, &truth);
            log_sum += relative_l2(&shexp.exp_ps_star(&log, 8), &truth);
        }
        let (chain, log) = (chain_sum / trials as f64, log_sum / trials as f64);
        eprintln!("{count} blockers: product chain {:.2}%, log + PS*-8 {:.2}%", 100.0 * chain, 100.0 * log);
        assert!(log <= 1.1 * chain + 1e-3, "{count} blockers: log space {log} against the chain's {chain}");
        // Two caps differ from the exact product only where they overlap (rare): noisy.
        if count >= 8 {
            let ratio = chain / chain_expected;
            assert!((0.6..1.6).contains(&ratio), "{count} blockers: chain {chain} against the notes' {chain_expected}");
        }
    }
}

/// Sums of logs do not depend on blocker order, and moving one blocker incrementally
/// (`f += f_new − f_old` where either reaches) equals accumulating from scratch, touching
/// only receivers within its influence.
#[test]
fn accumulation_is_order_free_and_incremental_equals_full() {
    let shexp = ShExp::new(4);
    let table = LogCapTable::new(&shexp, 256, LOG_CLIP_RELATIVE);
    let mut rng = SmallRng::seed_from_u64(3);
    let receivers: Vec<DVec3> =
        (0..400).map(|_| DVec3::new(rng.random_range(-40.0..40.0), 0.0, rng.random_range(-40.0..40.0))).collect();
    let mut blockers: Vec<Blocker> = (0..30)
        .map(|_| Blocker {
            centre: [rng.random_range(-40.0..40.0), rng.random_range(0.5..3.0), rng.random_range(-40.0..40.0)],
            radius: rng.random_range(0.1..0.5),
        })
        .collect();
    let forward = accumulate_logs(&receivers, &blockers, &table);
    let mut reversed_blockers = blockers.clone();
    reversed_blockers.reverse();
    let reversed = accumulate_logs(&receivers, &reversed_blockers, &table);
    assert!(forward.iter().zip(&reversed).all(|(a, b)| (a - b).abs() < 1e-12));
    let mut incremental = forward.clone();
    let old = blockers[7];
    let new = Blocker { centre: [old.centre[0] + 1.5, old.centre[1], old.centre[2] - 0.5], ..old };
    let touched = move_blocker(&mut incremental, &receivers, &old, &new, &table);
    blockers[7] = new;
    let full = accumulate_logs(&receivers, &blockers, &table);
    assert!(incremental.iter().zip(&full).all(|(a, b)| (a - b).abs() < 1e-12));
    assert!(!touched.is_empty() && touched.len() < receivers.len() / 4, "touched {}", touched.len());
    for (i, x) in receivers.iter().enumerate() {
        let reach = old.influence_radius().max(new.influence_radius());
        let near = (*x - DVec3::from(old.centre)).length() <= reach || (*x - DVec3::from(new.centre)).length() <= reach;
        assert_eq!(touched.contains(&i), near, "receiver {i}");
    }
}

/// HYB with an OL table fitted on multi-sphere log vectors stays within a few percent of the
/// exact exponential (notes §9.4c: mean 2.8%, max 8.9% halving to 0.5), and PS*-2 within
/// 0.5% mean (0.18%).
#[test]
fn hyb_and_ps_star_2_against_the_exact_exponential() {
    let bands = 4;
    let table = LogCapTable::new(&ShExp::new(bands), 256, LOG_CLIP_RELATIVE);
    let mut rng = SmallRng::seed_from_u64(23);
    let basis = ShBasis::new(bands);
    let mut y = vec![0.0; bands * bands];
    let mut zonal = vec![0.0; bands];
    let mut sample = |rng: &mut SmallRng| {
        let count = rng.random_range(1..=40);
        let mut f = vec![0.0; bands * bands];
        for _ in 0..count {
            let d: f64 = rng.random_range(1.5..6.0);
            let r: f64 = rng.random_range(0.2..1.0);
            table.lookup((r / d).asin(), &mut zonal);
            add_rotated_zonal(&basis, &zonal, upper_direction(rng), 1.0, &mut y, &mut f);
        }
        f
    };
    let training: Vec<Vec<f64>> = (0..1500).map(|_| sample(&mut rng)).collect();
    let plain = ShExp::new(bands);
    let ol = OlTable::fit(&plain, &training, 64, 8.0, 0.5);
    let shexp = ShExp::with_ol(bands, ol);
    let (mut hyb, mut ps2, mut hyb_max) = (0.0, 0.0, 0.0f64);
    let tests = 300;
    for _ in 0..tests {
        let f = sample(&mut rng);
        let exact = shexp.exp_exact(&f);
        let e = relative_l2(&shexp.exp_hyb(&f), &exact);
        hyb += e;
        hyb_max = hyb_max.max(e);
        ps2 += relative_l2(&shexp.exp_ps_star(&f, 2), &exact);
    }
    let (hyb, ps2) = (hyb / tests as f64, ps2 / tests as f64);
    eprintln!("HYB mean {:.2}% max {:.2}%, PS*-2 mean {:.2}%", 100.0 * hyb, 100.0 * hyb_max, 100.0 * ps2);
    assert!(hyb < 0.05, "HYB mean {hyb}");
    assert!(ps2 < 0.005, "PS*-2 mean {ps2}");
}

/// Ambient occlusion of a white Lambert floor under a constant sky, shaded as the `sh_prt`
/// mode does (`B = (1/π) Σ (T * g)_k L_k`, `T` the floor's cosine transfer at 4 bands), against
/// a fine-grid integral of the exact visibility: under one sphere straight above it is also
/// the closed form `1 − sin²α`; under 8 and 32 random spheres the mean error is 0.2% and
/// 1.4% (order-4 truncation).
#[test]
fn floor_under_spheres_against_the_exact_occlusion() {
    let bands = 4;
    let shexp = ShExp::new(bands);
    let table = LogCapTable::new(&shexp, 512, LOG_CLIP_RELATIVE);
    let product = BlockedProduct::new(ShExp::new(bands), bands);
    let grid = Grid::new(bands, 200, 400);
    let up = DVec3::Y;
    let transfer: Vec<f32> = grid.project(|d| d.dot(up).max(0.0)).iter().map(|&v| v as f32).collect();
    let shade = |t: &[f32]| SQRT_4PI * f64::from(t[0]) / PI;
    // One sphere straight above: closed form.
    let (r, h) = (0.5, 2.0);
    let one = [Blocker { centre: [0.0, h, 0.0], radius: r }];
    let mut t = transfer.clone();
    product.apply(&[DVec3::ZERO], &one, &table, ExpMethod::PsStar(2), 1.0, &mut [&mut t]);
    let expected = 1.0 - (r / h).powi(2);
    assert!((shade(&t) - expected).abs() < 0.01 * expected, "one sphere: {} vs {expected}", shade(&t));
    let mut rng = SmallRng::seed_from_u64(29);
    for (count, tolerance) in [(8, 0.01), (32, 0.04)] {
        let blockers: Vec<Blocker> = (0..count)
            .map(|_| Blocker {
                centre: [rng.random_range(-3.0..3.0), rng.random_range(0.6..3.0), rng.random_range(-3.0..3.0)],
                radius: rng.random_range(0.2..0.5),
            })
            .collect();
        let receivers: Vec<DVec3> =
            (0..40).map(|_| DVec3::new(rng.random_range(-2.0..2.0), 0.0, rng.random_range(-2.0..2.0))).collect();
        let mut blocked: Vec<f32> = receivers.iter().flat_map(|_| transfer.clone()).collect();
        product.apply(&receivers, &blockers, &table, ExpMethod::PsStar(2), 1.0, &mut [&mut blocked]);
        let (mut error, mut total) = (0.0, 0.0);
        for (i, x) in receivers.iter().enumerate() {
            let exact = grid.project(|d| {
                let hidden = blockers.iter().any(|b| {
                    let to = DVec3::from(b.centre) - *x;
                    d.dot(to) > 0.0 && to.length_squared() - d.dot(to).powi(2) <= b.radius * b.radius
                });
                if hidden { 0.0 } else { d.dot(up).max(0.0) }
            })[0]
                * SQRT_4PI
                / PI;
            error += (shade(&blocked[i * 16..(i + 1) * 16]) - exact).abs();
            total += exact;
        }
        let relative = error / total;
        eprintln!("{count} spheres: mean relative error {:.2}%", 100.0 * relative);
        assert!(relative < tolerance, "{count} spheres: {relative}");
    }
}

/// A receiver inside a sphere (a sphere dipping into the floor, or centred on the receiver)
/// sees nothing, as the reference's rays do; at strength 0 the set casts nothing.
#[test]
fn a_receiver_inside_a_sphere_sees_nothing() {
    let table = LogCapTable::new(&ShExp::new(4), 64, LOG_CLIP_RELATIVE);
    let product = BlockedProduct::new(ShExp::new(4), 4);
    for centre in [[0.0, 0.1, 0.0], [0.0, 0.0, 0.0]] {
        let sphere = [Blocker { centre, radius: 0.3 }];
        let mut t = vec![1.0f32; 16];
        product.apply(&[DVec3::ZERO], &sphere, &table, ExpMethod::PsStar(2), 1.0, &mut [&mut t]);
        assert!(t.iter().all(|v| *v == 0.0), "{centre:?}: {t:?}");
        let mut faded = vec![1.0f32; 16];
        product.apply(&[DVec3::ZERO], &sphere, &table, ExpMethod::PsStar(2), 0.0, &mut [&mut faded]);
        assert!(faded.iter().all(|v| *v == 1.0), "{centre:?} at strength 0: {faded:?}");
    }
}
