use super::*;
use rand::Rng;

/// A unit vector drawn from a vMF lobe (Wood's method on S²: `w = 1 + ln(u + (1 − u)e^{−2κ})/κ`).
fn sample_vmf(rng: &mut impl Rng, mean: DVec3, kappa: f64) -> DVec3 {
    let u: f64 = rng.random_range(0.0..1.0);
    let w = 1.0 + (u + (1.0 - u) * (-2.0 * kappa).exp()).ln() / kappa;
    let phi = rng.random_range(0.0..2.0 * PI);
    let (t, b) = mean.any_orthonormal_pair();
    let s = (1.0 - w * w).max(0.0).sqrt();
    (w * mean + s * (phi.cos() * t + phi.sin() * b)).normalize()
}

/// A bumpy 16 × 16 map: normals tilted by up to about 50° in a pattern with detail at every scale.
fn bumpy_map() -> NormalMap {
    let mut rng = crate::sampling::test_rng(21);
    let (width, height) = (16, 16);
    let normals = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            let tilt = DVec3::new((x * 1.3).sin() * 0.8, (y * 0.7 + x * 0.2).cos() * 0.6, 1.0);
            (tilt + DVec3::new(rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3), 0.0)).normalize()
        })
        .collect();
    NormalMap { width, height, normals }
}

/// The texels under texel `(x, y)` of level `level`.
fn block(map: &NormalMap, level: usize, x: usize, y: usize) -> Vec<DVec3> {
    let size = 1 << level;
    let mut out = Vec::new();
    for by in y * size..((y + 1) * size).min(map.height) {
        for bx in x * size..((x + 1) * size).min(map.width) {
            out.push(map.normals[by * map.width + bx]);
        }
    }
    out
}

/// MIP-mapping the NDF's SH by plain averaging gives, at every level, exactly the SH of the
/// union of the texels below (the NDF of the block, `(1/N) Σ Y_lm(n_q)`), and the mean of
/// their normals.
#[test]
fn mip_averaging_of_the_ndf_sh_is_the_sh_of_the_union() {
    let map = bumpy_map();
    let bands = 6;
    let pyramid = NdfPyramid::build(&map, bands);
    assert_eq!(pyramid.levels.len(), 5);
    let basis = ShBasis::new(bands);
    for (level, ndf) in pyramid.levels.iter().enumerate() {
        for y in 0..ndf.height {
            for x in 0..ndf.width {
                let normals = block(&map, level, x, y);
                let mut union = vec![0.0; bands * bands];
                for n in &normals {
                    for (u, y) in union.iter_mut().zip(basis.eval_vec(*n)) {
                        *u += y / normals.len() as f64;
                    }
                }
                for (a, b) in ndf.sh_of(x, y).iter().zip(&union) {
                    assert!((a - b).abs() < 1e-12, "level {level} ({x}, {y}): {a} vs {b}");
                }
                let mean = normals.iter().sum::<DVec3>() / normals.len() as f64;
                assert!((ndf.mean_normal[y * ndf.width + x] - mean).length() < 1e-12);
            }
        }
    }
    // The top texel's NDF is spread: its mean normal is clearly shorter than one.
    assert!(pyramid.levels[4].mean_normal[0].length() < 0.9);
}

/// Eq. 5.7 against the texels themselves: for a lobe `f(ω·n)` of degree 4 in `ω·n` (so exactly
/// five bands), the effective lobe from the filtered NDF equals the average of `f(ω·n_q)`
/// over the texels, at every level and at random directions.
#[test]
fn the_filtered_lobe_equals_the_average_over_the_texels() {
    let map = bumpy_map();
    let bands = 5;
    let pyramid = NdfPyramid::build(&map, bands);
    let f = |t: f64| 0.2 + 0.5 * t + 0.8 * t * t * t * t + 0.3 * t * t * t;
    let zonal = crate::sh::zonal_project(bands, 16, f);
    let mut rng = crate::sampling::test_rng(22);
    for (level, ndf) in pyramid.levels.iter().enumerate() {
        let (x, y) = (ndf.width / 2, ndf.height / 3);
        let lobe = effective_lobe(&zonal, ndf.sh_of(x, y));
        let normals = block(&map, level, x, y);
        for _ in 0..20 {
            let omega = crate::sampling::random_unit_vector(&mut rng);
            let direct = normals.iter().map(|n| f(omega.dot(*n))).sum::<f64>() / normals.len() as f64;
            let filtered = crate::sh::reconstruct(&lobe, omega);
            assert!((filtered - direct).abs() < 1e-9, "level {level}: {filtered} vs {direct}");
        }
    }
}

/// A flat map leaves the lobe as it is (its NDF is the delta at the normal at every level), and
/// Toksvig's filter gives it the largest concentration.
#[test]
fn a_flat_map_keeps_the_unfiltered_lobe() {
    let bands = 6;
    let pyramid = NdfPyramid::build(&NormalMap::flat(8, 4), bands);
    let zonal = crate::sh::zonal_project(bands, 32, |t| t.max(0.0).powi(8));
    let unfiltered = crate::sh::rotate_zonal(&zonal, DVec3::Z);
    for level in &pyramid.levels {
        let lobe = effective_lobe(&zonal, level.sh_of(0, 0));
        for (a, b) in lobe.iter().zip(&unfiltered) {
            assert!((a - b).abs() < 1e-12);
        }
        assert_eq!(Vmf::toksvig(level.mean_normal[0]).kappa, MAX_KAPPA);
    }
}

/// The closed form `κ ≈ (3r − r³)/(1 − r²)` inverts the exact mean resultant length of a vMF
/// on S², `coth κ − 1/κ`, within 6% over two decades of κ (its worst, 5%, near κ = 5); a one-lobe EM fit of normals drawn
/// from a lobe takes exactly the closed form of their mean length, and lands near the true κ.
#[test]
fn one_lobes_kappa_is_the_closed_form_of_the_mean_normals_length() {
    for kappa in [2.0f64, 5.0, 10.0, 50.0, 200.0] {
        let r = 1.0 / kappa.tanh() - 1.0 / kappa;
        let closed = Vmf::kappa_from_mean_length(r);
        assert!((closed / kappa - 1.0).abs() < 0.06, "κ {kappa}: closed form {closed}");
    }
    let mut rng = crate::sampling::test_rng(23);
    for kappa in [3.0, 20.0, 150.0] {
        let mean = DVec3::new(0.3, -0.2, 0.9).normalize();
        let normals: Vec<(DVec3, f64)> = (0..40_000).map(|_| (sample_vmf(&mut rng, mean, kappa), 1.0)).collect();
        let fit = fit_vmf_mixture(&normals, 1, 5);
        assert_eq!(fit.len(), 1);
        let resultant = normals.iter().map(|(n, _)| *n).sum::<DVec3>() / normals.len() as f64;
        assert!((fit[0].kappa - Vmf::kappa_from_mean_length(resultant.length())).abs() < 1e-9 * kappa);
        assert!((fit[0].kappa / kappa - 1.0).abs() < 0.08, "κ {kappa}: fitted {}", fit[0].kappa);
        assert!(fit[0].mean.dot(mean) > (1f64.to_radians()).cos(), "κ {kappa}: mean {}", fit[0].mean);
        assert!((fit[0].weight - 1.0).abs() < 1e-12);
    }
}

/// Spherical EM recovers a known three-lobe mixture drawn at random: each lobe's direction
/// within 2°, concentration within 10% and weight within 0.02.
#[test]
fn em_recovers_a_known_mixture() {
    let truth = [
        Vmf { weight: 0.5, kappa: 60.0, mean: DVec3::new(0.0, 0.0, 1.0) },
        Vmf { weight: 0.3, kappa: 25.0, mean: DVec3::new(0.6, 0.0, 0.8) },
        Vmf { weight: 0.2, kappa: 120.0, mean: DVec3::new(-0.3, 0.55, 0.78).normalize() },
    ];
    let mut rng = crate::sampling::test_rng(24);
    let normals: Vec<(DVec3, f64)> = (0..30_000)
        .map(|_| {
            let u: f64 = rng.random_range(0.0..1.0);
            let lobe = if u < 0.5 {
                &truth[0]
            } else if u < 0.8 {
                &truth[1]
            } else {
                &truth[2]
            };
            (sample_vmf(&mut rng, lobe.mean, lobe.kappa), 1.0)
        })
        .collect();
    let fit = fit_vmf_mixture(&normals, 3, 60);
    assert_eq!(fit.len(), 3);
    for lobe in &truth {
        let found = fit.iter().max_by(|a, b| a.mean.dot(lobe.mean).total_cmp(&b.mean.dot(lobe.mean))).unwrap();
        assert!(found.mean.dot(lobe.mean) > 2f64.to_radians().cos(), "{lobe:?}: {found:?}");
        assert!((found.kappa / lobe.kappa - 1.0).abs() < 0.1, "{lobe:?}: {found:?}");
        assert!((found.weight - lobe.weight).abs() < 0.02, "{lobe:?}: {found:?}");
    }
    // The fitted mixture is a density: it integrates to one.
    let quadrature = crate::quadrature::SphereQuadrature::new(400, 800);
    let total = quadrature.integrate(|d| fit.iter().map(|l| l.density(d)).sum::<f64>());
    assert!((total - 1.0).abs() < 1e-3, "{total}");
}

/// 8-bit texels decode to unit normals (`2·rgb − 1`); a wrong texel count is an error naming it.
#[test]
fn rgb_texels_decode_to_unit_normals() {
    let map = NormalMap::from_rgb8(2, 1, &[[128, 128, 255], [255, 128, 128]]).unwrap();
    assert!(map.normals[0].dot(DVec3::Z) > 0.9999);
    assert!(map.normals[1].dot(DVec3::X) > 0.9999);
    assert!(map.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-12));
    let error = NormalMap::from_rgb8(2, 2, &[[0, 0, 0]]).unwrap_err();
    assert!(error.contains("2×2") && error.contains("not 1"), "{error}");
}

/// A lobe's SH attenuation `e^{−l(l+1)/2κ}` against the Funk–Hecke eigenvalues of its density
/// by quadrature, `λ_l = 2π ∫ γ(t) P_l(t) dt`: within 4% at κ = 10 and 0.5% from κ = 50, l < 8.
#[test]
fn a_lobes_band_attenuation_matches_its_density() {
    let bands = 8;
    for (kappa, tolerance) in [(10.0, 0.04), (50.0, 0.005), (200.0, 0.005)] {
        let lobe = Vmf { weight: 1.0, kappa, mean: DVec3::Z };
        let zonal = crate::sh::zonal_project(bands, 400, |t| lobe.density(DVec3::new((1.0 - t * t).sqrt(), 0.0, t)));
        for (l, z) in zonal.iter().enumerate() {
            let eigenvalue = z * (4.0 * PI / (2 * l + 1) as f64).sqrt();
            let attenuation = lobe.band_attenuation(l);
            assert!(
                (eigenvalue / attenuation - 1.0).abs() < tolerance,
                "κ {kappa}, l {l}: {eigenvalue} vs {attenuation}"
            );
        }
    }
}

/// A high-frequency 64 × 64 normal map: a grid of bumps four texels across, with noise.
fn fine_bumps() -> NormalMap {
    let mut rng = crate::sampling::test_rng(25);
    let size = 64;
    let normals = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f64, (i / size) as f64);
            let k = 2.0 * PI / 4.0;
            let slope = DVec3::new(0.9 * (k * x).cos() * (0.5 * k * y).sin(), 0.7 * (k * y).cos(), 0.0);
            let noise = DVec3::new(rng.random_range(-0.15..0.15), rng.random_range(-0.15..0.15), 0.0);
            (DVec3::Z - slope - noise).normalize()
        })
        .collect();
    NormalMap { width: size, height: size, normals }
}

/// Relative RMS of `estimate` against `truth` over footprints and directions.
fn relative_rms(pairs: &[(f64, f64)]) -> f64 {
    let mean = pairs.iter().map(|(t, _)| t).sum::<f64>() / pairs.len() as f64;
    (pairs.iter().map(|(t, e)| (t - e) * (t - e)).sum::<f64>() / pairs.len() as f64).sqrt() / mean
}

/// The thesis's experiment (Figs. 5.2–5.3) on a plane: a pixel at MIP level `k` covers `4^k`
/// texels of a high-frequency normal map, and its ground truth is the average of the texels'
/// own shading (supersampling). Per level, the relative RMS error over footprints and
/// light or half-vector directions of:
/// - diffuse (Lambert, `max(l·n, 0)`): naive MIP-mapping of normals, Toksvig (one vMF lobe's
///   SH), and the NDF's SH at 3 bands (9 coefficients, eq. 5.7);
/// - glossy (Blinn-Phong, `(h·n)^64`): naive MIP-mapping, Toksvig, and a 6-lobe vMF mixture
///   fitted by EM.
///
/// Past the texels themselves (level 0, where naive is exact), the filtered methods beat naive
/// MIP-mapping at every level, and the vMF mixture beats Toksvig on the glossy lobe.
#[test]
fn filtered_ndfs_beat_mip_mapped_normals_at_every_distance() {
    let map = fine_bumps();
    let bands = 3;
    let pyramid = NdfPyramid::build(&map, bands);
    let cosine = crate::sh::zonal_project(bands, 32, |t| t.max(0.0));
    let exponent = 64.0;
    let mut rng = crate::sampling::test_rng(26);
    let directions: Vec<DVec3> = (0..24)
        .map(|_| {
            let d = crate::sampling::random_unit_vector(&mut rng);
            DVec3::new(d.x * 0.7, d.y * 0.7, d.z.abs() + 0.5).normalize()
        })
        .collect();
    eprintln!("level  diffuse: naive  Toksvig  SH-9   glossy: naive  Toksvig  vMF-6");
    for (level, ndf) in pyramid.levels.iter().enumerate().skip(1) {
        let (mut diffuse, mut glossy) = ([vec![], vec![], vec![]], [vec![], vec![], vec![]]);
        // At most 16 footprints per level, spread over the map.
        let step = (ndf.width / 4).max(1);
        for y in (0..ndf.height).step_by(step) {
            for x in (0..ndf.width).step_by(step) {
                let normals = block(&map, level, x, y);
                let mean = ndf.mean_normal[y * ndf.width + x];
                let naive = mean.normalize();
                let toksvig = Vmf::toksvig(mean);
                let toksvig_sh = effective_lobe(&cosine, &toksvig.sh(bands));
                let ndf_sh = effective_lobe(&cosine, ndf.sh_of(x, y));
                let weighted: Vec<(DVec3, f64)> = normals.iter().map(|n| (*n, 1.0)).collect();
                let mixture = fit_vmf_mixture(&weighted, 6, 30);
                for d in &directions {
                    let truth = normals.iter().map(|n| d.dot(*n).max(0.0)).sum::<f64>() / normals.len() as f64;
                    diffuse[0].push((truth, d.dot(naive).max(0.0)));
                    diffuse[1].push((truth, crate::sh::reconstruct(&toksvig_sh, *d)));
                    diffuse[2].push((truth, crate::sh::reconstruct(&ndf_sh, *d)));
                    let lobe = |t: f64| t.max(0.0).powf(exponent);
                    let truth = normals.iter().map(|n| lobe(d.dot(*n))).sum::<f64>() / normals.len() as f64;
                    glossy[0].push((truth, lobe(d.dot(naive))));
                    glossy[1].push((truth, filtered_glossy(&[toksvig], exponent, *d)));
                    glossy[2].push((truth, filtered_glossy(&mixture, exponent, *d)));
                }
            }
        }
        let d = diffuse.map(|p| relative_rms(&p));
        let g = glossy.map(|p| relative_rms(&p));
        eprintln!(
            "{level:>5}  {:>14.1}% {:>7.1}% {:>5.1}%  {:>13.1}% {:>7.1}% {:>5.1}%",
            100.0 * d[0],
            100.0 * d[1],
            100.0 * d[2],
            100.0 * g[0],
            100.0 * g[1],
            100.0 * g[2]
        );
        assert!(d[2] < d[0], "level {level}: SH {} against naive {}", d[2], d[0]);
        assert!(d[1] < d[0], "level {level}: Toksvig {} against naive {}", d[1], d[0]);
        assert!(g[1] < g[0], "level {level}: Toksvig {} against naive {}", g[1], g[0]);
        assert!(g[2] < g[1], "level {level}: vMF mixture {} against Toksvig {}", g[2], g[1]);
    }
}

/// The vMF pyramid has a level per MIP level down to one texel; its texels' mixtures are
/// densities (weights summing to one) fitted to the normals below them: on the flat map one
/// lobe at the normal, on the bumpy map, at the top, lobes spread as the normals are (the
/// mixture's mean direction lies near the mean normal).
#[test]
fn the_vmf_pyramid_fits_each_texels_normals() {
    let flat = vmf_pyramid(&NormalMap::flat(4, 4), 6, 10, 64);
    assert_eq!(flat.len(), 3);
    for level in &flat {
        for texel in level {
            assert_eq!(texel.len(), 1, "{texel:?}");
            assert!(texel[0].mean.dot(DVec3::Z) > 1.0 - 1e-12 && texel[0].kappa == MAX_KAPPA);
        }
    }
    let map = bumpy_map();
    let pyramid = vmf_pyramid(&map, 6, 20, 64);
    assert_eq!(pyramid.len(), 5);
    assert_eq!(pyramid[1].len(), 64);
    for level in &pyramid {
        for texel in level {
            assert!((texel.iter().map(|l| l.weight).sum::<f64>() - 1.0).abs() < 1e-9);
        }
    }
    let top = &pyramid[4][0];
    let mean_normal = map.normals.iter().sum::<DVec3>().normalize();
    let mixture_mean = top.iter().map(|l| l.weight * l.mean).sum::<DVec3>().normalize();
    assert!(mixture_mean.dot(mean_normal) > 5f64.to_radians().cos(), "{mixture_mean} vs {mean_normal}");
    assert!(top.len() > 1);
}

/// A real normal map (glTF sample RibsNormal.png) loads as unit normals, mostly facing out;
/// a missing file, a file that is no image, and a map too large say so by name.
#[test]
fn normal_maps_load_and_bad_files_are_named() {
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/gltf/assimp-glTF2");
    let map = load_normal_map(&assets.join("ClearCoat-glTF/RibsNormal.png")).unwrap();
    assert!(map.width > 0 && map.normals.len() == map.width * map.height);
    assert!(map.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-9));
    let mean = map.normals.iter().sum::<DVec3>() / map.normals.len() as f64;
    assert!(mean.z > 0.5, "mean normal {mean}");
    let missing = load_normal_map(std::path::Path::new("/nonexistent/normals.png")).unwrap_err();
    assert!(missing.contains("/nonexistent/normals.png"), "{missing}");
    let dir = std::env::temp_dir().join(format!("lightloom-normals-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = dir.join("notes.png");
    std::fs::write(&text, "not an image").unwrap();
    let error = load_normal_map(&text).unwrap_err();
    assert!(error.contains("notes.png"), "{error}");
    let huge =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/regressions/normal_map/huge_declared.png");
    std::fs::write(dir.join("huge.png"), &std::fs::read(huge).unwrap()[1..]).unwrap();
    let error = load_normal_map(&dir.join("huge.png")).unwrap_err();
    assert!(error.contains("100000 × 100000"), "{error}");
}

/// A glTF material's normal texture decodes to the map its image file does, with the
/// material's scale; an image whose header declares absurd dimensions is refused by name.
#[test]
fn gltf_normal_textures_decode_as_their_images() {
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/gltf/assimp-glTF2");
    let direct = load_normal_map(&assets.join("ClearCoat-glTF/RibsNormal.png")).unwrap();
    let loaded = load_gltf_normal_map(&assets.join("ClearCoat-glTF/ClearCoatTest.gltf"), "SharedNorm_Coating").unwrap();
    assert_eq!((loaded.scale, loaded.material.as_str()), (1.0, "SharedNorm_Coating"));
    assert!(loaded.map == direct && loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let huge = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/regressions/normal_map/huge_declared.png"),
    )
    .unwrap();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"images":[{{"uri":"data:image/png;base64,{}"}}],"textures":[{{"source":0}}],"materials":[{{"normalTexture":{{"index":0}}}}]}}"#,
        base64::encode(&huge[1..])
    );
    let dir = std::env::temp_dir().join(format!("lightloom-gltf-huge-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("huge.gltf"), json).unwrap();
    let error = load_gltf_normal_map(&dir.join("huge.gltf"), "").unwrap_err();
    assert!(error.contains("huge.gltf") && error.contains("100000 × 100000"), "{error}");
}

/// Sampling a map: at a texel's centre its own normal, halfway between two the normalised
/// mean, and across the edge the map repeats.
#[test]
fn sampling_is_bilinear_between_texel_centres_and_repeats() {
    let map = bumpy_map();
    let (w, h) = (map.width as f64, map.height as f64);
    let texel = |x: usize, y: usize| map.normals[y * map.width + x];
    for (x, y) in [(0, 0), (5, 3), (15, 15)] {
        let at = map.sample([(x as f64 + 0.5) / w, (y as f64 + 0.5) / h]);
        assert!((at - texel(x, y)).length() < 1e-12);
    }
    let between = map.sample([6.0 / w, 3.5 / h]);
    assert!((between - (texel(5, 3) + texel(6, 3)).normalize()).length() < 1e-12);
    let across = map.sample([1.0, 3.5 / h]);
    assert!((across - (texel(15, 3) + texel(0, 3)).normalize()).length() < 1e-12);
    assert!((map.sample([-0.5 / w, 0.5 / h]) - texel(15, 0)).length() < 1e-12);
}

/// Coarse levels fit twelve lobes where the map's normals are a few distinct slopes, and keep
/// six where they spread smoothly: a 64² map of diagonal ribs (eight distinct slopes, a period
/// of 16 texels) takes more than six lobes a texel (a lobe for each slope at least) from the
/// level of 16-texel blocks (a whole period) up, where twelve lobes draw its normals far likelier
/// than six; a 64² map of smooth random bumps keeps six everywhere.
#[test]
fn coarse_levels_take_twelve_lobes_only_where_they_pay() {
    let size = 64;
    let slopes = [-24.0f64, -16.0, -8.0, -2.0, 2.0, 8.0, 16.0, 24.0].map(f64::to_radians);
    let ribs = NormalMap {
        width: size,
        height: size,
        normals: (0..size * size)
            .map(|i| {
                let phase = ((i % size + i / size) % 16) / 2;
                let a = slopes[phase];
                DVec3::new(a.sin() / 2f64.sqrt(), a.sin() / 2f64.sqrt(), a.cos()).normalize()
            })
            .collect(),
    };
    let mut rng = crate::sampling::test_rng(5);
    let bumps: Vec<(f64, f64, f64)> =
        (0..40).map(|_| (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0), rng.random_range(0.0..6.3))).collect();
    let smooth = NormalMap {
        width: size,
        height: size,
        normals: (0..size * size)
            .map(|i| {
                let (u, v) = ((i % size) as f64 / size as f64, (i / size) as f64 / size as f64);
                let (mut dx, mut dy) = (0.0, 0.0);
                for (fu, fv, p) in &bumps {
                    dx += 0.02 * (40.0 * fu * u + 30.0 * fv * v + p).cos();
                    dy += 0.02 * (30.0 * fu * u + 40.0 * fv * v + p).sin();
                }
                DVec3::new(dx, dy, 1.0).normalize()
            })
            .collect(),
    };
    let counts = |map: &NormalMap| -> Vec<usize> {
        vmf_pyramid(map, 6, 20, 256).iter().map(|level| level.iter().map(Vec::len).max().unwrap()).collect()
    };
    let rib_counts = counts(&ribs);
    let smooth_counts = counts(&smooth);
    println!("lobes a texel per level: ribs {rib_counts:?}, smooth bumps {smooth_counts:?}");
    assert!(rib_counts[4..].iter().all(|&c| c >= 8), "{rib_counts:?}");
    assert!(smooth_counts.iter().all(|&c| c <= 6), "{smooth_counts:?}");
    // The premise: twelve lobes explain the ribs' normals far better than six.
    let normals: Vec<(DVec3, f64)> = ribs.normals.iter().map(|n| (*n, 1.0)).collect();
    let density = |mixture: &[Vmf]| {
        normals.iter().map(|(n, _)| mixture.iter().map(|l| l.density(*n)).sum::<f64>().ln()).sum::<f64>()
            / normals.len() as f64
    };
    let (six, twelve) = (fit_vmf_mixture(&normals, 6, 20), fit_vmf_mixture(&normals, 12, 20));
    assert!(density(&twelve) > density(&six) + 0.5, "{} against {}", density(&twelve), density(&six));
}
