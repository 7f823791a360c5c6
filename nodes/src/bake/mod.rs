//! Baking a project's lighting out for game engines: what `lightloom bake` and the editor's
//! File → Bake… write.
//!
//! - [`vertex_light`] — the diffuse light of the Output's mode per vertex (`E/π`).
//! - [`material_fit`] — materials as glTF metallic-roughness, with the fit's error.
//! - [`gltf_export`] — `scene.glb`.
//!
//! A bake is an engine request ([`bake_request`]): the Output's mode stages, the scene's BVH
//! (point-light shadows) and the area lights' irradiance. Everything expensive is a cached
//! stage, so a bake after an edit recomputes only what the edit touched; [`bake`] then turns
//! the evaluation into files, and [`write_atomically`] puts them in place.
//!
//! The bake's techniques sit below the node kinds, whose stages run them: [`crate::lightmap`]
//! (the atlas, texel receivers, RGBM and EXR), [`crate::probes`] (the SH probe grid) and
//! [`crate::specular_cube`] (the GGX-prefiltered environment and its KTX2 file).

pub mod baked_render;
pub mod gltf_export;
pub mod material_fit;
pub mod vertex_light;

use crate::engine::Evaluation;
use crate::engine::{Graph, Request, StageRef};
use crate::frame::FrameInputs;
use crate::frame::mode_stages;
use crate::kinds::output::{Mode, output_mode_and_view};
use crate::lightmap::{self, square_light_texels};
use crate::{probes, specular_cube};
use serde::Serialize;
use std::path::Path;

/// The glTF file a bake writes.
pub const SCENE_FILE: &str = "scene.glb";
/// The environment for image-based lighting: its SH and the specular cube's conventions, and
/// the GGX-prefiltered cube.
pub const ENVIRONMENT_JSON: &str = "environment.json";
pub const ENVIRONMENT_KTX2: &str = "environment_specular.ktx2";
/// The SH probe grid: layout and conventions, and the numbers.
pub const PROBES_JSON: &str = "probes.json";
pub const PROBES_BIN: &str = "probes.bin";
/// The lightmap as linear float RGB (`E/π`), beside the GLB.
pub const LIGHTMAP_EXR: &str = "lightmap.exr";
/// The manifest: conventions, settings, the materials' fits and the files, as JSON.
pub const MANIFEST_FILE: &str = "bake.json";

/// What baking the Output node `output` needs from the engine.
pub fn bake_request(graph: &Graph, output: &str) -> Request {
    let Some(node) = graph.node(output) else { return Request::default() };
    let (mode, _) = output_mode_and_view(node);
    let mut stages = mode_stages(graph, output, mode);
    if let Some(scene) = graph.upstream(output, "scene") {
        stages.push(StageRef::new(&scene.id, "ray_scene"));
    }
    if !graph.upstream_all(output, "area_lights").is_empty() {
        stages.push(StageRef::new(output, "area_irradiance"));
    }
    stages.push(StageRef::new(output, "bake_atlas"));
    stages.push(StageRef::new(output, "bake_probes"));
    if graph.upstream(output, "environment").is_some() {
        stages.push(StageRef::new(output, "bake_environment"));
    }
    match mode {
        Mode::ShPrt | Mode::ShAdaptive => stages.push(StageRef::new(output, "bake_texel_blocked")),
        Mode::WaveletVertex | Mode::WaveletPixel => stages.push(StageRef::new(
            output,
            if crate::kinds::output::separates_sun(graph, output, mode) {
                "bake_texel_residual_products"
            } else {
                "bake_texel_products"
            },
        )),
        Mode::Rsl => stages.push(StageRef::new(output, square_light_texels_stage(graph, output))),
        Mode::ShIrradiance => {}
    }
    if !graph.upstream_all(output, "area_lights").is_empty() {
        stages.push(StageRef::new(output, "bake_texel_area"));
    }
    Request::new(format!("bake of output `{output}` (mode {mode})"), stages)
}

/// The bake's square-light texels: of the sky without its sun when the Output lights the sun
/// apart (the bake adds it with its own shadows), else of the whole sky.
fn square_light_texels_stage(graph: &Graph, output: &str) -> &'static str {
    if crate::kinds::output::separates_sun(graph, output, Mode::Rsl) {
        "bake_texel_residual_square_lights"
    } else {
        "bake_texel_square_lights"
    }
}

/// One file of a bake.
#[derive(Clone, Debug)]
pub struct BakedFile {
    pub name: String,
    pub bytes: Vec<u8>,
}

/// Time one part of a bake took.
#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    pub stage: String,
    pub ms: f64,
}

/// The files of a bake and what they hold.
#[derive(Clone, Debug)]
pub struct Bake {
    pub files: Vec<BakedFile>,
    pub manifest: Manifest,
}

/// `bake.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Manifest {
    pub generator: String,
    pub mode: String,
    pub conventions: Conventions,
    pub materials: Vec<ManifestMaterial>,
    /// What `COLOR_0` is multiplied by to give `E/π`.
    pub vertex_light_scale: f32,
    pub lightmap: Option<ManifestLightmap>,
    /// Probes along x, y, z and their spacing (m), when baked.
    pub probes: Option<([usize; 3], f64)>,
    pub vertices: usize,
    pub triangles: usize,
    pub point_lights: usize,
    /// The square-light mode's lights, written as KHR directional lights.
    pub square_lights: usize,
    pub timings: Vec<StageTime>,
    /// `(file, bytes)`; the manifest itself is not listed.
    pub files: Vec<(String, usize)>,
}

/// The conventions every consumer needs, stated once.
#[derive(Clone, Debug, Serialize)]
pub struct Conventions {
    pub units: &'static str,
    pub axes: &'static str,
    pub vertex_light: &'static str,
    pub lightmap: &'static str,
    pub point_lights: &'static str,
}

impl Default for Conventions {
    fn default() -> Self {
        Self {
            units: "metres; radiance in the project's linear units (an environment texel's value)",
            axes: "right-handed, +Y up (glTF's)",
            vertex_light: "COLOR_0 * vertex_light_scale is linear E/pi: the radiance a white Lambertian surface \
                           reflects; the baked diffuse radiance is baseColor * COLOR_0 * vertex_light_scale (unlit). \
                           The scale (a power of two, also in the glTF scene's extras.lightloom.vertexLightScale) \
                           keeps COLOR_0 in glTF's 0..1. Environment (as the mode shadows it), area lights and \
                           point lights (shadowed) are included; fog's attenuation and airlight toward the viewer \
                           are not",
            lightmap: "TEXCOORD_1 is the lightmap UV (unwrapped with uvunwrap, charts padded, never \
                       overlapping; v down the image). Materials reference the lightmap with the \
                       LIGHTLOOM_lightmap extension: lightmapTexture (an RGBM PNG in the GLB, linear, value = rgb * \
                       a * range) and exr (the same as float RGB). Both hold E/pi like COLOR_0 * scale, per texel \
                       from the texel's own transport in the mode: blockers, area lights and point-light \
                       shadows included; square lights traced over their caps",
            point_lights: "KHR_lights_punctual intensity is the light's radiant intensity (W/sr) in the project's \
                           units (a spot's along its axis, its beam as the spot's cones; a light with a profile \
                           wider than a hemisphere, its mean intensity as a point light); their diffuse light is already baked (extras.lightloom.baked = true), so add them \
                           for specular only. In the square-light mode each square light is a directional light \
                           (intensity = radiance x solid angle, the irradiance facing it) with its solid angle and \
                           the radius of the cone of equal solid angle in extras.lightloom; its diffuse light is \
                           baked too",
        }
    }
}

/// The lightmap's layout and encoding.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestLightmap {
    pub width: u32,
    pub height: u32,
    pub texels_per_metre: f32,
    pub padding: u32,
    /// Texels with their own receiver (inside a chart).
    pub surface_texels: usize,
    pub utilization: f32,
    /// RGBM's range: `E/π = rgb × a × range` (each 0..1).
    pub rgbm_range: f32,
}

/// A material as written, with how well glTF's model fits it.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestMaterial {
    pub name: String,
    pub model: String,
    pub base_color: [f64; 3],
    pub roughness: f64,
    pub specular_factor: f64,
    pub specular_color: [f64; 3],
    pub anisotropy: Option<(f64, f64)>,
    /// Relative L2 difference of `f cos θ_i` ([`material_fit::MaterialFit::error`]).
    pub fit_error: f64,
}

/// The bake's own stages from its evaluation ([`bake_request`]).
pub struct BakedStages<'a> {
    pub probes: Option<&'a probes::ProbeGrid>,
    pub environment: Option<&'a specular_cube::EnvironmentBake>,
    pub atlas: &'a lightmap::LightmapAtlas,
    /// With the blocker spheres multiplied in.
    pub texel_sh: Option<&'a crate::transport::ShTransport>,
    pub texel_products: Option<&'a crate::triple_product::LocalProducts>,
    pub texel_square_lights: Option<&'a square_light_texels::SquareLightTexels>,
    pub texel_area: Option<&'a crate::kinds::output::area::AreaIrradiance>,
}

impl<'a> BakedStages<'a> {
    /// Reads them from `evaluation` of the Output node `output`.
    pub fn gather(evaluation: &'a Evaluation, output: &str) -> Result<Self, String> {
        fn get<'e, T: crate::engine::StageType>(
            e: &'e Evaluation,
            node: &str,
            stage: &str,
        ) -> Result<Option<&'e T>, String> {
            match e.get(node, stage) {
                None => Ok(None),
                Some(r) => match &r.value {
                    Ok(v) => v.expect::<T>().map(Some).map_err(|e| e.to_string()),
                    Err(e) => Err(format!("{node}.{stage} failed: {e}")),
                },
            }
        }
        Ok(Self {
            probes: get(evaluation, output, "bake_probes")?,
            environment: get(evaluation, output, "bake_environment")?,
            atlas: get(evaluation, output, "bake_atlas")?.ok_or("the lightmap atlas was not evaluated")?,
            texel_sh: get(evaluation, output, "bake_texel_blocked")?,
            // One of the two is requested: the residual sky's when the sun is lit apart.
            texel_products: match get(evaluation, output, "bake_texel_residual_products")? {
                Some(residual) => Some(residual),
                None => get(evaluation, output, "bake_texel_products")?,
            },
            texel_square_lights: match get(evaluation, output, "bake_texel_residual_square_lights")? {
                Some(residual) => Some(residual),
                None => get(evaluation, output, "bake_texel_square_lights")?,
            },
            texel_area: get(evaluation, output, "bake_texel_area")?,
        })
    }
}

/// Lightloom's own pictures of the baked lighting ([`baked_render`]), written beside the
/// bake as `preview_vertex.exr` and `preview_lightmap.exr` (linear radiance).
#[derive(Clone, Copy, Debug)]
pub struct PreviewRequest {
    pub camera: crate::reference::PinholeCamera,
    pub size: (usize, usize),
}

/// Turns an evaluated frame into the bake's files. `camera` is the project's render camera.
pub fn bake(
    frame: &FrameInputs,
    lightmap_inputs: Option<&BakedStages>,
    camera: Option<gltf_export::ExportCamera>,
    preview: Option<PreviewRequest>,
    progress: &dyn Fn(&str, f64),
) -> Result<Bake, String> {
    let meshes = frame.geometry.meshes.value.expect::<crate::mesh::MeshSet>().map_err(|e| e.to_string())?;
    let shadows = match &frame.ray_scene {
        Some(k) => Some(k.value.expect::<crate::raycast::RayScene>().map_err(|e| e.to_string())?),
        None => None,
    };
    let mut timings = Vec::new();
    let mut timed = |stage: &str, start: std::time::Instant| {
        timings.push(StageTime { stage: stage.into(), ms: start.elapsed().as_secs_f64() * 1e3 })
    };

    progress("vertex lighting", 0.0);
    let start = std::time::Instant::now();
    let light = vertex_light::vertex_light(frame, shadows)?;
    timed("vertex lighting", start);

    let mut files = Vec::new();
    let mut lightmap_png = Vec::new();
    let mut lightmap_range = 1.0;
    let mut lightmap_image = Vec::new();
    if let Some(inputs) = lightmap_inputs {
        progress("lightmap", 0.3);
        let start = std::time::Instant::now();
        let texels = vertex_light::texel_light(frame, inputs, shadows)?;
        let image = inputs.atlas.image(&texels);
        lightmap_image = image.clone();
        let (w, h) = (inputs.atlas.width, inputs.atlas.height);
        lightmap_range = gltf_export::vertex_light_scale(&image);
        lightmap_png = lightmap::png_bytes(&lightmap::encode_rgbm(&image, lightmap_range), w, h)?;
        files.push(BakedFile { name: LIGHTMAP_EXR.into(), bytes: lightmap::exr_bytes(&image, w, h)? });
        timed("lightmap", start);
    }

    if let (Some(request), Some(scene)) = (preview, shadows) {
        progress("previews", 0.5);
        let start = std::time::Instant::now();
        let lightmap = lightmap_inputs.map(|inputs| (inputs.atlas, lightmap_image.as_slice()));
        files.extend(previews(frame, meshes, scene, &light, lightmap, &request)?);
        timed("previews", start);
    }

    if let Some(grid) = lightmap_inputs.and_then(|i| i.probes) {
        let (json, bin) = probes::files(grid);
        files.push(BakedFile { name: PROBES_JSON.into(), bytes: json });
        files.push(BakedFile { name: PROBES_BIN.into(), bytes: bin });
    }

    if let Some(env) = lightmap_inputs.and_then(|i| i.environment) {
        files.push(BakedFile {
            name: ENVIRONMENT_JSON.into(),
            bytes: specular_cube::json_bytes(&env.sh, &env.cube, ENVIRONMENT_KTX2),
        });
        files.push(BakedFile { name: ENVIRONMENT_KTX2.into(), bytes: specular_cube::ktx2_bytes(&env.cube) });
    }

    progress("scene.glb", 0.6);
    let start = std::time::Instant::now();
    let materials: Vec<(String, crate::brdf::Material)> =
        frame.materials.iter().map(|m| (m.node.clone(), m.material.clone())).collect();
    let directional = square_lights(frame);
    let glb = gltf_export::write_glb(&gltf_export::ExportScene {
        meshes,
        vertex_light: &light,
        mesh_materials: &frame.geometry.mesh_materials,
        materials: &materials,
        lights: &frame.medium.lights,
        directional: &directional,
        camera,
        lightmap: lightmap_inputs.map(|inputs| gltf_export::ExportLightmap {
            atlas: inputs.atlas,
            png: &lightmap_png,
            range: lightmap_range,
            exr_name: LIGHTMAP_EXR,
        }),
    })?;
    timed("scene.glb", start);
    progress("done", 1.0);

    files.insert(0, BakedFile { name: SCENE_FILE.into(), bytes: glb.bytes });
    let manifest = Manifest {
        generator: format!("Lightloom {}", env!("CARGO_PKG_VERSION")),
        mode: frame.mode.to_string(),
        conventions: Conventions::default(),
        materials: glb.materials.iter().map(ManifestMaterial::of).collect(),
        vertex_light_scale: glb.vertex_light_scale,
        lightmap: lightmap_inputs.map(|inputs| ManifestLightmap {
            width: inputs.atlas.width,
            height: inputs.atlas.height,
            texels_per_metre: inputs.atlas.texels_per_metre,
            padding: inputs.atlas.padding,
            surface_texels: inputs.atlas.receivers.len(),
            utilization: inputs.atlas.utilization,
            rgbm_range: lightmap_range,
        }),
        probes: lightmap_inputs.and_then(|i| i.probes).map(|g| (g.counts, g.spacing)),
        vertices: light.len(),
        triangles: meshes.triangle_count(),
        point_lights: frame.medium.lights.len(),
        square_lights: directional.len(),
        timings,
        files: files.iter().map(|f| (f.name.clone(), f.bytes.len())).collect(),
    };
    Ok(Bake { files, manifest })
}

/// Lightloom's own pictures of the baked light (per vertex, and from the lightmap when there
/// is one), as EXR files, seen from `request`'s camera.
fn previews(
    frame: &FrameInputs,
    meshes: &crate::mesh::MeshSet,
    scene: &crate::raycast::RayScene,
    light: &[[f32; 3]],
    lightmap: Option<(&lightmap::LightmapAtlas, &[[f32; 3]])>,
    request: &PreviewRequest,
) -> Result<Vec<BakedFile>, String> {
    // The glTF's base colours: albedo × the mesh's colour, clamped to 0..1.
    let albedo: Vec<[f32; 3]> = meshes
        .meshes
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let a = frame.mesh_material(i).albedo;
            std::array::from_fn(|c| (a[c] * f64::from(m.base_color[c])).clamp(0.0, 1.0) as f32)
        })
        .collect();
    let mut pictures = vec![("preview_vertex.exr", baked_render::BakedLight::Vertex(light))];
    if let Some((atlas, image)) = lightmap {
        pictures.push(("preview_lightmap.exr", baked_render::BakedLight::Lightmap { atlas, image }));
    }
    let mut files = Vec::new();
    for (name, light) in pictures {
        let picture = baked_render::render(meshes, scene, &albedo, &light, &request.camera, request.size);
        let (w, h) = (request.size.0 as u32, request.size.1 as u32);
        files.push(BakedFile { name: name.into(), bytes: lightmap::exr_bytes(&picture.pixels, w, h)? });
    }
    Ok(files)
}

/// The rsl mode's square lights, as the directional lights the glTF carries.
fn square_lights(frame: &FrameInputs) -> Vec<gltf_export::DirectionalLight> {
    match &frame.surfaces {
        crate::frame::Surfaces::Rsl(s) => s
            .lights
            .iter()
            .map(|l| gltf_export::DirectionalLight {
                direction: [l[0], l[1], l[2]].map(f64::from),
                solid_angle: f64::from(l[3]),
                radiance: [l[4], l[5], l[6]].map(f64::from),
            })
            .collect(),
        _ => Vec::new(),
    }
}

impl ManifestMaterial {
    fn of(m: &gltf_export::WrittenMaterial) -> Self {
        Self {
            name: m.name.clone(),
            model: m.model.to_string(),
            base_color: m.fit.base_color,
            roughness: m.fit.roughness,
            specular_factor: m.fit.specular_factor,
            specular_color: m.fit.specular_color,
            anisotropy: m.fit.anisotropy,
            fit_error: m.fit.error,
        }
    }
}

impl Bake {
    /// The manifest as the bytes of [`MANIFEST_FILE`]. Timings vary run to run, so they are
    /// left out: the same project gives the same bytes.
    pub fn manifest_bytes(&self) -> Vec<u8> {
        let mut m = self.manifest.clone();
        m.timings.clear();
        let mut bytes = serde_json::to_vec_pretty(&m).expect("the manifest serialises");
        bytes.push(b'\n');
        bytes
    }
}

/// Writes `bake`'s files into `dir` (created if missing): every file is first written in full
/// to a staging folder inside `dir`, then renamed into place, the manifest last. A failure
/// before the renames leaves `dir` as it was; the staging folder is always removed.
pub fn write_atomically(bake: &Bake, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let staging = tempfile::Builder::new().prefix(".lightloom-bake-").tempdir_in(dir)?;
    let manifest = BakedFile { name: MANIFEST_FILE.into(), bytes: bake.manifest_bytes() };
    let all: Vec<&BakedFile> = bake.files.iter().chain(std::iter::once(&manifest)).collect();
    for file in &all {
        use std::io::Write;
        let mut f = std::fs::File::create(staging.path().join(&file.name))?;
        f.write_all(&file.bytes)?;
        f.sync_all()?;
    }
    for file in &all {
        std::fs::rename(staging.path().join(&file.name), dir.join(&file.name))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
