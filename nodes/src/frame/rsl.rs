//! The rotatable square lights' surfaces (Xu et al. 2006).

use super::*;

/// `rsl`: square lights per vertex (Xu et al. 2006 Eq. 5). The shader sums `I Ω ρ̄ V̄` over
/// the lights with `ρ̄` from the materials' summed-area tables at the vertex's view; `V̄`
/// comes per vertex and light from the `rsl_visibility` stage.
#[derive(Clone, Debug)]
pub struct RslSurfaces {
    /// Changes whenever any buffer below does.
    pub key: Key,
    /// Per light, world frame: `[direction xyz, solid angle, intensity rgb, 0]`.
    pub lights: Arc<Vec<[f32; 8]>>,
    /// [`crate::rsl::shade::LightVisibility`]: `V̄` per vertex and light.
    pub visibility: Keyed,
    /// Texels per side of every table.
    pub table_size: usize,
    /// Every material's corner-stored SATs, concatenated: `cos θ/π`, then one `lobe · cos θ`
    /// table per view slice, each `(table_size + 1)²`.
    pub tables: Arc<Vec<f32>>,
    /// Per material: `[first float, view grid (0 none, 1 isotropic, 2 anisotropic), slices per
    /// side or θ₀ slices, 0]`.
    pub layouts: Vec<[u32; 4]>,
    /// Per material: diffuse albedo and specular colour, scaled by what reaches surfaces
    /// through fog.
    pub albedo: Vec<[f64; 3]>,
    pub specular: Vec<[f64; 3]>,
}

impl RslSurfaces {
    /// `tables` are the materials' [`crate::rsl::brdf_sat::BrdfSat`]s, one per material.
    pub fn new(
        lights: &crate::rsl::WorldLights,
        lights_key: Key,
        visibility: Keyed,
        tables: &[Keyed],
        fog: Option<&FoggedEnvironment>,
        geometry: &Geometry,
    ) -> Result<Self, String> {
        use crate::rsl::brdf_sat::{BrdfSat, ViewGrid};
        let v = visibility.value.expect::<crate::rsl::shade::LightVisibility>().map_err(|e| e.to_string())?;
        let vertices = geometry.vertex_count();
        if v.vertices != vertices || v.lights != lights.lights.len() {
            return Err(format!(
                "the square-light visibility covers {} vertices × {} lights for {vertices} vertices × {} lights",
                v.vertices,
                v.lights,
                lights.lights.len()
            ));
        }
        let mut key = visibility.key ^ lights_key.rotate_left(5) ^ geometry.meshes.key.rotate_left(3);
        let (mut data, mut layouts, mut albedo, mut specular) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let attenuation = fog.map_or([1.0; 3], |f| f.fog.attenuation);
        let scale = |c: [f64; 3]| std::array::from_fn(|i| c[i] * attenuation[i]);
        let mut size = None;
        for keyed in tables {
            let sat = keyed.value.expect::<BrdfSat>().map_err(|e| e.to_string())?;
            if *size.get_or_insert(sat.size) != sat.size {
                return Err("the materials' summed-area tables differ in resolution".into());
            }
            key = key.rotate_left(7) ^ keyed.key;
            let (kind, slices) = match (sat.lobes.is_empty(), sat.views) {
                (true, _) => (0, 0),
                (false, ViewGrid::Isotropic { slices }) => (1, slices),
                (false, ViewGrid::Anisotropic { size }) => (2, size),
            };
            layouts.push([data.len() as u32, kind, slices as u32, 0]);
            for table in std::iter::once(&sat.cosine).chain(&sat.lobes) {
                data.extend(table.corners().iter().map(|&c| c as f32));
            }
            albedo.push(scale(sat.diffuse));
            specular.push(scale(sat.specular));
        }
        let table_size = size.ok_or("the rsl mode needs a material: link a BRDF editor to the Output")?;
        let lights = lights
            .lights
            .iter()
            .map(|l| {
                let [x, y, z] = l.direction.map(|c| c as f32);
                let [r, g, b] = l.intensity.map(|c| c as f32);
                [x, y, z, l.solid_angle as f32, r, g, b, 0.0]
            })
            .collect();
        Ok(Self {
            key,
            lights: Arc::new(lights),
            visibility,
            table_size,
            tables: Arc::new(data),
            layouts,
            albedo,
            specular,
        })
    }
}

/// `rsl` as a frame part: the square lights in the world, each vertex's visibility of them
/// (from the scene's per-object tables), each material's BRDF tables.
pub(super) struct Rsl;

impl ModeFrame for Rsl {
    fn material_stages(&self) -> &'static [&'static str] {
        &["rsl_tables"]
    }

    fn needs_material(&self) -> bool {
        true
    }

    fn stages(&self, linked: &Linked) -> Vec<StageRef> {
        let mut stages = Vec::new();
        if let Some(scene) = &linked.scene {
            stages.push(StageRef::new(scene, "rsl_self_visibility"));
            stages.push(StageRef::new(scene, "rsl_occluders"));
        }
        if let Some(lights) = &linked.square_lights {
            stages.push(StageRef::new(lights, lights_stage(linked.separate_sun)));
        }
        stages.push(StageRef::new(linked.output, visibility_stage(linked.separate_sun)));
        stages
    }

    fn surfaces(&self, g: &Gather, parts: &MaterialParts, inputs: &SurfaceInputs) -> Result<Surfaces, String> {
        let node = g
            .upstream("square_lights")
            .ok_or("the rsl mode needs square lights: link an RSL decomposer to the Output's square_lights input")?;
        let lights = g.keyed(&node, lights_stage(g.separate_sun))?;
        let world = lights.value.expect::<crate::rsl::WorldLights>().map_err(|e| e.to_string())?;
        let visibility = g.keyed(g.output, visibility_stage(g.separate_sun))?;
        let tables: Vec<Keyed> = parts.mode_stages.iter().flatten().cloned().collect();
        Ok(Surfaces::Rsl(RslSurfaces::new(world, lights.key, visibility, &tables, inputs.fogged, inputs.geometry)?))
    }
}

/// The decomposer's lights: of the sky without its sun when the Output lights the sun apart
/// (the sun pass draws it with its own shadows), else of the whole sky.
fn lights_stage(separate_sun: bool) -> &'static str {
    if separate_sun { "residual_world_lights" } else { "world_lights" }
}

/// Each vertex's visibility of the lights of [`lights_stage`].
fn visibility_stage(separate_sun: bool) -> &'static str {
    if separate_sun { "rsl_residual_visibility" } else { "rsl_visibility" }
}
