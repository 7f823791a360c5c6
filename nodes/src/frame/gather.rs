//! A frame gathered from an evaluation.

use super::*;

impl FrameInputs {
    pub fn gather(evaluation: &Evaluation, graph: &Graph, output: &str) -> Result<Self, String> {
        let keyed = |node: &str, stage: &str| -> Result<Keyed, String> {
            let r = evaluation.get(node, stage).ok_or_else(|| format!("stage {node}.{stage} was not evaluated"))?;
            match &r.value {
                Ok(v) => Ok(Keyed { key: r.key, value: v.clone() }),
                Err(e) => Err(format!("{node}.{stage} failed: {e}")),
            }
        };
        let upstream = |port: &str| graph.upstream(output, port).map(|n| n.id.clone());
        let scene = upstream("scene").ok_or("the Output node's scene input is not connected")?;
        let meshes = keyed(&scene, "geometry")?;
        let ray_scene = evaluation.get(&scene, "ray_scene").map(|_| keyed(&scene, "ray_scene")).transpose()?;
        let (sh, radiance) = match upstream("environment") {
            Some(env) => (Some(keyed(&env, "sh")?), Some(keyed(&env, "rotated_radiance")?)),
            None => (None, None),
        };
        let material_nodes = graph.upstream_all(output, "material");
        if material_nodes.len() > MAX_MATERIALS {
            return Err(format!(
                "{} materials are linked to the Output; at most {MAX_MATERIALS} are supported",
                material_nodes.len()
            ));
        }
        let settings: OutputSettings = typed(&keyed(output, "settings")?, "settings")?;
        // The best mode ready now: the requested one, or the unshadowed preview while the
        // requested mode's transport is still computing.
        let ready =
            mode_stages(graph, output, settings.mode).iter().all(|r| evaluation.get(&r.node, &r.stage).is_some());
        let mode = if ready { settings.mode } else { Mode::ShIrradiance };
        let pending =
            (!ready).then(|| format!("unshadowed preview: mode {} is still computing what it needs", settings.mode));
        let mut materials = Vec::new();
        let mut normal_notes = Vec::new();
        let mut lobes = Vec::new();
        let mut tables = Vec::new();
        let mut rsl_tables = Vec::new();
        for node in &material_nodes {
            let normal = normal_maps::normal_detail(&keyed, graph, &node.id, mode, &mut normal_notes);
            materials.push(FrameMaterial {
                node: node.id.clone(),
                material: typed(&keyed(&node.id, "material")?, "material")?,
                normal,
            });
            if matches!(mode, Mode::ShPrt | Mode::ShAdaptive) {
                lobes.push(Some(typed(&keyed(&node.id, "sh_lobe")?, "sh_lobe")?));
            }
            if mode.is_wavelet() {
                tables.push(keyed(&node.id, "local_table")?);
            }
            if mode == Mode::Rsl {
                rsl_tables.push(keyed(&node.id, "rsl_tables")?);
            }
        }
        if materials.is_empty() {
            if mode.is_wavelet() || mode == Mode::Rsl {
                return Err(format!("the {mode} mode needs a material: link a BRDF editor to the Output"));
            }
            materials.push(FrameMaterial { node: String::new(), material: Default::default(), normal: None });
            lobes.push(None);
        }
        let fog = match upstream("medium") {
            Some(node) => Some(medium::fog_frame(&keyed, &node, sh.as_ref(), mode)?),
            None => None,
        };
        let fogged = fog.as_ref().and_then(|f| f.environment.as_ref());
        // With the sun lit apart, the transport carries the sky without it.
        let separate_sun = separates_sun(graph, output);
        let (lighting_sh, sun) = match upstream("environment") {
            Some(env) if separate_sun => {
                let split = keyed(&env, "sun")?;
                let split = split.value.expect::<crate::sun::SunSplit>().map_err(|e| e.to_string())?;
                let rotation = *keyed(&env, "rotation")?.value.expect::<glam::DMat3>().map_err(|e| e.to_string())?;
                (Some(keyed(&env, "residual_sh")?), split.sun.map(|s| SunFrame::new(&s.rotated(rotation))))
            }
            _ => (sh.clone(), None),
        };
        let light = lighting_sh
            .as_ref()
            .map(|sh| sh.value.expect::<crate::sh::ShRgb>())
            .transpose()
            .map_err(|e| e.to_string())?;
        let mut mesh_materials = Vec::new();
        let mut unmatched: std::collections::BTreeMap<String, usize> = Default::default();
        if let Some(set) = meshes.value.get::<crate::mesh::MeshSet>() {
            for mesh in &set.meshes {
                let found =
                    crate::kinds::output::named_material(&mesh.material, materials.iter().map(|m| m.node.as_str()));
                if found.is_none() && !mesh.material.is_empty() {
                    *unmatched.entry(mesh.material.clone()).or_default() += 1;
                }
                mesh_materials.push(found.unwrap_or(0) as u32);
            }
        }
        let geometry = Geometry { meshes, mesh_materials };
        // Without an environment the wavelet modes have no lighting to multiply in: surfaces get
        // no environment light.
        let wavelet_environment = match mode.is_wavelet() {
            true if separate_sun => Some(keyed(output, "wavelet_residual_environment")?),
            true => Some(keyed(output, "wavelet_environment")?),
            false => None,
        };
        let no_environment = wavelet_environment
            .as_ref()
            .is_some_and(|e| e.value.get::<crate::cubemap::CubeMap>().is_some_and(|c| c.size == 0));
        let surfaces = match mode {
            Mode::ShPrt | Mode::ShAdaptive => Surfaces::Prt(PrtSurfaces::new(
                keyed(output, "blocked_transport")?,
                keyed(
                    output,
                    match mode {
                        Mode::ShAdaptive => crate::kinds::output::adaptive::stage_names(separate_sun).0,
                        _ if separate_sun => "incident_residual_sh",
                        _ => "incident_sh",
                    },
                )?,
                light,
                fogged,
                &materials,
                lobes,
                geometry.vertex_count(),
            )?),
            Mode::WaveletVertex | Mode::WaveletPixel if !no_environment => {
                let environment = upstream("environment").ok_or("the wavelet modes need an environment")?;
                let scene = upstream("scene").ok_or("the wavelet modes need a scene")?;
                let rotation =
                    *keyed(&environment, "rotation")?.value.expect::<glam::DMat3>().map_err(|e| e.to_string())?;
                let lighting = WaveletLighting {
                    visibility: keyed(output, "local_visibility")?,
                    receivers: keyed(&scene, "receivers")?,
                    environment: wavelet_environment.ok_or("the wavelet environment was not evaluated")?,
                    rotation,
                };
                let texels = if mode == Mode::WaveletPixel { Some(keyed(output, "texel_visibility")?) } else { None };
                Surfaces::Wavelet(Box::new(WaveletSurfaces::new(
                    lighting,
                    &tables,
                    texels,
                    fogged,
                    &geometry,
                    &materials,
                    settings.wavelet_details,
                )?))
            }
            Mode::Rsl => {
                let node = upstream("square_lights").ok_or(
                    "the rsl mode needs square lights: link an RSL decomposer to the Output's square_lights input",
                )?;
                let lights = keyed(&node, "world_lights")?;
                let world = lights.value.expect::<crate::rsl::WorldLights>().map_err(|e| e.to_string())?;
                Surfaces::Rsl(RslSurfaces::new(
                    world,
                    lights.key,
                    keyed(output, "rsl_visibility")?,
                    &rsl_tables,
                    fogged,
                    &geometry,
                )?)
            }
            _ => Surfaces::Irradiance(IrradianceSurfaces::new(light, fogged, &materials)),
        };
        let mut lights = match upstream("lights") {
            Some(node) => typed::<Vec<crate::light::PointLight>>(&keyed(&node, "lights")?, "lights")?,
            None => Vec::new(),
        };
        let mut ignored_inputs = Vec::new();
        if !matches!(settings.mode, Mode::ShPrt | Mode::ShAdaptive)
            && let Some(n) = upstream("blockers")
        {
            ignored_inputs.push(format!(
                "`blockers` (from `{n}`) shadow the SH modes sh_prt and sh_adaptive only (the reference traces them \
                 in every mode)"
            ));
        }
        let blockers = match upstream("blockers") {
            Some(n) if evaluation.get(&n, "spheres").is_some() => {
                Some(typed::<crate::kinds::blockers::BlockerSet>(&keyed(&n, "spheres")?, "spheres")?)
            }
            _ => None,
        };
        if settings.mode != Mode::Rsl
            && let Some(n) = upstream("square_lights")
        {
            ignored_inputs.push(format!("`square_lights` (from `{n}`) are drawn by the rsl mode only"));
        }
        if lights.len() > MAX_LIGHTS {
            ignored_inputs.push(format!("{} point lights are linked; the first {MAX_LIGHTS} are drawn", lights.len()));
            lights.truncate(MAX_LIGHTS);
        }
        // With one material linked everything uses it by design; with several, say which
        // names matched nothing.
        if materials.len() > 1 && !unmatched.is_empty() {
            let names: Vec<String> = unmatched.iter().map(|(name, n)| format!("`{name}` ({n} mesh(es))")).collect();
            ignored_inputs.push(format!(
                "materials not linked to the Output: {}; those meshes use `{}`",
                names.join(", "),
                materials[0].node
            ));
        }
        // Area lights join once their transport is traced (a later request tier).
        let light_nodes = graph.upstream_all(output, "area_lights");
        let area_lights = area_lights::area_light_frame(
            evaluation,
            &light_nodes,
            output,
            &keyed,
            &materials,
            geometry.vertex_count(),
        )?;
        let normal_maps =
            NormalMapFrame::new(&materials, light, !matches!(mode, Mode::ShIrradiance), &mut normal_notes);
        let mut lobe_limits = lobe_limits::lobe_limits(graph, output, &scene, settings.mode, &materials, sun.is_some());
        lobe_limits.extend(normal_notes);
        let medium = MediumFrame::new(lights, &materials, fog);
        if !light_nodes.is_empty() && upstream("blockers").is_some() {
            ignored_inputs.push(
                "`area_lights` cast no blocker-sphere shadows (the reference has them): the spheres shadow the \
                 environment only"
                    .into(),
            );
        }
        Ok(Self {
            geometry,
            ray_scene,
            mode,
            pending,
            background: Background { radiance, visible: settings.background },
            settings,
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
