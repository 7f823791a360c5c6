//! A frame gathered from an evaluation: each feature's part from the stages linked to the
//! Output, then what the user should know about inputs the frame cannot draw.

use super::*;
use std::collections::BTreeMap;

/// What every part of a gather reads: the evaluation, the Output and the mode drawn.
struct Gather<'a> {
    evaluation: &'a Evaluation,
    graph: &'a Graph,
    output: &'a str,
    settings: OutputSettings,
    mode: Mode,
    /// The environment's sun is lit apart from the mode's transport.
    separate_sun: bool,
}

/// The materials linked to the Output and what the mode reads of each.
struct MaterialParts {
    materials: Vec<FrameMaterial>,
    /// The SH modes' glossy lobes (one per material; `None` for the default material).
    lobes: Vec<Option<crate::prt::GlossyLobe>>,
    /// The wavelet modes' local-frame tables.
    tables: Vec<Keyed>,
    /// The rsl mode's BRDF tables.
    rsl_tables: Vec<Keyed>,
    /// Why a material's normal map is drawn approximately or not at all.
    normal_notes: Vec<(String, String)>,
}

/// A stage's value with its key, or why there is none.
fn keyed(evaluation: &Evaluation, node: &str, stage: &str) -> Result<Keyed, String> {
    let r = evaluation.get(node, stage).ok_or_else(|| format!("stage {node}.{stage} was not evaluated"))?;
    match &r.value {
        Ok(v) => Ok(Keyed { key: r.key, value: v.clone() }),
        Err(e) => Err(format!("{node}.{stage} failed: {e}")),
    }
}

impl Gather<'_> {
    fn keyed(&self, node: &str, stage: &str) -> Result<Keyed, String> {
        keyed(self.evaluation, node, stage)
    }

    /// The engine's CPU relight of the wavelet modes' receiver sets, where the request asked
    /// for it and it finished (else the viewport relights with its kernel).
    fn relit(&self, texels: bool) -> Option<RelitSets> {
        use crate::kinds::output::relight::stage_name;
        let done = |texels: bool| {
            let r = self.evaluation.get(self.output, stage_name(texels, self.separate_sun))?;
            r.value.as_ref().ok().map(|v| Keyed { key: r.key, value: v.clone() })
        };
        let texels = match texels {
            true => Some(done(true)?),
            false => None,
        };
        Some(RelitSets { vertices: done(false)?, texels })
    }

    fn upstream(&self, port: &str) -> Option<String> {
        self.graph.upstream(self.output, port).map(|n| n.id.clone())
    }

    fn materials(&self) -> Result<MaterialParts, String> {
        let nodes = self.graph.upstream_all(self.output, "material");
        if nodes.len() > MAX_MATERIALS {
            return Err(format!(
                "{} materials are linked to the Output; at most {MAX_MATERIALS} are supported",
                nodes.len()
            ));
        }
        let mode = self.mode;
        let mut parts = MaterialParts {
            materials: Vec::new(),
            lobes: Vec::new(),
            tables: Vec::new(),
            rsl_tables: Vec::new(),
            normal_notes: Vec::new(),
        };
        let keyed = |node: &str, stage: &str| self.keyed(node, stage);
        for node in &nodes {
            let normal = normal_maps::normal_detail(&keyed, self.graph, &node.id, mode, &mut parts.normal_notes);
            let material = typed(&self.keyed(&node.id, "material")?, "material")?;
            parts.materials.push(FrameMaterial { node: node.id.clone(), material, normal });
            if matches!(mode, Mode::ShPrt | Mode::ShAdaptive) {
                parts.lobes.push(Some(typed(&self.keyed(&node.id, "sh_lobe")?, "sh_lobe")?));
            }
            if mode.is_wavelet() {
                parts.tables.push(self.keyed(&node.id, "local_table")?);
            }
            if mode == Mode::Rsl {
                parts.rsl_tables.push(self.keyed(&node.id, "rsl_tables")?);
            }
        }
        if parts.materials.is_empty() {
            if mode.is_wavelet() || mode == Mode::Rsl {
                return Err(format!("the {mode} mode needs a material: link a BRDF editor to the Output"));
            }
            parts.materials.push(FrameMaterial { node: String::new(), material: Default::default(), normal: None });
            parts.lobes.push(None);
        }
        Ok(parts)
    }

    /// The SH light the mode's transport carries (the sky without its sun when the sun is lit
    /// apart), and the sun.
    fn sun(&self, sh: Option<&Keyed>) -> Result<(Option<Keyed>, Option<SunFrame>), String> {
        match self.upstream("environment") {
            Some(env) if self.separate_sun => {
                let split = self.keyed(&env, "sun")?;
                let split = split.value.expect::<crate::sun::SunSplit>().map_err(|e| e.to_string())?;
                let rotation =
                    *self.keyed(&env, "rotation")?.value.expect::<glam::DMat3>().map_err(|e| e.to_string())?;
                Ok((Some(self.keyed(&env, "residual_sh")?), split.sun.map(|s| SunFrame::new(&s.rotated(rotation)))))
            }
            _ => Ok((sh.cloned(), None)),
        }
    }

    /// The scene's meshes with the index of each one's material, and the material names that
    /// matched no linked material (with how many meshes each).
    fn geometry(&self, meshes: Keyed, materials: &[FrameMaterial]) -> (Geometry, BTreeMap<String, usize>) {
        let mut mesh_materials = Vec::new();
        let mut unmatched = BTreeMap::new();
        if let Some(set) = meshes.value.get::<crate::mesh::MeshSet>() {
            for mesh in &set.meshes {
                let linked = materials.iter().map(|m| m.node.as_str());
                let found = crate::kinds::output::named_material(&mesh.material, linked);
                if found.is_none() && !mesh.material.is_empty() {
                    *unmatched.entry(mesh.material.clone()).or_default() += 1;
                }
                mesh_materials.push(found.unwrap_or(0) as u32);
            }
        }
        (Geometry { meshes, mesh_materials }, unmatched)
    }

    /// How the mode lights surfaces.
    fn surfaces(
        &self,
        parts: &mut MaterialParts,
        light: Option<&crate::sh::ShRgb>,
        fogged: Option<&FoggedEnvironment>,
        geometry: &Geometry,
    ) -> Result<Surfaces, String> {
        let (output, mode, separate_sun) = (self.output, self.mode, self.separate_sun);
        let lobes = std::mem::take(&mut parts.lobes);
        let materials = &parts.materials;
        // Without an environment the wavelet modes have no lighting to multiply in: surfaces get
        // no environment light.
        let wavelet_environment = match mode.is_wavelet() {
            true if separate_sun => Some(self.keyed(output, "wavelet_residual_environment")?),
            true => Some(self.keyed(output, "wavelet_environment")?),
            false => None,
        };
        let no_environment = wavelet_environment
            .as_ref()
            .is_some_and(|e| e.value.get::<crate::cubemap::CubeMap>().is_some_and(|c| c.size == 0));
        Ok(match mode {
            Mode::ShPrt | Mode::ShAdaptive => {
                let incident = match mode {
                    Mode::ShAdaptive => crate::kinds::output::adaptive::stage_names(separate_sun).0,
                    _ if separate_sun => "incident_residual_sh",
                    _ => "incident_sh",
                };
                Surfaces::Prt(PrtSurfaces::new(
                    self.keyed(output, "blocked_transport")?,
                    self.keyed(output, incident)?,
                    light,
                    fogged,
                    materials,
                    lobes,
                    geometry.vertex_count(),
                )?)
            }
            Mode::WaveletVertex | Mode::WaveletPixel if !no_environment => {
                let environment = self.upstream("environment").ok_or("the wavelet modes need an environment")?;
                let scene = self.upstream("scene").ok_or("the wavelet modes need a scene")?;
                let rotation = self.keyed(&environment, "rotation")?;
                let lighting = WaveletLighting {
                    visibility: self.keyed(output, "local_visibility")?,
                    receivers: self.keyed(&scene, "receivers")?,
                    environment: wavelet_environment.ok_or("the wavelet environment was not evaluated")?,
                    rotation: *rotation.value.expect::<glam::DMat3>().map_err(|e| e.to_string())?,
                };
                let texels =
                    if mode == Mode::WaveletPixel { Some(self.keyed(output, "texel_visibility")?) } else { None };
                let details = self.settings.wavelet_details;
                let mut surfaces =
                    WaveletSurfaces::new(lighting, &parts.tables, texels, fogged, geometry, materials, details)?;
                surfaces.relit = self.relit(surfaces.texels.is_some());
                Surfaces::Wavelet(Box::new(surfaces))
            }
            Mode::Rsl => {
                let node = self.upstream("square_lights").ok_or(
                    "the rsl mode needs square lights: link an RSL decomposer to the Output's square_lights input",
                )?;
                let lights = self.keyed(&node, "world_lights")?;
                let world = lights.value.expect::<crate::rsl::WorldLights>().map_err(|e| e.to_string())?;
                let visibility = self.keyed(output, "rsl_visibility")?;
                Surfaces::Rsl(RslSurfaces::new(world, lights.key, visibility, &parts.rsl_tables, fogged, geometry)?)
            }
            _ => Surfaces::Irradiance(IrradianceSurfaces::new(light, fogged, materials)),
        })
    }

    /// Inputs the frame does not draw as linked, said plainly: blockers outside the SH modes,
    /// square lights outside `rsl`, lights beyond [`MAX_LIGHTS`] (dropped here), unmatched
    /// material names, area lights beside blockers.
    fn ignored_inputs(
        &self,
        lights: &mut Vec<PointLight>,
        materials: &[FrameMaterial],
        unmatched: &BTreeMap<String, usize>,
        area_lights: bool,
    ) -> Vec<String> {
        let mode = self.settings.mode;
        let mut ignored = Vec::new();
        let blockers = self.upstream("blockers");
        if let Some(n) = &blockers
            && !matches!(mode, Mode::ShPrt | Mode::ShAdaptive)
        {
            ignored.push(format!(
                "`blockers` (from `{n}`) shadow the SH modes sh_prt and sh_adaptive only (the reference traces them \
                 in every mode)"
            ));
        }
        if let Some(n) = self.upstream("square_lights")
            && mode != Mode::Rsl
        {
            ignored.push(format!("`square_lights` (from `{n}`) are drawn by the rsl mode only"));
        }
        if lights.len() > MAX_LIGHTS {
            ignored.push(format!("{} point lights are linked; the first {MAX_LIGHTS} are drawn", lights.len()));
            lights.truncate(MAX_LIGHTS);
        }
        // With one material linked everything uses it by design; with several, say which
        // names matched nothing.
        if materials.len() > 1 && !unmatched.is_empty() {
            let names: Vec<String> = unmatched.iter().map(|(name, n)| format!("`{name}` ({n} mesh(es))")).collect();
            ignored.push(format!(
                "materials not linked to the Output: {}; those meshes use `{}`",
                names.join(", "),
                materials[0].node
            ));
        }
        if area_lights && blockers.is_some() {
            ignored.push(
                "`area_lights` cast no blocker-sphere shadows (the reference has them): the spheres shadow the \
                 environment only"
                    .into(),
            );
        }
        ignored
    }
}

impl FrameInputs {
    pub fn gather(evaluation: &Evaluation, graph: &Graph, output: &str) -> Result<Self, String> {
        let settings: OutputSettings = typed(&keyed(evaluation, output, "settings")?, "settings")?;
        // The best mode ready now: the requested one, or the unshadowed preview while the
        // requested mode's transport is still computing.
        let requested = settings.mode;
        let ready = mode_stages(graph, output, requested).iter().all(|r| evaluation.get(&r.node, &r.stage).is_some());
        let mode = if ready { requested } else { Mode::ShIrradiance };
        let pending =
            (!ready).then(|| format!("unshadowed preview: mode {requested} is still computing what it needs"));
        let g = Gather { evaluation, graph, output, settings, mode, separate_sun: separates_sun(graph, output) };
        let scene = g.upstream("scene").ok_or("the Output node's scene input is not connected")?;
        let ray_scene = evaluation.get(&scene, "ray_scene").map(|_| g.keyed(&scene, "ray_scene")).transpose()?;
        let (sh, radiance) = match g.upstream("environment") {
            Some(env) => (Some(g.keyed(&env, "sh")?), Some(g.keyed(&env, "rotated_radiance")?)),
            None => (None, None),
        };
        let mut parts = g.materials()?;
        let mut normal_notes = std::mem::take(&mut parts.normal_notes);
        let keyed = |node: &str, stage: &str| g.keyed(node, stage);
        let fog = match g.upstream("medium") {
            Some(node) => Some(medium::fog_frame(&keyed, &node, sh.as_ref(), g.mode)?),
            None => None,
        };
        let fogged = fog.as_ref().and_then(|f| f.environment.as_ref());
        // With the sun lit apart, the transport carries the sky without it.
        let (lighting_sh, sun) = g.sun(sh.as_ref())?;
        let light = lighting_sh
            .as_ref()
            .map(|sh| sh.value.expect::<crate::sh::ShRgb>())
            .transpose()
            .map_err(|e| e.to_string())?;
        let (geometry, unmatched) = g.geometry(g.keyed(&scene, "geometry")?, &parts.materials);
        let surfaces = g.surfaces(&mut parts, light, fogged, &geometry)?;
        let materials = parts.materials;
        let mut lights = match g.upstream("lights") {
            Some(node) => typed::<Vec<PointLight>>(&g.keyed(&node, "lights")?, "lights")?,
            None => Vec::new(),
        };
        let blockers = match g.upstream("blockers") {
            Some(n) if evaluation.get(&n, "spheres").is_some() => {
                Some(typed::<crate::kinds::blockers::BlockerSet>(&g.keyed(&n, "spheres")?, "spheres")?)
            }
            _ => None,
        };
        // Area lights join once their transport is traced (a later request tier).
        let light_nodes = graph.upstream_all(output, "area_lights");
        let vertices = geometry.vertex_count();
        let area_lights =
            area_lights::area_light_frame(evaluation, &light_nodes, output, &keyed, &materials, vertices)?;
        let ignored_inputs = g.ignored_inputs(&mut lights, &materials, &unmatched, !light_nodes.is_empty());
        let shadowed = !matches!(g.mode, Mode::ShIrradiance);
        let normal_maps = NormalMapFrame::new(&materials, light, shadowed, &mut normal_notes);
        let mut lobe_limits = lobe_limits::lobe_limits(graph, output, &scene, requested, &materials, sun.is_some());
        lobe_limits.extend(normal_notes);
        let medium = MediumFrame::new(lights, &materials, fog);
        Ok(Self {
            geometry,
            ray_scene,
            mode,
            pending,
            background: Background { radiance, visible: g.settings.background },
            settings: g.settings,
            ignored_inputs,
            lobe_limits,
            materials,
            surfaces,
            medium,
            area_lights,
            blockers,
            sun,
            normal_maps,
        })
    }
}
