use super::*;
use crate::mesh::Mesh;
use glam::DMat4;

fn cancel() -> CancelToken {
    CancelToken::default()
}

/// One closed sphere mesh is covered by one sphere of its radius (to a voxel), centred on it;
/// what it leaves uncovered is the shell the grid loses (at most two voxels thick).
#[test]
fn a_sphere_is_fitted_by_one_sphere() {
    let mesh = crate::mesh::sphere(1.0, 48).transformed(DMat4::from_translation(DVec3::new(0.5, 2.0, -1.0)));
    let fit = fit_spheres(&MeshSet { meshes: vec![mesh] }, 1, 64, &cancel()).unwrap();
    let (c, r) = fit.spheres[0];
    assert!((DVec3::from(c) - DVec3::new(0.5, 2.0, -1.0)).length() < 1.5 * fit.voxel, "{c:?}");
    assert!((r - 1.0).abs() < 1.5 * fit.voxel, "{r}");
    assert!(fit.uncovered < 1.0 - (1.0 - 2.0 * fit.voxel).powi(3), "{fit:?}");
}

/// On a torus (no single sphere fits), more spheres cover more: the uncovered fraction falls
/// with the count, and the spheres stay inside the solid, checked independently by the torus's
/// implicit equation at points sampled in each sphere.
#[test]
fn more_spheres_cover_more_of_a_torus_and_stay_inside() {
    let (major, minor) = (1.0, 0.35);
    let torus = MeshSet { meshes: vec![crate::mesh::torus(major, minor, 64)] };
    let mut last = 1.0;
    for count in [8, 30, 120] {
        let fit = fit_spheres(&torus, count, 96, &cancel()).unwrap();
        assert_eq!(fit.spheres.len(), count);
        assert!(fit.uncovered < last, "{count}: {} after {last}", fit.uncovered);
        last = fit.uncovered;
        let torus_distance = |p: DVec3| (glam::DVec2::new(p.x, p.z).length() - major).hypot(p.y) - minor;
        for (c, r) in &fit.spheres {
            for d in [DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z, DVec3::ONE.normalize()] {
                let p = DVec3::from(*c) + d * *r;
                assert!(torus_distance(p) < 0.6 * fit.voxel, "{count}: a sphere reaches {p} outside the torus");
            }
        }
        assert!(fit.outside < 0.01, "{fit:?}");
    }
    assert!(last < 0.2, "120 spheres leave {last} of the torus uncovered");
}

/// A cube's volume fraction covered by a single inscribed ball is π/6 (closed form).
#[test]
fn one_sphere_in_a_cube_covers_pi_over_six() {
    let cube = MeshSet { meshes: vec![crate::mesh::cuboid([2.0; 3], 4, false)] };
    let fit = fit_spheres(&cube, 1, 80, &cancel()).unwrap();
    let covered = 1.0 - fit.uncovered;
    assert!((covered - std::f64::consts::PI / 6.0).abs() < 0.04, "{covered}");
}

#[test]
fn open_or_flat_meshes_are_refused_with_a_reason() {
    let plane = MeshSet { meshes: vec![crate::mesh::plane(2.0, 4)] };
    let e = fit_spheres(&plane, 10, 32, &cancel()).unwrap_err().to_string();
    assert!(e.contains("flat") || e.contains("inside"), "{e}");
    let e = fit_spheres(&MeshSet { meshes: vec![Mesh::default()] }, 10, 32, &cancel()).unwrap_err().to_string();
    assert!(e.contains("no triangles"), "{e}");
}
