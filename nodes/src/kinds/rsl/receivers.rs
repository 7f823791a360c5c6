//! What the `rsl` mode precomputes on the scenes and materials it draws (Xu et al. 2006 §4.2–4.3),
//! added to every kind that offers a scene or a material ([`extensions`]): the per-object
//! self-visibility and occluder fields, and each material's summed-area tables. They live with
//! the technique, not in those kinds.

use crate::engine::spec::{ParamKind, ParamSpec, ParamValue, PortType, StageExtension, StageSpec};
use crate::engine::{StageContext, StageError, StageValue};
use crate::kinds::scene::{check_ray_budget, per_object_memo};
use crate::raycast::RayScene;
use crate::transport::Receivers;

/// The stages (and the parameter) the `rsl` mode adds to scenes and materials.
pub fn extensions() -> Vec<StageExtension> {
    vec![
        StageExtension {
            on: PortType::Scene,
            params: vec![ParamSpec {
                name: "occluder_resolution",
                label: "Occluder field resolution",
                unit: "px",
                kind: ParamKind::Choice { options: &["8", "16", "32"], default: "8", labels: &[] },
                doc: "Square-light mode: cube texels per face on each of the 16 shells around every object where \
                      its shadow on others is sampled (the paper uses 32; each step up is 4x the rays).",
            }],
            stages: vec![
                StageSpec {
                    name: "rsl_self_visibility",
                    version: 1,
                    params: &["objects", "tessellation"],
                    stages: &[],
                    inputs: &[],
                    persist: None,
                    compute: rsl_self_visibility,
                },
                StageSpec {
                    name: "rsl_occluders",
                    version: 1,
                    params: &["objects", "tessellation", "occluder_resolution"],
                    stages: &[],
                    inputs: &[],
                    persist: None,
                    compute: rsl_occluders,
                },
            ],
        },
        StageExtension {
            on: PortType::Material,
            params: vec![],
            stages: vec![StageSpec {
                name: "rsl_tables",
                version: 1,
                params: &[],
                stages: &["material"],
                inputs: &[],
                persist: None,
                compute: rsl_tables,
            }],
        },
    ]
}

/// Per-object self-visibility distance tables for the `rsl` mode (Xu et al. §4.3.1, Eq. 10),
/// in each object's object space and memoised on its shape: moving, turning or recolouring an
/// object casts no ray (the report counts the memo hits).
fn rsl_self_visibility(ctx: &StageContext) -> Result<StageValue, StageError> {
    let ParamValue::Objects(objects) = ctx.value("objects")? else {
        return Err(StageError::Internal("objects".into()));
    };
    let size = crate::rsl::vdt::VDT_SIZE;
    // Rays per vertex: the work is the vertices.
    let vertices = |meshes: &[crate::mesh::Mesh]| meshes.iter().map(|m| m.positions.len()).sum::<usize>() as f64;
    let tables = per_object_memo(ctx, objects, &format!("svdf v1 {size}"), vertices, |object, meshes, progress| {
        let scene = RayScene::build(meshes);
        let receivers = Receivers::from_meshes(meshes);
        check_ray_budget(receivers.len(), size * size, "tessellation")?;
        let bytes = (receivers.len() * size * size) as u64;
        if bytes > crate::limits::MAX_RSL_TABLE_BYTES {
            return Err(StageError::Failed(format!(
                "object `{}`: its self-visibility tables would take {} MiB ({} vertices × {} KiB); the limit is {} \
                 MiB: lower tessellation",
                object.name,
                bytes >> 20,
                receivers.len(),
                size * size / 1024,
                crate::limits::MAX_RSL_TABLE_BYTES >> 20
            )));
        }
        crate::rsl::vdt::Svdf::compute(&scene, &receivers, size, ctx.cancel_token(), progress)
    })?;
    let out: Vec<_> = objects
        .iter()
        .zip(tables)
        .map(|(object, svdf)| crate::rsl::vdt::ObjectSvdf {
            name: object.name.clone(),
            world_from_object: object.transform().to_cols_array(),
            svdf,
        })
        .collect();
    Ok(StageValue::new(out))
}

/// Per-object occluder fields for the `rsl` mode (Xu et al. §4.3.2, Eq. 11): how each object
/// shadows the others, in its object space and memoised on its shape, so moves cast no ray.
fn rsl_occluders(ctx: &StageContext) -> Result<StageValue, StageError> {
    let ParamValue::Objects(objects) = ctx.value("objects")? else {
        return Err(StageError::Internal("objects".into()));
    };
    let face: usize =
        ctx.choice("occluder_resolution")?.parse().map_err(|_| StageError::Internal("resolution".into()))?;
    let table = crate::rsl::vdt::VDT_SIZE;
    // Alone, an object shadows nothing else.
    if objects.len() < 2 {
        return Ok(StageValue::new(Vec::<crate::rsl::ovdf::ObjectOvdf>::new()));
    }
    // The same rays per object whatever its mesh.
    let fields = per_object_memo(
        ctx,
        objects,
        &format!("ovdf v1 {face} {table}"),
        |_| 1.0,
        |_, meshes, progress| {
            check_ray_budget(crate::rsl::ovdf::SHELLS * 6 * face * face, table * table, "occluder_resolution")?;
            let bounds = crate::rsl::ovdf::bounding_sphere(meshes);
            crate::rsl::ovdf::Ovdf::compute(&RayScene::build(meshes), bounds, face, table, ctx.cancel_token(), progress)
        },
    )?;
    let out: Vec<_> = objects
        .iter()
        .zip(fields)
        .map(|(object, ovdf)| crate::rsl::ovdf::ObjectOvdf {
            name: object.name.clone(),
            world_from_object: object.transform().to_cols_array(),
            ovdf,
        })
        .collect();
    Ok(StageValue::new(out))
}

/// Summed-area tables of `ρ cos θ` over the equal-area plane for the `rsl` mode (Xu et al.
/// §4.2): 3D for isotropic lobes, 4D for anisotropic ones. Rebuilt on a BRDF edit only.
fn rsl_tables(ctx: &StageContext) -> Result<StageValue, StageError> {
    let m = ctx.stage::<crate::brdf::Material>("material")?;
    let brdf = crate::brdf::Brdf::from_material(m);
    Ok(StageValue::new(crate::rsl::brdf_sat::BrdfSat::build(&brdf, ctx.cancel_token())?))
}
