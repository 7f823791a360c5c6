//! The reference renderer against closed forms and its own invariants.

use super::*;
use crate::brdf::Material;
use crate::mesh;

fn cube_from(f: impl Fn(DVec3) -> [f64; 3] + Sync) -> CubeMap {
    CubeMap::from_fn(16, 2, f)
}

/// Every mesh shaded by `brdf`, no background.
fn lit<'a>(scene: &'a RayScene, meshes: &'a MeshSet, environment: &'a CubeMap, brdf: Brdf) -> ReferenceScene<'a> {
    ReferenceScene {
        scene,
        meshes,
        brdfs: vec![brdf; meshes.meshes.len()],
        environment,
        background: false,
        blockers: &[],
        area_lights: &[],
        point_lights: &[],
        normal_maps: &[],
        textbook_normal_maps: false,
    }
}

/// A constant normal map tilting the shading normal by 35° about the tangent shades a
/// glossy floor, in the textbook rule, exactly as the same tilt written into the mesh's
/// normals does (the same samples, the same frames), and visibly unlike the untilted floor.
/// In the production rule the shadow terminator dims it, never brightens it, and only a
/// little where the light is high.
#[test]
fn a_normal_map_shades_as_the_normals_it_encodes() {
    let flat = mesh::plane(4.0, 4);
    let tangents = mesh::vertex_tangents(&flat);
    let tilt = 35f64.to_radians();
    let mut tilted = flat.clone();
    for (n, t) in tilted.normals.iter_mut().zip(&tangents) {
        let (n0, t0) = (DVec3::from(n.map(f64::from)), DVec3::from(t.map(f64::from)));
        *n = (t0 * tilt.sin() + n0 * tilt.cos()).as_vec3().to_array();
    }
    let map = crate::normal_filtering::NormalMap {
        width: 2,
        height: 2,
        normals: vec![DVec3::new(tilt.sin(), 0.0, tilt.cos()); 4],
    };
    let environment = cube_from(|d| [0.2 + 3.0 * d.x.max(0.0).powi(4), 0.3 + d.y.max(0.0), 0.2]);
    let material =
        Material { model: crate::brdf::Model::Ggx, roughness: 0.3, f0: 0.8, specular: [1.0; 3], ..Default::default() };
    let camera = PinholeCamera { position: DVec3::new(0.0, 2.0, 3.0), target: DVec3::ZERO, fov_y_deg: 30.0 };
    let render_with =
        |mesh: &mesh::Mesh, maps: &[Option<(&crate::normal_filtering::NormalMap, f64)>], textbook: bool| {
            let meshes = MeshSet { meshes: vec![mesh.clone()] };
            let scene = RayScene::build(&meshes);
            let rs = ReferenceScene {
                normal_maps: maps,
                textbook_normal_maps: textbook,
                ..lit(&scene, &meshes, &environment, Brdf::from_material(&material))
            };
            render(&rs, &camera, (16, 16), 16, 3, &CancelToken::default(), &|_| {}).unwrap().pixels
        };
    let mapped = render_with(&flat, &[Some((&map, 1.0))], true);
    let written = render_with(&tilted, &[], true);
    let unmapped = render_with(&flat, &[], true);
    let production = render_with(&flat, &[Some((&map, 1.0))], false);
    let (sum, sum_mapped): (f32, f32) = (production.iter().flatten().sum(), mapped.iter().flatten().sum());
    assert!(
        production.iter().flatten().zip(mapped.iter().flatten()).all(|(p, m)| *p <= m * (1.0 + 1e-5) + 1e-9)
            && sum > 0.8 * sum_mapped
            && sum < 0.999 * sum_mapped,
        "the terminator dims the map's light a little: {sum} of {sum_mapped}"
    );
    let scale = written.iter().flatten().fold(0.0f32, |m, v| m.max(*v));
    let differ = |a: &[[f32; 3]], b: &[[f32; 3]]| {
        a.iter().zip(b).flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs())).fold(0.0f32, f32::max)
    };
    assert!(differ(&mapped, &written) < 1e-3 * scale, "{} (scale {scale})", differ(&mapped, &written));
    assert!(differ(&unmapped, &written) > 0.1 * scale, "the tilt changes too little to test");
}

/// A map whose normals lean up the image leans the shading normal the same way in the
/// world on a floor whose UVs are mirrored in u (its tangents turn round, its frame's
/// handedness with them), and on one mirrored by its transform: the images agree to their
/// noise (the turned frames sample other directions), far closer than a map leaning down.
#[test]
fn a_mirrored_uv_layout_keeps_the_maps_up_direction() {
    let tilt = 35f64.to_radians();
    let leaning = |y: f64| crate::normal_filtering::NormalMap {
        width: 2,
        height: 2,
        normals: vec![DVec3::new(0.0, y * tilt.sin(), tilt.cos()); 4],
    };
    let (map, down) = (leaning(1.0), leaning(-1.0));
    let environment = cube_from(|d| [0.2 + 3.0 * d.z.max(0.0).powi(4), 0.3 + d.y.max(0.0), 0.2]);
    let material =
        Material { model: crate::brdf::Model::Ggx, roughness: 0.3, f0: 0.8, specular: [1.0; 3], ..Default::default() };
    let camera = PinholeCamera { position: DVec3::new(0.0, 2.0, 3.0), target: DVec3::ZERO, fov_y_deg: 30.0 };
    let render_with = |mesh: &mesh::Mesh, map: &crate::normal_filtering::NormalMap| {
        let meshes = MeshSet { meshes: vec![mesh.clone()] };
        let scene = RayScene::build(&meshes);
        let maps = [Some((map, 1.0))];
        // The textbook rule: a flip would draw maps leaning either way alike where the view is
        // low.
        let rs = ReferenceScene {
            normal_maps: &maps,
            textbook_normal_maps: true,
            ..lit(&scene, &meshes, &environment, Brdf::from_material(&material))
        };
        render(&rs, &camera, (16, 16), 64, 3, &CancelToken::default(), &|_| {}).unwrap().pixels
    };
    let floor = mesh::plane(4.0, 4);
    let mut mirrored = floor.clone();
    for uv in &mut mirrored.uvs {
        uv[0] = 1.0 - uv[0];
    }
    let flipped = floor.clone().transformed(glam::DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0)));
    let reference = render_with(&floor, &map);
    let rms = |a: &[[f32; 3]]| {
        let sum: f64 =
            a.iter().zip(&reference).flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]) as f64)).map(|d| d * d).sum();
        (sum / (a.len() * 3) as f64).sqrt()
    };
    let opposite = rms(&render_with(&floor, &down));
    for (name, mesh) in [("mirrored UVs", &mirrored), ("mirroring transform", &flipped)] {
        let same = rms(&render_with(mesh, &map));
        assert!(same < 0.2 * opposite, "{name}: {same} against {opposite} for the opposite lean");
        let wrong = rms(&render_with(mesh, &down));
        assert!(wrong > 0.8 * opposite, "{name}: leaning down gives {wrong}, not about {opposite}");
    }
}

#[test]
fn environment_sampler_pdf_integrates_to_one_and_matches_its_samples() {
    let cube = cube_from(|d| [1.0 + 20.0 * d.y.max(0.0).powi(8), 1.0, 0.5]);
    let env = EnvironmentSampler::new(&cube);
    let q = crate::quadrature::SphereQuadrature::new(600, 1200);
    let total = q.integrate(|d| env.pdf(d));
    assert!((total - 1.0).abs() < 5e-3, "∫pdf = {total}");
    // E[L/pdf] = ∫ L dω (texel-constant radiance) for the sampler's own directions.
    let exact: f64 = cube.samples().map(|(_, w, l)| w * l[0]).sum();
    let mut rng = crate::sampling::test_rng(5);
    let n = 100_000;
    let estimate = (0..n)
        .map(|_| {
            let d = env.sample([rng.random(), rng.random(), rng.random()]);
            env.radiance(d).x / env.pdf(d)
        })
        .sum::<f64>()
        / n as f64;
    assert!((estimate / exact - 1.0).abs() < 5e-3, "{estimate} vs {exact}");
}

#[test]
fn white_furnace_sphere_reflects_the_environment() {
    // A white Lambert sphere under a constant environment, no occluders: every visible
    // pixel is exactly L (the estimator has zero variance only if pdfs and weights are right
    // up to noise, so allow 2%).
    let meshes = MeshSet { meshes: vec![mesh::sphere(1.0, 48)] };
    let scene = RayScene::build(&meshes);
    let environment = cube_from(|_| [0.7, 0.7, 0.7]);
    let material = Material { albedo: [1.0; 3], ..Default::default() };
    let rs = lit(&scene, &meshes, &environment, Brdf::from_material(&material));
    let camera = PinholeCamera { position: DVec3::new(0.0, 0.0, 4.0), target: DVec3::ZERO, fov_y_deg: 40.0 };
    let image = render(&rs, &camera, (32, 32), 64, 1, &CancelToken::default(), &|_| {}).unwrap();
    // Pixels well inside the silhouette (it is 11.4 px in radius).
    let inside: Vec<f32> = (0..32 * 32)
        .filter(|i| ((i % 32) as f64 - 15.5).hypot((i / 32) as f64 - 15.5) < 9.0)
        .map(|i| image.pixels[i][0])
        .collect();
    let mean = inside.iter().sum::<f32>() / inside.len() as f32;
    assert!((mean - 0.7).abs() < 0.007, "mean {mean} over {} pixels", inside.len());
    assert!(inside.iter().all(|v| (v - 0.7).abs() < 0.1), "{inside:?}");
    assert_eq!(image.pixels[0], [0.0; 3], "background off");
}

#[test]
fn glossy_sphere_under_a_constant_sky_reflects_its_directional_albedo() {
    // Under a constant L with no occluders, B(ω_o) = L ∫ f(ω_i, ω_o) cos θ_i dω_i. At the
    // sphere's centre pixel ω_o = n; the directional albedo comes from quadrature.
    let meshes = MeshSet { meshes: vec![mesh::sphere(1.0, 96)] };
    let scene = RayScene::build(&meshes);
    let environment = cube_from(|_| [1.0; 3]);
    let material = Material {
        model: crate::brdf::Model::Ggx,
        albedo: [0.2; 3],
        roughness: 0.3,
        f0: 0.5,
        specular: [1.0; 3],
        ..Default::default()
    };
    let brdf = Brdf::from_material(&material);
    let albedo =
        crate::quadrature::SphereQuadrature::new(1500, 600).integrate(|wi| brdf.eval(wi, DVec3::Z).x * wi.z.max(0.0));
    let rs = lit(&scene, &meshes, &environment, brdf);
    let camera = PinholeCamera { position: DVec3::new(0.0, 0.0, 4.0), target: DVec3::ZERO, fov_y_deg: 1.0 };
    let image = render(&rs, &camera, (2, 2), 4096, 3, &CancelToken::default(), &|_| {}).unwrap();
    let value = image.pixels.iter().map(|p| p[0] as f64).sum::<f64>() / 4.0;
    assert!((value / albedo - 1.0).abs() < 0.01, "{value} vs {albedo}");
}

#[test]
fn point_under_a_blocker_matches_the_analytic_shadowed_irradiance() {
    // A white Lambert floor under a constant sky of radiance L with a sphere of radius r
    // at height h above the point seen by the camera: B = L (1 - sin²α) with sin α = r/h
    // (the sphere removes the cap's cosine-weighted share, sin²α of π).
    let (r, h) = (0.5, 2.0);
    let meshes = MeshSet {
        meshes: vec![
            mesh::plane(40.0, 1),
            mesh::sphere(r, 96).transformed(glam::DMat4::from_translation(DVec3::new(0.0, h, 0.0))),
        ],
    };
    let scene = RayScene::build(&meshes);
    let environment = cube_from(|_| [1.0; 3]);
    let material = Material { albedo: [1.0; 3], ..Default::default() };
    let rs = lit(&scene, &meshes, &environment, Brdf::from_material(&material));
    // A narrow view of the floor point under the sphere, seen from the side.
    let camera =
        PinholeCamera { position: DVec3::new(3.0, 0.8, 0.0), target: DVec3::new(0.0, 0.0, 0.0), fov_y_deg: 2.0 };
    let image = render(&rs, &camera, (4, 4), 4096, 2, &CancelToken::default(), &|_| {}).unwrap();
    let value = image.pixels.iter().map(|p| p[0] as f64).sum::<f64>() / 16.0;
    let expected = 1.0 - (r / h).powi(2);
    assert!((value - expected).abs() < 0.01, "{value} vs {expected}");
}

/// The same closed form with the sphere as a blocker sphere (blocks light, is not seen):
/// the camera sees the floor point through it from above.
#[test]
fn point_under_a_blocker_sphere_matches_the_analytic_shadowed_irradiance() {
    let (r, h) = (0.5, 2.0);
    let meshes = MeshSet { meshes: vec![mesh::plane(40.0, 1)] };
    let scene = RayScene::build(&meshes);
    let environment = cube_from(|_| [1.0; 3]);
    let material = Material { albedo: [1.0; 3], ..Default::default() };
    let blockers = [crate::sh_exponential::Blocker { centre: [0.0, h, 0.0], radius: r }];
    let rs =
        ReferenceScene { blockers: &blockers, ..lit(&scene, &meshes, &environment, Brdf::from_material(&material)) };
    let camera =
        PinholeCamera { position: DVec3::new(0.01, 4.0, 0.0), target: DVec3::new(0.0, 0.0, 0.0), fov_y_deg: 2.0 };
    let image = render(&rs, &camera, (4, 4), 4096, 2, &CancelToken::default(), &|_| {}).unwrap();
    let value = image.pixels.iter().map(|p| p[0] as f64).sum::<f64>() / 16.0;
    let expected = 1.0 - (r / h).powi(2);
    assert!((value - expected).abs() < 0.01, "{value} vs {expected}");
}
