//! The Output's bake settings and the stages only a bake pulls (see [`crate::bake`]): the
//! lightmap atlas and its texels' own transport, computed like the vertices' in the Output's
//! mode. Cached like every stage, so a second bake after an edit recomputes only what the edit
//! touched (a material edit no transport, a light move no atlas).

use crate::engine::spec::{ParamGroup, ParamKind, ParamSpec, StageSpec};
use crate::engine::{Codec, StageContext, StageError, StageValue};

/// The bake's settings, folded in the Output's inspector.
pub const GROUPS: &[ParamGroup] = &[ParamGroup {
    label: "Bake",
    doc: "What Bake… (File menu) and the lightloom bake command write for game engines: lightmaps, SH probes \
          and the prefiltered environment.",
    params: &[
        "bake_lightmap_density",
        "bake_lightmap_padding",
        "bake_probe_spacing",
        "bake_probe_bands",
        "bake_cube_size",
    ],
}];

pub fn params() -> Vec<ParamSpec> {
    vec![
        ParamSpec {
            name: "bake_lightmap_density",
            label: "Lightmap texels per metre",
            unit: "1/m",
            kind: ParamKind::Float { min: 0.5, max: 1024.0, default: 16.0 },
            doc: "Lightmap resolution on the scene's surfaces (the same everywhere). The lightmap is at most \
                  4096 texels a side; each texel gets its own shadow transport in the mode, so the bake's cost \
                  grows with the square of this.",
        },
        ParamSpec {
            name: "bake_lightmap_padding",
            label: "Lightmap padding",
            unit: "texels",
            kind: ParamKind::Int { min: 1, max: 16, default: 2 },
            doc: "Empty texels around each lightmap chart (filled with the chart's edge light), so \
                  filtering and mipmaps do not bleed between charts.",
        },
        ParamSpec {
            name: "bake_cube_size",
            label: "Specular cube size",
            unit: "px",
            kind: ParamKind::Choice { options: &["32", "64", "128", "256"], default: "128", labels: &[] },
            doc: "Face size of the GGX-prefiltered specular cube map (mip 0; each further mip is rougher).",
        },
        ParamSpec {
            name: "bake_probe_spacing",
            label: "Probe spacing",
            unit: "m",
            kind: ParamKind::Float { min: 0.05, max: 1000.0, default: 1.0 },
            doc: "Distance between the SH light probes of the grid over the scene's bounds (for lighting \
                  dynamic objects in a game engine).",
        },
        ParamSpec {
            name: "bake_probe_bands",
            label: "Probe SH bands",
            unit: "",
            kind: ParamKind::Int { min: 1, max: 5, default: 3 },
            doc: "SH bands per probe (3 = L2, 9 coefficients, what Unity and Godot use).",
        },
    ]
}

pub fn stages() -> Vec<StageSpec> {
    vec![
        StageSpec {
            name: "bake_atlas",
            version: 1,
            params: &["bake_lightmap_density", "bake_lightmap_padding"],
            stages: &[],
            inputs: &[("scene", "geometry")],
            persist: None,
            compute: bake_atlas,
        },
        StageSpec {
            name: "bake_probes",
            version: 1,
            params: &["bake_probe_spacing", "bake_probe_bands"],
            stages: &[],
            inputs: &[
                ("scene", "geometry"),
                ("scene", "ray_scene"),
                ("environment", "rotated_radiance"),
                ("environment", "sh"),
                ("lights", "lights"),
                ("area_lights", "light"),
                ("medium", "medium"),
                ("medium", "f_tables"),
            ],
            persist: None,
            compute: bake_probes,
        },
        StageSpec {
            name: "bake_environment",
            version: 1,
            params: &["bake_cube_size"],
            stages: &[],
            inputs: &[("environment", "rotated_radiance"), ("environment", "sh")],
            persist: None,
            compute: bake_environment,
        },
        StageSpec {
            name: "bake_texel_sh",
            version: 1,
            params: &[],
            stages: &["bake_atlas"],
            inputs: &[("scene", "ray_scene"), ("scene", "transport_sh")],
            persist: Some(Codec::of::<crate::transport::ShTransport>()),
            compute: bake_texel_sh,
        },
        StageSpec {
            name: "bake_texel_blocked",
            version: 1,
            params: &[],
            stages: &["bake_atlas", "bake_texel_sh"],
            inputs: &[("blockers", "spheres")],
            persist: None,
            compute: bake_texel_blocked,
        },
        StageSpec {
            name: "bake_texel_square_lights",
            version: 1,
            params: &[],
            stages: &["bake_atlas"],
            inputs: &[("scene", "ray_scene"), ("square_lights", "turned_lights")],
            persist: None,
            compute: |ctx| bake_texel_square_lights(ctx, "turned_lights"),
        },
        StageSpec {
            name: "bake_texel_residual_square_lights",
            version: 1,
            params: &[],
            stages: &["bake_atlas"],
            inputs: &[("scene", "ray_scene"), ("square_lights", "residual_turned_lights")],
            persist: None,
            compute: |ctx| bake_texel_square_lights(ctx, "residual_turned_lights"),
        },
        StageSpec {
            name: "bake_texel_area_transport",
            version: 1,
            params: &[],
            stages: &["bake_atlas"],
            inputs: &[("scene", "ray_scene"), ("area_lights", "face"), ("area_lights", "placement")],
            persist: None,
            compute: bake_texel_area_transport,
        },
        StageSpec {
            name: "bake_texel_area",
            version: 1,
            params: &[],
            stages: &["bake_atlas", "bake_texel_area_transport"],
            inputs: &[("area_lights", "light")],
            persist: None,
            compute: bake_texel_area,
        },
        StageSpec {
            name: "bake_texel_local",
            version: 1,
            params: &[],
            stages: &["bake_atlas"],
            inputs: &[("scene", "ray_scene"), ("scene", "transport_local")],
            persist: Some(Codec::of::<crate::transport::SphericalTransport>()),
            compute: bake_texel_local,
        },
        StageSpec {
            name: "bake_texel_products",
            version: 1,
            params: &["wavelet_terms"],
            stages: &["bake_atlas", "bake_texel_local"],
            inputs: &[("environment", "radiance"), ("environment", "rotation")],
            persist: None,
            compute: bake_texel_products,
        },
        StageSpec {
            name: "bake_texel_residual_products",
            version: 1,
            params: &["wavelet_terms"],
            stages: &["bake_atlas", "bake_texel_local"],
            inputs: &[("environment", "sun"), ("environment", "rotation")],
            persist: None,
            compute: bake_texel_residual_products,
        },
    ]
}

fn bake_atlas(ctx: &StageContext) -> Result<StageValue, StageError> {
    let meshes = ctx.required_input::<crate::mesh::MeshSet>("scene", "geometry")?;
    let density = ctx.float("bake_lightmap_density")? as f32;
    let padding = ctx.int("bake_lightmap_padding")? as u32;
    let cancel = ctx.cancel_token();
    let atlas = crate::lightmap::LightmapAtlas::build(meshes, density, padding, &|f| {
        ctx.progress(f);
        !cancel.is_cancelled()
    });
    ctx.check_cancel()?;
    let atlas = atlas.map_err(StageError::Failed)?;
    ctx.inform(format!(
        "lightmap {}×{} at {:.1} texels/m: {} texels on surfaces ({:.0}% of the page)",
        atlas.width,
        atlas.height,
        atlas.texels_per_metre,
        atlas.receivers.len(),
        atlas.utilization * 100.0
    ));
    Ok(StageValue::new(atlas))
}

/// The texels' SH transport, with the vertices' bands and rays.
fn bake_texel_sh(ctx: &StageContext) -> Result<StageValue, StageError> {
    let atlas = ctx.stage::<crate::lightmap::LightmapAtlas>("bake_atlas")?;
    let scene = ctx.required_input::<crate::raycast::RayScene>("scene", "ray_scene")?;
    let vertices = ctx.required_input::<crate::transport::ShTransport>("scene", "transport_sh")?;
    crate::kinds::scene::check_ray_budget(atlas.receivers.len(), vertices.rays, "the lightmap's texels per metre")?;
    Ok(StageValue::new(crate::transport::sh_transport(
        scene,
        &atlas.receivers,
        vertices.bands,
        vertices.rays,
        ctx.cancel_token(),
        &|f| ctx.progress(f),
    )?))
}

/// The texels' SH transport with the blocker spheres multiplied in (as `blocked_transport`
/// per vertex).
fn bake_texel_blocked(ctx: &StageContext) -> Result<StageValue, StageError> {
    let atlas = ctx.stage::<crate::lightmap::LightmapAtlas>("bake_atlas")?;
    let transport = ctx.stage::<crate::transport::ShTransport>("bake_texel_sh")?;
    Ok(StageValue::new(super::with_blockers(ctx, transport, &atlas.receivers)?))
}

/// The square lights' lit cosine at every texel, traced ([`crate::lightmap::square_light_texels`]);
/// `lights`: the decomposer's whole-sky lights, or those of the sky without its sun.
fn bake_texel_square_lights(ctx: &StageContext, lights: &str) -> Result<StageValue, StageError> {
    use crate::lightmap::square_light_texels::{RINGS, SECTORS, SquareLightTexels, trace};
    let atlas = ctx.stage::<crate::lightmap::LightmapAtlas>("bake_atlas")?;
    let scene = ctx.required_input::<crate::raycast::RayScene>("scene", "ray_scene")?;
    let Some(lights) = ctx.input::<crate::rsl::WorldLights>("square_lights", lights)? else {
        return Ok(StageValue::new(SquareLightTexels::default()));
    };
    crate::kinds::scene::check_ray_budget(
        atlas.receivers.len(),
        lights.lights.len() * RINGS * SECTORS,
        "the lightmap's texels per metre",
    )?;
    Ok(StageValue::new(trace(scene, &atlas.receivers, lights, ctx.cancel_token(), &|f| ctx.progress(f))?))
}

/// The area lights' top-face transport at every texel (as `area_transport` per vertex).
fn bake_texel_area_transport(ctx: &StageContext) -> Result<StageValue, StageError> {
    let atlas = ctx.stage::<crate::lightmap::LightmapAtlas>("bake_atlas")?;
    Ok(StageValue::new(super::area::transport_of(ctx, &atlas.receivers, "the lightmap's texels per metre")?))
}

/// The area lights' irradiance at every texel.
fn bake_texel_area(ctx: &StageContext) -> Result<StageValue, StageError> {
    let atlas = ctx.stage::<crate::lightmap::LightmapAtlas>("bake_atlas")?;
    let transports = ctx.stage::<super::area::AreaTransport>("bake_texel_area_transport")?;
    Ok(StageValue::new(super::area::irradiance_of(ctx, &atlas.receivers, transports)?))
}

/// The texels' local-frame visibility, at the vertices' depth and terms.
fn bake_texel_local(ctx: &StageContext) -> Result<StageValue, StageError> {
    let atlas = ctx.stage::<crate::lightmap::LightmapAtlas>("bake_atlas")?;
    let scene = ctx.required_input::<crate::raycast::RayScene>("scene", "ray_scene")?;
    let vertices = ctx.required_input::<crate::transport::SphericalTransport>("scene", "transport_local")?;
    let depth = vertices.depth;
    crate::kinds::scene::check_ray_budget(
        atlas.receivers.len(),
        20 << (2 * depth.min(20)),
        "the lightmap's texels per metre",
    )?;
    Ok(StageValue::new(crate::transport::spherical_transport(
        scene,
        &atlas.receivers,
        depth,
        vertices.keep,
        ctx.cancel_token(),
        &|f| ctx.progress(f),
    )?))
}

/// The texels' triple products with the environment (as `local_products` per vertex).
fn bake_texel_products(ctx: &StageContext) -> Result<StageValue, StageError> {
    texel_products(ctx, ctx.input::<crate::cubemap::CubeMap>("environment", "radiance")?)
}

/// [`bake_texel_products`] of the sky without its sun, when the sun is lit apart (the bake
/// traces its shadows per texel instead).
fn bake_texel_residual_products(ctx: &StageContext) -> Result<StageValue, StageError> {
    texel_products(ctx, ctx.input::<crate::sun::SunSplit>("environment", "sun")?.map(|split| &split.residual))
}

fn texel_products(ctx: &StageContext, environment: Option<&crate::cubemap::CubeMap>) -> Result<StageValue, StageError> {
    let atlas = ctx.stage::<crate::lightmap::LightmapAtlas>("bake_atlas")?;
    let transport = ctx.stage::<crate::transport::SphericalTransport>("bake_texel_local")?;
    let terms: usize =
        ctx.choice("wavelet_terms")?.parse().map_err(|_| StageError::Internal("wavelet_terms".into()))?;
    let grid = crate::triple_product::CellGrid::for_coefficients(terms).map_err(StageError::Failed)?;
    let (Some(environment), Some(rotation)) = (environment, ctx.input::<glam::DMat3>("environment", "rotation")?)
    else {
        return Ok(StageValue::new(crate::triple_product::LocalProducts::default()));
    };
    let lighting = crate::triple_product::Lighting { environment, rotation: *rotation, table: None };
    let visibility = crate::triple_product::local_visibility(grid, transport, ctx.cancel_token())?;
    Ok(StageValue::new(crate::triple_product::local_products(
        grid,
        &lighting,
        &atlas.receivers,
        &visibility,
        ctx.cancel_token(),
    )?))
}

/// The SH probe grid over the scene's bounds.
fn bake_probes(ctx: &StageContext) -> Result<StageValue, StageError> {
    let meshes = ctx.required_input::<crate::mesh::MeshSet>("scene", "geometry")?;
    let scene = ctx.required_input::<crate::raycast::RayScene>("scene", "ray_scene")?;
    let environment = ctx.input::<crate::cubemap::CubeMap>("environment", "rotated_radiance")?;
    let lights = ctx.input::<Vec<crate::light::PointLight>>("lights", "lights")?;
    let areas = ctx.inputs_all::<crate::kinds::area_light::AreaLight>("area_lights", "light")?;
    let fogged = match (
        ctx.input::<crate::kinds::fog::Medium>("medium", "medium")?,
        ctx.input::<Vec<crate::single_scattering::FTable>>("medium", "f_tables")?,
        ctx.input::<crate::sh::ShRgb>("environment", "sh")?,
    ) {
        (Some(medium), Some(tables), sh) => {
            let phase = medium
                .phase_function()
                .ok_or_else(|| StageError::Failed("the fog's phase polynomial is invalid".into()))?;
            let no_light = crate::sh::ShRgb { bands: 1, coeffs: vec![[0.0; 3]] };
            let light = sh.unwrap_or(&no_light);
            let environment = crate::single_scattering::FoggedEnvironment::new(
                medium.beta,
                medium.environment_distance,
                &phase,
                tables,
                light,
            );
            Some((medium.beta, environment))
        }
        _ => None,
    };
    let lighting = crate::probes::ProbeLighting {
        points: lights.map_or(&[], |l| l.as_slice()),
        areas: areas.iter().map(|(_, a)| &a.emitter).collect(),
        fog: fogged.as_ref().map(|(beta, environment)| (*beta, environment)),
    };
    let grid = crate::probes::bake(
        scene,
        meshes.bounds(),
        ctx.float("bake_probe_spacing")?,
        ctx.int("bake_probe_bands")? as usize,
        environment,
        &lighting,
        ctx.cancel_token(),
        &|f| ctx.progress(f),
    )?;
    let invalid = grid.valid.iter().filter(|v| !**v).count();
    ctx.inform(format!(
        "{}×{}×{} probes every {} m ({invalid} inside geometry)",
        grid.counts[0], grid.counts[1], grid.counts[2], grid.spacing
    ));
    Ok(StageValue::new(grid))
}

/// The environment's SH (L2) and its GGX-prefiltered specular cube.
fn bake_environment(ctx: &StageContext) -> Result<StageValue, StageError> {
    let cube = ctx.required_input::<crate::cubemap::CubeMap>("environment", "rotated_radiance")?;
    let sh = ctx.required_input::<crate::sh::ShRgb>("environment", "sh")?;
    let size: usize =
        ctx.choice("bake_cube_size")?.parse().map_err(|_| StageError::Internal("bake_cube_size".into()))?;
    let sh = sh.truncated(3);
    let specular = crate::specular_cube::prefilter(cube, size, ctx.cancel_token())?;
    ctx.inform(format!("specular cube {}² with {} roughness levels", specular.levels[0].size, specular.levels.len()));
    Ok(StageValue::new(crate::specular_cube::EnvironmentBake { sh, cube: specular }))
}
