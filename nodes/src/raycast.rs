//! Ray casting against scene triangles on `obvhs`'s 8-wide compressed-wide BVH (CWBVH, built
//! by PLOC in parallel), with robust self-intersection offsets. Used by every visibility
//! precompute.

use crate::mesh::MeshSet;
use glam::{DVec3, Vec3A};
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(RayScene, "ray-tracing scene", |v| v.triangle_count() * 48 * 2);

/// Triangles and their BVH. Not serialisable (obvhs has no serde): rebuilt on load.
pub struct RayScene {
    bvh: CwBvh,
    /// Triangles in BVH order (no index indirection while traversing), with precomputed
    /// edges and normal for intersection.
    triangles: Vec<RtTriangle>,
    /// Original triangle index of each BVH-ordered triangle.
    original: Vec<u32>,
    /// Offset used to leave a surface: scales with the scene's size.
    epsilon: f32,
    /// Hash of the triangles (what memoised ray results depend on).
    fingerprint: u128,
}

/// Identity: two scenes are equal only if they are the same object.
impl PartialEq for RayScene {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self, other)
    }
}

impl std::fmt::Debug for RayScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RayScene({} triangles)", self.triangles.len())
    }
}

impl RayScene {
    /// Builds from every triangle of a mesh set (degenerate triangles, and those with a
    /// coordinate that is not finite or beyond [`crate::limits::MAX_COORDINATE`], are skipped:
    /// they occlude nothing, and garbage extents break the BVH builder).
    pub fn build(meshes: &MeshSet) -> Self {
        let mut triangles = Vec::new();
        let mut original = Vec::new();
        let mut index = 0u32;
        for mesh in &meshes.meshes {
            for t in mesh.indices.chunks_exact(3) {
                let v = |i: u32| Vec3A::from_array(mesh.positions[i as usize]);
                let tri = Triangle { v0: v(t[0]), v1: v(t[1]), v2: v(t[2]) };
                let sane = |v: Vec3A| v.is_finite() && v.abs().max_element() <= crate::limits::MAX_COORDINATE;
                let finite = sane(tri.v0) && sane(tri.v1) && sane(tri.v2);
                if finite && (tri.v1 - tri.v0).cross(tri.v2 - tri.v0).length_squared() > 0.0 {
                    triangles.push(tri);
                    original.push(index);
                }
                index += 1;
            }
        }
        Self::from_triangles(triangles, original)
    }

    fn from_triangles(triangles: Vec<Triangle>, original: Vec<u32>) -> Self {
        let (lo, hi) = triangles.iter().fold((Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN)), |(lo, hi), t| {
            (lo.min(t.v0).min(t.v1).min(t.v2), hi.max(t.v0).max(t.v1).max(t.v2))
        });
        let extent =
            if triangles.is_empty() { 1.0 } else { (hi - lo).max_element().max(lo.abs().max(hi.abs()).max_element()) };
        let epsilon = (extent * 2e-5).max(1e-6);
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        for t in &triangles {
            for v in [t.v0, t.v1, t.v2] {
                hasher.update(bytemuck::cast_slice(&v.to_array()));
            }
        }
        let fingerprint = hasher.digest128();
        if triangles.is_empty() {
            return Self { bvh: CwBvh::default(), triangles: Vec::new(), original, epsilon, fingerprint };
        }
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &triangles,
            obvhs::BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        let ordered: Vec<RtTriangle> =
            bvh.primitive_indices.iter().map(|&i| RtTriangle::from(&triangles[i as usize])).collect();
        let original = bvh.primitive_indices.iter().map(|&i| original[i as usize]).collect();
        Self { bvh, triangles: ordered, original, epsilon, fingerprint }
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// A hash of the triangles, equal for scenes built from the same geometry.
    pub fn fingerprint(&self) -> u128 {
        self.fingerprint
    }

    /// Scene-relative offset used by [`RayScene::leave_surface`].
    pub fn epsilon(&self) -> f32 {
        self.epsilon
    }

    /// A ray origin just off the surface at `p`, on the front side of its normal `n`, so a ray
    /// into the upper hemisphere cannot hit the triangle it starts on, while a ray below the
    /// surface hits the surface itself (a receiver never sees through its own surface). The
    /// offset grows with the scene's size and with `|p|` (float spacing).
    pub fn leave_surface(&self, p: DVec3, n: DVec3) -> Vec3A {
        let scale = self.epsilon as f64 + p.abs().max_element() * 4.0 * f32::EPSILON as f64;
        (p + n * scale).as_vec3().into()
    }

    /// Whether anything blocks `origin + t·direction` for `t` in `(0, tmax)`.
    pub fn occluded(&self, origin: Vec3A, direction: Vec3A, tmax: f32) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let ray = Ray::new(origin, direction, 0.0, tmax);
        !self.bvh.ray_traverse_miss(ray, |ray, id| self.triangles[id].intersect(ray))
    }

    /// Closest hit: distance and original triangle index.
    pub fn closest(&self, origin: Vec3A, direction: Vec3A) -> Option<(f32, u32)> {
        if self.triangles.is_empty() {
            return None;
        }
        let mut hit = RayHit::none();
        self.bvh
            .ray_traverse(Ray::new_inf(origin, direction), &mut hit, |ray, id| self.triangles[id].intersect(ray))
            .then(|| (hit.t, self.original[hit.primitive_id as usize]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{self, MeshSet};
    use crate::sampling::{random_unit_vector, test_rng};

    /// Garbage geometry (a corrupted buffer offset reads floats up to 3e38) once recursed
    /// until the stack overflowed while the BVH was built: such triangles are dropped.
    #[test]
    fn absurd_coordinates_build_a_bvh_without_them() {
        use rand::Rng;
        let mut rng = test_rng(3);
        let mut positions = Vec::new();
        for i in 0..30_000 {
            let scale = if i % 3 == 0 { 1.0 } else { 10f32.powi(rng.random_range(-30..=38)) };
            positions.push([0, 1, 2].map(|_| rng.random_range(-3.0..3.0f32) * scale));
        }
        positions.extend([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let indices = (0..positions.len() as u32).collect();
        let mesh = mesh::Mesh { positions, indices, ..Default::default() };
        let scene = RayScene::build(&MeshSet { meshes: vec![mesh] });
        assert!(scene.triangles.len() < 10_001, "{} triangles kept", scene.triangles.len());
        let hit = scene.closest(Vec3A::new(0.2, 0.2, 1.0), Vec3A::new(0.0, 0.0, -1.0));
        assert!(hit.is_some(), "the sane triangle is still hit");
    }

    #[test]
    fn occlusion_matches_analytic_sphere_hits() {
        let scene = RayScene::build(&MeshSet {
            meshes: vec![mesh::sphere(1.0, 64).transformed(glam::DMat4::from_translation(DVec3::new(0.0, 0.0, -5.0)))],
        });
        let mut rng = test_rng(51);
        let mut disagreements = 0;
        for _ in 0..4000 {
            let d = random_unit_vector(&mut rng);
            // Analytic: the ray from the origin hits a sphere of radius 1 at (0,0,-5) iff the
            // angle to its centre is below asin(1/5) (the tessellation differs by < 0.1%).
            let analytic = d.dot(DVec3::new(0.0, 0.0, -1.0)) > (1.0 - 0.04f64).sqrt();
            let traced = scene.occluded(Vec3A::ZERO, d.as_vec3().into(), f32::INFINITY);
            if analytic != traced {
                disagreements += 1;
            }
        }
        assert!(disagreements <= 8, "{disagreements} of 4000 rays disagree with the analytic sphere");
        let (t, _) = scene.closest(Vec3A::ZERO, Vec3A::new(0.0, 0.0, -1.0)).unwrap();
        assert!((t - 4.0).abs() < 1e-3, "{t}");
        assert!(!scene.occluded(Vec3A::ZERO, Vec3A::new(0.0, 0.0, -1.0), 3.9));
    }

    #[test]
    fn rays_leaving_a_surface_do_not_hit_it() {
        // Points on a finely tessellated sphere cast outwards over the upper hemisphere: a
        // convex object never occludes itself.
        let sphere = mesh::sphere(1.0, 48);
        let scene = RayScene::build(&MeshSet { meshes: vec![sphere.clone()] });
        let mut rng = test_rng(52);
        let mut self_hits = 0;
        for i in (0..sphere.positions.len()).step_by(7) {
            let p = DVec3::from(sphere.positions[i].map(f64::from));
            let n = DVec3::from(sphere.normals[i].map(f64::from));
            for _ in 0..20 {
                let mut d = random_unit_vector(&mut rng);
                if d.dot(n) < 0.05 {
                    d = -d;
                }
                if d.dot(n) < 0.05 {
                    continue;
                }
                if scene.occluded(scene.leave_surface(p, n), d.as_vec3().into(), f32::INFINITY) {
                    self_hits += 1;
                }
            }
        }
        assert_eq!(self_hits, 0);
    }
}
