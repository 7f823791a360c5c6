//! Monte Carlo reference renderer: ground truth for the relighting modes. Direct lighting from
//! the environment with binary visibility and the same BRDFs (`Ma et al.` eq. 1,
//! `B(x, ω_o) = ∫ L V ρ (ω_i·n) dω_i`), on the same BVH, for the same camera.
//!
//! Estimator: per pixel, jittered camera rays; at each hit one environment-importance sample
//! and one BRDF sample, combined by multiple importance sampling (balance heuristic), each with
//! a shadow ray. The environment is the cube map's texel-constant radiance (what the SH and
//! wavelet projections see); environment samples pick a texel by `luminance × solid angle` and
//! a point uniformly in its face rectangle, with the exact solid-angle density.
//!
//! Normal maps follow Mitsuba 3's convention (its `normalmap` defaults since August 2025, whose
//! shadow terminator Blender 4.5 also has), not the textbook one that blackens every texel
//! whose perturbed normal faces away from the view (at a grazing view, much of a bumpy surface):
//! - **Flipped invalid normals** (Schüssler et al. 2017, *Microfacet-based normal mapping*, the
//!   "flip" fallback): where the view lies below the perturbed normal, its tangential part is
//!   mirrored, `(x, y, z) → (−x, −y, z)` in tangent space.
//! - **The shadow terminator** (Estevez, Kulla et al., *Ray Tracing Gems* ch. 12, 2019): each
//!   light direction `ω` is weighted by `2 / (1 + √(1 + α² tan²θ_ω))`, `θ_ω` measured from the
//!   unperturbed normal and `α² = min(tan²θ_n / 8, 1)` from the perturbed normal's tilt `θ_n`,
//!   so light fades smoothly where the bumps' own geometry would shadow it.

mod area_emitter;

pub use area_emitter::AreaEmitter;

use crate::brdf::Brdf;
use crate::cubemap::{self, CubeMap, FACES};
use crate::engine::{CancelToken, StageError};
use crate::mesh::MeshSet;
use crate::picture::srgb_to_linear;
use crate::raycast::RayScene;
use glam::{DMat3, DVec3, Vec3A};
use rand::{Rng, SeedableRng, rngs::SmallRng};
use rayon::prelude::*;
use std::f64::consts::PI;

/// A pinhole camera (`+Y` up), as `project::Camera` and the viewport use it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PinholeCamera {
    pub position: DVec3,
    pub target: DVec3,
    pub fov_y_deg: f64,
}

/// The camera frame `(right, up)` for a view direction: up is world +Y where it can be; looking
/// straight up or down, right is +X. The viewport and the reference share it.
pub fn camera_basis(forward: DVec3) -> (DVec3, DVec3) {
    let right = forward.cross(DVec3::Y).try_normalize().unwrap_or(DVec3::X);
    (right, right.cross(forward))
}

impl PinholeCamera {
    /// Direction through image point `(x, y)` in pixels (`y` down), matching the viewport's
    /// right-handed perspective.
    pub fn ray(&self, x: f64, y: f64, width: usize, height: usize) -> DVec3 {
        let forward = (self.target - self.position).normalize();
        let (right, up) = camera_basis(forward);
        let tan = (self.fov_y_deg.to_radians() / 2.0).tan();
        let aspect = width as f64 / height as f64;
        let ndc_x = 2.0 * x / width as f64 - 1.0;
        let ndc_y = 1.0 - 2.0 * y / height as f64;
        (forward + right * (ndc_x * tan * aspect) + up * (ndc_y * tan)).normalize()
    }
}

/// Importance sampling of a cube map by `luminance × solid angle`.
pub struct EnvironmentSampler<'a> {
    cube: &'a CubeMap,
    cdf: Vec<f64>,
    /// Per texel: probability.
    probability: Vec<f64>,
}

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

impl<'a> EnvironmentSampler<'a> {
    pub fn new(cube: &'a CubeMap) -> Self {
        let n = cube.size;
        let solid = cube.face_solid_angles();
        let weights: Vec<f64> = (0..FACES * n * n)
            .map(|i| luminance(cube.texels[i].map(f64::from)).max(0.0) * solid[i % (n * n)])
            .collect();
        let total: f64 = weights.iter().sum();
        // A black environment: sample uniformly by solid angle (all estimates are zero anyway).
        let weights: Vec<f64> = if total > 0.0 {
            weights.iter().map(|w| w / total).collect()
        } else {
            let s: f64 = solid.iter().sum::<f64>() * FACES as f64;
            (0..FACES * n * n).map(|i| solid[i % (n * n)] / s).collect()
        };
        let mut acc = 0.0;
        let cdf = weights
            .iter()
            .map(|w| {
                acc += w;
                acc
            })
            .collect();
        Self { cube, cdf, probability: weights }
    }

    /// Texel index of a direction (nearest texel).
    fn texel_of(&self, dir: DVec3) -> (usize, f64, f64) {
        let n = self.cube.size;
        let (face, u, v) = cubemap::dir_to_face_uv(dir);
        let x = ((u * n as f64) as usize).min(n - 1);
        let y = ((v * n as f64) as usize).min(n - 1);
        ((face * n + y) * n + x, 2.0 * u - 1.0, 2.0 * v - 1.0)
    }

    /// Texel-constant radiance in a direction.
    pub fn radiance(&self, dir: DVec3) -> DVec3 {
        DVec3::from(self.cube.texels[self.texel_of(dir).0].map(f64::from))
    }

    /// Solid-angle density of [`EnvironmentSampler::sample`].
    pub fn pdf(&self, dir: DVec3) -> f64 {
        let (i, a, b) = self.texel_of(dir);
        let texel_area = (2.0 / self.cube.size as f64).powi(2);
        self.probability[i] / texel_area * (1.0 + a * a + b * b).powf(1.5)
    }

    pub fn sample(&self, u: [f64; 3]) -> DVec3 {
        let i =
            self.cdf.partition_point(|c| *c < u[0] * self.cdf.last().copied().unwrap_or(1.0)).min(self.cdf.len() - 1);
        let n = self.cube.size;
        let (face, y, x) = (i / (n * n), (i / n) % n, i % n);
        cubemap::face_uv_to_dir(face, (x as f64 + u[1]) / n as f64, (y as f64 + u[2]) / n as f64)
    }
}

/// Irradiance `E = ∫ L(ω) V(ω) max(n·ω, 0) dω` at a surface point (or a probe, with `scene`
/// occluding), by Monte Carlo: `samples` environment samples and as many cosine samples,
/// combined with the balance heuristic. The bake's vertex light, lightmaps and probes are
/// checked against it.
pub fn irradiance(
    scene: &RayScene,
    environment: &EnvironmentSampler,
    point: DVec3,
    normal: DVec3,
    samples: usize,
    rng: &mut impl Rng,
) -> DVec3 {
    let origin = scene.leave_surface(point, normal);
    let visible = |dir: DVec3| !scene.occluded(origin, dir.as_vec3().into(), f32::INFINITY);
    let (t, b) = normal.any_orthonormal_pair();
    let mut sum = DVec3::ZERO;
    for _ in 0..samples {
        // Environment sample.
        let dir = environment.sample([rng.random(), rng.random(), rng.random()]);
        let cos = dir.dot(normal);
        if cos > 0.0 && visible(dir) {
            let (p_env, p_cos) = (environment.pdf(dir), cos / PI);
            sum += environment.radiance(dir) * cos / (p_env + p_cos);
        }
        // Cosine sample.
        let (u1, u2): (f64, f64) = (rng.random(), rng.random());
        let r = u1.sqrt();
        let phi = 2.0 * PI * u2;
        let local = DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
        let dir = t * local.x + b * local.y + normal * local.z;
        let cos = local.z;
        if cos > 0.0 && visible(dir) {
            let (p_env, p_cos) = (environment.pdf(dir), cos / PI);
            sum += environment.radiance(dir) * cos / (p_env + p_cos);
        }
    }
    sum / samples as f64
}

/// Geometry, material and lighting of a reference render.
pub struct ReferenceScene<'a> {
    pub scene: &'a RayScene,
    pub meshes: &'a MeshSet,
    /// The BRDF of each mesh.
    pub brdfs: Vec<Brdf>,
    /// The environment as the relighting modes see it (after rotation, exposure and tint).
    pub environment: &'a CubeMap,
    /// Draw the environment where camera rays miss.
    pub background: bool,
    /// Spheres that block light but are not seen (blocker sphere sets stand in for geometry).
    pub blockers: &'a [crate::sh_exponential::Blocker],
    /// Painted area lights (not seen by camera rays, as in the viewport).
    pub area_lights: &'a [AreaEmitter],
    /// Point lights, with their profiles (not seen by camera rays), shadowed by the scene and
    /// the blockers.
    pub point_lights: &'a [crate::light::PointLight],
    /// Per mesh, the normal map its shading normal is perturbed by and the map's repeats per
    /// unit of UV (in the frame of its normal, tangent and `± n × t` by the vertices'
    /// handedness, at the hit's UV); none
    /// past the list's end.
    pub normal_maps: &'a [Option<(&'a crate::normal_filtering::NormalMap, f64)>],
    /// The textbook normal map (no flip, no shadow terminator: Mitsuba's `normalmap` with
    /// `flip_invalid_normals` and `use_shadowing_function` off) instead of the production one
    /// (see the module doc).
    pub textbook_normal_maps: bool,
}

/// A linear HDR image, rows top to bottom, with the fraction of each pixel's samples that
/// hit geometry.
#[derive(Clone, Debug, PartialEq)]
pub struct HdrImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
    pub coverage: Vec<f32>,
}

impl HdrImage {
    /// Pixels wholly covered by geometry: where lighting is compared (silhouettes and the
    /// background measure anti-aliasing and texture filtering, not lighting).
    pub fn surface_mask(&self) -> Vec<bool> {
        self.coverage.iter().map(|c| *c >= 1.0).collect()
    }
}

/// Per-triangle lookup from the ray scene's triangle index to its mesh.
struct TriangleTable {
    /// First global triangle index of each mesh.
    starts: Vec<u32>,
    tangents: Vec<Vec<[f32; 3]>>,
    /// Per mesh and vertex, the normal-map frame's handedness.
    bitangent_signs: Vec<Vec<f32>>,
}

impl TriangleTable {
    fn new(meshes: &MeshSet) -> Self {
        let mut starts = Vec::new();
        let mut next = 0u32;
        for m in &meshes.meshes {
            starts.push(next);
            next += m.triangle_count() as u32;
        }
        Self {
            starts,
            tangents: meshes.meshes.iter().map(crate::mesh::vertex_tangents).collect(),
            bitangent_signs: meshes.meshes.iter().map(crate::mesh::vertex_bitangent_signs).collect(),
        }
    }

    fn locate(&self, triangle: u32) -> (usize, usize) {
        let mesh = self.starts.partition_point(|s| *s <= triangle) - 1;
        (mesh, (triangle - self.starts[mesh]) as usize)
    }
}

/// The surface seen along a camera ray: its mesh, position, shading frame (columns `t, b, n`),
/// geometric normal, base colour, and under a normal map the unperturbed normal and the shadow
/// terminator's `α²` (zero without a map).
struct Hit {
    mesh: usize,
    position: DVec3,
    frame: DMat3,
    geometric: DVec3,
    base_color: DVec3,
    unperturbed: DVec3,
    terminator: f64,
}

impl Hit {
    /// The shadow terminator's weight for light arriving along `wi_world` (see the module doc):
    /// 1 without a normal map.
    fn shadow_terminator(&self, wi_world: DVec3) -> f64 {
        if self.terminator <= 0.0 {
            return 1.0;
        }
        let cos2 = self.unperturbed.dot(wi_world).powi(2).max(1e-12);
        let tan2 = ((1.0 - cos2) / cos2).max(0.0);
        2.0 / (1.0 + (1.0 + self.terminator * tan2).sqrt())
    }
}

/// Whether the ray `origin + t dir`, `t > 0`, meets the sphere (an origin inside it is blocked).
fn ray_hits_sphere(origin: DVec3, dir: DVec3, sphere: &crate::sh_exponential::Blocker) -> bool {
    segment_hits_sphere(origin, dir, f64::INFINITY, sphere)
}

/// Whether the segment from `origin` along `dir` (unit) for `length` meets the sphere.
fn segment_hits_sphere(origin: DVec3, dir: DVec3, length: f64, sphere: &crate::sh_exponential::Blocker) -> bool {
    let centre = DVec3::from(sphere.centre);
    let along = (centre - origin).dot(dir).clamp(0.0, length);
    (origin + dir * along - centre).length_squared() <= sphere.radius * sphere.radius
}

fn shade_point(rs: &ReferenceScene, table: &TriangleTable, origin: DVec3, dir: DVec3) -> Option<Hit> {
    let (t, triangle) = rs.scene.closest(origin.as_vec3().into(), dir.as_vec3().into())?;
    let (mi, ti) = table.locate(triangle);
    let mesh = &rs.meshes.meshes[mi];
    let idx = [0, 1, 2].map(|k| mesh.indices[ti * 3 + k] as usize);
    let p = idx.map(|i| DVec3::from(mesh.positions[i].map(f64::from)));
    let position = origin + dir * t as f64;
    // Barycentrics of the hit point.
    let (e1, e2, ep) = (p[1] - p[0], p[2] - p[0], position - p[0]);
    let (d11, d12, d22, dp1, dp2) = (e1.dot(e1), e1.dot(e2), e2.dot(e2), ep.dot(e1), ep.dot(e2));
    let det = (d11 * d22 - d12 * d12).max(1e-300);
    let (b1, b2) = ((d22 * dp1 - d12 * dp2) / det, (d11 * dp2 - d12 * dp1) / det);
    let w = [1.0 - b1 - b2, b1, b2];
    let lerp = |v: &[[f32; 3]]| idx.iter().zip(w).map(|(i, w)| DVec3::from(v[*i].map(f64::from)) * w).sum::<DVec3>();
    let mut geometric = e1.cross(e2).normalize_or(DVec3::Y);
    let mut n = lerp(&mesh.normals).normalize_or(geometric);
    // Seen from behind: shade the back side, as the viewport does.
    if geometric.dot(dir) > 0.0 {
        geometric = -geometric;
        n = -n;
    }
    let t_raw = lerp(&table.tangents[mi]);
    let mut tangent = (t_raw - n * n.dot(t_raw)).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
    let (unperturbed, mut terminator) = (n, 0.0);
    if let Some((map, tiling)) = rs.normal_maps.get(mi).copied().flatten()
        && mesh.uvs.len() == mesh.positions.len()
    {
        let uv = idx.iter().zip(w).fold([0.0; 2], |a, (i, w)| {
            let uv = mesh.uvs[*i];
            [a[0] + f64::from(uv[0]) * w, a[1] + f64::from(uv[1]) * w]
        });
        let handedness = idx.iter().zip(w).map(|(i, w)| f64::from(table.bitangent_signs[mi][*i]) * w).sum::<f64>();
        let bitangent = n.cross(tangent) * if handedness < 0.0 { -1.0 } else { 1.0 };
        let to_world = DMat3::from_cols(tangent, bitangent, n);
        let mut local = map.sample(uv.map(|c| c * tiling));
        // Seen from below the perturbed normal: its tangential part mirrored (the flip).
        if !rs.textbook_normal_maps && (-dir).dot(n) * (-dir).dot(to_world * local) <= 0.0 {
            local = DVec3::new(-local.x, -local.y, local.z);
        }
        let perturbed = (to_world * local).try_normalize().unwrap_or(n);
        if !rs.textbook_normal_maps {
            let cos2 = perturbed.dot(n).powi(2).max(1e-12);
            terminator = ((1.0 - cos2) / cos2 / 8.0).min(1.0);
        }
        n = perturbed;
        tangent = (tangent - n * n.dot(tangent)).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
    }
    let frame = DMat3::from_cols(tangent, n.cross(tangent), n);
    Some(Hit {
        mesh: mi,
        position,
        frame,
        geometric,
        base_color: DVec3::from(mesh.base_color.map(f64::from)),
        unperturbed,
        terminator,
    })
}

/// One MIS estimate of direct environment lighting leaving `hit` towards `wo_world`.
fn direct_lighting(
    rs: &ReferenceScene,
    env: &EnvironmentSampler,
    hit: &Hit,
    wo_world: DVec3,
    rng: &mut SmallRng,
) -> DVec3 {
    let to_local = hit.frame.transpose();
    let wo = to_local * wo_world;
    let mut brdf = rs.brdfs[hit.mesh];
    brdf.diffuse *= hit.base_color;
    let origin = rs.scene.leave_surface(hit.position, hit.geometric);
    let visible = |wi_world: DVec3| {
        !rs.blockers.iter().any(|b| ray_hits_sphere(hit.position, wi_world, b))
            && !rs.scene.occluded(origin, Vec3A::from(wi_world.as_vec3()), f32::INFINITY)
    };
    // Whether the way to a light `dist` away along `wi_world` is blocked.
    let blocked = |wi_world: DVec3, dist: f64| {
        rs.blockers.iter().any(|b| segment_hits_sphere(hit.position, wi_world, dist, b))
            || rs.scene.occluded(origin, Vec3A::from(wi_world.as_vec3()), (dist * (1.0 - 1e-6)) as f32)
    };
    let mut total = DVec3::ZERO;
    // Environment sample.
    let wi_world = env.sample([rng.random(), rng.random(), rng.random()]);
    let wi = to_local * wi_world;
    if wi.z > 0.0 && wi_world.dot(hit.geometric) > 0.0 {
        let f = brdf.eval(wi, wo) * hit.shadow_terminator(wi_world);
        if f != DVec3::ZERO {
            let (pe, pb) = (env.pdf(wi_world), brdf.pdf(wo, wi));
            if pe > 0.0 && visible(wi_world) {
                total += f * env.radiance(wi_world) * wi.z / (pe + pb);
            }
        }
    }
    // BRDF sample.
    let wi = brdf.sample(wo, [rng.random(), rng.random(), rng.random()]);
    let wi_world = hit.frame * wi;
    if wi.z > 0.0 && wi_world.dot(hit.geometric) > 0.0 {
        let f = brdf.eval(wi, wo) * hit.shadow_terminator(wi_world);
        if f != DVec3::ZERO {
            let (pe, pb) = (env.pdf(wi_world), brdf.pdf(wo, wi));
            if pb > 0.0 && visible(wi_world) {
                total += f * env.radiance(wi_world) * wi.z / (pe + pb);
            }
        }
    }
    // Point lights: each one's direct light, `f · I(ω) cos θ / d²`, where nothing blocks it.
    for light in rs.point_lights {
        let to_light = DVec3::from(light.position) - hit.position;
        let dist = to_light.length();
        if dist <= 1e-9 {
            continue;
        }
        let wi_world = to_light / dist;
        let wi = to_local * wi_world;
        if wi.z <= 0.0 || wi_world.dot(hit.geometric) <= 0.0 {
            continue;
        }
        if !blocked(wi_world, dist) {
            total += brdf.eval(wi, wo)
                * hit.shadow_terminator(wi_world)
                * DVec3::from(light.intensity_toward(-wi_world))
                * wi.z
                / (dist * dist);
        }
    }
    // One sample of each area light (they are not geometry, so BRDF samples never reach them).
    for light in rs.area_lights {
        let Some((p, radiance, pdf)) = light.sample([rng.random(), rng.random(), rng.random()]) else { continue };
        let Some((wi_world, dist, g)) = light.towards(hit.position, p) else { continue };
        let wi = to_local * wi_world;
        if wi.z <= 0.0 || wi_world.dot(hit.geometric) <= 0.0 {
            continue;
        }
        if !blocked(wi_world, dist) {
            total += brdf.eval(wi, wo) * hit.shadow_terminator(wi_world) * radiance * wi.z * g / pdf;
        }
    }
    total
}

/// Renders `samples` jittered paths per pixel, in parallel rows, checking `cancel` per row.
pub fn render(
    rs: &ReferenceScene,
    camera: &PinholeCamera,
    (width, height): (usize, usize),
    samples: usize,
    seed: u64,
    cancel: &CancelToken,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<HdrImage, StageError> {
    if width == 0 || height == 0 || width * height > 16384 * 16384 || samples == 0 {
        return Err(StageError::Failed(format!("reference size {width}x{height} with {samples} samples is invalid")));
    }
    let env = EnvironmentSampler::new(rs.environment);
    let table = TriangleTable::new(rs.meshes);
    let done = std::sync::atomic::AtomicUsize::new(0);
    type Row = Vec<([f32; 3], f32)>;
    let rows: Vec<Result<Row, StageError>> = (0..height)
        .into_par_iter()
        .map(|y| {
            cancel.check()?;
            let mut rng = SmallRng::seed_from_u64(seed ^ (y as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let row = (0..width)
                .map(|x| {
                    let mut sum = DVec3::ZERO;
                    let mut hits = 0;
                    for s in 0..samples {
                        // Stratified jitter over a √n × √n grid (n rounded to a square).
                        let side = (samples as f64).sqrt().ceil() as usize;
                        let (sx, sy) = (s % side, (s / side) % side);
                        let jx = (sx as f64 + rng.random::<f64>()) / side as f64;
                        let jy = (sy as f64 + rng.random::<f64>()) / side as f64;
                        let dir = camera.ray(x as f64 + jx, y as f64 + jy, width, height);
                        sum += match shade_point(rs, &table, camera.position, dir) {
                            Some(hit) => {
                                hits += 1;
                                direct_lighting(rs, &env, &hit, -dir, &mut rng)
                            }
                            None if rs.background => DVec3::from(rs.environment.sample(dir)),
                            None => DVec3::ZERO,
                        };
                    }
                    ((sum / samples as f64).as_vec3().to_array(), hits as f32 / samples as f32)
                })
                .collect();
            let finished = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(finished as f64 / height as f64);
            Ok(row)
        })
        .collect();
    let mut pixels = Vec::with_capacity(width * height);
    let mut coverage = Vec::with_capacity(width * height);
    for row in rows {
        for (p, c) in row? {
            pixels.push(p);
            coverage.push(c);
        }
    }
    Ok(HdrImage { width, height, pixels, coverage })
}

/// How far an approximation is from the reference.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ImageError {
    /// Root mean square difference of linear radiance over pixels and channels.
    pub rmse: f64,
    /// `rmse` divided by the reference's mean radiance.
    pub relative_rmse: f64,
    /// PSNR in dB of linear radiance, with the reference's 99th-percentile value as the peak.
    pub psnr_db: f64,
}

/// Compares linear images of the same size over the pixels where `mask` is true (all when
/// `None`).
pub fn compare(
    approximation: &[[f32; 3]],
    reference: &[[f32; 3]],
    mask: Option<&[bool]>,
) -> Result<ImageError, String> {
    if approximation.len() != reference.len()
        || reference.is_empty()
        || mask.is_some_and(|m| m.len() != reference.len())
    {
        return Err(format!("image sizes differ: {} vs {} pixels", approximation.len(), reference.len()));
    }
    let selected: Vec<usize> = (0..reference.len()).filter(|i| mask.is_none_or(|m| m[*i])).collect();
    if selected.is_empty() {
        return Err("no pixel to compare: nothing covers the view".into());
    }
    let reference: Vec<[f32; 3]> = selected.iter().map(|i| reference[*i]).collect();
    let approximation: Vec<[f32; 3]> = selected.iter().map(|i| approximation[*i]).collect();
    let mut sq = 0.0;
    let mut mean = 0.0;
    for (a, r) in approximation.iter().zip(&reference) {
        for c in 0..3 {
            let (a, r) = (a[c] as f64, r[c] as f64);
            sq += (a - r) * (a - r);
            mean += r;
        }
    }
    let count = (reference.len() * 3) as f64;
    let rmse = (sq / count).sqrt();
    mean /= count;
    let mut values: Vec<f32> = reference.iter().flat_map(|p| *p).collect();
    values.sort_by(f32::total_cmp);
    let peak = values[(values.len() - 1) * 99 / 100].max(1e-12) as f64;
    Ok(ImageError {
        rmse,
        relative_rmse: if mean > 0.0 { rmse / mean } else { rmse },
        psnr_db: 20.0 * (peak / rmse.max(1e-300)).log10(),
    })
}

/// The heat map's default full scale: half the reference's mean radiance.
pub fn error_map_scale(reference: &[[f32; 3]]) -> f64 {
    let mean = reference.iter().map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0).sum::<f64>() / reference.len().max(1) as f64;
    (mean * 0.5).max(1e-6)
}

/// A heat map of per-pixel error: `|a - r|` (mean over channels) divided by `scale`, through a
/// perceptually ordered colour ramp (black → purple → orange → yellow → white, like "inferno").
/// Pixels outside `mask` are drawn dark grey.
pub fn error_heat_map(
    approximation: &[[f32; 3]],
    reference: &[[f32; 3]],
    mask: Option<&[bool]>,
    scale: f64,
) -> Vec<[f32; 3]> {
    approximation
        .iter()
        .zip(reference)
        .enumerate()
        .map(|(i, (a, r))| {
            if mask.is_some_and(|m| !m[i]) {
                return [0.02; 3];
            }
            let e = (0..3).map(|c| (a[c] - r[c]).abs() as f64).sum::<f64>() / 3.0;
            // The ramp is in display (sRGB) values; return linear so the tone mapper's sRGB
            // encoding (with linear tone mapping) shows the ramp as designed.
            error_ramp(e / scale.max(1e-30)).map(|c| srgb_to_linear(c) as f32)
        })
        .collect()
}

/// The heat map's colour at `t` (0 no error, 1 the scale or more), in display (sRGB) values.
pub fn error_ramp(t: f64) -> [f64; 3] {
    const RAMP: [[f64; 3]; 5] =
        [[0.0, 0.0, 0.015], [0.34, 0.06, 0.43], [0.87, 0.32, 0.23], [0.99, 0.77, 0.18], [0.99, 1.0, 0.92]];
    let t = t.clamp(0.0, 1.0) * (RAMP.len() - 1) as f64;
    let (i, f) = ((t.floor() as usize).min(RAMP.len() - 2), t - t.floor().min((RAMP.len() - 2) as f64));
    [0, 1, 2].map(|c| RAMP[i][c] * (1.0 - f) + RAMP[i + 1][c] * f)
}

#[cfg(test)]
mod tests;
