use super::*;
use crate::brdf::{Brdf, Material, Model};
use crate::quadrature::SphereQuadrature;

/// GGX of α, Blinn-Phong of exponent 2/α² − 2 or Phong of its quarter (Fresnel 1), as the reference renderer
/// evaluates them.
fn lobe_of(shape: LobeShape, alpha: f64) -> Brdf {
    let (model, exponent) = match shape {
        LobeShape::Ggx => (Model::Ggx, 0.0),
        LobeShape::BlinnPhong => (Model::BlinnPhong, 2.0 / (alpha * alpha) - 2.0),
        LobeShape::Phong => (Model::Phong, (2.0 / (alpha * alpha) - 2.0) / 4.0),
    };
    Brdf::from_material(&Material {
        model,
        albedo: [0.0; 3],
        roughness: alpha.sqrt(),
        exponent,
        f0: 1.0,
        ..Material::default()
    })
}

#[test]
fn albedo_and_mean_direction_match_brute_force_quadrature() {
    let quadrature = SphereQuadrature::new(900, 1800);
    let cases = [(0.05f64, 0.09), (0.3, 0.09), (1.0, 0.2), (0.1, 0.5), (0.02, 0.2)];
    for (shape, (mu, alpha)) in LobeShape::ALL.into_iter().flat_map(|s| cases.map(|c| (s, c))) {
        let brdf = lobe_of(shape, alpha);
        let wo = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let albedo = quadrature.integrate(|wi| brdf.lobe_value(wi, wo) * wi.z.max(0.0));
        let along = |axis: DVec3| quadrature.integrate(|wi| brdf.lobe_value(wi, wo) * wi.z.max(0.0) * wi.dot(axis));
        let mean = DVec3::new(along(DVec3::X), along(DVec3::Y), along(DVec3::Z)).normalize();
        let lobe = reflected_lobe(shape, mu, alpha);
        assert!(
            (lobe.albedo / albedo - 1.0).abs() < 5e-3,
            "{shape:?} μ {mu} α {alpha}: E {} against {albedo}",
            lobe.albedo
        );
        let angle = lobe.mean.dot(mean).clamp(-1.0, 1.0).acos().to_degrees();
        assert!(angle < 0.3, "{shape:?} μ {mu} α {alpha}: mean {:?} against {mean:?} ({angle}°)", lobe.mean);
    }
}

#[test]
fn grazing_views_turn_the_mean_far_towards_the_normal() {
    // At α 0.09 seen 3° above the horizon the rays' mean lies near 20° up, not at the mirror's 3°.
    let lobe = reflected_lobe(LobeShape::Ggx, 0.05, 0.09);
    let elevation = lobe.mean.z.asin().to_degrees();
    assert!((15.0..25.0).contains(&elevation), "{elevation}");
    assert!(lobe.albedo > 0.85 && lobe.albedo < 0.95, "{}", lobe.albedo);
    // Near the normal the mean stays near the mirror direction.
    assert!(reflected_lobe(LobeShape::Ggx, 0.9, 0.09).toward_normal < 0.05);
    // Blinn-Phong's lobe has no long tail: at the same grazing view its mean turns far less.
    let short = reflected_lobe(LobeShape::BlinnPhong, 0.05, 0.09);
    assert!(short.mean.z.asin().to_degrees() < 0.75 * elevation, "{:?}", short.mean);
    // And GGX's grazing rays spread wider than its head-on ones (by the tail the visible
    // normals lean into); the horizon's cut keeps Blinn-Phong's no wider.
    let t = table();
    let at = |shape: usize, i: usize| t.entries[(shape * ALPHA_STEPS + 2) * MU_STEPS + i][2];
    assert!(at(0, 2) > 1.5, "{}", at(0, 2));
    assert!(at(1, 2) < 1.1, "{}", at(1, 2));
}

#[test]
fn the_table_holds_a_mirror_and_normal_incidence_exactly() {
    let t = table();
    assert_eq!(t.entries.len(), LobeShape::ALL.len() * MU_STEPS * ALPHA_STEPS);
    for shape in 0..LobeShape::ALL.len() {
        let first = shape * ALPHA_STEPS * MU_STEPS;
        for i in 0..MU_STEPS {
            assert_eq!(t.entries[first + i], [1.0, 0.0, 1.0], "α 0 is a mirror");
        }
        for j in 0..ALPHA_STEPS {
            let head_on = t.entries[first + j * MU_STEPS + MU_STEPS - 1];
            assert_eq!(head_on[1], 0.0, "μ 1: the mean is the normal");
            assert!((head_on[2] - 1.0).abs() < 1e-6, "μ 1 is the broadening's unit");
        }
    }
}
