//! Per-vertex shading with square lights (Xu et al. 2006 Eq. 5, in the consistent form of
//! notes §4): `B = Σᵢ Iᵢ Ωᵢ · ρ̄ᵢ · V̄ᵢ`, with `ρ̄ᵢ` the mean of `ρ cos θ` over the light's
//! square ([`super::brdf_sat`]) and `V̄ᵢ` its visible fraction ([`super::vdt`]).
//!
//! The split between CPU and GPU: [`light_visibility`] computes `V̄` per vertex and light
//! (it changes with the lights' directions and the objects' poses, never with the camera or a
//! BRDF edit); the GPU sums `Iᵢ Ωᵢ ρ̄ᵢ V̄ᵢ` per vertex with the view-dependent BRDF lookups
//! (`shaders/mesh_rsl.wgsl`). [`shade`] is the same sum on the CPU, for tests and references.

use super::brdf_sat::BrdfSat;
use super::ovdf::ObjectOvdf;
use super::plane::{square_edge, to_plane};
use super::vdt::{ObjectSvdf, Ramp, visible_fraction};
use super::{SquareLight, WorldLights};
use crate::engine::{CancelToken, StageError};
use glam::{DMat3, DMat4, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

crate::stage_type!(LightVisibility, "square-light visibility", |v| v.values.len() * 4);

/// `V̄` per vertex and light, vertex-major (`values[vertex · lights + light]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LightVisibility {
    pub lights: usize,
    pub vertices: usize,
    pub values: Vec<f32>,
}

/// The shading frame `[t, n × t, n]` (columns) from a normal and a tangent, as the renderer
/// builds it.
pub fn shading_frame(normal: DVec3, tangent: DVec3) -> DMat3 {
    let n = normal.normalize_or(DVec3::Y);
    let t = (tangent - n * n.dot(tangent)).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
    DMat3::from_cols(t, n.cross(t), n)
}

/// `V̄` of every light at every vertex of `objects` (in scene order), with the objects at their
/// current poses: the self-visibility table times every other object's occluder field (Eq. 5
/// averages each occluder separately and multiplies). A light's world direction is taken into
/// an object's space as `M⁻¹ c` (normalised), a vertex into an occluder's as `M_J⁻¹ x`.
/// `occluders[j]` is object `j`'s field (it does not shadow itself); fields beyond the objects
/// belong to occluders that receive no shading.
pub fn light_visibility(
    objects: &[ObjectSvdf],
    occluders: &[ObjectOvdf],
    lights: &WorldLights,
    ramp: Ramp,
    cancel: &CancelToken,
) -> Result<LightVisibility, StageError> {
    let k = lights.lights.len();
    // Each occluder: object-from-world (affine and linear) and the lights in its space.
    let fields: Vec<(DMat4, Vec<DVec3>)> = occluders
        .iter()
        .map(|o| {
            let world_from_object = DMat4::from_cols_array(&o.world_from_object);
            let linear = DMat3::from_mat4(world_from_object).inverse();
            let directions =
                lights.lights.iter().map(|l| (linear * DVec3::from(l.direction)).normalize_or(DVec3::Z)).collect();
            (world_from_object.inverse(), directions)
        })
        .collect();
    let mut values = Vec::new();
    for (index, object) in objects.iter().enumerate() {
        cancel.check()?;
        let world_from_object = DMat4::from_cols_array(&object.world_from_object);
        let linear = DMat3::from_mat4(world_from_object);
        let object_from_world = linear.inverse();
        let directions: Vec<(DVec3, f64)> = lights
            .lights
            .iter()
            .map(|l| {
                let d = (object_from_world * DVec3::from(l.direction)).normalize_or(DVec3::Z);
                (d, square_edge(l.solid_angle))
            })
            .collect();
        let svdf = &object.svdf;
        let fields = &fields;
        let directions = &directions;
        let rows: Vec<f32> = (0..svdf.vertices)
            .into_par_iter()
            .flat_map_iter(|v| {
                let to_local = svdf.frame(v).transpose();
                let world = world_from_object.transform_point3(DVec3::from(svdf.positions[v].map(f64::from)));
                directions
                    .iter()
                    .enumerate()
                    .map(move |(i, &(d, edge))| {
                        let p = to_plane(to_local * d);
                        let mut visible = visible_fraction(svdf.distance(v, p), edge, ramp);
                        for (j, (object_from_world, occluder_directions)) in fields.iter().enumerate() {
                            if j == index || visible <= 0.0 {
                                continue;
                            }
                            let x = object_from_world.transform_point3(world);
                            let omega = lights.lights[i].solid_angle;
                            visible *= occluders[j].ovdf.visible_fraction(x, occluder_directions[i], omega, ramp);
                        }
                        visible as f32
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        values.extend(rows);
    }
    Ok(LightVisibility { lights: k, vertices: objects.iter().map(|o| o.svdf.vertices).sum(), values })
}

/// One light's contribution `I Ω ρ̄ V̄` at a vertex with shading frame `frame`, seen from the
/// world direction `view`.
pub fn light_term(sat: &BrdfSat, light: &SquareLight, visibility: f64, frame: DMat3, view: DVec3) -> DVec3 {
    if visibility <= 0.0 {
        return DVec3::ZERO;
    }
    let to_local = frame.transpose();
    let c = to_local * DVec3::from(light.direction);
    let brdf = sat.mean(c, light.solid_angle, to_local * view);
    DVec3::from(light.intensity) * light.solid_angle * visibility * brdf
}

/// Outgoing radiance at a vertex: `Σᵢ Iᵢ Ωᵢ ρ̄ᵢ V̄ᵢ` (`visibility` is the vertex's row).
pub fn shade(sat: &BrdfSat, lights: &[SquareLight], visibility: &[f32], frame: DMat3, view: DVec3) -> DVec3 {
    lights.iter().zip(visibility).map(|(l, &v)| light_term(sat, l, f64::from(v), frame, view)).sum()
}
