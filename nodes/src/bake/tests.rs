//! The bake against independent computations: closed-form point-light irradiance with
//! analytic shadows, Monte Carlo irradiance of the environment, and the written GLB read back
//! by the `gltf` crate.

use super::*;
use crate::engine::{CancelToken, Engine};
use crate::kinds::output::find_output;
use crate::project::Project;
use glam::DVec3;
use std::f64::consts::PI;

fn frame_of(ron: &str, overrides: &[&str]) -> FrameInputs {
    let mut project = Project::from_ron(ron, Path::new("test.ron")).unwrap();
    for o in overrides {
        project.apply_override(o).unwrap();
    }
    let graph = project.graph(Path::new("test.ron")).unwrap();
    let output = find_output(&graph, None).unwrap().id.clone();
    let engine = Engine::in_memory();
    let evaluation =
        engine.evaluate_request(&graph, &bake_request(&graph, &output), &CancelToken::default(), None, &|_, _| {});
    let frame = FrameInputs::gather(&evaluation, &graph, &output).unwrap();
    assert!(frame.pending.is_none(), "{:?}", frame.pending);
    frame
}

fn default_frame(overrides: &[&str]) -> FrameInputs {
    frame_of(&crate::project::default_project().to_ron(), overrides)
}

const LAMP_OVER_BALL: &str = r#"(
    version: 4,
    name: "a lamp over a ball on a floor",
    cameras: [(name: "main", position: (0.0, 2.0, 5.0), target: (0.0, 0.5, 0.0))],
    nodes: [
        (id: "scene", kind: "Scene", params: {
            "objects": Objects([
                (name: "floor", shape: Plane(size: 4.0)),
                (name: "ball", shape: Sphere(radius: 0.5), translation: (0.0, 1.0, 0.0)),
            ]),
            "tessellation": Int(96),
        }),
        (id: "lamp", kind: "PointLight", params: {"position": Vec3((0.4, 3.0, 0.2)), "intensity": Color((10.0, 5.0, 2.0))}),
        (id: "out", kind: "Output", params: {"mode": Choice("sh_irradiance")}),
    ],
    links: [
        (from: ("scene", "scene"), to: ("out", "scene")),
        (from: ("lamp", "lights"), to: ("out", "lights")),
    ],
)"#;

/// `I cos θ / (π d²)` where the segment to the lamp misses the analytic ball; vertices whose
/// segment passes within 5% of the ball's radius of its surface are skipped (the tessellated
/// ball differs from the analytic one there), as are grazing ones.
#[test]
fn point_lights_bake_as_inverse_square_cosine_with_shadows() {
    let frame = frame_of(LAMP_OVER_BALL, &[]);
    let scene = frame.ray_scene.as_ref().unwrap().value.get::<crate::raycast::RayScene>().unwrap();
    let light = vertex_light::vertex_light(&frame, Some(scene)).unwrap();
    let meshes = frame.geometry.meshes.value.get::<crate::mesh::MeshSet>().unwrap();
    let points = vertex_light::vertex_points(meshes);
    let (lamp, intensity) = (DVec3::new(0.4, 3.0, 0.2), DVec3::new(10.0, 5.0, 2.0));
    let (centre, radius) = (DVec3::new(0.0, 1.0, 0.0), 0.5);
    let (mut shadowed, mut lit, mut compared) = (0, 0, 0);
    for (p, got) in points.iter().zip(&light) {
        let to_lamp = lamp - p.position;
        let d = to_lamp.length();
        let l = to_lamp / d;
        let cos = l.dot(p.normal);
        if cos < 0.05 {
            continue;
        }
        // Closest approach of the segment to the ball's centre.
        let t = (centre - p.position).dot(l).clamp(0.0, d);
        let miss = (p.position + l * t - centre).length();
        let on_ball = ((p.position - centre).length() - radius).abs() < 1e-3;
        if !on_ball && (miss - radius).abs() < 0.05 * radius {
            continue;
        }
        let blocked = !on_ball && miss < radius;
        let expected = if blocked { DVec3::ZERO } else { intensity * cos / (PI * d * d) };
        for c in 0..3 {
            assert!(
                (f64::from(got[c]) - expected[c]).abs() <= 1e-4 * expected[c].max(1e-3),
                "vertex at {:?}: {got:?} against {expected:?} (blocked {blocked})",
                p.position
            );
        }
        compared += 1;
        if blocked { shadowed += 1 } else { lit += 1 }
    }
    assert!(shadowed > 20 && lit > 1000, "{shadowed} shadowed, {lit} lit of {compared}");
}

/// Each mode's baked environment light against Monte Carlo irradiance (MIS, shadow rays) at
/// 240 random vertices of the default scene (sky with a sun, objects on a floor): the
/// relative L1 error over those vertices. Tolerances are each mode's own accuracy: the
/// unshadowed SH mode against unshadowed irradiance (9–25 coefficients of a sun), the
/// shadowed modes against shadowed irradiance.
#[test]
fn each_modes_vertex_light_matches_monte_carlo_irradiance() {
    use rand::{Rng, SeedableRng};
    for (mode, shadowed, tolerance) in
        [("sh_irradiance", false, 0.08), ("sh_prt", true, 0.15), ("wavelet_vertex", true, 0.08)]
    {
        let frame = default_frame(&[&format!("output.mode={mode}")]);
        let light = vertex_light::vertex_light(&frame, None).unwrap();
        let meshes = frame.geometry.meshes.value.get::<crate::mesh::MeshSet>().unwrap();
        let points = vertex_light::vertex_points(meshes);
        let cube = frame.background.radiance.as_ref().unwrap().value.get::<crate::cubemap::CubeMap>().unwrap();
        let sampler = crate::reference::EnvironmentSampler::new(cube);
        let empty = crate::raycast::RayScene::build(&crate::mesh::MeshSet { meshes: vec![] });
        let occluders = if shadowed {
            frame.ray_scene.as_ref().unwrap().value.get::<crate::raycast::RayScene>().unwrap()
        } else {
            &empty
        };
        let mut rng = rand::rngs::SmallRng::seed_from_u64(11);
        let (mut diff, mut total, mut unshadowed_diff) = (0.0, 0.0, 0.0);
        for _ in 0..240 {
            let i = rng.random_range(0..points.len());
            let p = points[i];
            let e = crate::reference::irradiance(occluders, &sampler, p.position, p.normal, 512, &mut rng) / PI;
            let got = DVec3::from(light[i].map(f64::from));
            diff += (got - e).abs().element_sum();
            total += e.element_sum();
            if shadowed {
                // The same point with nothing in the way: the test sees shadows.
                let open = crate::reference::irradiance(&empty, &sampler, p.position, p.normal, 128, &mut rng) / PI;
                unshadowed_diff += (got - open).abs().element_sum();
            }
        }
        let error = diff / total;
        eprintln!("{mode}: relative L1 error {error:.4} (against unshadowed light: {:.4})", unshadowed_diff / total);
        assert!(error < tolerance, "{mode}: {error}");
        if shadowed {
            assert!(unshadowed_diff / total > 2.0 * error, "{mode}: shadows are not what the bake shows");
        }
    }
}

#[test]
fn the_glb_reads_back_with_world_positions_light_lights_and_camera() {
    // A turned, stretched ball: its node's TRS must give back the world positions.
    let ron = LAMP_OVER_BALL.replace(
        "translation: (0.0, 1.0, 0.0)",
        "translation: (0.3, 1.0, -0.2), rotation_deg: (10.0, 30.0, 0.0), scale: (1.0, 1.5, 1.0)",
    );
    let frame = frame_of(&ron, &[]);
    let scene = frame.ray_scene.as_ref().unwrap().value.get::<crate::raycast::RayScene>().unwrap();
    let light = vertex_light::vertex_light(&frame, Some(scene)).unwrap();
    let baked = bake(&frame, Some(baked_camera()), &|_, _| {}).unwrap();
    let again = bake(&frame, Some(baked_camera()), &|_, _| {}).unwrap();
    assert_eq!(baked.files[0].bytes, again.files[0].bytes, "the same frame gives the same bytes");
    assert_eq!(baked.manifest_bytes(), again.manifest_bytes());

    let (document, buffers, _) = gltf::import_slice(&baked.files[0].bytes).unwrap();
    let scale = baked.manifest.vertex_light_scale;
    let meshes = frame.geometry.meshes.value.get::<crate::mesh::MeshSet>().unwrap();
    let mut first = 0;
    let mut seen_meshes = 0;
    for node in document.nodes() {
        if let Some(mesh) = node.mesh() {
            let source = meshes.meshes.iter().position(|m| Some(m.name.as_str()) == mesh.name()).unwrap();
            let start: usize = meshes.meshes[..source].iter().map(|m| m.positions.len()).sum();
            let world = glam::Mat4::from_cols_array_2d(&node.transform().matrix());
            let primitive = mesh.primitives().next().unwrap();
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
            let colors: Vec<[f32; 3]> = reader.read_colors(0).unwrap().into_rgb_f32().collect();
            for (k, (p, c)) in positions.iter().zip(&colors).enumerate() {
                let p = world.transform_point3(glam::Vec3::from(*p));
                let original = glam::Vec3::from(meshes.meshes[source].positions[k]);
                assert!((p - original).length() < 1e-4, "{p} vs {original}");
                for ch in 0..3 {
                    assert_eq!(c[ch] * scale, light[start + k][ch], "COLOR_0 × scale is the baked light");
                }
            }
            first += positions.len();
            seen_meshes += 1;
        }
        if let Some(camera) = node.camera() {
            let m = glam::Mat4::from_cols_array_2d(&node.transform().matrix());
            let forward = m.transform_vector3(glam::Vec3::NEG_Z);
            let towards = (glam::Vec3::new(0.0, 0.5, 0.0) - glam::Vec3::new(0.0, 2.0, 5.0)).normalize();
            assert!(forward.dot(towards) > 0.9999, "the camera looks at its target");
            assert!(matches!(camera.projection(), gltf::camera::Projection::Perspective(_)));
        }
    }
    assert_eq!((seen_meshes, first), (2, light.len()));
    let lights: Vec<_> = document.lights().unwrap().collect();
    assert_eq!(lights.len(), 1);
    assert!((lights[0].intensity() - 10.0).abs() < 1e-6);
    assert_eq!(lights[0].color(), [1.0, 0.5, 0.2]);
}

fn baked_camera() -> gltf_export::ExportCamera {
    gltf_export::ExportCamera {
        name: "main".into(),
        position: [0.0, 2.0, 5.0],
        target: [0.0, 0.5, 0.0],
        fov_y_deg: 40.0,
        aspect: 16.0 / 9.0,
    }
}

#[test]
fn writes_are_whole_or_nothing() {
    let frame = frame_of(LAMP_OVER_BALL, &[]);
    let baked = bake(&frame, None, &|_, _| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    write_atomically(&baked, &out).unwrap();
    let mut names: Vec<String> =
        std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names, [MANIFEST_FILE, SCENE_FILE], "no staging folder is left");
    assert_eq!(std::fs::read(out.join(SCENE_FILE)).unwrap(), baked.files[0].bytes);
    // A destination that cannot be a folder: an error, and nothing written beside it.
    let blocked = dir.path().join("file");
    std::fs::write(&blocked, b"x").unwrap();
    assert!(write_atomically(&baked, &blocked).is_err());
    assert_eq!(std::fs::read(&blocked).unwrap(), b"x");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}
