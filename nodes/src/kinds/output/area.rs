//! The Output's area lights: near-field relighting of the scene by the painted lights linked to
//! it ([`crate::near_field`], Sun 2008 §4.5), drawn in every relighting mode. Kept apart from
//! the modes' stages.
//!
//! - `area_transport`: per distinct top face and frame among the lights, every vertex's top-face
//!   transport (one ray per cell, each vertex's traced as one bundle, and 4 × 4 on an occluder's
//!   silhouette; they end at the highest plane of the lights in that frame: what
//!   lies above the lights, a ceiling, casts no shadow). A tilted light's frame
//!   ([`crate::near_field::LightFrame`]) is the world turned so that it lies level: its
//!   receivers are turned into it and its rays back out. Lights with equal faces and frames
//!   share a transport; it is memoised on the geometry, the face, the frame and that plane, so
//!   painting, moving a light within its plane or adding a light like one already traced
//!   traces no top face again. Beside the faces, each light's
//!   part beyond its face ([`crate::near_field::beyond_face`]: closed-form cells, one ray per
//!   quadrant of the light), memoised on the geometry, the face and the light's placement, so a
//!   move re-traces only those rays.
//! - `area_texel_transport` and `area_texel_irradiance`: the same at the texels of meshes with a
//!   visibility texture, so their shadows are resolved per texel, not per vertex (a floor's
//!   vertices are often too far apart for a shadow).
//! - `area_preview`: every light unshadowed, in closed form and without a ray, what the
//!   viewport shows while `area_transport` traces.
//! - `area_irradiance`: `E = Σ_ℓ scale_ℓ (Σ_k L_k^{(ℓ)} T_k + Σ_c F̄_c^{(ℓ)} R_c)` per vertex
//!   (Eq. 4.36, plus the cells beyond the face). Each light's
//!   unscaled sum is memoised on the light's coefficients, placement and face, so an edit of one
//!   light reruns only its own, and intensity or tint only rescales. Below it, each source
//!   coefficient's response ([`crate::near_field::responses`]) is memoised on the placement, the
//!   face and the coefficient's index, so a stroke computes only the coefficients it newly keeps
//!   and a move recomputes them all.

use crate::engine::spec::{PortSpec, PortType, StageSpec};
use crate::engine::{Key, StageContext, StageError, StageValue};
use crate::kinds::area_light::AreaLight;
use crate::near_field::beyond_face::{self, BeyondFace, VISIBILITY, beyond_face, cell_means};
use crate::near_field::{
    FaceTransport, FaceVisibility, LightFrame, LightPlacement, TargetKeep, TopFace, face_visibility, irradiance,
    max_silhouette, rays_per_receiver, response_batch, responses, shade_columns, visible_transport,
};
use crate::raycast::RayScene;
use crate::transport::Receivers;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

crate::stage_type!(Arc<FaceTransport>, "top-face transport", encoding = 2, |v| v.cells.len() * 4
    + v.bounds.len() * 16
    + 32);
crate::stage_type!(Arc<FaceVisibility>, "top-face visibility", encoding = 2, |v| v.bits.len() * 8
    + v.partial_offsets.len() * 8
    + v.partial.len() * 4
    + 32);
crate::stage_type!(AreaTransport, "area-light transport", encoding = 6, |v| v
    .faces
    .iter()
    .map(|f| {
        f.transport.cells.len() * 4
            + f.transport.bounds.len() * 16
            + f.visibility.bits.len() * 8
            + f.visibility.partial_offsets.len() * 8
            + f.visibility.partial.len() * 4
            + 64
    })
    .chain(v.beyond.iter().map(|b| b.responses.responses.len() * 4 + 64))
    .sum());
crate::stage_type!(Arc<BeyondFace>, "light beyond the top face", encoding = 1, |v| v.responses.len() * 4 + 16);
crate::stage_type!(
    AreaHighlights,
    "area-light highlights",
    |v| v.radiance.len() * 12 + 16,
    numbers = |v| v.radiance.iter().flatten().map(|&c| f64::from(c))
);
crate::stage_type!(
    AreaIrradiance,
    "area-light irradiance",
    |v| v.irradiance.len() * 12 + 16,
    numbers = |v| v.irradiance.iter().flatten().map(|&c| f64::from(c))
);
crate::stage_type!(UnscaledIrradiance, "one area light's irradiance", encoding = 1, |v| v.0.len() * 12);
crate::stage_type!(Response, "one light coefficient's response", encoding = 1, |v| v.0.len() * 8);

/// Bytes of one light's responses the memory cache may hold (a quarter of its default budget);
/// a light with more coefficients × vertices is shaded without keeping them.
const RESPONSE_MEMO_BYTES: usize = 512 << 20;

thread_local! {
    /// Each thread's world directions and ray list for one receiver's bundle of top-face rays.
    static BUNDLE: std::cell::RefCell<(Vec<glam::Vec3A>, Vec<u32>)> = const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// Receivers per cancellation check and progress step of the transport.
const TRANSPORT_CHUNK: usize = 512;

/// The transports of the linked lights' distinct top faces.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AreaTransport {
    pub faces: Vec<SharedTransport>,
    /// Per linked light, its responses beyond its face ([`crate::near_field::beyond_face`]).
    pub beyond: Vec<LightBeyond>,
}

/// One light's cells seen beyond its top face, by its placement and face.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightBeyond {
    pub placement: LightPlacement,
    pub face: TopFace,
    pub responses: Arc<BeyondFace>,
}

/// One face's transport and the key it is memoised under (what the lights' sums depend on),
/// with the visibility it was built from (glossy transports reuse it without new rays).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SharedTransport {
    pub key: Key,
    /// The frame of the lights it serves (and of its receivers' cells).
    pub frame: LightFrame,
    pub transport: Arc<FaceTransport>,
    pub visibility: Arc<FaceVisibility>,
}

/// Radiance the linked area lights' glossy reflections send toward the Output's viewpoint, per
/// vertex (RGB, the specular colour applied; empty when no material has a lobe).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AreaHighlights {
    pub radiance: Vec<[f32; 3]>,
}

/// Irradiance from every linked area light, per vertex (RGB, W/m² per unit radiance scale).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AreaIrradiance {
    pub irradiance: Vec<[f32; 3]>,
}

/// One light's irradiance before its intensity and tint.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct UnscaledIrradiance(pub Vec<[f32; 3]>);

/// One source coefficient's share of every vertex's irradiance ([`responses`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Response(pub Vec<f64>);

/// The Output's input for area lights (any number).
pub fn input() -> PortSpec {
    PortSpec { name: "area_lights", ty: PortType::AreaLight, required: false, many: true }
}

pub fn stages() -> Vec<StageSpec> {
    vec![
        StageSpec {
            name: "area_transport",
            version: 7,
            params: &[],
            stages: &[],
            inputs: &[
                ("scene", "receivers"),
                ("scene", "ray_scene"),
                ("area_lights", "face"),
                ("area_lights", "placement"),
            ],
            persist: Some(crate::engine::Codec::of::<AreaTransport>()),
            compute: area_transport,
        },
        StageSpec {
            name: "area_irradiance",
            version: 4,
            params: &[],
            stages: &["area_transport"],
            inputs: &[("scene", "receivers"), ("scene", "geometry"), ("area_lights", "light")],
            persist: None,
            compute: area_irradiance,
        },
        StageSpec {
            name: "area_preview",
            version: 1,
            params: &[],
            stages: &[],
            inputs: &[("scene", "receivers"), ("area_lights", "light")],
            persist: None,
            compute: area_preview,
        },
        StageSpec {
            name: "area_texel_transport",
            version: 2,
            params: &[],
            stages: &[],
            inputs: &[
                ("scene", "texel_receivers"),
                ("scene", "ray_scene"),
                ("area_lights", "face"),
                ("area_lights", "placement"),
            ],
            // 4 KiB per texel: kept in memory, not written to the disk cache.
            persist: None,
            compute: area_texel_transport,
        },
        StageSpec {
            name: "area_texel_irradiance",
            version: 2,
            params: &[],
            stages: &["area_texel_transport"],
            inputs: &[("scene", "texel_receivers"), ("area_lights", "light")],
            persist: None,
            compute: area_texel_irradiance,
        },
        StageSpec {
            name: "area_highlights",
            version: 2,
            params: &["highlight_eye"],
            stages: &["area_transport"],
            inputs: &[
                ("scene", "receivers"),
                ("scene", "geometry"),
                ("area_lights", "light"),
                ("material", "material"),
            ],
            persist: None,
            compute: area_highlights,
        },
    ]
}

fn positions(receivers: &Receivers) -> Vec<DVec3> {
    receivers.positions.iter().map(|p| DVec3::from(p.map(f64::from))).collect()
}

/// Every receiver's point and unit normal.
fn points_and_normals(receivers: &Receivers) -> (Vec<DVec3>, Vec<DVec3>) {
    (0..receivers.len()).map(|i| receivers.point(i)).unzip()
}

/// One receiver's top-face rays as one bundle, from `origin` along the plane intercepts `up`
/// (in the light's frame, turned into the world by `to_world`): they rise one unit per unit of
/// their parameter, so all of them end at the `ceiling` at one reach.
fn trace_bundle(
    scene: &RayScene,
    to_world: glam::DMat3,
    ceiling: f64,
    origin: DVec3,
    up: &[DVec3],
    blocked: &mut [bool],
) {
    let reach = (ceiling - origin.y).max(0.0) as f32;
    BUNDLE.with_borrow_mut(|(directions, rays)| {
        directions.clear();
        directions.extend(up.iter().map(|&d| (to_world * d).as_vec3a()));
        rays.clear();
        rays.extend(0..directions.len() as u32);
        scene.occlude_bundle((to_world * origin).as_vec3a(), directions, rays, reach, blocked);
    });
}

/// `values` (points or directions) turned into `frame`; borrowed as they are in the world's.
fn in_frame<'a>(frame: &LightFrame, values: &'a [DVec3]) -> std::borrow::Cow<'a, [DVec3]> {
    if frame.is_world() {
        return std::borrow::Cow::Borrowed(values);
    }
    let to_light = frame.to_light();
    std::borrow::Cow::Owned(values.iter().map(|&v| to_light * v).collect())
}

fn face_bytes(face: &TopFace) -> [u8; 16] {
    let mut bytes = [0; 16];
    bytes[..8].copy_from_slice(&(face.order as u64).to_le_bytes());
    bytes[8..].copy_from_slice(&face.size.to_bits().to_le_bytes());
    bytes
}

fn area_transport(ctx: &StageContext) -> Result<StageValue, StageError> {
    let receivers = ctx.required_input::<Receivers>("scene", "receivers")?;
    Ok(StageValue::new(transport_of(ctx, receivers, "the scene's tessellation")?))
}

/// The top-face transports of `receivers` (the vertices, or a bake's lightmap texels); a
/// budget overrun names `density` as what to lower.
pub(super) fn transport_of(
    ctx: &StageContext,
    receivers: &Receivers,
    density: &str,
) -> Result<AreaTransport, StageError> {
    let scene = ctx.required_input::<RayScene>("scene", "ray_scene")?;
    // Each light's placement beside its face: its part beyond the face is traced apart.
    let faces_of = ctx.inputs_all::<TopFace>("area_lights", "face")?;
    let lights: Vec<(LightPlacement, TopFace)> = ctx
        .inputs_all::<LightPlacement>("area_lights", "placement")?
        .into_iter()
        .filter_map(|(node, placement)| faces_of.iter().find(|(n, _)| *n == node).map(|(_, face)| (*placement, **face)))
        .collect();
    // The distinct (face, frame) pairs: lights share a traced visibility only in one frame.
    let mut faces: Vec<(TopFace, LightFrame)> = Vec::new();
    for (placement, face) in &lights {
        if !faces.contains(&(*face, placement.frame)) {
            faces.push((*face, placement.frame));
        }
    }
    let cells: usize = faces.iter().map(|(f, _)| f.order * f.order).sum();
    let rays: usize = faces.iter().map(|(f, _)| rays_per_receiver(f)).sum();
    crate::kinds::scene::check_ray_budget(receivers.len(), rays + lights.len() * VISIBILITY * VISIBILITY, density)?;
    // Per receiver and face: its cells, its visibility bits, its silhouette cells' shares.
    let visibility: usize =
        faces.iter().map(|(f, _)| (f.order * f.order).div_ceil(64) * 8 + max_silhouette(f) * 4 + 8).sum();
    let bytes = (receivers.len()
        * (cells * 4 + visibility + lights.len() * beyond_face::CELLS * beyond_face::CELLS * 4)) as u64;
    if bytes > crate::limits::MAX_AREA_TRANSPORT_BYTES {
        return Err(StageError::Failed(format!(
            "the area lights' transport could take up to {} MiB ({} receivers × {cells} top-face cells and {} light(s)); the \
             limit is {} MiB: lower {density}",
            bytes >> 20,
            receivers.len(),
            lights.len(),
            crate::limits::MAX_AREA_TRANSPORT_BYTES >> 20
        )));
    }
    // What every transport depends on besides its face and frame: the receivers and the triangles.
    let mut geometry = xxhash_rust::xxh3::Xxh3::new();
    geometry.update(b"area transport v2");
    geometry.update(bytemuck::cast_slice(&receivers.positions));
    geometry.update(bytemuck::cast_slice(&receivers.normals));
    geometry.update(&scene.fingerprint().to_le_bytes());
    let (world_points, world_normals) = points_and_normals(receivers);
    // Rays leave each surface just off it; the transport itself reads only the normals.
    let world_origins: Vec<DVec3> =
        world_points.iter().zip(&world_normals).map(|(&p, &n)| scene.leave_surface(p, n).as_dvec3()).collect();
    let mut out = AreaTransport::default();
    for (f, (face, frame)) in faces.iter().enumerate() {
        // Rays end at the highest plane of the lights in this frame (the top-face directions
        // all point up there): what lies above the lights, a ceiling, casts no shadow.
        // To the micrometre: a drag within a tilted light's plane keeps its height in its frame
        // only to rounding, and must not trace again.
        let ceiling = lights
            .iter()
            .filter(|(p, _)| p.frame == *frame)
            .map(|(p, _)| (p.height * 1e6).round() / 1e6)
            .fold(f64::NEG_INFINITY, f64::max);
        let (origins, normals) = (in_frame(frame, &world_origins), in_frame(frame, &world_normals));
        let to_world = frame.to_world();
        let mut of_frame = geometry.clone();
        of_frame.update(&ceiling.to_bits().to_le_bytes());
        if !frame.is_world() {
            of_frame.update(&postcard::to_allocvec(frame).map_err(|e| StageError::Internal(e.to_string()))?);
        }
        let visibility_key =
            xxhash_rust::xxh3::xxh3_128(&[of_frame.digest128().to_le_bytes().as_slice(), &face_bytes(face)].concat());
        let visibility = ctx.memo(visibility_key, || {
            let mut visibility = FaceVisibility::empty(*face);
            for start in (0..receivers.len()).step_by(TRANSPORT_CHUNK) {
                ctx.check_cancel()?;
                let end = (start + TRANSPORT_CHUNK).min(receivers.len());
                let part = face_visibility(*face, &origins[start..end], &normals[start..end], |origin, up, blocked| {
                    trace_bundle(scene, to_world, ceiling, origin, up, blocked)
                });
                visibility.append(part);
                ctx.progress((f as f64 + end as f64 / receivers.len().max(1) as f64) / faces.len() as f64);
            }
            Ok(Arc::new(visibility))
        })?;
        let visibility: Arc<FaceVisibility> = (*visibility).clone();
        let key = xxhash_rust::xxh3::xxh3_128(&[&visibility_key.to_le_bytes()[..], b"diffuse cells"].concat());
        let transport = ctx.memo(key, || {
            ctx.check_cancel()?;
            Ok(Arc::new(visible_transport(&visibility, 0..receivers.len(), &normals, |_, _| 1.0)))
        })?;
        out.faces.push(SharedTransport { key, frame: *frame, transport: (*transport).clone(), visibility });
    }
    let geometry = geometry.digest128().to_le_bytes();
    for (placement, face) in &lights {
        if out.beyond.iter().any(|b| b.placement == *placement && b.face == *face) {
            continue;
        }
        let key = xxhash_rust::xxh3::xxh3_128(
            &[
                geometry.as_slice(),
                &face_bytes(face),
                b"beyond the face v3",
                &postcard::to_allocvec(placement).map_err(|e| StageError::Internal(e.to_string()))?,
            ]
            .concat(),
        );
        let frame = placement.frame;
        let to_world = frame.to_world();
        let responses = ctx.memo(key, || {
            let (points, normals) = (in_frame(&frame, &world_points), in_frame(&frame, &world_normals));
            let origins = in_frame(&frame, &world_origins);
            let mut responses = Vec::with_capacity(receivers.len() * beyond_face::CELLS * beyond_face::CELLS);
            for start in (0..receivers.len()).step_by(TRANSPORT_CHUNK * 8) {
                ctx.check_cancel()?;
                let end = (start + TRANSPORT_CHUNK * 8).min(receivers.len());
                let part = beyond_face(
                    face,
                    placement,
                    &points[start..end],
                    &normals[start..end],
                    &origins[start..end],
                    |origin, target| {
                        let to = to_world * (target - origin);
                        let reach = to.length() * (1.0 - 1e-4);
                        !scene.occluded((to_world * origin).as_vec3a(), (to / to.length()).as_vec3a(), reach as f32)
                    },
                );
                responses.extend(part.responses);
            }
            Ok(Arc::new(BeyondFace { responses }))
        })?;
        out.beyond.push(LightBeyond { placement: *placement, face: *face, responses: (*responses).clone() });
    }
    if receivers.is_empty() {
        return Ok(out);
    }
    ctx.inform(format!(
        "{} top face(s) of {} cells traced for {} receivers ({} KB each)",
        faces.len(),
        faces.first().map_or(0, |(f, _)| f.order * f.order),
        receivers.len(),
        cells * 4 / 1024
    ));
    Ok(out)
}

/// The top-face transports of the texels of meshes with a visibility texture: their shadows
/// resolved per texel instead of per vertex (empty without such a mesh).
fn area_texel_transport(ctx: &StageContext) -> Result<StageValue, StageError> {
    let texels = ctx.required_input::<crate::transport::TexelReceivers>("scene", "texel_receivers")?;
    Ok(StageValue::new(transport_of(ctx, &texels.receivers, "the scene's visibility texture size")?))
}

/// [`area_irradiance`] at the texels of meshes with a visibility texture.
fn area_texel_irradiance(ctx: &StageContext) -> Result<StageValue, StageError> {
    let texels = ctx.required_input::<crate::transport::TexelReceivers>("scene", "texel_receivers")?;
    let transports = ctx.stage::<AreaTransport>("area_texel_transport")?;
    Ok(StageValue::new(irradiance_of(ctx, &texels.receivers, transports)?))
}

/// Every linked light's unshadowed irradiance per vertex in closed form, no ray
/// ([`crate::near_field::beyond_face::unshadowed`]): shown while the transport is traced. The
/// cells' responses are memoised on the receivers and the placement, so a stroke re-weights them.
fn area_preview(ctx: &StageContext) -> Result<StageValue, StageError> {
    let receivers = ctx.required_input::<Receivers>("scene", "receivers")?;
    let (points, normals) = points_and_normals(receivers);
    let mut geometry = xxhash_rust::xxh3::Xxh3::new();
    geometry.update(b"area preview v2");
    geometry.update(bytemuck::cast_slice(&receivers.positions));
    geometry.update(bytemuck::cast_slice(&receivers.normals));
    let mut total = vec![[0.0f64; 3]; receivers.len()];
    for (_, light) in ctx.inputs_all::<AreaLight>("area_lights", "light")? {
        let mut key = geometry.clone();
        key.update(&postcard::to_allocvec(&light.placement).map_err(|e| StageError::Internal(e.to_string()))?);
        let responses = ctx.memo(key.digest128(), || {
            ctx.check_cancel()?;
            let frame = &light.placement.frame;
            Ok(Arc::new(beyond_face::unshadowed(
                &light.placement,
                &in_frame(frame, &points),
                &in_frame(frame, &normals),
            )))
        })?;
        for (sum, e) in total.iter_mut().zip(responses.irradiance(&cell_means(&light.source))) {
            for c in 0..3 {
                sum[c] += light.scale[c] * e[c];
            }
        }
    }
    let irradiance = total.into_iter().map(|c| c.map(|v| v.max(0.0) as f32)).collect();
    Ok(StageValue::new(AreaIrradiance { irradiance }))
}

fn area_irradiance(ctx: &StageContext) -> Result<StageValue, StageError> {
    let receivers = ctx.required_input::<Receivers>("scene", "receivers")?;
    let transports = ctx.stage::<AreaTransport>("area_transport")?;
    let irradiance = irradiance_of(ctx, receivers, transports)?;
    warn_coarse_meshes(ctx, receivers, &irradiance)?;
    Ok(StageValue::new(irradiance))
}

/// A mesh shaded per vertex whose vertices lie farther apart than this share of the smallest
/// linked light's shorter side is too coarse for its shadows.
const COARSE_SPACING: f64 = 1.0 / 8.0;

/// Warns of each lit mesh shaded per vertex (no visibility texture) whose vertices lie far apart
/// next to the linked lights: a light's shadow falls between them, smeared along the triangles'
/// diagonals, displaced and detached from what casts it (a 20 m plane of 16 segments under
/// a 2 m panel: 26% from Mitsuba per vertex, 3.3% per texel).
fn warn_coarse_meshes(ctx: &StageContext, receivers: &Receivers, lit: &AreaIrradiance) -> Result<(), StageError> {
    let meshes = ctx.required_input::<crate::mesh::MeshSet>("scene", "geometry")?;
    let lights = ctx.inputs_all::<AreaLight>("area_lights", "light")?;
    let side =
        lights.iter().map(|(_, l)| l.placement.extent[0].min(l.placement.extent[1])).fold(f64::INFINITY, f64::min);
    let mut coarse = Vec::new();
    for (m, mesh) in meshes.meshes.iter().enumerate() {
        let start = receivers.mesh_offsets.get(m).copied().unwrap_or(receivers.len());
        let end = receivers.mesh_offsets.get(m + 1).copied().unwrap_or(receivers.len()).max(start);
        let shaded = lit.irradiance.get(start..end).is_some_and(|e| e.iter().any(|c| c.iter().any(|&v| v > 0.0)));
        if mesh.visibility_texture || mesh.indices.len() < 3 || !shaded {
            continue;
        }
        // The mean edge length of its triangles.
        let point = |i: u32| glam::Vec3::from(mesh.positions[i as usize]);
        let edges: f64 = mesh
            .indices
            .chunks_exact(3)
            .map(|t| {
                let (a, b, c) = (point(t[0]), point(t[1]), point(t[2]));
                f64::from(a.distance(b) + b.distance(c) + c.distance(a))
            })
            .sum();
        let spacing = edges / mesh.indices.len() as f64;
        if spacing > COARSE_SPACING * side {
            coarse.push(format!("`{}` (triangle edges {spacing:.2} m on average)", mesh.name));
        }
    }
    if let Some(first) = coarse.first() {
        let others = match coarse.len() {
            1 => String::new(),
            n => format!(" and {} other mesh(es)", n - 1),
        };
        ctx.warn(format!(
            "{first}{others}: coarse next to a {side:.1} m area light, so the light's shadows fall between the \
             vertices and smear along the triangles; turn on the object's visibility texture to shade it per \
             texel (a built-in shape can also take a higher tessellation)"
        ));
    }
    Ok(())
}

/// Every linked light's irradiance at `receivers` through their `transports`.
pub(super) fn irradiance_of(
    ctx: &StageContext,
    receivers: &Receivers,
    transports: &AreaTransport,
) -> Result<AreaIrradiance, StageError> {
    let points = positions(receivers);
    let mut total = vec![[0.0f64; 3]; receivers.len()];
    for (_, light) in ctx.inputs_all::<AreaLight>("area_lights", "light")? {
        let shared = face_of(transports, light)?;
        let points = in_frame(&light.placement.frame, &points);
        let beyond = transports
            .beyond
            .iter()
            .find(|b| b.placement == light.placement && b.face == light.face)
            .map(|b| b.responses.as_ref());
        add_light(ctx, light, shared, beyond, &points, &mut total)?;
    }
    // Truncated products ring slightly below zero near a light's footprint; irradiance cannot.
    let irradiance = total.into_iter().map(|c| c.map(|v| v.max(0.0) as f32)).collect();
    Ok(AreaIrradiance { irradiance })
}

fn face_of<'a>(transports: &'a AreaTransport, light: &AreaLight) -> Result<&'a SharedTransport, StageError> {
    transports
        .faces
        .iter()
        .find(|f| f.transport.face == light.face && f.frame == light.placement.frame)
        .ok_or_else(|| StageError::Internal("no transport for a light's top face".into()))
}

/// Adds `scale · Σ_k L_k T_k` of one light through `shared`'s transport to `total`, and its
/// light `beyond` the face; the unscaled sum is memoised on the light's coefficients,
/// placement, shading and the transport (what `beyond` depends on too).
fn add_light(
    ctx: &StageContext,
    light: &AreaLight,
    shared: &SharedTransport,
    beyond: Option<&BeyondFace>,
    points: &[DVec3],
    total: &mut [[f64; 3]],
) -> Result<(), StageError> {
    let described = (&light.source, &light.placement, &light.shading());
    let mut key = xxhash_rust::xxh3::Xxh3::new();
    key.update(b"area irradiance v2");
    key.update(&shared.key.to_le_bytes());
    key.update(&postcard::to_allocvec(&described).map_err(|e| StageError::Internal(e.to_string()))?);
    let unscaled = ctx.memo(key.digest128(), || {
        ctx.check_cancel()?;
        let e = match light.keep {
            TargetKeep::Largest(_) => {
                irradiance(&light.source, &light.placement, &shared.transport, points, light.shading())
            }
            _ => shade_by_responses(ctx, light, shared, points)?,
        };
        let e = match beyond {
            Some(beyond) => e
                .iter()
                .zip(beyond.irradiance(&cell_means(&light.source)))
                .map(|(a, b)| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
                .collect(),
            None => e,
        };
        Ok(UnscaledIrradiance(e.into_iter().map(|c| c.map(|v| v as f32)).collect()))
    })?;
    for (sum, e) in total.iter_mut().zip(&unscaled.0) {
        for c in 0..3 {
            sum[c] += light.scale[c] * f64::from(e[c]);
        }
    }
    Ok(())
}

/// Per vertex, the BRDF of its mesh's material: the material linked under the mesh's name, else
/// the first linked, else the default (as the frame assigns them).
fn vertex_brdfs(ctx: &StageContext, receivers: &Receivers) -> Result<(Vec<crate::brdf::Brdf>, Vec<u32>), StageError> {
    let meshes = ctx.required_input::<crate::mesh::MeshSet>("scene", "geometry")?;
    let linked = ctx.inputs_all::<crate::brdf::Material>("material", "material")?;
    let mut brdfs: Vec<crate::brdf::Brdf> = linked.iter().map(|(_, m)| crate::brdf::Brdf::from_material(m)).collect();
    if brdfs.is_empty() {
        brdfs.push(crate::brdf::Brdf::from_material(&Default::default()));
    }
    let mut of_vertex = vec![0u32; receivers.len()];
    for (m, mesh) in meshes.meshes.iter().enumerate() {
        let found = super::named_material(&mesh.material, linked.iter().map(|(node, _)| *node));
        let start = receivers.mesh_offsets.get(m).copied().unwrap_or(receivers.len());
        let end = receivers.mesh_offsets.get(m + 1).copied().unwrap_or(receivers.len());
        of_vertex[start.min(end)..end].fill(found.unwrap_or(0) as u32);
    }
    Ok((brdfs, of_vertex))
}

/// Vertices per cancellation check and progress step of a glossy transport.
const GLOSSY_CHUNK: usize = 2048;

/// Sun 2008 §4.9, near-field relighting of specular scenes for a fixed view: per face, the
/// transport weighted by each vertex's specular lobe toward `highlight_eye` (from the face's
/// visibility, no new rays; memoised on the visibility, the eye and the materials), shaded by
/// every light as the irradiance is, with each light's cells beyond the face weighted by the
/// lobe toward their centres ([`beyond_face::weighted`]), then tinted by each material's
/// specular colour.
fn area_highlights(ctx: &StageContext) -> Result<StageValue, StageError> {
    let receivers = ctx.required_input::<Receivers>("scene", "receivers")?;
    let transports = ctx.stage::<AreaTransport>("area_transport")?;
    let (brdfs, of_vertex) = vertex_brdfs(ctx, receivers)?;
    let lights = ctx.inputs_all::<AreaLight>("area_lights", "light")?;
    if brdfs.iter().all(|b| b.lobe == crate::brdf::Lobe::None) || lights.is_empty() {
        return Ok(StageValue::new(AreaHighlights::default()));
    }
    let eye = DVec3::from(ctx.vec3("highlight_eye")?);
    let points = positions(receivers);
    // Per vertex: its normal, world to its shading frame, and the direction to the eye there
    // (for a tilted light, from its frame to the shading frame).
    let (normals, views): (Vec<DVec3>, Vec<(glam::DMat3, DVec3)>) = (0..receivers.len())
        .map(|i| {
            let (p, n) = receivers.point(i);
            let tangent = DVec3::from(receivers.tangents[i].map(f64::from));
            let to_local = crate::rsl::shade::shading_frame(n, tangent).transpose();
            (n, (to_local, to_local * (eye - p).normalize_or(n)))
        })
        .unzip();
    // What a glossy transport depends on besides its face's visibility: the eye and each
    // vertex's lobe.
    let lobes: Vec<String> = brdfs.iter().map(|b| format!("{:?}/{}", b.lobe, b.f0)).collect();
    let mut seen = xxhash_rust::xxh3::Xxh3::new();
    seen.update(b"area glossy transport v2");
    seen.update(bytemuck::cast_slice(&eye.to_array()));
    seen.update(&postcard::to_allocvec(&lobes).map_err(|e| StageError::Internal(e.to_string()))?);
    seen.update(bytemuck::cast_slice(&of_vertex));
    let mut total = vec![[0.0f64; 3]; receivers.len()];
    for (_, light) in &lights {
        let diffuse = face_of(transports, light)?;
        let mut key = seen.clone();
        key.update(&diffuse.key.to_le_bytes());
        let key = key.digest128();
        let visibility = &diffuse.visibility;
        // The light's frame: its cells' directions turn back into the world for the lobes.
        let frame = light.placement.frame;
        let (normals, points) = (in_frame(&frame, &normals), in_frame(&frame, &points));
        let views: std::borrow::Cow<[(glam::DMat3, DVec3)]> = if frame.is_world() {
            std::borrow::Cow::Borrowed(&views)
        } else {
            let to_world = frame.to_world();
            views.iter().map(|&(to_local, wo)| (to_local * to_world, wo)).collect()
        };
        let transport = ctx.memo(key, || {
            let mut glossy = FaceTransport::empty(visibility.face);
            for start in (0..receivers.len()).step_by(GLOSSY_CHUNK) {
                ctx.check_cancel()?;
                let end = (start + GLOSSY_CHUNK).min(receivers.len());
                glossy.append(visible_transport(visibility, start..end, &normals, |r, w| {
                    let (to_local, wo) = views[r];
                    brdfs[of_vertex[r] as usize].lobe_value(to_local * w, wo)
                }));
                ctx.progress(end as f64 / receivers.len().max(1) as f64);
            }
            Ok(Arc::new(glossy))
        })?;
        let glossy =
            SharedTransport { key, frame, transport: (*transport).clone(), visibility: diffuse.visibility.clone() };
        // The light beyond the face, through each vertex's lobe toward the eye.
        let beyond = match transports.beyond.iter().find(|b| b.placement == light.placement && b.face == light.face) {
            Some(beyond) => {
                let mut at = xxhash_rust::xxh3::Xxh3::new();
                at.update(b"glossy beyond the face v1");
                at.update(&key.to_le_bytes());
                at.update(&postcard::to_allocvec(&light.placement).map_err(|e| StageError::Internal(e.to_string()))?);
                let weighted = ctx.memo(at.digest128(), || {
                    ctx.check_cancel()?;
                    Ok(Arc::new(beyond_face::weighted(&beyond.responses, &light.placement, &points, |r, w| {
                        let (to_local, wo) = views[r];
                        brdfs[of_vertex[r] as usize].lobe_value(to_local * w, wo)
                    })))
                })?;
                Some((*weighted).clone())
            }
            None => None,
        };
        add_light(ctx, light, &glossy, beyond.as_deref(), &points, &mut total)?;
    }
    let radiance = total
        .iter()
        .zip(&of_vertex)
        .map(|(l, &m)| {
            let specular = brdfs[m as usize].specular;
            std::array::from_fn(|c| (l[c].max(0.0) * specular[c]) as f32)
        })
        .collect();
    Ok(StageValue::new(AreaHighlights { radiance }))
}

/// `E = Σ_i F_i G_i` with each coefficient's response `G_i` memoised (see the module doc): the
/// responses the light lacks are computed together, then all are summed in the light's order,
/// the bits of [`irradiance`].
fn shade_by_responses(
    ctx: &StageContext,
    light: &AreaLight,
    shared: &SharedTransport,
    points: &[DVec3],
) -> Result<Vec<[f64; 3]>, StageError> {
    let mut placed = xxhash_rust::xxh3::Xxh3::new();
    placed.update(b"area response v1");
    placed.update(&shared.key.to_le_bytes());
    placed.update(
        &postcard::to_allocvec(&(&light.placement, &light.shading()))
            .map_err(|e| StageError::Internal(e.to_string()))?,
    );
    let key_of = |(i1, i2): (u16, u16)| {
        let mut key = placed.clone();
        key.update(&i1.to_le_bytes());
        key.update(&i2.to_le_bytes());
        key.digest128()
    };
    let indices: Vec<(u16, u16)> = light.source.coefficients.iter().map(|c| c.0).collect();
    // A light too detailed for its responses to be kept is shaded afresh (the same bits).
    if indices.len() * points.len() * 8 > RESPONSE_MEMO_BYTES {
        return Ok(irradiance(&light.source, &light.placement, &shared.transport, points, light.shading()));
    }
    let mut columns: Vec<Option<crate::engine::Memo<Response>>> =
        indices.iter().map(|&i| ctx.memo_cached::<Response>(key_of(i))).collect();
    // Where in the light's order the memory cache lacks a response.
    let missing: Vec<usize> = (0..indices.len()).filter(|&at| columns[at].is_none()).collect();
    for batch in missing.chunks(response_batch(points.len())) {
        ctx.check_cancel()?;
        let wanted: Vec<(u16, u16)> = batch.iter().map(|&at| indices[at]).collect();
        let g = responses(&wanted, &light.placement, &shared.transport, points, light.shading())
            .ok_or_else(|| StageError::Internal("responses of a light whose kept set follows it".into()))?;
        for (values, &at) in g.into_iter().zip(batch) {
            columns[at] = Some(ctx.memo(key_of(indices[at]), || Ok(Response(values)))?);
        }
    }
    let columns: Vec<&[f64]> = columns.iter().map(|c| c.as_ref().map_or(&[][..], |c| c.0.as_slice())).collect();
    Ok(shade_columns(&light.source, &columns, points.len()))
}
