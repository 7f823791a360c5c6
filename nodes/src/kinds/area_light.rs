//! Area light painter: a planar light, facing down unless tilted, with a painted radiance texture
//! (`crate::light_texture`), compressed in 2D Haar for near-field relighting by affine wavelet
//! products (`crate::near_field`, Sun 2008 §4.5).
//!
//! Stages follow the notes' dirty rules (§6): a stroke reruns `texture` and `source`; a move
//! reruns `placement` (a tilted light's placement is in its own frame, [`LightFrame`], so a
//! move within its plane keeps its traced transport); resizing or turning also reruns `source` (a turned light is resampled
//! into its bounding rectangle, a 2D Haar transform of at most 128², well under a millisecond
//! at 64²). Each of these reruns `light`, which only gathers them with the intensity × tint
//! scale and the light as the reference samples it; the Output memoises each light's
//! propagation, so intensity and tint only rescale it.

use crate::engine::spec::{
    Availability, NodeKindSpec, ParamKind, ParamSpec, ParamValue, PortSpec, PortType, StageSpec,
};
use crate::engine::{StageContext, StageError, StageValue};
use crate::light_texture::{LightTexture, PaintOp, load_image, render, turned_extent};
use crate::near_field::{
    AccMode, FACE_ORDER, LightFrame, LightPlacement, LightSource, Shading, TargetKeep, TopFace, light_source,
};
use crate::picture::Preview;
use crate::reference::AreaEmitter;
use serde::{Deserialize, Serialize};

crate::stage_type!(TopFace, "top face", |_v| 16);
crate::stage_type!(LightPlacement, "area light placement", |_v| 48);
crate::stage_type!(AreaLight, "area light", |v| v.source.coefficients.len() * 16 + v.emitter.radiance.len() * 32 + 96);

/// Everything the relighting needs of one light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AreaLight {
    pub source: LightSource,
    /// The rectangle the (turned) texture was resampled into.
    pub placement: LightPlacement,
    /// Intensity × tint: the shading scales by it.
    pub scale: [f64; 3],
    pub face: TopFace,
    pub keep: TargetKeep,
    pub acc: AccMode,
    /// The light as the Monte Carlo reference samples it: the painted texture on the turned
    /// rectangle, times intensity and tint.
    pub emitter: AreaEmitter,
}

impl AreaLight {
    pub fn shading(&self) -> Shading {
        Shading { keep: self.keep, acc: self.acc }
    }
}

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "AreaLightPainter",
        label: "Area light painter",
        doc: "A planar light with a painted radiance texture, facing down or tilted, for near-field shadows and highlights \
              (affine wavelet products, Sun 2008 ch. 4). Paint, move, resize and recolour it; the texture is kept \
              as its paint operations.",
        inputs: vec![],
        outputs: vec![PortSpec { name: "area_light", ty: PortType::AreaLight, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "resolution",
                label: "Texture",
                unit: "texels",
                kind: ParamKind::Choice {
                    options: &["32", "64", "128"],
                    default: "64",
                    labels: &[
                        ("32 × 32", "coarse detail, fastest"),
                        ("64 × 64", ""),
                        ("128 × 128", "fine detail; more coefficients to keep"),
                    ],
                },
                doc: "Side of the light's texture.",
            },
            ParamSpec {
                name: "paint",
                label: "Paint",
                unit: "",
                kind: ParamKind::Paint,
                doc: "The light's paint operations in order (strokes, erase, fill, blur, imported images, warps, \
                      shapes), replayed onto a white light.",
            },
            ParamSpec {
                name: "position",
                label: "Centre",
                unit: "m",
                kind: ParamKind::Vec3 { min: -1e4, max: 1e4, default: [0.0, 2.0, 0.0] },
                doc: "Centre of the light; its plane passes through it.",
            },
            ParamSpec::float(
                "width",
                "Width",
                "m",
                (1e-3, 1e3, 1.0),
                "Extent along the light's width axis (x before a turn).",
            ),
            ParamSpec::float(
                "depth",
                "Depth",
                "m",
                (1e-3, 1e3, 1.0),
                "Extent along the light's depth axis (z before a turn).",
            ),
            ParamSpec::float("angle", "Turn", "°", (-360.0, 360.0, 0.0), "Turn about the vertical."),
            ParamSpec::float(
                "tilt",
                "Tilt",
                "°",
                (-180.0, 180.0, 0.0),
                "Tilt about the light's width axis: 0 faces straight down, 90 faces along the depth axis \
                 (toward −z before a turn), 180 faces up. A tilted light traces its own shadows (lights share \
                 them only with equal tilt and turn).",
            ),
            ParamSpec::float("intensity", "Intensity", "", (0.0, 1e6, 10.0), "Radiance scale of the texture."),
            ParamSpec {
                name: "tint",
                label: "Tint",
                unit: "",
                kind: ParamKind::Color { max: 1e3, default: [1.0, 1.0, 1.0] },
                doc: "Colour the texture is multiplied by.",
            },
            ParamSpec::float(
                "source_keep",
                "Texture detail kept",
                "%",
                (0.01, 100.0, 2.0),
                "Share of the texture's wavelet coefficients kept per channel (the largest).",
            ),
            ParamSpec::float(
                "target_keep",
                "Lighting detail kept",
                "%",
                (1.0, 100.0, 100.0),
                "Share of each receiver's top-face coefficients shaded. 100% shades them all, exactly and \
                 fastest (the face's cells summed under each light coefficient); below it, the coefficients \
                 a constant light would reach most are picked, as in the thesis, at the cost of the coupling \
                 coefficients.",
            ),
            ParamSpec {
                name: "target_heuristic",
                label: "Pick lighting detail by",
                unit: "",
                kind: ParamKind::Choice {
                    options: &["prediction", "largest"],
                    default: "prediction",
                    labels: &[
                        ("Prediction", "how a constant light would reach each receiver: skips work, fastest"),
                        ("Largest light", "the largest propagated coefficients: computes them all first"),
                    ],
                },
                doc: "How each receiver's kept top-face coefficients are picked (below 100% lighting detail).",
            },
            ParamSpec {
                name: "acc",
                label: "Couplings",
                unit: "",
                kind: ParamKind::Choice {
                    options: &["analytic", "table256", "table64"],
                    default: "analytic",
                    labels: &[
                        ("Exact", "computed at every vertex: no quantisation"),
                        ("Table 256", "snapped to a 256-step grid and shared by nearby vertices: within about 1%"),
                        ("Table 64", "a coarser grid, shared more widely: within about 3%"),
                    ],
                },
                doc: "Below 100% lighting detail, how the light's wavelets are carried to each vertex (the affine \
                      coupling coefficients): exactly, or looked up on a grid over the light's scale and offset as \
                      seen from the vertex. At 100% no coupling is computed, and a grid only shifts the light.",
            },
            ParamSpec::float(
                "face_size",
                "Face size",
                "",
                (1.0, 20.0, 4.0),
                "Width of the receivers' top face in units of height: within it the light's texture and \
                 shadows are carried exactly, beyond it in 4 × 4 cells with one shadow ray each quarter \
                 (3–4 covers a light well; larger faces resolve shadows more coarsely).",
            ),
        ],
        stages: vec![
            StageSpec {
                name: "texture",
                version: 1,
                params: &["resolution", "paint"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: texture,
            },
            StageSpec {
                name: "source",
                version: 1,
                params: &["source_keep", "angle", "width", "depth"],
                stages: &["texture"],
                inputs: &[],
                persist: None,
                compute: source,
            },
            StageSpec {
                name: "placement",
                version: 2,
                params: &["position", "width", "depth", "angle", "tilt"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: placement,
            },
            StageSpec {
                name: "face",
                version: 1,
                params: &["face_size"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: face,
            },
            StageSpec {
                name: "light",
                version: 4,
                params: &[
                    "intensity",
                    "tint",
                    "target_keep",
                    "target_heuristic",
                    "acc",
                    "position",
                    "width",
                    "depth",
                    "angle",
                    "tilt",
                ],
                stages: &["texture", "source", "placement", "face"],
                inputs: &[],
                persist: None,
                compute: light,
            },
        ],
        previews: vec![crate::engine::spec::PreviewSpec {
            stages: &["texture"],
            make: |v| Some(Preview::Image(texture_preview(v[0].get()?))),
            size: [96.0, 96.0],
            caption: "the light's emission, seen from above (auto-exposed)",
        }],
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::engine::spec::no_referenced_files,
    }
}

fn texture_preview(texture: &LightTexture) -> crate::picture::PreviewImage {
    let emission = texture.emission();
    let scale = crate::preview::auto_scale(emission.iter().copied());
    crate::picture::PreviewImage {
        width: texture.side,
        height: texture.side,
        rgba: emission.iter().map(|&c| crate::preview::display_rgb8(c, scale)).collect(),
    }
}

fn paint_log<'a>(ctx: &'a StageContext) -> Result<&'a [PaintOp], StageError> {
    match ctx.value("paint")? {
        ParamValue::Paint(ops) => Ok(ops),
        other => Err(StageError::Internal(format!("paint holds {}", other.type_name()))),
    }
}

fn texture(ctx: &StageContext) -> Result<StageValue, StageError> {
    let side: usize = ctx.choice("resolution")?.parse().map_err(|_| StageError::Internal("resolution".into()))?;
    let dir = ctx.project_dir();
    let texture = render(paint_log(ctx)?, side, &mut |path| load_image(&dir.join(path))).map_err(StageError::Failed)?;
    Ok(StageValue::new(texture))
}

/// The emission resampled into the turned light's bounding rectangle (zero outside the light),
/// then in 2D Haar with the largest coefficients kept.
fn source(ctx: &StageContext) -> Result<StageValue, StageError> {
    let texture = ctx.stage::<LightTexture>("texture")?;
    let (width, depth, angle) = (ctx.float("width")?, ctx.float("depth")?, ctx.float("angle")?);
    let n = texture.side;
    let turned = texture.turned(width, depth, angle);
    let keep = ((ctx.float("source_keep")? / 100.0 * (n * n) as f64).ceil() as usize).clamp(1, n * n);
    let source = light_source(&turned, n, keep);
    ctx.inform(format!(
        "{} of {} coefficients kept per channel: {:.2}% of the texture's energy",
        keep,
        n * n,
        100.0 * source.retained_energy
    ));
    Ok(StageValue::new(source))
}

fn placement(ctx: &StageContext) -> Result<StageValue, StageError> {
    let angle = ctx.float("angle")?;
    let extent = turned_extent(ctx.float("width")?, ctx.float("depth")?, angle);
    let frame = LightFrame::new(angle, ctx.float("tilt")?);
    Ok(StageValue::new(LightPlacement::oriented(ctx.vec3("position")?, extent, frame)))
}

/// The receivers' top face: lights with equal faces share the Output's transport.
fn face(ctx: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(TopFace { order: FACE_ORDER, size: ctx.float("face_size")? }))
}

fn light(ctx: &StageContext) -> Result<StageValue, StageError> {
    let intensity = ctx.float("intensity")?;
    let tint = ctx.vec3("tint")?;
    let target = ctx.float("target_keep")?;
    let keep = match (target >= 100.0, ctx.choice("target_heuristic")?) {
        (true, _) => TargetKeep::All,
        (false, "largest") => TargetKeep::Largest(target / 100.0),
        (false, _) => TargetKeep::Predicted(target / 100.0),
    };
    let acc = match ctx.choice("acc")? {
        "table256" => AccMode::Table(256),
        "table64" => AccMode::Table(64),
        _ => AccMode::Analytic,
    };
    let texture = ctx.stage::<LightTexture>("texture")?;
    let scale = tint.map(|t| t * intensity);
    let radiance = texture.emission().into_iter().map(|c| std::array::from_fn(|i| c[i] * scale[i])).collect();
    let shape = (ctx.float("width")?, ctx.float("depth")?, ctx.float("angle")?);
    let emitter = AreaEmitter::new(ctx.vec3("position")?, shape, texture.side, radiance).tilted(ctx.float("tilt")?);
    Ok(StageValue::new(AreaLight {
        source: ctx.stage::<LightSource>("source")?.clone(),
        placement: *ctx.stage::<LightPlacement>("placement")?,
        scale,
        face: *ctx.stage::<TopFace>("face")?,
        keep,
        acc,
        emitter,
    }))
}
