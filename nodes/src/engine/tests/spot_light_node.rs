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
    // Type C: C = 0° along the luminaire's length, C = 90° a quarter turn counter-clockwise
    // seen from above (looking along the nadir): `C0 × nadir`.
    let c0 = profile.frame.x_axis;
    let c90 = c0.cross(aim);
    let (mut worst, mut n) = (0.0f64, 0);
    for gamma in (0..=85).step_by(5).map(|g| f64::from(g) + 1.3) {
        for c in (0..360).step_by(15).map(|c| f64::from(c) + 2.7) {
            let (g, c_rad) = (gamma.to_radians(), c.to_radians());
            let dir = aim * g.cos() + (c0 * c_rad.cos() + c90 * c_rad.sin()) * g.sin();
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
    assert!((c0.dot(unspun) - 30f64.to_radians().cos()).abs() < 1e-9);
}

/// A hand-made file with a different intensity in each quarter, on a light pointing straight
/// down: seen from above, C = 0° lies along +Z (the unspun reference) and the angles turn
/// counter-clockwise, so C = 90° shines towards +X, 180° towards −Z and 270° towards −X.
#[test]
fn horizontal_angles_turn_as_the_standard_says() {
    let dir = std::env::temp_dir().join(format!("lightloom-quarters-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("quarters.ies");
    let rows = "10 10\n20 20\n30 30\n40 40\n10 10\n";
    std::fs::write(
        &file,
        format!("IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 2 5 1 2 0 0 0\n1 1 1\n0 90\n0 90 180 270 360\n{rows}"),
    )
    .unwrap();
    let mut graph = default_graph_with("spot", "SpotLight", &[]);
    graph.set_param("spot", "cone", ParamValue::Float(180.0)).unwrap();
    graph.set_param("spot", "intensity", ParamValue::Color([40.0; 3])).unwrap();
    graph.set_param("spot", "profile", ParamValue::Path(file.display().to_string())).unwrap();
    let eval = Engine::in_memory().evaluate(&graph, &CancelToken::default(), None);
    assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
    let light = value_of::<Vec<PointLight>>(&eval, "spot", "lights").pop().unwrap();
    // 45° below the horizon, towards each side.
    for (side, candela) in [(DVec3::Z, 10.0), (DVec3::X, 20.0), (DVec3::NEG_Z, 30.0), (DVec3::NEG_X, 40.0)] {
        let got = light.intensity_toward((side + DVec3::NEG_Y).normalize())[0];
        assert!((got - candela).abs() < 0.5, "towards {side}: {got} W/sr, the file says {candela}");
    }
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
    // The beam a glTF spot keeps: full to 20°, out by where it falls under 1% (a little inside
    // 40°, to the table's rows 1.4° apart).
    assert!((inner.to_degrees() - 20.0).abs() < 1e-9 && (outer.to_degrees() - 39.0).abs() < 1.5, "{inner} {outer}");
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
