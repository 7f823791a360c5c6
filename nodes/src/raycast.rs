//! Ray casting against scene triangles on `obvhs`'s 8-wide compressed-wide BVH (CWBVH, built
//! by PLOC in parallel), with robust self-intersection offsets. Used by every visibility
//! precompute.

mod bundle;

use crate::mesh::MeshSet;
use glam::{DVec3, Vec3A};
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(RayScene, "ray-tracing scene", |v| v.triangle_count() * 48 * 2 + v.bundles.byte_size());

/// obvhs's reinsertion batch ratio: the share of the BVH's nodes its first pass considers
/// moving (its later passes take shrinking shares of it).
const REINSERTION_BATCH_RATIO: f32 = 0.2;
/// Triangles per leaf of the bundle BVH, and the cost of a node visit against a triangle
/// test, for obvhs's SAH leaf collapse. A bundle's node visit costs more than its pack tests
/// (four triangles in one test), so leaves hold more than a single ray's would: on the engine
/// model, 16 and 6.0 trace 9% faster than 8 and 3.0 at 256 directions (4 and 3.0: 10%
/// slower).
const BUNDLE_LEAF_TRIANGLES: u32 = 16;
const BUNDLE_TRAVERSAL_COST: f32 = 6.0;

/// Triangles and their BVH. Not serialisable (obvhs has no serde): rebuilt on load.
pub struct RayScene {
    bvh: CwBvh,
    /// Triangles in BVH order (no index indirection while traversing), with precomputed
    /// edges and normal for intersection.
    triangles: Vec<RtTriangle>,
    /// Original triangle index of each BVH-ordered triangle.
    original: Vec<u32>,
    /// A binary BVH for bundles of rays from one origin.
    bundles: bundle::BundleTree,
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
            let bundles = bundle::BundleTree::default();
            return Self { bvh: CwBvh::default(), triangles: Vec::new(), original, bundles, epsilon, fingerprint };
        }
        // obvhs's medium build (PLOC, then reinsertion), with the slow build's reinsertion
        // ratio (a fifth, not a twentieth: 7% fewer box and triangle tests per bundle ray on the
        // engine model, BVH build 135-166 ms against about 150), kept as a binary BVH for
        // bundles and made 8-wide for single rays.
        let params = obvhs::BvhBuildParams::medium_build();
        let mut bvh2 = obvhs::ploc::PlocBuilder::with_capacity(triangles.len()).build(
            params.ploc_search_distance,
            &triangles,
            (0..triangles.len() as u32).collect(),
            params.sort_precision,
            params.search_depth_threshold,
        );
        obvhs::bvh2::reinsertion::ReinsertionOptimizer::default().run(&mut bvh2, REINSERTION_BATCH_RATIO, None);
        let bvh = obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(&bvh2, 3, true, false);
        obvhs::bvh2::leaf_collapser::collapse(&mut bvh2, BUNDLE_LEAF_TRIANGLES, BUNDLE_TRAVERSAL_COST);
        let bundles = bundle::BundleTree::from_bvh2(&bvh2, &triangles);
        let ordered: Vec<RtTriangle> =
            bvh.primitive_indices.iter().map(|&i| RtTriangle::from(&triangles[i as usize])).collect();
        let original = bvh.primitive_indices.iter().map(|&i| original[i as usize]).collect();
        Self { bvh, triangles: ordered, original, bundles, epsilon, fingerprint }
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

    /// Whether anything blocks `origin + t·direction` for `t` in `(0, tmax)`. A surface through
    /// the origin itself (`t = 0`) does not.
    pub fn occluded(&self, origin: Vec3A, direction: Vec3A, tmax: f32) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let ray = Ray::new(origin, direction, f32::MIN_POSITIVE, tmax);
        !self.bvh.ray_traverse_miss(ray, |ray, id| self.triangles[id].intersect(ray))
    }

    /// [`RayScene::occluded`] for many rays from one origin at once: sets `blocked[i]` for each
    /// listed ray `i` (an index into `directions`) that something blocks within `(0, tmax)`.
    /// Far faster than one ray at a time for a receiver's hemisphere of directions.
    pub fn occlude_bundle(&self, origin: Vec3A, directions: &[Vec3A], rays: &[u32], tmax: f32, blocked: &mut [bool]) {
        assert_eq!(directions.len(), blocked.len(), "one flag per direction");
        self.bundles.occlude(origin, directions, rays, tmax, blocked);
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

    /// Occlusion by brute force in f64: every triangle, Möller–Trumbore, hits in `(0, tmax)`.
    fn brute_force_occluded(meshes: &MeshSet, origin: DVec3, d: DVec3, tmax: f64) -> bool {
        meshes.meshes.iter().any(|m| {
            m.indices.chunks_exact(3).any(|t| {
                let v = |i: u32| DVec3::from(m.positions[i as usize].map(f64::from));
                let (v0, v1, v2) = (v(t[0]), v(t[1]), v(t[2]));
                let (e1, e2) = (v1 - v0, v2 - v0);
                let p = d.cross(e2);
                let det = e1.dot(p);
                if det == 0.0 {
                    return false;
                }
                let s = origin - v0;
                let u = s.dot(p) / det;
                let q = s.cross(e1);
                let v = d.dot(q) / det;
                let t = e2.dot(q) / det;
                u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && t < tmax
            })
        })
    }

    /// Objects of every size around random origins (some inside the sphere, some between
    /// the objects), with random reaches.
    fn cluttered_scene() -> MeshSet {
        let at = |x, y, z| glam::DMat4::from_translation(DVec3::new(x, y, z));
        MeshSet {
            meshes: vec![
                mesh::plane(8.0, 6),
                mesh::sphere(0.7, 24).transformed(at(0.5, 0.8, 0.0)),
                mesh::torus(1.2, 0.3, 20).transformed(at(-1.0, 0.4, 1.0)),
                mesh::sphere(0.05, 6).transformed(at(1.5, 0.2, -1.0)),
            ],
        }
    }

    /// The bundle tracer against f64 brute force and against obvhs's single rays, on random
    /// origins and directions: they differ only for rays that graze a triangle's edge.
    #[test]
    fn bundles_agree_with_brute_force_and_single_rays() {
        use rand::Rng;
        let meshes = cluttered_scene();
        let scene = RayScene::build(&meshes);
        let mut rng = test_rng(53);
        let (mut rays, mut against_brute, mut against_single, mut blocked_count) = (0, 0, 0, 0);
        for _ in 0..60 {
            let origin =
                DVec3::new(rng.random_range(-3.0..3.0), rng.random_range(0.01..2.0), rng.random_range(-3.0..3.0));
            let tmax = if rng.random_bool(0.5) { f32::INFINITY } else { rng.random_range(0.1..4.0) };
            let directions: Vec<DVec3> = (0..300).map(|_| random_unit_vector(&mut rng)).collect();
            let single: Vec<Vec3A> = directions.iter().map(|d| d.as_vec3().into()).collect();
            // Every other ray, so unlisted rays must stay untouched.
            let listed: Vec<u32> = (0..300).step_by(2).collect();
            let mut blocked = vec![false; 300];
            let o = origin.as_vec3().into();
            scene.occlude_bundle(o, &single, &listed, tmax, &mut blocked);
            for k in 0..300 {
                if k % 2 == 1 {
                    assert!(!blocked[k], "an unlisted ray was traced");
                    continue;
                }
                rays += 1;
                blocked_count += blocked[k] as usize;
                let exact = brute_force_occluded(&meshes, o.as_dvec3(), single[k].as_dvec3(), f64::from(tmax));
                against_brute += (exact != blocked[k]) as usize;
                against_single += (scene.occluded(o, single[k], tmax) != blocked[k]) as usize;
            }
        }
        assert!(blocked_count > rays / 5 && blocked_count < rays * 4 / 5, "{blocked_count} of {rays} blocked");
        assert!(against_brute <= rays / 5000, "{against_brute} of {rays} rays differ from brute force");
        assert!(against_single <= rays / 5000, "{against_single} of {rays} rays differ from single rays");
    }

    /// A ray traced alone (walked ray by ray from the root) gets the same flag as in its
    /// bundle (lists, then ray by ray where they thin out): the same tests, bit for bit.
    #[test]
    fn a_ray_alone_gets_its_flag_in_the_bundle() {
        use rand::Rng;
        let scene = RayScene::build(&cluttered_scene());
        let mut rng = test_rng(55);
        let mut blocked_total = 0;
        for case in 0..20 {
            let origin =
                Vec3A::new(rng.random_range(-3.0..3.0), rng.random_range(0.01..2.0), rng.random_range(-3.0..3.0));
            let directions: Vec<Vec3A> = (0..200).map(|_| random_unit_vector(&mut rng).as_vec3().into()).collect();
            let rays: Vec<u32> = (0..200).collect();
            let tmax = if case % 2 == 0 { f32::INFINITY } else { rng.random_range(0.2..4.0) };
            let mut bundled = vec![false; 200];
            scene.occlude_bundle(origin, &directions, &rays, tmax, &mut bundled);
            for k in rays {
                let mut alone = vec![false; 200];
                scene.occlude_bundle(origin, &directions, &[k], tmax, &mut alone);
                assert_eq!(alone[k as usize], bundled[k as usize], "case {case}, ray {k}");
            }
            blocked_total += bundled.iter().filter(|b| **b).count();
        }
        assert!(blocked_total > 500, "only {blocked_total} rays blocked: the cases test too little");
    }

    /// The walk with two rays per AVX instruction gives the same flags as the portable one
    /// (one ray per SSE instruction), on odd and even ray lists, with some rays already marked
    /// blocked (skipped), axis-aligned directions among random ones, and finite and infinite
    /// reaches.
    #[test]
    fn avx2_and_portable_bundles_agree() {
        use rand::Rng;
        #[cfg(target_arch = "x86_64")]
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 on this CPU: both sides would be the portable walk");
            return;
        }
        let scene = RayScene::build(&cluttered_scene());
        let mut rng = test_rng(54);
        let mut blocked_total = 0;
        for case in 0..60 {
            let origin =
                Vec3A::new(rng.random_range(-3.0..3.0), rng.random_range(0.01..2.0), rng.random_range(-3.0..3.0));
            let mut directions: Vec<Vec3A> = (0..250).map(|_| random_unit_vector(&mut rng).as_vec3().into()).collect();
            // Along the axes too: zero components take the slab test's 1e30 path.
            directions.extend([Vec3A::X, -Vec3A::X, Vec3A::Y, -Vec3A::Y, Vec3A::Z, -Vec3A::Z]);
            let rays: Vec<u32> = (0..256).filter(|_| rng.random_bool(0.7)).collect();
            let tmax = if case % 2 == 0 { f32::INFINITY } else { rng.random_range(0.2..4.0) };
            let preset: Vec<bool> = (0..256).map(|_| rng.random_bool(0.1)).collect();
            let mut portable = preset.clone();
            scene.bundles.occlude_portable(origin, &directions, &rays, tmax, &mut portable);
            let mut dispatched = preset.clone();
            scene.occlude_bundle(origin, &directions, &rays, tmax, &mut dispatched);
            assert_eq!(portable, dispatched, "case {case}, {} rays", rays.len());
            blocked_total += dispatched.iter().zip(&preset).filter(|(d, p)| **d && !**p).count();
        }
        assert!(blocked_total > 1000, "only {blocked_total} rays newly blocked: the cases test too little");
    }

    /// A ray from a point exactly on a surface is not blocked by that surface (a hit at
    /// `t = 0`), whichever way it leaves, for single rays and bundles alike; the next surface
    /// still blocks it.
    #[test]
    fn a_surface_through_the_origin_does_not_block() {
        let floor = mesh::plane(4.0, 4);
        let roof = floor.clone().transformed(glam::DMat4::from_translation(DVec3::new(0.0, 1.0, 0.0)));
        let scene = RayScene::build(&MeshSet { meshes: vec![floor, roof] });
        // On the floor inside a triangle, on an edge and on a vertex of its grid.
        for origin in [Vec3A::new(0.3, 0.0, 0.45), Vec3A::new(0.5, 0.0, 0.2), Vec3A::new(1.0, 0.0, 1.0)] {
            let down = Vec3A::new(0.1, -1.0, 0.2).normalize();
            let up = Vec3A::new(0.1, 1.0, 0.2).normalize();
            assert!(!scene.occluded(origin, down, f32::INFINITY), "down from {origin}");
            assert!(scene.occluded(origin, up, f32::INFINITY), "the roof, from {origin}");
            assert!(!scene.occluded(origin, up, 0.9), "short of the roof, from {origin}");
            let mut blocked = [false; 2];
            scene.occlude_bundle(origin, &[down, up], &[0, 1], f32::INFINITY, &mut blocked);
            assert_eq!(blocked, [false, true], "bundle from {origin}");
            let mut blocked = [false; 2];
            scene.occlude_bundle(origin, &[down, up], &[0, 1], 0.9, &mut blocked);
            assert_eq!(blocked, [false, false], "bundle short of the roof, from {origin}");
        }
    }

    /// Rays through the shared edges of a closed mesh from inside never slip through (the
    /// edge planes are shared exactly). A box: its faces' vertices coincide exactly, where a UV
    /// sphere's seam does not. (A ray exactly through a vertex may, as in Embree.)
    #[test]
    fn bundles_are_watertight_on_shared_edges() {
        let cube = mesh::cuboid([2.0, 2.0, 2.0], 4, false);
        let scene = RayScene::build(&MeshSet { meshes: vec![cube.clone()] });
        let centre = Vec3A::new(0.01, -0.02, 0.015);
        let mut directions = Vec::new();
        for t in cube.indices.chunks_exact(3) {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                let (a, b) =
                    (Vec3A::from_array(cube.positions[a as usize]), Vec3A::from_array(cube.positions[b as usize]));
                for s in [0.1, 0.37, 0.5, 0.81] {
                    directions.push((a.lerp(b, s) - centre).normalize());
                }
            }
        }
        let rays: Vec<u32> = (0..directions.len() as u32).collect();
        let mut blocked = vec![false; directions.len()];
        scene.occlude_bundle(centre, &directions, &rays, f32::INFINITY, &mut blocked);
        assert!(
            blocked.iter().all(|&b| b),
            "{} of {} rays through edges escaped",
            blocked.iter().filter(|b| !**b).count(),
            blocked.len()
        );
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
