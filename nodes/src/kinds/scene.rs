//! Scene node: the objects lit by the graph (built-in shapes and a glTF file), their receiver
//! points, the ray-tracing BVH, and the visibility transport every PRT technique reads.

use crate::engine::spec::{
    Availability, NodeKindSpec, ParamKind, ParamSpec, ParamValue, PortSpec, PortType, StageSpec,
};
use crate::engine::{Codec, StageContext, StageError, StageValue};
use crate::mesh::{self, MeshSet};
use crate::raycast::RayScene;
pub use crate::scene_object::{SceneObject, Shape};
use crate::transport::{self, Receivers};
use glam::{DMat4, DQuat, DVec3};

impl SceneObject {
    pub fn new(name: &str, shape: Shape) -> Self {
        Self {
            name: name.into(),
            shape,
            translation: [0.0; 3],
            rotation_deg: [0.0; 3],
            scale: [1.0; 3],
            color: crate::scene_object::grey(),
            visibility_texture: false,
            material: String::new(),
            box_uvs: None,
        }
    }

    pub fn at(mut self, translation: [f64; 3]) -> Self {
        self.translation = translation;
        self
    }

    pub fn with_color(mut self, color: [f64; 3]) -> Self {
        self.color = color;
        self
    }

    pub fn transform(&self) -> DMat4 {
        let [x, y, z] = self.rotation_deg.map(f64::to_radians);
        let rotation = DQuat::from_rotation_y(y) * DQuat::from_rotation_x(x) * DQuat::from_rotation_z(z);
        DMat4::from_scale_rotation_translation(DVec3::from(self.scale), rotation, DVec3::from(self.translation))
    }

    /// Range checks with messages naming the object.
    pub fn check(&self) -> Result<(), String> {
        let numbers: Vec<f64> =
            self.translation.iter().chain(&self.rotation_deg).chain(&self.scale).chain(&self.color).copied().collect();
        if numbers.iter().any(|v| !v.is_finite()) {
            return Err(format!("object `{}` has a non-finite number", self.name));
        }
        if self.translation.iter().any(|v| v.abs() > 1e6) {
            return Err(format!("object `{}` is more than 1e6 m from the origin", self.name));
        }
        if self.scale.iter().any(|s| s.abs() < 1e-6 || s.abs() > 1e6) {
            return Err(format!(
                "object `{}` has scale {:?}; each axis must be within 1e-6..1e6 in size",
                self.name, self.scale
            ));
        }
        if self.color.iter().any(|c| *c < 0.0 || *c > 1.0) {
            return Err(format!("object `{}` colour {:?} must be within 0..1", self.name, self.color));
        }
        let sizes: Vec<f64> = match &self.shape {
            Shape::Gltf { file } if file.is_empty() => {
                return Err(format!("object `{}` is a glTF model without a file: choose one", self.name));
            }
            Shape::Gltf { .. } => vec![],
            Shape::Plane { size } | Shape::CornellBox { size } => vec![*size],
            Shape::Sphere { radius } => vec![*radius],
            Shape::Box { size } => size.to_vec(),
            Shape::Torus { major, minor } => vec![*major, *minor],
        };
        if sizes.iter().any(|s| !s.is_finite() || *s <= 0.0 || *s > 1e6) {
            return Err(format!("object `{}` has a size outside (0, 1e6] m", self.name));
        }
        if let Some(size) = self.box_uvs
            && !(size.is_finite() && (1e-6..=1e6).contains(&size))
        {
            return Err(format!("object `{}` has box_uvs {size}: a tile must be within 1e-6..1e6 m", self.name));
        }
        Ok(())
    }

    /// World-space meshes of the object; `project_dir` resolves a glTF model's file.
    pub fn meshes(&self, tessellation: usize, project_dir: &std::path::Path) -> Result<Vec<mesh::Mesh>, String> {
        Ok(self.place(self.raw_meshes(tessellation, project_dir)?, self.transform()))
    }

    /// Object-space meshes (no transform): what per-object transport is computed on.
    pub fn object_meshes(&self, tessellation: usize, project_dir: &std::path::Path) -> Result<Vec<mesh::Mesh>, String> {
        Ok(self.place(self.raw_meshes(tessellation, project_dir)?, DMat4::IDENTITY))
    }

    fn raw_meshes(&self, tessellation: usize, project_dir: &std::path::Path) -> Result<Vec<mesh::Mesh>, String> {
        Ok(match &self.shape {
            Shape::Plane { size } => vec![mesh::plane(*size, (tessellation / 4).max(1))],
            Shape::Sphere { radius } => vec![mesh::sphere(*radius, tessellation)],
            Shape::Box { size } => vec![mesh::cuboid(*size, (tessellation / 8).max(1), false)],
            Shape::Torus { major, minor } => vec![mesh::torus(*major, *minor, tessellation)],
            Shape::CornellBox { size } => mesh::cornell_box(*size, (tessellation / 8).max(1)),
            Shape::Gltf { file } => {
                let imported = crate::gltf_import::import(&project_dir.join(file))
                    .map_err(|e| format!("object `{}`: {e}", self.name))?;
                imported.meshes
            }
        })
    }

    /// Applies the object's transform, colour, material and name to its meshes.
    fn place(&self, raw: Vec<mesh::Mesh>, transform: DMat4) -> Vec<mesh::Mesh> {
        // A model's parts are always named `object/part`, so they can be found by the object.
        let model = matches!(self.shape, Shape::Gltf { .. });
        let single = raw.len() == 1 && !model;
        raw.into_iter()
            .map(|m| {
                // Box-projected coordinates overlap: no visibility texture over them.
                let own_uvs = m.uvs.len() == m.positions.len();
                let m = match self.box_uvs {
                    Some(size) => m.box_projected(size, self.scale.map(f64::abs)),
                    None => m,
                };
                let mut m = m.transformed(transform);
                m.transform = transform.to_cols_array();
                m.visibility_texture = self.visibility_texture && own_uvs;
                // A model keeps its own materials unless the object names one.
                if !(model && self.material.is_empty()) {
                    m.material = self.material.clone();
                }
                let tint = self.color.map(|c| c as f32);
                if single {
                    m.base_color = tint;
                    m.name = self.name.clone();
                } else {
                    m.base_color = [0, 1, 2].map(|c| m.base_color[c] * tint[c] / 0.8);
                    m.name = format!("{}/{}", self.name, m.name);
                }
                m
            })
            .collect()
    }
}

/// The default project's scene: a sphere and a torus on a floor.
pub fn default_objects() -> Vec<SceneObject> {
    vec![
        SceneObject { visibility_texture: true, ..SceneObject::new("floor", Shape::Plane { size: 8.0 }) },
        SceneObject::new("sphere", Shape::Sphere { radius: 0.75 }).at([-0.9, 0.75, 0.0]).with_color([0.9, 0.35, 0.3]),
        SceneObject {
            rotation_deg: [60.0, 20.0, 0.0],
            ..SceneObject::new("torus", Shape::Torus { major: 0.6, minor: 0.22 })
                .at([1.0, 0.75, 0.2])
                .with_color([0.3, 0.5, 0.9])
        },
    ]
}

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "Scene",
        label: "Scene",
        doc: "Objects to light: built-in shapes and glTF models, with transforms and colours.",
        inputs: vec![],
        outputs: vec![PortSpec { name: "scene", ty: PortType::Scene, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "objects",
                label: "Objects",
                unit: "",
                kind: ParamKind::Objects { default: default_objects() },
                doc: "Shapes and glTF models, their transforms, colours and materials.",
            },
            ParamSpec {
                name: "tessellation",
                label: "Tessellation",
                unit: "",
                kind: ParamKind::Int { min: 3, max: 1024, default: 48 },
                doc: "Segments of curved shapes (flat shapes use a quarter).",
            },
            ParamSpec {
                name: "visibility_texture_size",
                label: "Visibility texture size",
                unit: "px",
                kind: ParamKind::Choice { options: &["16", "32", "64", "128", "256"], default: "64", labels: &[] },
                doc: "Texels per side of the visibility textures of objects that ask for one.",
            },
            ParamSpec {
                name: "transport_bands",
                label: "Transport SH bands",
                unit: "",
                kind: ParamKind::Int { min: 1, max: 16, default: 6 },
                doc: "Bands of the SH visibility and transfer.",
            },
            ParamSpec {
                name: "transport_rays",
                label: "Rays per receiver",
                unit: "",
                kind: ParamKind::Int { min: 16, max: 65536, default: 256 },
                doc: "Spherical Fibonacci directions per receiver for the SH transport.",
            },
            ParamSpec {
                name: "haar_resolution",
                label: "Haar cube face size",
                unit: "px",
                kind: ParamKind::Choice { options: &["4", "8", "16", "32", "64"], default: "16", labels: &[] },
                doc: "Visibility cube map per receiver (one ray per texel).",
            },
            ParamSpec {
                name: "haar_terms",
                label: "Haar terms",
                unit: "",
                kind: ParamKind::Int { min: 1, max: 24576, default: 128 },
                doc: "Largest area-weighted Haar coefficients kept per receiver.",
            },
            ParamSpec {
                name: "local_frame_depth",
                label: "Local-frame depth",
                unit: "",
                kind: ParamKind::Int { min: 1, max: 5, default: 3 },
                doc: "Icosahedral subdivision level of the local-frame visibility (20·4^depth cells).",
            },
            ParamSpec {
                name: "local_frame_terms",
                label: "Local-frame terms",
                unit: "",
                kind: ParamKind::Int { min: 1, max: 20480, default: 320 },
                doc: "Spherical Haar coefficients kept per receiver (Ma et al. use 80 or 320).",
            },
        ],
        stages: vec![
            StageSpec {
                name: "geometry",
                version: 1,
                params: &["objects", "tessellation"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: geometry,
            },
            StageSpec {
                name: "receivers",
                version: 1,
                params: &[],
                stages: &["geometry"],
                inputs: &[],
                persist: None,
                compute: receivers,
            },
            StageSpec {
                name: "adjacency",
                version: 1,
                params: &[],
                stages: &["geometry"],
                inputs: &[],
                persist: None,
                compute: adjacency,
            },
            StageSpec {
                name: "vertex_frames",
                version: 1,
                params: &[],
                stages: &["geometry"],
                inputs: &[],
                persist: None,
                compute: vertex_frames,
            },
            StageSpec {
                name: "ray_scene",
                version: 1,
                params: &[],
                stages: &["geometry"],
                inputs: &[],
                persist: None,
                compute: ray_scene,
            },
            StageSpec {
                name: "texel_receivers",
                version: 1,
                params: &["visibility_texture_size"],
                stages: &["geometry"],
                inputs: &[],
                persist: None,
                compute: texel_receivers,
            },
            StageSpec {
                name: "transport_sh",
                version: 2,
                params: &["transport_bands", "transport_rays"],
                stages: &["receivers", "ray_scene"],
                inputs: &[],
                persist: Some(Codec::of::<crate::transport::ShTransport>()),
                compute: transport_sh,
            },
            StageSpec {
                name: "transport_objects",
                version: 2,
                params: &["objects", "tessellation", "transport_bands", "transport_rays"],
                stages: &[],
                inputs: &[],
                persist: Some(Codec::of::<Vec<crate::transport::ObjectTransport>>()),
                compute: transport_objects,
            },
            StageSpec {
                name: "transport_haar",
                version: 2,
                params: &["haar_resolution", "haar_terms"],
                stages: &["receivers", "ray_scene"],
                inputs: &[],
                persist: Some(Codec::of::<crate::transport::HaarTransport>()),
                compute: transport_haar,
            },
            StageSpec {
                name: "transport_local",
                version: 2,
                params: &["local_frame_depth", "local_frame_terms"],
                stages: &["receivers", "ray_scene"],
                inputs: &[],
                persist: Some(Codec::of::<crate::transport::SphericalTransport>()),
                compute: transport_local,
            },
            StageSpec {
                name: "transport_texels",
                version: 2,
                params: &["local_frame_depth", "local_frame_terms"],
                stages: &["texel_receivers", "ray_scene"],
                inputs: &[],
                persist: Some(Codec::of::<crate::transport::SphericalTransport>()),
                compute: transport_texels,
            },
        ],
        previews: Vec::new(),
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::gltf_import::referenced_files,
    }
}

fn texel_receivers(ctx: &StageContext) -> Result<StageValue, StageError> {
    let meshes = ctx.stage::<crate::mesh::MeshSet>("geometry")?;
    let size: usize =
        ctx.choice("visibility_texture_size")?.parse().map_err(|_| StageError::Internal("size".into()))?;
    Ok(StageValue::new(transport::TexelReceivers::rasterize(meshes, size)))
}

fn transport_texels(ctx: &StageContext) -> Result<StageValue, StageError> {
    let (depth, keep) = (ctx.int("local_frame_depth")? as usize, ctx.int("local_frame_terms")? as usize);
    let (r, s) = transport_inputs(ctx, "texel_receivers")?;
    check_ray_budget(r.len(), 20 << (2 * depth.min(20)), "visibility_texture_size or local_frame_depth")?;
    Ok(StageValue::new(transport::spherical_transport(s, r, depth, keep, ctx.cancel_token(), &|f| ctx.progress(f))?))
}

fn geometry(ctx: &StageContext) -> Result<StageValue, StageError> {
    let ParamValue::Objects(objects) = ctx.value("objects")? else {
        return Err(StageError::Internal("objects".into()));
    };
    let tessellation = ctx.int("tessellation")? as usize;
    let mut meshes = Vec::new();
    for object in objects {
        meshes.extend(object.meshes(tessellation, ctx.project_dir()).map_err(StageError::Failed)?);
    }
    let triangles: usize = meshes.iter().map(|m| m.triangle_count()).sum();
    if triangles > crate::limits::MAX_TRIANGLES {
        return Err(StageError::Failed(format!(
            "the scene has {triangles} triangles; the limit is {}: lower tessellation",
            crate::limits::MAX_TRIANGLES
        )));
    }
    Ok(StageValue::new(MeshSet { meshes }))
}

fn receivers(ctx: &StageContext) -> Result<StageValue, StageError> {
    let meshes = ctx.stage::<crate::mesh::MeshSet>("geometry")?;
    Ok(StageValue::new(Receivers::from_meshes(meshes)))
}

/// Vertex neighbours over the triangles, in the receivers' order (the adaptive SH mode's
/// region-of-interest search walks it).
fn adjacency(ctx: &StageContext) -> Result<StageValue, StageError> {
    let meshes = ctx.stage::<crate::mesh::MeshSet>("geometry")?;
    Ok(StageValue::new(crate::adaptive_sh::Adjacency::from_triangles(
        meshes.meshes.iter().map(|m| (m.positions.len(), m.indices.as_slice())),
    )))
}

/// Every vertex's normal-map tangent frame, as the viewport draws it.
fn vertex_frames(ctx: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(crate::mesh::VertexFrames::of(ctx.stage::<MeshSet>("geometry")?)))
}

fn ray_scene(ctx: &StageContext) -> Result<StageValue, StageError> {
    let meshes = ctx.stage::<crate::mesh::MeshSet>("geometry")?;
    Ok(StageValue::new(RayScene::build(meshes)))
}

/// The receivers (`receivers` or `texel_receivers`) and the ray scene.
fn transport_inputs<'a>(ctx: &'a StageContext, receivers: &str) -> Result<(&'a Receivers, &'a RayScene), StageError> {
    let r = match receivers {
        "texel_receivers" => &ctx.stage::<transport::TexelReceivers>(receivers)?.receivers,
        _ => ctx.stage::<Receivers>(receivers)?,
    };
    let s = ctx.stage::<crate::raycast::RayScene>("ray_scene")?;
    Ok((r, s))
}

/// Refuses a precompute of more than [`crate::limits::MAX_TOTAL_RAYS`] rays, saying which
/// parameters to lower.
pub(super) fn check_ray_budget(receivers: usize, per_receiver: usize, lower: &str) -> Result<(), StageError> {
    let total = receivers as u64 * per_receiver as u64;
    if total > crate::limits::MAX_TOTAL_RAYS {
        return Err(StageError::Failed(format!(
            "this would cast {:.1e} visibility rays ({receivers} receivers × {per_receiver}); the limit is {:.0e}: \
             lower {lower}",
            total as f64,
            crate::limits::MAX_TOTAL_RAYS as f64
        )));
    }
    Ok(())
}

fn transport_sh(ctx: &StageContext) -> Result<StageValue, StageError> {
    let (bands, rays) = (ctx.int("transport_bands")? as usize, ctx.int("transport_rays")? as usize);
    let (r, s) = transport_inputs(ctx, "receivers")?;
    check_ray_budget(r.len(), rays, "transport_rays or tessellation")?;
    Ok(StageValue::new(transport::sh_transport(s, r, bands, rays, ctx.cancel_token(), &|f| ctx.progress(f))?))
}

/// Per-object self-shadowing SH transport, each object memoised on its object-space shape,
/// so moving, rotating or recolouring one object recomputes nothing (see `ObjectTransport`).
fn transport_objects(ctx: &StageContext) -> Result<StageValue, StageError> {
    let ParamValue::Objects(objects) = ctx.value("objects")? else {
        return Err(StageError::Internal("objects".into()));
    };
    let (tessellation, bands, rays) =
        (ctx.int("tessellation")? as usize, ctx.int("transport_bands")? as usize, ctx.int("transport_rays")? as usize);
    let mut out = Vec::with_capacity(objects.len());
    for object in objects {
        let bytes = object_shape_key(ctx, object, &format!("self-sh v1 {tessellation} {bands} {rays}"))?;
        out.push(self_transport(ctx, &bytes, &object.name, object.transform(), (bands, rays), || {
            object.object_meshes(tessellation, ctx.project_dir()).map_err(StageError::Failed)
        })?);
        ctx.progress(out.len() as f64 / objects.len() as f64);
    }
    Ok(StageValue::new(out))
}

/// Bytes identifying an object's object-space geometry (its shape, and a model's file
/// content, not only its name) followed by `suffix` (what else the memoised value depends on).
fn object_shape_key(ctx: &StageContext, object: &SceneObject, suffix: &str) -> Result<Vec<u8>, StageError> {
    let mut bytes = postcard::to_stdvec(&object.shape).map_err(|e| StageError::Internal(e.to_string()))?;
    if let Some(file) = object.file() {
        let path = ctx.project_dir().join(file);
        let content = crate::limits::read_regular_file(&path, crate::limits::MAX_FILE_BYTES)
            .map_err(|e| StageError::Failed(format!("object `{}`: {e}", object.name)))?;
        bytes.extend_from_slice(&xxhash_rust::xxh3::xxh3_64(&content).to_le_bytes());
    }
    bytes.extend_from_slice(suffix.as_bytes());
    Ok(bytes)
}

/// Per object, a value computed from its object-space meshes and memoised on its shape, the
/// tessellation and `suffix` (what else the value depends on), so moving, turning or
/// recolouring an object recomputes nothing (the report counts the memo hits). Progress spans
/// the objects still to compute, each its share of their `work` (what the computation costs in
/// proportion to, from the meshes), so that the time left estimated from it holds when a
/// small object (a floor) comes before a large model.
pub(super) fn per_object_memo<T: crate::engine::Persisted + Clone>(
    ctx: &StageContext,
    objects: &[SceneObject],
    suffix: &str,
    work: impl Fn(&[crate::mesh::Mesh]) -> f64,
    compute: impl Fn(&SceneObject, &MeshSet, &(dyn Fn(f64) + Sync)) -> Result<T, StageError>,
) -> Result<Vec<T>, StageError> {
    let tessellation = ctx.int("tessellation")? as usize;
    let mut pending = Vec::with_capacity(objects.len());
    for object in objects {
        let key = xxhash_rust::xxh3::xxh3_128(&object_shape_key(ctx, object, &format!("{suffix} {tessellation}"))?);
        pending.push(match ctx.memo_cached::<T>(key) {
            Some(value) => (key, Err(value)),
            None => (key, Ok(object.object_meshes(tessellation, ctx.project_dir()).map_err(StageError::Failed)?)),
        });
    }
    let weight = |meshes: &Vec<crate::mesh::Mesh>| work(meshes).max(1e-9);
    let total: f64 = pending.iter().filter_map(|(_, p)| p.as_ref().ok()).map(weight).sum::<f64>().max(1e-9);
    let mut done = 0.0;
    let mut out = Vec::with_capacity(objects.len());
    for (object, (key, pending)) in objects.iter().zip(pending) {
        let value = match pending {
            Err(cached) => cached,
            Ok(meshes) => {
                let share = weight(&meshes) / total;
                let value = ctx.memo(key, || {
                    let meshes = MeshSet { meshes };
                    compute(object, &meshes, &|f| ctx.progress((done + f * share).min(1.0)))
                })?;
                done += share;
                ctx.progress(done.min(1.0));
                value
            }
        };
        out.push((*value).clone());
    }
    Ok(out)
}

/// One object's self-shadowing SH transport, memoised under the hash of `key_bytes`
/// (everything its object-space geometry and sampling depend on).
fn self_transport(
    ctx: &StageContext,
    key_bytes: &[u8],
    name: &str,
    world_from_object: DMat4,
    (bands, rays): (usize, usize),
    object_meshes: impl FnOnce() -> Result<Vec<crate::mesh::Mesh>, StageError>,
) -> Result<transport::ObjectTransport, StageError> {
    let sh = ctx.memo(xxhash_rust::xxh3::xxh3_128(key_bytes), || {
        let meshes = MeshSet { meshes: object_meshes()? };
        let scene = RayScene::build(&meshes);
        let receivers = Receivers::from_meshes(&meshes);
        check_ray_budget(receivers.len(), rays, "transport_rays or tessellation")?;
        transport::sh_transport(&scene, &receivers, bands, rays, ctx.cancel_token(), &|_| {})
    })?;
    Ok(transport::ObjectTransport {
        name: name.to_string(),
        world_from_object: world_from_object.to_cols_array(),
        sh: std::sync::Arc::new((*sh).clone()),
    })
}

fn transport_haar(ctx: &StageContext) -> Result<StageValue, StageError> {
    let size: usize =
        ctx.choice("haar_resolution")?.parse().map_err(|_| StageError::Internal("haar_resolution".into()))?;
    let keep = ctx.int("haar_terms")? as usize;
    let (r, s) = transport_inputs(ctx, "receivers")?;
    check_ray_budget(r.len(), 6 * size * size, "haar_resolution or tessellation")?;
    Ok(StageValue::new(transport::haar_transport(s, r, size, keep, ctx.cancel_token(), &|f| ctx.progress(f))?))
}

fn transport_local(ctx: &StageContext) -> Result<StageValue, StageError> {
    let (depth, keep) = (ctx.int("local_frame_depth")? as usize, ctx.int("local_frame_terms")? as usize);
    let (r, s) = transport_inputs(ctx, "receivers")?;
    check_ray_budget(r.len(), 20 << (2 * depth.min(20)), "local_frame_depth or tessellation")?;
    Ok(StageValue::new(transport::spherical_transport(s, r, depth, keep, ctx.cancel_token(), &|f| ctx.progress(f))?))
}
