//! Blocker spheres in the `sh_prt` mode through the engine: what a sphere move recomputes,
//! and the shadow against ray tracing.

use super::*;
use crate::kinds::blockers::BlockerSet;
use crate::transport::ShTransport;
use glam::DVec3;

/// The default project on a floor of 4 × 4 tiles (10 m each), under a blocker set, in `sh_prt`.
fn blockers_graph(spheres: Vec<([f64; 3], f64)>) -> Graph {
    let mut graph = default_graph_with("blockers", "BlockerSpheres", &[("blockers", "blockers", "output", "blockers")]);
    graph.set_param("blockers", "spheres", ParamValue::Spheres(spheres)).unwrap();
    let tiles = (0..16)
        .map(|i| {
            let (x, z) = (-15.0 + 10.0 * (i % 4) as f64, -15.0 + 10.0 * (i / 4) as f64);
            SceneObject::new(&format!("tile{i}"), Shape::Plane { size: 10.0 }).at([x, 0.0, z])
        })
        .collect();
    graph.set_param("scene", "objects", ParamValue::Objects(tiles)).unwrap();
    graph.set_param("scene", "tessellation", ParamValue::Int(64)).unwrap();
    graph.set_param("scene", "transport_rays", ParamValue::Int(64)).unwrap();
    graph.set_param("output", "mode", ParamValue::Choice("sh_prt".into())).unwrap();
    graph
}

/// Moving one sphere reruns the sphere list, the blocked transport (recomputing only the
/// parts within the sphere's reach, old or new) and the incident light; never the scene's
/// transport or the shadow tables. A floor vertex straight under a lone sphere gets the
/// closed-form occlusion `1 − sin²α` of a constant sky in its blocked DC transfer.
#[test]
fn a_sphere_move_recomputes_only_the_parts_it_reaches() {
    let mut spheres = vec![([0.0, 2.0, 0.0], 0.5), ([15.0, 1.0, 15.0], 0.3)];
    let mut graph = blockers_graph(spheres.clone());
    let engine = Engine::in_memory();
    let first = evaluate_frame(&engine, &graph);
    let blocked = value_of::<ShTransport>(&first, "output", "blocked_transport");
    let plain = value_of::<ShTransport>(&first, "scene", "transport_sh");
    let meshes = value_of::<crate::mesh::MeshSet>(&first, "scene", "geometry");
    let positions: Vec<DVec3> =
        meshes.meshes.iter().flat_map(|m| m.positions.iter().map(|p| DVec3::from(p.map(f64::from)))).collect();
    let centre = positions.iter().position(|p| p.length() < 1e-6).expect("a vertex at the origin");
    let n = blocked.bands * blocked.bands;
    let ratio = f64::from(blocked.transfer[centre * n]) / f64::from(plain.transfer[centre * n]);
    let expected = 1.0 - (0.5f64 / 2.0).powi(2);
    assert!((ratio - expected).abs() < 0.02, "occlusion under the sphere: {ratio} vs {expected}");
    let far = positions.iter().position(|p| (*p - DVec3::new(-15.0, 0.0, -15.0)).length() < 0.7).unwrap();
    assert_eq!(blocked.transfer[far * n..(far + 1) * n], plain.transfer[far * n..(far + 1) * n]);
    let parts = |eval: &Evaluation| memo_parts(eval, "output", "blocked_transport");
    let (computed, reused) = parts(&first);
    assert_eq!(reused, 0);
    spheres[1].0 = [16.0, 1.0, 15.0];
    graph.set_param("blockers", "spheres", ParamValue::Spheres(spheres)).unwrap();
    let second = evaluate_frame(&engine, &graph);
    let ran = ran(&second.report);
    assert_eq!(ran, set(&["blockers.spheres", "output.blocked_transport", "output.incident_sh"]), "a sphere move");
    let (recomputed, kept) = parts(&second);
    assert!(recomputed > 0 && recomputed < computed && kept > 0, "{recomputed} recomputed, {kept} kept of {computed}");
    let set_value = value_of::<BlockerSet>(&second, "blockers", "spheres");
    assert_eq!(set_value.blockers.len(), 2);
}

/// A set fitted to a closed glTF model (the 1 m textured box in assets/): one
/// sphere is its inscribed ball, leaving `1 − π/6` of the cube uncovered, and says so; 60
/// spheres leave less, and shadow the `sh_prt` frame through the set's transform.
#[test]
fn a_set_fitted_to_a_gltf_box_reports_its_coverage() {
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/gltf/assimp-glTF2/BoxTextured-glTF/BoxTextured.gltf");
    assert!(model.is_file(), "the repository's assets/ folder is expected at {}", model.display());
    let mut graph = blockers_graph(vec![]);
    graph.set_param("blockers", "fit_model", ParamValue::Path(model.display().to_string())).unwrap();
    graph.set_param("blockers", "fit_count", ParamValue::Int(1)).unwrap();
    graph.set_param("blockers", "offset", ParamValue::Vec3([0.0, 2.0, 0.0])).unwrap();
    let engine = Engine::in_memory();
    let one = evaluate_frame(&engine, &graph);
    let fit = value_of::<crate::sphere_set::SphereSetFit>(&one, "blockers", "fitted");
    assert_eq!(fit.spheres.len(), 1);
    let expected = 1.0 - std::f64::consts::PI / 6.0;
    assert!((fit.uncovered - expected).abs() < 0.05, "{} against {expected}", fit.uncovered);
    assert!(report(&one, "blockers", "spheres").info.iter().any(|l| l.contains("uncovered")));
    let set = value_of::<BlockerSet>(&one, "blockers", "spheres");
    let centre = DVec3::from(set.blockers[0].centre);
    assert!((centre - DVec3::new(0.0, 2.0, 0.0)).length() < 0.05, "the fit is placed by the offset: {centre}");
    graph.set_param("blockers", "fit_count", ParamValue::Int(60)).unwrap();
    let sixty = evaluate_frame(&engine, &graph);
    let more = value_of::<crate::sphere_set::SphereSetFit>(&sixty, "blockers", "fitted");
    assert_eq!(more.spheres.len(), 60);
    assert!(more.uncovered < fit.uncovered / 2.0, "{} after {}", more.uncovered, fit.uncovered);
    assert_eq!(value_of::<BlockerSet>(&sixty, "blockers", "spheres").blockers.len(), 60);
}
