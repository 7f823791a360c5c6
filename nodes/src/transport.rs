//! Visibility precompute at receiver points (PRT, Sun 2008 eqs. 2.26–2.28): binary visibility
//! `V(x, ω)` and shadowed cosine transfer `T(x, ω) = V(x, ω) max(n·ω, 0)` projected to
//! - SH (global frame),
//! - cube-map Haar (global frame, Ng et al. 2003/2004),
//! - icosahedral spherical Haar in the receiver's local frame (Ma et al. §3.1, eq. 7).
//!
//! Directions below a receiver's tangent plane (`n·ω ≤ 0`) are occluded by the receiver's own
//! surface by definition (the usual PRT convention: it holds for closed objects and planes
//! alike, halves the rays, and avoids rays grazing the receiver's own vertex, where
//! Möller–Trumbore is not watertight). The others leave the surface with
//! [`RayScene::leave_surface`].

use crate::cubemap::{self, FACES};
use crate::engine::{CancelToken, StageError};
use crate::mesh::MeshSet;
use crate::raycast::RayScene;
use crate::sh::{self, ShBasis};
use crate::wavelet::SparseVector;
use crate::wavelet::cube_haar::CubeHaar;
use crate::wavelet::spherical::SphericalHaar;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(Receivers, "receivers", |v| v.len() * 36);
crate::stage_type!(
    ShTransport,
    "SH transport",
    encoding = 1,
    |v| (v.visibility.len() + v.transfer.len()) * 4,
    numbers = |v| v.visibility.iter().chain(&v.transfer).map(|x| f64::from(*x))
);
crate::stage_type!(HaarTransport, "Haar transport", encoding = 1, |v| v
    .visibility
    .iter()
    .chain(&v.transfer)
    .map(|c| c.len() * 16 + 24)
    .sum());
crate::stage_type!(SphericalTransport, "local-frame transport", encoding = 1, |v| v
    .visibility
    .iter()
    .map(|c| c.len() * 16 + 24)
    .sum());
crate::stage_type!(TexelReceivers, "texel receivers", |v| v.receivers.len() * 44);
crate::stage_type!(Vec<ObjectTransport>, "per-object transport", encoding = 1, |v| v.len() * 160);

/// Receiver points: every mesh vertex, in mesh order, with a local frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Receivers {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// Unit tangents orthogonal to the normal (from UVs where present).
    pub tangents: Vec<[f32; 3]>,
    /// First receiver of each mesh.
    pub mesh_offsets: Vec<usize>,
}

impl Receivers {
    /// About `count` receivers, every n-th of the list, as one mesh (benchmarks' samples).
    pub fn every_nth(&self, count: usize) -> Receivers {
        let step = (self.len() / count.max(1)).max(1);
        let pick = |v: &Vec<[f32; 3]>| v.iter().step_by(step).copied().collect::<Vec<_>>();
        Receivers {
            positions: pick(&self.positions),
            normals: pick(&self.normals),
            tangents: pick(&self.tangents),
            mesh_offsets: vec![0],
        }
    }

    pub fn from_meshes(meshes: &MeshSet) -> Self {
        let mut r = Receivers::default();
        for mesh in &meshes.meshes {
            r.mesh_offsets.push(r.positions.len());
            let tangents = crate::mesh::vertex_tangents(mesh);
            r.positions.extend_from_slice(&mesh.positions);
            r.normals.extend_from_slice(&mesh.normals);
            r.tangents.extend(tangents);
        }
        r
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Adds a receiver inside triangle `corners` of `mesh` at barycentric weights `b`, with
    /// the interpolated position, normal and tangent (`tangents` per vertex).
    pub fn push_interpolated(
        &mut self,
        mesh: &crate::mesh::Mesh,
        tangents: &[[f32; 3]],
        corners: [usize; 3],
        b: [f64; 3],
    ) {
        let lerp = |v: &[[f32; 3]]| (0..3).map(|k| DVec3::from(v[corners[k]].map(f64::from)) * b[k]).sum::<DVec3>();
        self.positions.push(lerp(&mesh.positions).as_vec3().to_array());
        self.normals.push(lerp(&mesh.normals).normalize_or(DVec3::Y).as_vec3().to_array());
        self.tangents.push(lerp(tangents).normalize_or(DVec3::X).as_vec3().to_array());
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    pub fn point(&self, i: usize) -> (DVec3, DVec3) {
        (
            DVec3::from(self.positions[i].map(f64::from)),
            DVec3::from(self.normals[i].map(f64::from)).normalize_or(DVec3::Y),
        )
    }

    /// Local frame `[t, b, n]` (columns) of receiver `i`.
    pub fn frame(&self, i: usize) -> DMat3 {
        let n = DVec3::from(self.normals[i].map(f64::from)).normalize_or(DVec3::Y);
        let t = DVec3::from(self.tangents[i].map(f64::from));
        let t = (t - n * n.dot(t)).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
        DMat3::from_cols(t, n.cross(t), n)
    }
}

/// Calls `visit(x, y, barycentric weights)` for every texel centre of a `width × height` grid
/// that the triangle `uv` (in texels) covers, edges included; a degenerate triangle covers none.
pub fn for_each_covered_texel(
    uv: [[f64; 2]; 3],
    (width, height): (usize, usize),
    mut visit: impl FnMut(usize, usize, [f64; 3]),
) {
    let det = (uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1]) - (uv[2][0] - uv[0][0]) * (uv[1][1] - uv[0][1]);
    if det.abs() < 1e-12 {
        return;
    }
    let lo =
        |c: usize, n: usize| uv.iter().map(|p| p[c]).fold(f64::MAX, f64::min).floor().clamp(0.0, n as f64) as usize;
    let hi = |c: usize, n: usize| uv.iter().map(|p| p[c]).fold(f64::MIN, f64::max).ceil().clamp(0.0, n as f64) as usize;
    for y in lo(1, height)..hi(1, height) {
        for x in lo(0, width)..hi(0, width) {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let b1 = ((px - uv[0][0]) * (uv[2][1] - uv[0][1]) - (uv[2][0] - uv[0][0]) * (py - uv[0][1])) / det;
            let b2 = ((uv[1][0] - uv[0][0]) * (py - uv[0][1]) - (px - uv[0][0]) * (uv[1][1] - uv[0][1])) / det;
            let b0 = 1.0 - b1 - b2;
            if b0 >= -1e-9 && b1 >= -1e-9 && b2 >= -1e-9 {
                visit(x, y, [b0, b1, b2]);
            }
        }
    }
}

/// Receivers at the texel centres of per-mesh visibility textures over the meshes' UVs
/// (Ma et al. §3.4): a coarse mesh gets per-texel shadows without tessellation.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TexelReceivers {
    pub size: usize,
    pub receivers: Receivers,
    /// Per receiver: `(mesh index, x, y)` of its texel (row 0 at v = 0).
    pub texels: Vec<(u32, u16, u16)>,
}

impl TexelReceivers {
    /// Rasterises the UV triangles of every mesh with `visibility_texture` set; each covered
    /// texel centre becomes a receiver with the interpolated position, normal and tangent.
    /// Where UVs overlap, the first triangle wins.
    pub fn rasterize(meshes: &MeshSet, size: usize) -> Self {
        let mut out = TexelReceivers { size, ..Default::default() };
        for (m, mesh) in meshes.meshes.iter().enumerate() {
            if !mesh.visibility_texture || mesh.uvs.len() != mesh.positions.len() {
                continue;
            }
            out.receivers.mesh_offsets.push(out.receivers.len());
            let tangents = crate::mesh::vertex_tangents(mesh);
            let mut covered = vec![false; size * size];
            for t in mesh.indices.chunks_exact(3) {
                let corners = [t[0], t[1], t[2]].map(|i| i as usize);
                let uv = corners.map(|i| mesh.uvs[i].map(|c| c as f64 * size as f64));
                for_each_covered_texel(uv, (size, size), |x, y, b| {
                    if !std::mem::replace(&mut covered[y * size + x], true) {
                        out.receivers.push_interpolated(mesh, &tangents, corners, b);
                        out.texels.push((m as u32, x as u16, y as u16));
                    }
                });
            }
        }
        out
    }
}

/// `n` directions on the sphere by the spherical Fibonacci lattice (equal-area, low
/// discrepancy); each stands for `4π/n` steradians.
pub fn fibonacci_directions(n: usize) -> Vec<DVec3> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// SH visibility and shadowed cosine transfer per receiver.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ShTransport {
    pub bands: usize,
    pub rays: usize,
    /// `receivers × bands²`: `V_lm = ∫ V Y_lm dω`.
    pub visibility: Vec<f32>,
    /// `receivers × bands²`: `T_lm = ∫ V max(n·ω, 0) Y_lm dω`; diffuse exit radiance is
    /// `(albedo/π) Σ T_lm L_lm`.
    pub transfer: Vec<f32>,
}

impl ShTransport {
    pub fn receiver(&self, i: usize) -> (&[f32], &[f32]) {
        let n = self.bands * self.bands;
        (&self.visibility[i * n..(i + 1) * n], &self.transfer[i * n..(i + 1) * n])
    }
}

/// Self-shadowing SH transport of one rigid object, in the object's own space (Sloan et al.'s
/// per-object PRT). Moving or rotating the object leaves it valid: a renderer rotates the
/// lighting into object space (`ShRotation` with `world_from_object`'s rotation). The
/// approximation: shadows *between* objects are not in it (the scene-wide `transport_sh`
/// stage has them, and blocker spheres can add dynamic occluders).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectTransport {
    pub name: String,
    /// Column-major object-to-world matrix.
    pub world_from_object: [f64; 16],
    /// Receivers in object space, in the order of the object's world-space mesh vertices.
    pub sh: std::sync::Arc<ShTransport>,
}

/// Cube-map Haar visibility and transfer per receiver (largest area-weighted coefficients).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct HaarTransport {
    pub size: usize,
    pub keep: usize,
    /// Coefficients of `V` sampled at texel centres.
    pub visibility: Vec<SparseVector>,
    /// Coefficients of `V·max(n·ω, 0)·ΔΩ_texel`, so that `Σ_texels L T = Σ_i L_i T_i`.
    pub transfer: Vec<SparseVector>,
}

/// Visibility in each receiver's local frame on the icosahedral Haar basis.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SphericalTransport {
    pub depth: usize,
    pub keep: usize,
    pub visibility: Vec<SparseVector>,
}

/// Casts one ray per direction from receiver `i`; returns visibility (true = unoccluded).
fn visibility_along(scene: &RayScene, p: DVec3, n: DVec3, directions: &[DVec3]) -> Vec<bool> {
    let origin = scene.leave_surface(p, n);
    let rays: Vec<u32> = (0..directions.len() as u32).filter(|&k| directions[k as usize].dot(n) > 0.0).collect();
    let single: Vec<glam::Vec3A> = directions.iter().map(|d| d.as_vec3().into()).collect();
    let mut blocked = vec![false; directions.len()];
    scene.occlude_bundle(origin, &single, &rays, f32::INFINITY, &mut blocked);
    directions.iter().zip(blocked).map(|(d, blocked)| d.dot(n) > 0.0 && !blocked).collect()
}

/// Runs `f` over receivers in parallel chunks, checking for cancellation between chunks.
fn per_receiver<T: Send>(
    count: usize,
    cancel: &CancelToken,
    progress: &(dyn Fn(f64) + Sync),
    f: impl Fn(usize) -> T + Sync,
) -> Result<Vec<T>, StageError> {
    let chunk = 64;
    let done = std::sync::atomic::AtomicUsize::new(0);
    let chunks: Vec<Result<Vec<T>, StageError>> = (0..count.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            cancel.check()?;
            let out = (c * chunk..((c + 1) * chunk).min(count)).map(&f).collect();
            let finished = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(finished as f64 * chunk as f64 / count.max(1) as f64);
            Ok(out)
        })
        .collect();
    let mut all = Vec::with_capacity(count);
    for c in chunks {
        all.extend(c?);
    }
    Ok(all)
}

/// SH transport with `rays` Fibonacci directions per receiver (the same set for all, so the
/// basis is evaluated once per direction).
pub fn sh_transport(
    scene: &RayScene,
    receivers: &Receivers,
    bands: usize,
    rays: usize,
    cancel: &CancelToken,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<ShTransport, StageError> {
    let directions = fibonacci_directions(rays);
    let basis = ShBasis::new(bands);
    let nc = sh::coeff_count(bands);
    let table: Vec<f64> = directions.iter().flat_map(|d| basis.eval_vec(*d)).collect();
    let weight = 4.0 * PI / rays as f64;
    let per = per_receiver(receivers.len(), cancel, progress, |i| {
        let (p, n) = receivers.point(i);
        let visible = visibility_along(scene, p, n, &directions);
        let mut v = vec![0.0f64; nc];
        let mut t = vec![0.0f64; nc];
        for (k, d) in directions.iter().enumerate() {
            if !visible[k] {
                continue;
            }
            let cos = d.dot(n).max(0.0);
            let y = &table[k * nc..(k + 1) * nc];
            for j in 0..nc {
                v[j] += y[j];
                t[j] += y[j] * cos;
            }
        }
        (
            v.iter().map(|x| (x * weight) as f32).collect::<Vec<_>>(),
            t.iter().map(|x| (x * weight) as f32).collect::<Vec<_>>(),
        )
    })?;
    let mut out = ShTransport {
        bands,
        rays,
        visibility: Vec::with_capacity(per.len() * nc),
        transfer: Vec::with_capacity(per.len() * nc),
    };
    for (v, t) in per {
        out.visibility.extend(v);
        out.transfer.extend(t);
    }
    Ok(out)
}

/// Directions through the texel centres of a `size²` cube map, in texel order.
fn cube_texel_directions(size: usize) -> Vec<DVec3> {
    (0..FACES * size * size)
        .map(|i| {
            let (face, x, y) = (i / (size * size), i % size, (i / size) % size);
            cubemap::face_uv_to_dir(face, (x as f64 + 0.5) / size as f64, (y as f64 + 0.5) / size as f64)
        })
        .collect()
}

fn as_unit(visible: Vec<bool>) -> Vec<f64> {
    visible.into_iter().map(|v| if v { 1.0 } else { 0.0 }).collect()
}

/// Visibility at the texel centres of a `size²` cube map (one ray per texel).
pub fn cube_visibility(scene: &RayScene, p: DVec3, n: DVec3, size: usize) -> Vec<f64> {
    as_unit(visibility_along(scene, p, n, &cube_texel_directions(size)))
}

/// Cube-map Haar transport keeping `keep` coefficients per receiver and function.
pub fn haar_transport(
    scene: &RayScene,
    receivers: &Receivers,
    size: usize,
    keep: usize,
    cancel: &CancelToken,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<HaarTransport, StageError> {
    let haar = CubeHaar::new(size);
    let solid_angles: Vec<f64> =
        (0..size * size).map(|i| cubemap::texel_solid_angle(size, i % size, i / size)).collect();
    let directions = cube_texel_directions(size);
    let per = per_receiver(receivers.len(), cancel, progress, |i| {
        let (p, n) = receivers.point(i);
        let v = as_unit(visibility_along(scene, p, n, &directions));
        let t: Vec<f64> = v
            .iter()
            .enumerate()
            .map(|(k, v)| v * directions[k].dot(n).max(0.0) * solid_angles[k % (size * size)])
            .collect();
        (haar.approximate(&v, keep), haar.approximate(&t, keep))
    })?;
    let (visibility, transfer) = per.into_iter().unzip();
    Ok(HaarTransport { size, keep, visibility, transfer })
}

/// Local-frame spherical Haar visibility (one ray per finest cell centre, in the receiver's
/// frame `[t, b, n]`), keeping the `keep` largest coefficients.
pub fn spherical_transport(
    scene: &RayScene,
    receivers: &Receivers,
    depth: usize,
    keep: usize,
    cancel: &CancelToken,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<SphericalTransport, StageError> {
    let basis = SphericalHaar::new(depth);
    let local: Vec<DVec3> = (0..basis.len())
        .map(|c| {
            let [a, b, d] = basis.triangle(depth, c);
            (a + b + d).normalize()
        })
        .collect();
    let visibility = per_receiver(receivers.len(), cancel, progress, |i| {
        let (p, n) = receivers.point(i);
        let frame = receivers.frame(i);
        let world: Vec<DVec3> = local.iter().map(|d| frame * *d).collect();
        let cells: Vec<f64> =
            visibility_along(scene, p, n, &world).into_iter().map(|v| if v { 1.0 } else { 0.0 }).collect();
        basis.approximate(&cells, keep)
    })?;
    Ok(SphericalTransport { depth, keep, visibility })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh;

    fn plane_and_sphere(radius: f64, height: f64) -> MeshSet {
        let blocker = mesh::sphere(radius, 96).transformed(glam::DMat4::from_translation(DVec3::new(0.0, height, 0.0)));
        MeshSet { meshes: vec![mesh::plane(10.0, 4), blocker] }
    }

    fn single_receiver(p: DVec3, n: DVec3) -> Receivers {
        Receivers {
            positions: vec![p.as_vec3().to_array()],
            normals: vec![n.as_vec3().to_array()],
            tangents: vec![n.any_orthonormal_vector().as_vec3().to_array()],
            mesh_offsets: vec![0],
        }
    }

    #[test]
    fn unoccluded_transfer_is_the_clamped_cosine_closed_form() {
        let scene = RayScene::build(&MeshSet { meshes: vec![mesh::plane(10.0, 2)] });
        let n = DVec3::Y;
        let r = single_receiver(DVec3::ZERO, n);
        let t = sh_transport(&scene, &r, 6, 8192, &CancelToken::default(), &|_| {}).unwrap();
        let (v, transfer) = t.receiver(0);
        let y = ShBasis::new(6).eval_vec(n);
        for (i, got) in transfer.iter().enumerate() {
            // T_lm = Â_l Y_lm(n) (clamped cosine ZH rotated to n).
            let want = sh::clamped_cosine_factor(sh::band_of(i)) * y[i];
            assert!((*got as f64 - want).abs() < 4e-3, "T[{i}] = {got}, closed form {want}");
        }
        // The plane hides the lower hemisphere: V_00 = 2π / sqrt(4π).
        assert!((v[0] as f64 - 2.0 * PI / (4.0 * PI).sqrt()).abs() < 2e-3, "{}", v[0]);
    }

    #[test]
    fn point_under_a_sphere_sees_the_analytic_solid_angle() {
        // Visible solid angle above a plane with a sphere of radius r at height h overhead:
        // 2π − 2π(1 − sqrt(1 − (r/h)²)) = 2π sqrt(1 − (r/h)²).
        for (radius, height) in [(0.5, 1.0), (0.9, 1.0), (0.2, 2.0)] {
            let scene = RayScene::build(&plane_and_sphere(radius, height));
            let r = single_receiver(DVec3::ZERO, DVec3::Y);
            let t = sh_transport(&scene, &r, 1, 16384, &CancelToken::default(), &|_| {}).unwrap();
            let visible = t.receiver(0).0[0] as f64 * (4.0 * PI).sqrt();
            let exact = 2.0 * PI * (1.0 - (radius / height).powi(2)).sqrt();
            assert!((visible - exact).abs() < 0.01 * exact, "r {radius} h {height}: {visible} vs {exact}");
        }
    }

    #[test]
    fn haar_transport_equals_brute_force_projection_of_the_same_samples() {
        let scene = RayScene::build(&plane_and_sphere(0.6, 1.2));
        let receivers = single_receiver(DVec3::new(0.3, 0.0, 0.1), DVec3::Y);
        let size = 8;
        let keep = 40;
        let t = haar_transport(&scene, &receivers, size, keep, &CancelToken::default(), &|_| {}).unwrap();
        let samples = cube_visibility(&scene, DVec3::new(0.3, 0.0, 0.1), DVec3::Y, size);
        let haar = CubeHaar::new(size);
        let nonzero = haar.forward(&samples).iter().filter(|c| **c != 0.0).count();
        assert_eq!(t.visibility[0].len(), keep.min(nonzero));
        for &(index, value) in &t.visibility[0].entries {
            // <V, ψ_index> over the same texel samples, with ψ from the inverse transform.
            let mut unit = vec![0.0; haar.len()];
            unit[index as usize] = 1.0;
            let psi = haar.inverse(&unit);
            let brute: f64 = samples.iter().zip(&psi).map(|(v, p)| v * p).sum();
            assert!((brute - value).abs() < 1e-9, "coefficient {index}: {value} vs {brute}");
        }
        // Double product with a constant environment L = 1 gives the unoccluded-cosine
        // integral: Σ_texels T = ∫ V max(n·ω,0) dω.
        let full = SparseVector::from_dense(&haar.forward(&vec![1.0; haar.len()]));
        let all = haar_transport(&scene, &receivers, size, haar.len(), &CancelToken::default(), &|_| {}).unwrap();
        let e = full.dot(&all.transfer[0]);
        let sh = sh_transport(&scene, &receivers, 1, 16384, &CancelToken::default(), &|_| {}).unwrap();
        let reference = sh.receiver(0).1[0] as f64 * (4.0 * PI).sqrt();
        assert!((e - reference).abs() < 0.05 * reference, "cube {e} vs Fibonacci {reference}");
    }

    #[test]
    fn spherical_transport_sees_the_ground_in_the_local_frame() {
        // On a floor, local directions with z < 0 (below the surface) are blocked and all
        // others are free: the cell values equal that exactly.
        let scene = RayScene::build(&MeshSet { meshes: vec![mesh::plane(10.0, 2)] });
        let receivers = single_receiver(DVec3::ZERO, DVec3::Y);
        let depth = 3;
        let t = spherical_transport(&scene, &receivers, depth, usize::MAX, &CancelToken::default(), &|_| {}).unwrap();
        let basis = SphericalHaar::new(depth);
        let cells = basis.inverse(&t.visibility[0].to_dense(basis.len()));
        for (c, v) in cells.iter().enumerate() {
            let [a, b, d] = basis.triangle(depth, c);
            let centre_z = (a + b + d).normalize().z;
            let expected = if centre_z > 0.0 { 1.0 } else { 0.0 };
            assert!((v - expected).abs() < 1e-9, "cell {c}: {v} (centre z {centre_z})");
        }
    }

    #[test]
    fn visibility_texture_shadows_a_single_quad() {
        // A floor made of two triangles under a sphere: the texel receivers resolve the
        // shadow that its four vertices cannot, and agree with a receiver placed directly at
        // the same point.
        let mut floor = mesh::plane(4.0, 1);
        floor.visibility_texture = true;
        let meshes = MeshSet {
            meshes: vec![
                floor,
                mesh::sphere(0.5, 48).transformed(glam::DMat4::from_translation(DVec3::new(0.0, 1.0, 0.0))),
            ],
        };
        let scene = RayScene::build(&meshes);
        let texels = TexelReceivers::rasterize(&meshes, 32);
        assert_eq!(texels.receivers.len(), 32 * 32, "the quad covers its whole UV square");
        let t = sh_transport(&scene, &texels.receivers, 1, 4096, &CancelToken::default(), &|_| {}).unwrap();
        let (centre, _) = (0..texels.receivers.len())
            .map(|i| (i, DVec3::from(texels.receivers.positions[i].map(f64::from)).length()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        let direct = sh_transport(
            &scene,
            &single_receiver(DVec3::from(texels.receivers.positions[centre].map(f64::from)), DVec3::Y),
            1,
            4096,
            &CancelToken::default(),
            &|_| {},
        )
        .unwrap();
        assert!((t.receiver(centre).0[0] - direct.receiver(0).0[0]).abs() < 1e-6);
        // Shadowed under the sphere, unshadowed at the corners.
        let corner = t.receiver(0).0[0] as f64 * (4.0 * PI).sqrt();
        let under = t.receiver(centre).0[0] as f64 * (4.0 * PI).sqrt();
        assert!(corner > 2.0 * PI * 0.97 && under < 2.0 * PI * 0.9, "corner {corner}, under {under}");
    }

    #[test]
    fn cancellation_stops_transport() {
        let scene = RayScene::build(&plane_and_sphere(0.5, 1.0));
        let receivers = Receivers::from_meshes(&plane_and_sphere(0.5, 1.0));
        let cancel = CancelToken::default();
        cancel.cancel();
        assert_eq!(sh_transport(&scene, &receivers, 3, 64, &cancel, &|_| {}).unwrap_err(), StageError::Cancelled);
    }
}
