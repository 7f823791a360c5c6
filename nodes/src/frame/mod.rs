//! What one frame draws, per feature: the background, the surfaces (one variant per relighting
//! mode), and the medium and point lights. Gathered from an evaluation by
//! [`FrameInputs::gather`]; renderers upload it as it is. All lighting
//! math (convolution to irradiance, light through fog, table coarsening) happens here, so a
//! renderer only packs and draws.

use crate::brdf::Material;
use crate::engine::spec::ParamValue;
use crate::engine::{Evaluation, Graph, Request, StageRef};
use crate::engine::{Key, StageValue};
use crate::kinds::output::{Mode, OutputSettings, View, output_mode_and_view, separates_sun};
use crate::light::PointLight;
use crate::sh::ShRgb;
use crate::single_scattering::FoggedEnvironment;
use std::sync::Arc;

/// Materials one frame can shade with (the shaders' uniform arrays).
pub const MAX_MATERIALS: usize = 8;

/// Point lights one frame can shade with.
pub const MAX_LIGHTS: usize = 8;

/// Irradiance bands shaded per pixel: `Â_l` is 0 for odd `l > 1` and `|Â_6| < 0.016 Â_0`
/// (Sun 2008 eq. 2.24), so bands above 4 add nothing visible.
pub const IRRADIANCE_BANDS: usize = 5;

/// A stage value with its key (renderers re-upload only when the key changes).
#[derive(Clone, Debug)]
pub struct Keyed {
    pub key: Key,
    pub value: Arc<StageValue>,
}

/// Everything one frame draws, per feature.
#[derive(Clone, Debug)]
pub struct FrameInputs {
    pub geometry: Geometry,
    /// The scene's BVH (for the reference renderer and picking), when it was requested.
    pub ray_scene: Option<Keyed>,
    /// The mode drawn: the Output's mode, or [`Mode::ShIrradiance`] while that mode's transport
    /// is still computing (then `pending` says so).
    pub mode: Mode,
    pub pending: Option<String>,
    pub settings: OutputSettings,
    /// Connected inputs the renderer does not draw yet, and material names that matched
    /// nothing, to tell the user.
    pub ignored_inputs: Vec<String>,
    /// Materials whose highlight the mode cannot show as it is: `(node, why and what shows
    /// it)`.
    pub lobe_limits: Vec<(String, String)>,
    /// The materials linked to the Output, in link order (the default material when none is),
    /// at most [`MAX_MATERIALS`].
    pub materials: Vec<FrameMaterial>,
    pub background: Background,
    pub surfaces: Surfaces,
    pub medium: MediumFrame,
    /// Painted area lights, added over any mode's surfaces once their transport is ready.
    pub area_lights: Option<AreaLightFrame>,
    /// The blocker spheres linked to the Output, when evaluated (the reference traces them).
    pub blockers: Option<crate::kinds::blockers::BlockerSet>,
    /// The environment's sun, lit per pixel apart from the mode's transport ([`crate::sun`]).
    pub sun: Option<SunFrame>,
    /// The materials' normal maps as the viewport samples them.
    pub normal_maps: NormalMapFrame,
}

/// A sun disc in world space (the environment's rotation applied), lit per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct SunFrame {
    /// Radiance inside the disc.
    pub radiance: [f64; 3],
    pub solid_angle: f64,
    /// Unit vector to the disc's centre, and the cosine of its angular radius.
    pub axis: [f32; 3],
    pub cos_radius: f64,
    /// Unit vectors towards the disc, spreading it evenly: each stands for
    /// `solid_angle / directions.len()` of it.
    pub directions: Vec<[f32; 3]>,
    /// How many of the last directions lie evenly on the disc's rim
    /// ([`crate::sun::rim_directions`]).
    pub rim_directions: usize,
}

impl SunFrame {
    pub fn new(sun: &crate::sun::Sun) -> Self {
        let directions: Vec<[f32; 3]> =
            sun.disc_directions(crate::sun::DISC_SAMPLES).iter().map(|d| d.as_vec3().to_array()).collect();
        Self {
            radiance: sun.radiance,
            solid_angle: sun.solid_angle(),
            axis: glam::DVec3::from(sun.direction).as_vec3().to_array(),
            cos_radius: sun.radius.cos(),
            rim_directions: crate::sun::rim_directions(directions.len()),
            directions,
        }
    }
}

/// The scene's meshes and which material each uses.
#[derive(Clone, Debug)]
pub struct Geometry {
    /// A [`crate::mesh::MeshSet`].
    pub meshes: Keyed,
    /// Its [`crate::mesh::VertexFrames`].
    pub frames: Keyed,
    /// Per mesh: its index in the frame's materials.
    pub mesh_materials: Vec<u32>,
}

impl Geometry {
    /// The geometry of a [`crate::mesh::MeshSet`] outside an evaluation (benchmarks and
    /// tests), its tangent frames computed here. Their key is made from the meshes' (an
    /// evaluation keys them as the scene's `vertex_frames` stage instead).
    pub fn of_meshes(meshes: Keyed, mesh_materials: Vec<u32>) -> Result<Self, String> {
        let set = meshes.value.expect::<crate::mesh::MeshSet>().map_err(|e| e.to_string())?;
        let frames = crate::mesh::VertexFrames::of(set);
        let frames = Keyed { key: meshes.key.rotate_left(1) ^ 0x7a6e, value: Arc::new(StageValue::new(frames)) };
        Ok(Self { meshes, frames, mesh_materials })
    }

    pub fn vertex_count(&self) -> usize {
        self.meshes.value.get::<crate::mesh::MeshSet>().map_or(0, |m| m.meshes.iter().map(|m| m.positions.len()).sum())
    }
}

/// The environment seen behind the scene.
#[derive(Clone, Debug)]
pub struct Background {
    /// The rotated radiance cube map ([`crate::cubemap::CubeMap`]), if an environment is linked.
    pub radiance: Option<Keyed>,
    pub visible: bool,
}

/// One material of a frame, as the reference renderer and the UI see it.
#[derive(Clone, Debug)]
pub struct FrameMaterial {
    /// The BRDF editor node (empty for the default material).
    pub node: String,
    pub material: Material,
    /// Its normal map, once loaded.
    pub normal: Option<NormalDetail>,
    /// Its specular lobe, as the sun is shaded with it per pixel ([`Self::lobe`]).
    lobe: SpecularLobe,
}

impl FrameMaterial {
    pub fn new(node: impl Into<String>, material: Material, normal: Option<NormalDetail>) -> Self {
        let brdf = crate::brdf::Brdf::from_material(&material);
        let lobe = SpecularLobe { lobe: brdf.lobe, f0: brdf.f0, colour: brdf.specular.to_array() };
        Self { node: node.into(), material, normal, lobe }
    }

    /// Its specular lobe (the material's [`crate::brdf::Brdf`]'s).
    pub fn lobe(&self) -> SpecularLobe {
        self.lobe
    }
}

/// A material's specular lobe ([`crate::brdf::Brdf`]'s): its distribution, Fresnel at normal
/// incidence, and colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpecularLobe {
    pub lobe: crate::brdf::Lobe,
    pub f0: f64,
    pub colour: [f64; 3],
}

mod area_lights;
mod environment;
mod gather;
mod lobe_limits;
mod medium;
mod modes;
mod normal_maps;
mod parts;
mod prt;
mod request;
mod rsl;
mod wavelet;

use gather::{Gather, MaterialParts};
use modes::{Linked, ModeFrame, SurfaceInputs};

pub use area_lights::{AreaLightFrame, AreaTexels};
pub use medium::{FogFrame, MediumFrame};
pub use normal_maps::{HIGHLIGHT_BANDS, NormalDetail, NormalMapFrame, VertexHighlight, normal_map_stages};
pub use prt::{IrradianceSurfaces, PrtSurfaces, incident_sh};
pub use request::{FrameNeeds, frame_request, frame_request_for, mode_stages};
pub use rsl::RslSurfaces;
pub use wavelet::{RelitSets, WaveletLighting, WaveletReceivers, WaveletSurfaces};

/// How surfaces are lit: one variant per relighting mode.
#[derive(Clone, Debug)]
pub enum Surfaces {
    Irradiance(IrradianceSurfaces),
    Prt(PrtSurfaces),
    Wavelet(Box<WaveletSurfaces>),
    Rsl(RslSurfaces),
}

impl FrameInputs {
    /// The frame material of mesh `i`.
    pub fn mesh_frame_material(&self, i: usize) -> &FrameMaterial {
        &self.materials[self.geometry.mesh_materials.get(i).copied().unwrap_or(0) as usize]
    }

    /// The material of mesh `i`.
    pub fn mesh_material(&self, i: usize) -> &Material {
        &self.mesh_frame_material(i).material
    }

    /// The Monte Carlo reference of this frame (see [`crate::reference`]).
    pub fn render_reference(
        &self,
        camera: &crate::reference::PinholeCamera,
        size: (usize, usize),
        seed: u64,
        cancel: &crate::engine::CancelToken,
        progress: &(dyn Fn(f64) + Sync),
    ) -> Result<crate::reference::HdrImage, String> {
        let Some(scene) = self.ray_scene.as_ref().and_then(|r| r.value.get::<crate::raycast::RayScene>()) else {
            return Err("the scene's ray_scene stage was not evaluated".into());
        };
        let meshes = self.geometry.meshes.value.expect::<crate::mesh::MeshSet>().map_err(|e| e.to_string())?;
        let black = crate::cubemap::CubeMap::new(1, vec![[0.0; 3]; 6]);
        let environment = match &self.background.radiance {
            Some(r) => r.value.expect::<crate::cubemap::CubeMap>().map_err(|e| e.to_string())?,
            None => &black,
        };
        let normal_maps: Vec<Option<(&crate::normal_filtering::NormalMap, f64)>> = (0..meshes.meshes.len())
            .map(|i| {
                let detail = self.mesh_frame_material(i).normal.as_ref()?;
                let map = detail.map.value.get::<crate::normal_filtering::NormalMap>()?;
                (!map.normals.is_empty()).then_some((map, detail.settings.tiling))
            })
            .collect();
        let rs = crate::reference::ReferenceScene {
            scene,
            meshes,
            brdfs: (0..meshes.meshes.len()).map(|i| crate::brdf::Brdf::from_material(self.mesh_material(i))).collect(),
            environment,
            background: self.settings.background,
            // Blocker spheres are opaque to the reference's rays; a set faded to strength 0
            // casts nothing (fractional strengths are an artistic fade it does not model).
            blockers: self.blockers.as_ref().filter(|b| b.strength > 0.0).map_or(&[], |b| b.blockers.as_slice()),
            area_lights: self.area_lights.as_ref().map_or(&[], |a| a.emitters.as_slice()),
            point_lights: &self.medium.lights,
            normal_maps: &normal_maps,
            textbook_normal_maps: false,
        };
        crate::reference::render(&rs, camera, size, self.settings.reference_samples, seed, cancel, progress)
            .map_err(|e| e.to_string())
    }

    /// The mesh seen through image point `(x, y)` (pixels, `y` down) of a `width × height` view:
    /// its index in the scene's meshes, or `None` for the background.
    pub fn pick(
        &self,
        camera: &crate::reference::PinholeCamera,
        (x, y): (f64, f64),
        (width, height): (usize, usize),
    ) -> Option<usize> {
        let (Some(scene), Some(meshes)) = (
            self.ray_scene.as_ref().and_then(|r| r.value.get::<crate::raycast::RayScene>()),
            self.geometry.meshes.value.get::<crate::mesh::MeshSet>(),
        ) else {
            return None;
        };
        let dir = camera.ray(x, y, width.max(1), height.max(1));
        let (_, triangle) = scene.closest(camera.position.as_vec3a(), dir.as_vec3a())?;
        meshes.mesh_of_triangle(triangle as usize)
    }
}

/// A copy of a gathered stage's value as `T` (an error naming both types otherwise).
pub(crate) fn typed<T: crate::engine::StageType + Clone>(keyed: &Keyed, stage: &str) -> Result<T, String> {
    keyed.value.expect::<T>().cloned().map_err(|e| format!("stage `{stage}`: {e}"))
}
