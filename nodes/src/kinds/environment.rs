//! Environment map node: an equirect HDR file or the procedural sky, as radiance cube map,
//! SH (Sun 2008 eq. 2.12) and cube-map Haar wavelets (Ng et al.). Rotating the environment
//! re-resamples the cube map and rotates the SH (per-band matrices); it never re-projects the
//! unrotated SH.

use crate::cubemap::{CubeMap, Equirect};
use crate::engine::spec::PreviewSpec;
use crate::engine::spec::{Availability, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, StageSpec};
use crate::engine::{StageContext, StageError, StageValue};
use crate::preview::{self, Preview};
use crate::sh::{self, ShRotation};
use crate::sky::ProceduralSky;
use crate::wavelet::SparseVector;
use crate::wavelet::cube_haar::CubeHaar;
use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(WaveletLighting, "wavelet", |v| v.channels.iter().map(|c| c.len() * 16).sum());
crate::stage_type!(DMat3, "rotation");
crate::stage_type!(RadianceScale, "radiance scale");
crate::stage_type!(crate::sun::SunSplit, "sun and residual sky", |v| v.residual.texels.len() * 12 + 64);

/// Exposure and tint as one factor per RGB channel (`2^exposure · tint`): what consumers that
/// keep the unscaled source (the RSL decomposer) multiply in, O(1) per edit.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RadianceScale(pub [f64; 3]);

/// Sparse Haar lighting per colour channel.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WaveletLighting {
    pub size: usize,
    pub channels: [SparseVector; 3],
}

pub const RESOLUTIONS: &[&str] = &["16", "32", "64", "128", "256", "512"];

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "EnvironmentMap",
        label: "Environment map",
        doc: "Distant HDR lighting from an equirectangular .exr/.hdr file or the built-in sky.",
        inputs: vec![],
        outputs: vec![PortSpec { name: "environment", ty: PortType::Environment, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "source",
                label: "Source",
                unit: "",
                kind: ParamKind::Choice {
                    options: &["procedural_sky", "file"],
                    default: "procedural_sky",
                    labels: &[],
                },
                doc: "Built-in sky with sun, or an image file.",
            },
            ParamSpec {
                name: "file",
                label: "File",
                unit: "",
                kind: ParamKind::Path { extensions: &["exr", "hdr"], selects: Some(("source", "file")) },
                doc: "Equirectangular image, relative to the project.",
            },
            ParamSpec {
                name: "sun_elevation",
                label: "Sun elevation",
                unit: "deg",
                kind: ParamKind::Float { min: -10.0, max: 90.0, default: 35.0 },
                doc: "Procedural sky only.",
            },
            ParamSpec {
                name: "sun_azimuth",
                label: "Sun azimuth",
                unit: "deg",
                kind: ParamKind::Float { min: -180.0, max: 180.0, default: 40.0 },
                doc: "Procedural sky only; 0 is -Z, 90 is +X.",
            },
            ParamSpec {
                name: "sun_intensity",
                label: "Sun radiance",
                unit: "",
                kind: ParamKind::Float { min: 0.0, max: 1e6, default: 400.0 },
                doc: "Procedural sky only.",
            },
            ParamSpec {
                name: "sun_size",
                label: "Sun radius",
                unit: "deg",
                kind: ParamKind::Float { min: 0.1, max: 20.0, default: 2.5 },
                doc: "Procedural sky only.",
            },
            ParamSpec {
                name: "rotation",
                label: "Rotation (yaw, pitch, roll)",
                unit: "deg",
                kind: ParamKind::Vec3 { min: -360.0, max: 360.0, default: [0.0; 3] },
                doc: "R = Ry(yaw) Rx(pitch) Rz(roll); the lighting is turned by R.",
            },
            ParamSpec {
                name: "exposure",
                label: "Exposure",
                unit: "EV",
                kind: ParamKind::Float { min: -20.0, max: 20.0, default: 0.0 },
                doc: "Scales radiance by 2^EV.",
            },
            ParamSpec {
                name: "tint",
                label: "Tint",
                unit: "",
                kind: ParamKind::Color { max: 100.0, default: [1.0; 3] },
                doc: "Multiplies radiance per channel.",
            },
            ParamSpec {
                name: "resolution",
                label: "Cube face size",
                unit: "px",
                kind: ParamKind::Choice { options: RESOLUTIONS, default: "64", labels: &[] },
                doc: "Resolution of the radiance cube map (and its wavelets).",
            },
            ParamSpec {
                name: "sh_bands",
                label: "SH bands",
                unit: "",
                kind: ParamKind::Int { min: 1, max: 16, default: 6 },
                doc: "Bands of the SH projection (N bands = N² coefficients). The SH modes light with \
                      the fewer of these and the scene's transport bands (6 by default): on lights \
                      near the horizon, an up-facing surface's irradiance converges slowly in the \
                      bands (a studio HDRI's floor: 1.22 times the truth through band 2, 1.10 through \
                      band 4, 1.07 through band 6; N bands reach band N - 1).",
            },
            ParamSpec {
                name: "wavelet_terms",
                label: "Wavelet terms",
                unit: "",
                kind: ParamKind::Int { min: 1, max: 1 << 20, default: 256 },
                doc: "Haar coefficients kept per channel (largest area-weighted).",
            },
        ],
        stages: vec![
            StageSpec {
                name: "source",
                version: 1,
                params: &["source", "file", "sun_elevation", "sun_azimuth", "sun_intensity", "sun_size"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: source,
            },
            StageSpec {
                name: "radiance",
                version: 1,
                params: &["exposure", "tint", "resolution"],
                stages: &["source"],
                inputs: &[],
                persist: None,
                compute: radiance,
            },
            StageSpec {
                name: "radiance_scale",
                version: 1,
                params: &["exposure", "tint"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: radiance_scale,
            },
            StageSpec {
                name: "sh_unrotated",
                version: 1,
                params: &["sh_bands"],
                stages: &["radiance"],
                inputs: &[],
                persist: None,
                compute: sh_unrotated,
            },
            StageSpec {
                name: "rotation",
                version: 1,
                params: &["rotation"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: rotation,
            },
            StageSpec {
                name: "rotated_radiance",
                version: 1,
                params: &["rotation"],
                stages: &["radiance"],
                inputs: &[],
                persist: None,
                compute: rotated_radiance,
            },
            StageSpec {
                name: "sh",
                version: 1,
                params: &["rotation"],
                stages: &["sh_unrotated"],
                inputs: &[],
                persist: None,
                compute: sh_rotated,
            },
            StageSpec {
                name: "source_sun",
                version: 1,
                params: &["resolution"],
                stages: &["source"],
                inputs: &[],
                persist: None,
                compute: source_sun,
            },
            StageSpec {
                name: "sun",
                version: 2,
                params: &["exposure", "tint"],
                stages: &["source_sun"],
                inputs: &[],
                persist: None,
                compute: sun,
            },
            StageSpec {
                name: "residual_sh_unrotated",
                version: 1,
                params: &["sh_bands"],
                stages: &["sun"],
                inputs: &[],
                persist: None,
                compute: residual_sh_unrotated,
            },
            StageSpec {
                name: "residual_sh",
                version: 1,
                params: &["rotation"],
                stages: &["residual_sh_unrotated"],
                inputs: &[],
                persist: None,
                compute: residual_sh_rotated,
            },
            StageSpec {
                name: "highlight_cube",
                version: 1,
                params: &[],
                stages: &["rotated_radiance"],
                inputs: &[],
                persist: None,
                compute: highlight_cube,
            },
            StageSpec {
                name: "residual_highlight_cube",
                version: 1,
                params: &["rotation"],
                stages: &["sun"],
                inputs: &[],
                persist: None,
                compute: residual_highlight_cube,
            },
            StageSpec {
                name: "haar",
                version: 1,
                params: &["wavelet_terms"],
                stages: &["rotated_radiance"],
                inputs: &[],
                persist: None,
                compute: haar,
            },
        ],
        previews: vec![
            PreviewSpec {
                stages: &["rotated_radiance"],
                make: |v| Some(Preview::Image(preview::environment_thumbnail(v[0].get()?, 192, 96))),
                size: [128.0, 64.0],
                caption: "environment (auto-exposed)",
            },
            PreviewSpec {
                stages: &["sh"],
                make: |v| Some(Preview::Image(preview::sh_lighting_sphere(v[0].get()?, 96))),
                size: [64.0, 64.0],
                caption: "SH lighting on a white diffuse sphere (auto-exposed)",
            },
        ],
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::engine::spec::no_referenced_files,
    }
}

/// Equirect images wider than this are box-filtered down on load (with a warning).
pub const MAX_EQUIRECT_WIDTH: usize = 4096;

/// Box-filters an image wider than `max_width` down by a power of two (nothing downstream
/// resolves more than a 512² cube face, ≈ 2048 equirect pixels across), with a note saying so.
pub fn fit_width(image: Equirect, max_width: usize) -> (Equirect, Option<String>) {
    if image.width <= max_width {
        return (image, None);
    }
    let factor = image.width.div_ceil(max_width).next_power_of_two();
    let small = image.downsample(factor);
    let note = format!(
        "{}x{} is larger than needed; downsampled (box filter) to {}x{}",
        image.width, image.height, small.width, small.height
    );
    (small, Some(note))
}

/// `R = Ry(yaw) Rx(pitch) Rz(roll)` from degrees.
pub fn rotation_matrix(yaw_pitch_roll_deg: [f64; 3]) -> DMat3 {
    let [y, p, r] = yaw_pitch_roll_deg.map(f64::to_radians);
    DMat3::from_rotation_y(y) * DMat3::from_rotation_x(p) * DMat3::from_rotation_z(r)
}

fn source(ctx: &StageContext) -> Result<StageValue, StageError> {
    match ctx.choice("source")? {
        "file" => {
            let path =
                ctx.path("file")?.ok_or_else(|| StageError::Failed("source is `file` but no file is set".into()))?;
            let loaded = crate::envmap_io::load_equirect(&path).map_err(|e| StageError::Failed(e.to_string()))?;
            for w in &loaded.warnings {
                ctx.warn(w.clone());
            }
            let (image, note) = fit_width(loaded.image, MAX_EQUIRECT_WIDTH);
            if let Some(note) = note {
                ctx.warn(note);
            }
            Ok(StageValue::new(image))
        }
        _ => {
            let (elevation, azimuth) =
                (ctx.float("sun_elevation")?.to_radians(), ctx.float("sun_azimuth")?.to_radians());
            let sun = DVec3::new(elevation.cos() * azimuth.sin(), elevation.sin(), -elevation.cos() * azimuth.cos());
            let intensity = ctx.float("sun_intensity")?;
            let sky = ProceduralSky {
                sun_direction: sun.to_array(),
                sun_radius_deg: ctx.float("sun_size")?,
                sun_radiance: [intensity, intensity * 0.925, intensity * 0.8],
                ..ProceduralSky::default()
            };
            Ok(StageValue::new(crate::cubemap::Equirect::from_fn(512, 256, 3, |d| sky.radiance(d))))
        }
    }
}

fn radiance_scale(ctx: &StageContext) -> Result<StageValue, StageError> {
    let scale = 2f64.powf(ctx.float("exposure")?);
    let tint = ctx.vec3("tint")?;
    Ok(StageValue::new(RadianceScale(tint.map(|t| t * scale))))
}

fn radiance(ctx: &StageContext) -> Result<StageValue, StageError> {
    let image = ctx.stage::<crate::cubemap::Equirect>("source")?;
    let size: usize = ctx.choice("resolution")?.parse().map_err(|_| StageError::Internal("resolution".into()))?;
    let scale = 2f64.powf(ctx.float("exposure")?);
    let tint = ctx.vec3("tint")?;
    let mut cube = image.to_cubemap(size);
    for t in &mut cube.texels {
        for c in 0..3 {
            t[c] = (t[c] as f64 * scale * tint[c]) as f32;
        }
    }
    Ok(StageValue::new(cube))
}

fn sh_unrotated(ctx: &StageContext) -> Result<StageValue, StageError> {
    let cube = ctx.stage::<crate::cubemap::CubeMap>("radiance")?;
    Ok(StageValue::new(sh::project_samples(ctx.int("sh_bands")? as usize, cube.samples())))
}

/// The rotation `R` (column-major): the rotated environment is `L'(d) = L(R⁻¹ d)`. Consumers
/// that can rotate their query instead of the map (the wavelet modes' frame table) read it with
/// the unrotated `radiance`, so a rotation rebuilds nothing.
fn rotation(ctx: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(rotation_matrix(ctx.vec3("rotation")?)))
}

/// The unrotated map's dominant light as a disc, and the sky without it ([`crate::sun`]).
/// The split of the radiance: the source's split (`source_sun`) with exposure and tint applied,
/// so the sun the Output lights apart is the very one the square lights' sky lacks.
fn sun(ctx: &StageContext) -> Result<StageValue, StageError> {
    let scale = 2f64.powf(ctx.float("exposure")?);
    let tint = ctx.vec3("tint")?;
    let split = ctx.stage::<crate::sun::SunSplit>("source_sun")?;
    Ok(StageValue::new(split.scaled(tint.map(|t| t * scale))))
}

/// The sun split of the source before exposure and tint (the same texels as `sun`'s, up to
/// that scale): what a decomposition that must not rerun on an exposure edit reads.
fn source_sun(ctx: &StageContext) -> Result<StageValue, StageError> {
    let image = ctx.stage::<crate::cubemap::Equirect>("source")?;
    let size: usize = ctx.choice("resolution")?.parse().map_err(|_| StageError::Internal("resolution".into()))?;
    Ok(StageValue::new(crate::sun::split(&image.to_cubemap(size))))
}

fn residual_sh_unrotated(ctx: &StageContext) -> Result<StageValue, StageError> {
    let split = ctx.stage::<crate::sun::SunSplit>("sun")?;
    Ok(StageValue::new(sh::project_samples(ctx.int("sh_bands")? as usize, split.residual.samples())))
}

fn residual_sh_rotated(ctx: &StageContext) -> Result<StageValue, StageError> {
    let sh = ctx.stage::<crate::sh::ShRgb>("residual_sh_unrotated")?;
    let rotation = rotation_matrix(ctx.vec3("rotation")?);
    Ok(StageValue::new(ShRotation::new(sh.bands, rotation).apply_rgb(sh)))
}

fn rotated_radiance(ctx: &StageContext) -> Result<StageValue, StageError> {
    let cube = ctx.stage::<crate::cubemap::CubeMap>("radiance")?;
    Ok(StageValue::new(rotated(cube, ctx.vec3("rotation")?)))
}

/// `cube` turned by the rotation of `yaw_pitch_roll_deg`: `L'(d) = L(R⁻¹ d)`, box-filtered (a
/// copy where there is none).
fn rotated(cube: &CubeMap, yaw_pitch_roll_deg: [f64; 3]) -> CubeMap {
    if yaw_pitch_roll_deg == [0.0; 3] {
        return cube.clone();
    }
    let inverse = rotation_matrix(yaw_pitch_roll_deg).transpose();
    CubeMap::from_fn(cube.size, 2, |d| cube.sample(inverse * d))
}

fn sh_rotated(ctx: &StageContext) -> Result<StageValue, StageError> {
    let sh = ctx.stage::<crate::sh::ShRgb>("sh_unrotated")?;
    let rotation = rotation_matrix(ctx.vec3("rotation")?);
    Ok(StageValue::new(ShRotation::new(sh.bands, rotation).apply_rgb(sh)))
}

/// Faces of the GGX-prefiltered cubes a normal-mapped surface's per-vertex highlight is
/// corrected with (`frame::VertexHighlight`): six roughness levels, 128² down to 4².
pub const HIGHLIGHT_CUBE_SIZE: usize = 128;

/// The rotated radiance, GGX-prefiltered ([`crate::specular_cube`]).
fn highlight_cube(ctx: &StageContext) -> Result<StageValue, StageError> {
    let cube = ctx.stage::<CubeMap>("rotated_radiance")?;
    Ok(StageValue::new(crate::specular_cube::prefilter(cube, HIGHLIGHT_CUBE_SIZE, ctx.cancel_token())?))
}

/// The rotated sky without its sun (what the transport carries with the sun lit apart),
/// GGX-prefiltered.
fn residual_highlight_cube(ctx: &StageContext) -> Result<StageValue, StageError> {
    let split = ctx.stage::<crate::sun::SunSplit>("sun")?;
    let sky = rotated(&split.residual, ctx.vec3("rotation")?);
    Ok(StageValue::new(crate::specular_cube::prefilter(&sky, HIGHLIGHT_CUBE_SIZE, ctx.cancel_token())?))
}

fn haar(ctx: &StageContext) -> Result<StageValue, StageError> {
    let cube = ctx.stage::<crate::cubemap::CubeMap>("rotated_radiance")?;
    let keep = ctx.int("wavelet_terms")? as usize;
    let transform = CubeHaar::new(cube.size);
    let channels = [0, 1, 2].map(|c| {
        let values: Vec<f64> = cube.texels.iter().map(|t| t[c] as f64).collect();
        transform.approximate(&values, keep)
    });
    Ok(StageValue::new(WaveletLighting { size: cube.size, channels }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oversized_images_are_downsampled_keeping_their_energy() {
        let image = Equirect::from_fn(64, 32, 1, |d| [1.0 + d.y.max(0.0) * 5.0, 0.5, d.x.abs()]);
        let (same, note) = fit_width(image.clone(), 64);
        assert!(note.is_none() && same == image);
        let (small, note) = fit_width(image.clone(), 20);
        assert_eq!((small.width, small.height), (16, 8));
        assert!(note.unwrap().contains("64x32") && small.width == 16);
        let energy = |e: &Equirect| e.samples().map(|(_, w, l)| w * l[0]).sum::<f64>();
        assert!((energy(&small) - energy(&image)).abs() < 1e-6 * energy(&image));
    }
}
