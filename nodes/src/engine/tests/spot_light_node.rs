//! The spot light through the engine: its light's intensity in every direction is the `.ies`
//! file's candela at the photometric angles of that direction, turned by the light's aim and
//! spin, cut by its cone; and it draws, bakes and traces as a point light does.

use super::*;
use crate::ies::Photometry;
use crate::light::PointLight;
use glam::DVec3;

fn wall_pack() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/ies/wall_pack.ies")
}

/// Against the file read directly: for directions all round an aimed and spun light, the
/// intensity is `peak × candela(γ, C) / max candela`, with `γ` from the aim and `C` from the
/// spun `φ = 0` plane (the asymmetric wall pack tells the planes apart).
#[test]
fn intensity_follows_the_files_candela_in_the_lights_frame() {
    let mut graph = default_graph_with("spot", "SpotLight", &[("spot", "lights", "output", "lights")]);
    let aim = DVec3::new(0.3, -1.0, 0.4).normalize();
    graph.set_param("spot", "direction", ParamValue::Vec3(aim.to_array())).unwrap();
    graph.set_param("spot", "spin", ParamValue::Float(30.0)).unwrap();
    graph.set_param("spot", "cone", ParamValue::Float(180.0)).unwrap();
    graph.set_param("spot", "intensity", ParamValue::Color([20.0, 10.0, 5.0])).unwrap();
    graph.set_param("spot", "profile", ParamValue::Path(wall_pack().display().to_string())).unwrap();
    let eval = Engine::in_memory().evaluate(&graph, &CancelToken::default(), None);
    assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
    let lights = value_of::<Vec<PointLight>>(&eval, "spot", "lights");
    let light = lights.last().unwrap();
    let profile = light.profile.as_ref().unwrap();
    assert!((profile.frame.z_axis - aim).length() < 1e-12);
    let file = Photometry::load(&wall_pack()).unwrap();
    let peak = file.peak();
    let (x, y) = (profile.frame.x_axis, profile.frame.y_axis);
    let (mut worst, mut n) = (0.0f64, 0);
    for gamma in (0..=85).step_by(5).map(|g| f64::from(g) + 1.3) {
        for c in (0..360).step_by(15).map(|c| f64::from(c) + 2.7) {
            let (g, c_rad) = (gamma.to_radians(), c.to_radians());
            let dir = aim * g.cos() + (x * c_rad.cos() + y * c_rad.sin()) * g.sin();
            let want = 20.0 * file.candela(gamma, c) / peak;
            let got = light.intensity_toward(dir)[0];
            worst = worst.max((got - want).abs() / 20.0);
            n += 1;
        }
    }
    // The table's rows are 1.4° apart and its columns 5.6°: within 3% of the peak everywhere.
    assert!(worst < 0.03, "worst difference {worst:.4} of the peak over {n} directions");
    assert_eq!(light.intensity_toward(aim)[1] / light.intensity_toward(aim)[0], 0.5, "the colour holds");
    // The 0° plane is where the spin puts it: 30° from the unspun reference.
    let unspun = crate::light::AngularProfile::tabulate(aim, 0.0, |_, _| 1.0).frame.x_axis;
    assert!((x.dot(unspun) - 30f64.to_radians().cos()).abs() < 1e-9);
}

/// A cone without a file: full inside `cone × (1 − falloff)`, dark past `cone`, a smooth step
/// between; the light keeps its cone for formats that take one.
#[test]
fn a_plain_cone_has_a_soft_edge() {
    let mut graph = default_graph_with("spot", "SpotLight", &[]);
    graph.set_param("spot", "cone", ParamValue::Float(40.0)).unwrap();
    graph.set_param("spot", "falloff", ParamValue::Float(0.5)).unwrap();
    let eval = Engine::in_memory().evaluate(&graph, &CancelToken::default(), None);
    let light = value_of::<Vec<PointLight>>(&eval, "spot", "lights").pop().unwrap();
    let at = |deg: f64| {
        let r = deg.to_radians();
        light.intensity_toward(DVec3::new(r.sin(), -r.cos(), 0.0))[0] / light.intensity[0]
    };
    assert!((at(0.0) - 1.0).abs() < 1e-6 && (at(19.0) - 1.0).abs() < 0.02);
    assert!(at(30.0) > 0.2 && at(30.0) < 0.8, "{}", at(30.0));
    assert!(at(41.5) < 1e-6 && at(90.0) == 0.0);
    let (inner, outer) = light.profile.as_ref().unwrap().cone.unwrap();
    assert!((inner.to_degrees() - 20.0).abs() < 1e-9 && (outer.to_degrees() - 40.0).abs() < 1e-9);
}

/// Linked to the Output, the spot joins the frame's point lights, which the viewport shades,
/// the reference traces and the bake lights vertices with.
#[test]
fn the_frame_draws_it_as_a_light() {
    let mut graph = default_graph_with("spot", "SpotLight", &[("spot", "lights", "output", "lights")]);
    graph.set_param("output", "mode", ParamValue::Choice("sh_irradiance".into())).unwrap();
    let eval = evaluate_frame(&Engine::in_memory(), &graph);
    let frame = crate::frame::FrameInputs::gather(&eval, &graph, "output").unwrap();
    assert!(frame.medium.lights.iter().any(|l| l.profile.as_ref().is_some_and(|p| p.cone.is_some())));
}
