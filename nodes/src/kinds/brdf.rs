//! BRDF editor node: the material's parameters, its lobe preview, its SH projection (the zonal
//! lobe the `sh_prt` mode convolves with) and the material tabulated in the local frame for the
//! triple product modes (Ma et al. §3.2; `triple_product::tabulate_brdf`).

pub use crate::brdf::{Material, Model};
use crate::engine::spec::PreviewSpec;
use crate::engine::spec::{Availability, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, StageSpec};
use crate::engine::{StageContext, StageError, StageValue};
use crate::picture::Preview;

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "BrdfEditor",
        label: "BRDF editor",
        doc: "Analytic BRDFs: Lambert, Phong, Blinn-Phong, GGX (isotropic/anisotropic), Ward; an optional normal map, filtered by its normal distribution at every distance.",
        inputs: vec![],
        outputs: vec![PortSpec { name: "material", ty: PortType::Material, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "model",
                label: "Model",
                unit: "",
                kind: ParamKind::Choice { options: Model::NAMES, default: "lambert", labels: &[] },
                doc: "BRDF model.",
            },
            ParamSpec {
                name: "albedo",
                label: "Albedo",
                unit: "",
                kind: ParamKind::Color { max: 1.0, default: [0.8; 3] },
                doc: "Diffuse reflectance.",
            },
            ParamSpec {
                name: "specular",
                label: "Specular colour",
                unit: "",
                kind: ParamKind::Color { max: 1.0, default: [1.0; 3] },
                doc: "Tint of the specular lobe (its strength is Fresnel F0).",
            },
            ParamSpec::float(
                "roughness",
                "Roughness",
                "",
                (0.01, 1.0, 0.4),
                "GGX/Ward roughness (alpha = roughness²).",
            ),
            ParamSpec::float("exponent", "Exponent", "", (1.0, 10000.0, 64.0), "Phong/Blinn-Phong exponent."),
            ParamSpec::float(
                "anisotropy",
                "Anisotropy",
                "",
                (-1.0, 1.0, 0.0),
                "Stretch of the lobe along the tangent.",
            ),
            ParamSpec::float(
                "f0",
                "Fresnel F0",
                "",
                (0.0, 1.0, 0.04),
                "Specular reflectance at normal incidence: Schlick's Fresnel for GGX, the lobe's weight for Phong, Blinn-Phong and Ward.",
            ),
        ]
        .into_iter()
        .chain(super::brdf_normal_map::params())
        .collect(),
        stages: vec![
            StageSpec {
                name: "material",
                version: 1,
                params: &["model", "albedo", "specular", "roughness", "exponent", "anisotropy", "f0"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: material,
            },
            StageSpec {
                name: "preview",
                version: 1,
                params: &[],
                stages: &["material"],
                inputs: &[],
                persist: None,
                compute: preview,
            },
            StageSpec {
                name: "sh_lobe",
                version: 1,
                params: &[],
                stages: &["material"],
                inputs: &[],
                persist: None,
                compute: sh_lobe,
            },
            StageSpec {
                name: "local_table",
                version: 1,
                params: &[],
                stages: &["material"],
                inputs: &[],
                persist: None,
                compute: local_table,
            },
        ]
        .into_iter()
        .chain(super::brdf_normal_map::stages())
        .collect(),
        previews: vec![PreviewSpec {
            stages: &["preview"],
            make: |v| Some(Preview::Lobe(v[0].get::<crate::brdf::LobePreview>()?.clone())),
            size: [200.0, 104.0],
            caption: "f·cos θi in the plane of incidence (each curve scaled to its peak)",
        }, super::brdf_normal_map::preview()],
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::gltf_import::referenced_files,
    }
}

/// The lobe plot and directional albedos the node shows.
fn preview(ctx: &StageContext) -> Result<StageValue, StageError> {
    let m = ctx.stage::<Material>("material")?;
    Ok(StageValue::new(crate::brdf::LobePreview::of(&crate::brdf::Brdf::from_material(m))))
}

/// The material's SH projection for the `sh_prt` mode: the zonal factors of its (equivalent)
/// Phong lobe about the mirror direction, 16 bands (empty for Lambert).
fn sh_lobe(ctx: &StageContext) -> Result<StageValue, StageError> {
    let m = ctx.stage::<Material>("material")?;
    Ok(StageValue::new(crate::prt::glossy_lobe(m, crate::prt::LOBE_BANDS).unwrap_or_default()))
}

/// The material tabulated in the local frame on 320 icosahedral cells (Ma et al. §3.2; the
/// renderer merges cells for 80).
fn local_table(ctx: &StageContext) -> Result<StageValue, StageError> {
    let m = ctx.stage::<Material>("material")?;
    let grid = crate::triple_product::CellGrid::for_coefficients(320).map_err(StageError::Internal)?;
    let brdf = crate::brdf::Brdf::from_material(m);
    Ok(StageValue::new(crate::triple_product::tabulate_brdf(&brdf, grid, ctx.cancel_token())?))
}

fn material(ctx: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(Material {
        model: ctx.option("model")?,
        albedo: ctx.vec3("albedo")?,
        specular: ctx.vec3("specular")?,
        roughness: ctx.float("roughness")?,
        exponent: ctx.float("exponent")?,
        anisotropy: ctx.float("anisotropy")?,
        f0: ctx.float("f0")?,
    }))
}
