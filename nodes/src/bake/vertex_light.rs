//! The diffuse light of a frame per vertex, as its mode draws it: what the bake writes as
//! `COLOR_0` and what lightmaps and probes are checked against.
//!
//! Every value is `E / π`, linear: the radiance a white Lambertian surface reflects (multiply by
//! the base colour for a surface's diffuse radiance). Each mode's sum is the CPU twin of its
//! shader's diffuse part (`shaders/mesh*.wgsl`), with two differences a bake wants: point lights
//! are shadowed (one ray per vertex and light; the viewport draws them unshadowed), and nothing
//! depends on the viewer (fog's attenuation towards the eye and its airlight stay out).

use crate::frame::{FrameInputs, Surfaces};
use crate::light::PointLight;
use crate::mesh::MeshSet;
use crate::raycast::RayScene;
use crate::sh::{ShBasis, ShRgb};
use glam::{DVec3, Vec3A};
use rayon::prelude::*;
use std::f64::consts::PI;

/// One surface point the light is evaluated at.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub position: DVec3,
    pub normal: DVec3,
    pub tangent: DVec3,
}

/// The scene's vertices as surface points, in [`MeshSet`] order.
pub fn vertex_points(meshes: &MeshSet) -> Vec<SurfacePoint> {
    let mut points = Vec::new();
    for mesh in &meshes.meshes {
        let tangents = if mesh.tangents.len() == mesh.positions.len() {
            mesh.tangents.clone()
        } else {
            crate::mesh::vertex_tangents(mesh)
        };
        for ((p, n), t) in mesh.positions.iter().zip(&mesh.normals).zip(&tangents) {
            points.push(SurfacePoint {
                position: DVec3::from(p.map(f64::from)),
                normal: DVec3::from(n.map(f64::from)).normalize_or(DVec3::Y),
                tangent: DVec3::from(t.map(f64::from)),
            });
        }
    }
    points
}

/// `E / π` per vertex of `frame`'s scene: the mode's environment light, area lights and point
/// lights (shadowed by `shadows` when given).
pub fn vertex_light(frame: &FrameInputs, shadows: Option<&RayScene>) -> Result<Vec<[f32; 3]>, String> {
    let meshes = frame.geometry.meshes.value.expect::<MeshSet>().map_err(|e| e.to_string())?;
    let points = vertex_points(meshes);
    let products = match &frame.surfaces {
        Surfaces::Wavelet(s) => Some(s.cpu_products()?),
        _ => None,
    };
    let environment = match &frame.surfaces {
        Surfaces::Prt(s) => {
            Transport::Sh(s.transport.value.expect::<crate::transport::ShTransport>().map_err(|e| e.to_string())?)
        }
        Surfaces::Wavelet(_) => Transport::Products(products.as_ref().expect("computed above")),
        _ => Transport::None,
    };
    let mut light = environment_light(frame, &points, environment)?;
    if let Some(area) = area_light(frame)? {
        add(&mut light, &area);
    }
    add_point_lights(frame, &points, shadows, &mut light)?;
    add_sun(frame, &points, shadows, &mut light);
    Ok(finish(light))
}

/// `E / π` per texel of the bake's atlas, as [`vertex_light`] computes it per vertex, from
/// each texel's own transport: `texel_sh` (blockers included) in the SH transfer modes,
/// `texel_products` in the wavelet modes, the traced square lights in their mode, the area
/// lights' texel irradiance, and point lights with a shadow ray per texel.
pub fn texel_light(
    frame: &FrameInputs,
    stages: &super::BakedStages,
    shadows: Option<&RayScene>,
) -> Result<Vec<[f32; 3]>, String> {
    let r = &stages.atlas.receivers;
    let points: Vec<SurfacePoint> = (0..r.len())
        .map(|i| {
            let (position, normal) = r.point(i);
            SurfacePoint { position, normal, tangent: DVec3::from(r.tangents[i].map(f64::from)) }
        })
        .collect();
    let transport = match &frame.surfaces {
        Surfaces::Prt(_) => Transport::Sh(stages.texel_sh.ok_or("the lightmap's SH transport was not evaluated")?),
        Surfaces::Wavelet(_) => {
            Transport::Products(stages.texel_products.ok_or("the lightmap's wavelet products were not evaluated")?)
        }
        Surfaces::Rsl(_) => Transport::SquareLights(
            stages.texel_square_lights.ok_or("the lightmap's square-light visibility was not evaluated")?,
        ),
        Surfaces::Irradiance(_) => Transport::None,
    };
    let mut light = environment_light(frame, &points, transport)?;
    if frame.area_lights.is_some() {
        let area = stages.texel_area.ok_or("the lightmap's area-light irradiance was not evaluated")?;
        if area.irradiance.len() != points.len() {
            return Err(format!("the area lights cover {} of {} texels", area.irradiance.len(), points.len()));
        }
        add(&mut light, &area.irradiance.iter().map(|e| e.map(|c| f64::from(c) / PI)).collect::<Vec<_>>());
    }
    add_point_lights(frame, &points, shadows, &mut light)?;
    add_sun(frame, &points, shadows, &mut light);
    Ok(finish(light))
}

/// Per receiver: what the mode's environment light is read from.
enum Transport<'a> {
    /// The frame's own data (unshadowed SH, or the square lights' per-vertex visibility).
    None,
    Sh(&'a crate::transport::ShTransport),
    Products(&'a crate::triple_product::LocalProducts),
    /// Traced at lightmap texels, in place of the vertices' `V̄`.
    SquareLights(&'a crate::lightmap::square_light_texels::SquareLightTexels),
}

fn add(light: &mut [[f64; 3]], more: &[[f64; 3]]) {
    for (out, m) in light.iter_mut().zip(more) {
        for c in 0..3 {
            out[c] += m[c];
        }
    }
}

fn finish(light: Vec<[f64; 3]>) -> Vec<[f32; 3]> {
    light.into_iter().map(|l| l.map(|c| c.max(0.0) as f32)).collect()
}

/// The area lights' `E / π` per vertex, once their transport is evaluated.
fn area_light(frame: &FrameInputs) -> Result<Option<Vec<[f64; 3]>>, String> {
    let Some(area) = &frame.area_lights else { return Ok(None) };
    let e = area.irradiance.value.expect::<crate::kinds::output::area::AreaIrradiance>().map_err(|e| e.to_string())?;
    Ok(Some(e.irradiance.iter().map(|e| e.map(|c| f64::from(c) / PI)).collect()))
}

fn add_point_lights(
    frame: &FrameInputs,
    points: &[SurfacePoint],
    shadows: Option<&RayScene>,
    light: &mut [[f64; 3]],
) -> Result<(), String> {
    let point_lights = PointLightShading::new(frame)?;
    light.par_iter_mut().zip(points).for_each(|(out, p)| {
        let add = point_lights.light(p, shadows);
        for c in 0..3 {
            out[c] += add[c];
        }
    });
    Ok(())
}

/// A separately lit sun's `E / π` ([`crate::sun`]): its directions' equal shares of the disc,
/// each shadowed by one ray when `shadows` is given (the viewport's shadow maps, traced). The
/// environment's share then lights the residual sky (for wavelet texels,
/// `bake_texel_residual_products`).
fn add_sun(frame: &FrameInputs, points: &[SurfacePoint], shadows: Option<&RayScene>, light: &mut [[f64; 3]]) {
    let Some(sun) = &frame.sun else { return };
    let share = sun.solid_angle / sun.directions.len().max(1) as f64 / PI;
    light.par_iter_mut().zip(points).for_each(|(out, p)| {
        let origin = shadows.map(|scene| scene.leave_surface(p.position, p.normal));
        let mut cosines = 0.0;
        for d in &sun.directions {
            let cos = DVec3::from(d.map(f64::from)).dot(p.normal);
            let visible = cos > 0.0
                && shadows
                    .zip(origin)
                    .is_none_or(|(scene, origin)| !scene.occluded(origin, Vec3A::from(*d), f32::INFINITY));
            if visible {
                cosines += cos;
            }
        }
        for c in 0..3 {
            out[c] += sun.radiance[c] * share * cosines;
        }
    });
}

/// The environment's share of `E / π` at each point, per the frame's mode, from `transport`
/// (one entry per point).
fn environment_light(
    frame: &FrameInputs,
    points: &[SurfacePoint],
    transport: Transport,
) -> Result<Vec<[f64; 3]>, String> {
    let fog = frame.medium.fog.as_ref().and_then(|f| f.environment.as_ref().map(|e| (f, e)));
    // The wavelet and square-light modes cannot convolve their light: fog attenuates it and
    // adds the glow's (unshadowed) irradiance, as `fog_shade` does.
    let through_fog = |light: [f64; 3], normal: DVec3| -> [f64; 3] {
        let Some((medium, env)) = fog else { return light };
        let glow =
            if medium.scatter_onto_surfaces { sh_irradiance(&env.scattered.irradiance(), normal) } else { [0.0; 3] };
        std::array::from_fn(|c| light[c] * env.fog.attenuation[c] + glow[c] / PI)
    };
    Ok(match (&frame.surfaces, transport) {
        (Surfaces::Irradiance(s), _) => match &s.irradiance {
            Some(e) => points.par_iter().map(|p| sh_irradiance(e, p.normal).map(|c| c / PI)).collect(),
            None => vec![[0.0; 3]; points.len()],
        },
        (Surfaces::Prt(s), Transport::Sh(t)) => {
            let n = t.bands * t.bands;
            if t.transfer.len() != points.len() * n {
                return Err(format!(
                    "the SH transport covers {} of {} points",
                    t.transfer.len() / n.max(1),
                    points.len()
                ));
            }
            match &s.light {
                Some(light) => (0..points.len())
                    .into_par_iter()
                    .map(|i| crate::prt::diffuse_exit(light, &t.transfer[i * n..(i + 1) * n], DVec3::ONE).to_array())
                    .collect(),
                None => vec![[0.0; 3]; points.len()],
            }
        }
        (Surfaces::Wavelet(s), Transport::Products(p)) => {
            let cells = p.cells;
            if p.values.len() != points.len() * cells * 3 {
                return Err(format!(
                    "the wavelet products cover {} of {} points",
                    p.values.len() / (cells * 3).max(1),
                    points.len()
                ));
            }
            points
                .par_iter()
                .enumerate()
                .map(|(i, point)| {
                    let row = &p.values[i * cells * 3..(i + 1) * cells * 3];
                    let mut sum = [0.0; 3];
                    for c in 0..cells {
                        for k in 0..3 {
                            sum[k] += f64::from(row[c * 3 + k]) * f64::from(s.diffuse_table[c]);
                        }
                    }
                    through_fog(sum, point.normal)
                })
                .collect()
        }
        (Surfaces::Rsl(s), Transport::SquareLights(traced)) => {
            let k = traced.lights;
            if k != s.lights.len() || traced.values.len() != points.len() * k {
                return Err("the traced square lights do not cover the texels".into());
            }
            points
                .par_iter()
                .enumerate()
                .map(|(i, point)| {
                    let mut sum = DVec3::ZERO;
                    for (light, &lit) in s.lights.iter().zip(&traced.values[i * k..(i + 1) * k]) {
                        let intensity = DVec3::new(light[4].into(), light[5].into(), light[6].into());
                        sum += intensity * f64::from(light[3]) * f64::from(lit);
                    }
                    through_fog(sum.to_array(), point.normal)
                })
                .collect()
        }
        (Surfaces::Rsl(s), _) => {
            let v = s.visibility.value.expect::<crate::rsl::shade::LightVisibility>().map_err(|e| e.to_string())?;
            let cosine = lambert_sat();
            let k = v.lights;
            if v.values.len() != points.len() * k {
                return Err("the square-light visibility does not cover the points".into());
            }
            points
                .par_iter()
                .enumerate()
                .map(|(i, point)| {
                    let to_local = crate::rsl::shade::shading_frame(point.normal, point.tangent).transpose();
                    let mut sum = DVec3::ZERO;
                    for (light, &vis) in s.lights.iter().zip(&v.values[i * k..(i + 1) * k]) {
                        if vis <= 0.0 {
                            continue;
                        }
                        let direction = DVec3::new(light[0].into(), light[1].into(), light[2].into());
                        let omega = f64::from(light[3]);
                        let intensity = DVec3::new(light[4].into(), light[5].into(), light[6].into());
                        let (cos_mean, _) = cosine.means(to_local * direction, omega, DVec3::Z);
                        sum += intensity * omega * f64::from(vis) * cos_mean;
                    }
                    through_fog(sum.to_array(), point.normal)
                })
                .collect()
        }
        _ => return Err("the mode's transport does not match its surfaces".into()),
    })
}

/// `E(n) = Σ E_lm Y_lm(n)` for irradiance coefficients `e`.
fn sh_irradiance(e: &ShRgb, normal: DVec3) -> [f64; 3] {
    e.eval(&ShBasis::new(e.bands), normal)
}

/// The square lights' `cos θ / π` table (material-independent; built once).
fn lambert_sat() -> &'static crate::rsl::brdf_sat::BrdfSat {
    static SAT: std::sync::OnceLock<crate::rsl::brdf_sat::BrdfSat> = std::sync::OnceLock::new();
    SAT.get_or_init(|| {
        let lambert = crate::brdf::Brdf::from_material(&crate::brdf::Material::default());
        crate::rsl::brdf_sat::BrdfSat::build(&lambert, &crate::engine::CancelToken::default())
            .expect("an uncancelled Lambert table")
    })
}

/// Point lights onto a Lambertian surface, through the medium when there is one (Sun 2008
/// eqs. 3.27 and 3.29 towards the surface: `e^{-β d}/d² cos θ` plus the light scattered onto
/// it, `β² G₁(βd, θ)/(2π βd)`).
struct PointLightShading<'a> {
    lights: &'a [PointLight],
    fog: Option<([f64; 3], &'a crate::single_scattering::PhongGTables)>,
}

impl<'a> PointLightShading<'a> {
    fn new(frame: &'a FrameInputs) -> Result<Self, String> {
        let fog = match &frame.medium.fog {
            Some(f) => Some((
                f.beta,
                f.g_tables.value.expect::<crate::single_scattering::PhongGTables>().map_err(|e| e.to_string())?,
            )),
            None => None,
        };
        Ok(Self { lights: &frame.medium.lights, fog })
    }

    /// `E / π` at `p` from every light.
    fn light(&self, p: &SurfacePoint, shadows: Option<&RayScene>) -> [f64; 3] {
        let mut out = [0.0; 3];
        for light in self.lights {
            let to_light = DVec3::from(light.position) - p.position;
            let d = to_light.length().max(1e-4);
            let l = to_light / d;
            let cos = l.dot(p.normal);
            let visible = cos > 0.0
                && shadows.is_none_or(|scene| {
                    let origin = scene.leave_surface(p.position, p.normal);
                    let direction = Vec3A::from(l.as_vec3());
                    let tmax = (DVec3::from(light.position) - DVec3::from(Vec3A::to_array(&origin).map(f64::from)))
                        .length() as f32;
                    !scene.occluded(origin, direction, tmax * (1.0 - 1e-4))
                });
            let intensity = light.intensity_toward(-l);
            for c in 0..3 {
                let beta = self.fog.map_or(0.0, |f| f.0[c]);
                let direct = if visible { (-beta * d).exp() / (d * d) * cos } else { 0.0 };
                let scattered = self.fog.map_or(0.0, |(_, g)| {
                    crate::single_scattering::surface_scattered(beta, d, cos.clamp(-1.0, 1.0).acos(), 1.0, g)
                });
                out[c] += intensity[c] * (direct + scattered) / PI;
            }
        }
        out
    }
}
