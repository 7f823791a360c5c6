//! The baked scene as binary glTF 2.0 (`scene.glb`), written with the `gltf` crate's JSON
//! types: one node per mesh with its object's transform (TRS) and the geometry in object
//! space, materials as metallic-roughness ([`super::material_fit`]), the baked light per
//! vertex as `COLOR_0`, point lights as `KHR_lights_punctual`, and the project's camera.
//!
//! `COLOR_0` is linear `E/π` (see [`super::vertex_light`]) divided by one scale for the whole
//! scene, since glTF colours lie in 0..1: a renderer shows the baked lighting as `baseColor ×
//! COLOR_0 × scale`, unlit. The scale is a power of two (so the division is exact), stored in
//! the scene's `extras.lightloom.vertexLightScale`.

use super::material_fit::MaterialFit;
use crate::light::PointLight;
use crate::mesh::MeshSet;
use glam::{DMat3, DMat4, DQuat, DVec3};
use gltf::json::{self, validation::Checked::Valid, validation::USize64};
use std::borrow::Cow;
use std::collections::BTreeMap;

/// The project's camera as glTF needs it.
#[derive(Clone, Debug)]
pub struct ExportCamera {
    pub name: String,
    pub position: [f64; 3],
    pub target: [f64; 3],
    pub fov_y_deg: f64,
    pub aspect: f64,
}

/// A distant light of finite size (a square light of the `rsl` mode).
#[derive(Clone, Debug, PartialEq)]
pub struct DirectionalLight {
    /// Unit direction towards the light.
    pub direction: [f64; 3],
    /// Its solid angle, sr.
    pub solid_angle: f64,
    /// Its mean radiance.
    pub radiance: [f64; 3],
}

/// What [`write_glb`] writes.
pub struct ExportScene<'a> {
    pub meshes: &'a MeshSet,
    /// `E/π` per vertex, in [`MeshSet`] order.
    pub vertex_light: &'a [[f32; 3]],
    /// Per mesh: its index in `materials`.
    pub mesh_materials: &'a [u32],
    /// `(name, material)` in the frame's order.
    pub materials: &'a [(String, crate::brdf::Material)],
    pub lights: &'a [PointLight],
    /// The square-light mode's lights, written as directional lights.
    pub directional: &'a [DirectionalLight],
    pub camera: Option<ExportCamera>,
    pub lightmap: Option<ExportLightmap<'a>>,
}

/// The lightmap: its atlas (`TEXCOORD_1`, seam vertices duplicated) and its RGBM PNG, shown
/// to every material through the `LIGHTLOOM_lightmap` extension (shaped like `MSFT_lightmap`):
/// `{"lightmapTexture": {"index", "texCoord": 1}, "encoding": "RGBM", "range", "exr"}`, the
/// decoded value being `E/π` as in `COLOR_0 × scale`.
pub struct ExportLightmap<'a> {
    pub atlas: &'a crate::lightmap::LightmapAtlas,
    pub png: &'a [u8],
    pub range: f32,
    /// The float EXR beside the GLB.
    pub exr_name: &'a str,
}

/// The extension materials point at the lightmap with.
pub const LIGHTMAP_EXTENSION: &str = "LIGHTLOOM_lightmap";

/// One glTF material written: its source and fit.
#[derive(Clone, Debug)]
pub struct WrittenMaterial {
    pub name: String,
    /// The BRDF editor node it comes from (empty for the default material).
    pub source: String,
    pub model: String,
    pub fit: MaterialFit,
}

/// The file and what is in it.
pub struct Glb {
    pub bytes: Vec<u8>,
    pub materials: Vec<WrittenMaterial>,
    /// What `COLOR_0` is multiplied by to give `E/π`.
    pub vertex_light_scale: f32,
}

/// Byte data of the BIN chunk, with views 4-byte aligned.
#[derive(Default)]
struct BinBuilder {
    data: Vec<u8>,
}

impl BinBuilder {
    fn view(
        &mut self,
        root: &mut json::Root,
        bytes: &[u8],
        target: json::buffer::Target,
    ) -> json::Index<json::buffer::View> {
        let offset = self.data.len();
        self.data.extend_from_slice(bytes);
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: None,
            extras: Default::default(),
            name: None,
            target: Some(Valid(target)),
        })
    }
}

fn accessor(
    root: &mut json::Root,
    view: json::Index<json::buffer::View>,
    count: usize,
    component: json::accessor::ComponentType,
    type_: json::accessor::Type,
    bounds: Option<([f32; 3], [f32; 3])>,
) -> json::Index<json::Accessor> {
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(component)),
        extensions: None,
        extras: Default::default(),
        type_: Valid(type_),
        min: bounds.map(|b| json::Value::from(b.0.to_vec())),
        max: bounds.map(|b| json::Value::from(b.1.to_vec())),
        name: None,
        normalized: false,
        sparse: None,
    })
}

fn floats<const N: usize>(values: &[[f32; N]]) -> Vec<u8> {
    values.iter().flatten().flat_map(|v| v.to_le_bytes()).collect()
}

/// Splits an object transform into glTF's translation, rotation and scale, with the matrix
/// taking world points to object space; `None` when it is singular or not a TRS.
fn decompose(transform: DMat4) -> Option<(DVec3, DQuat, DVec3, DMat4)> {
    let inverse = transform.inverse();
    if !inverse.is_finite() || transform.determinant().abs() < 1e-12 {
        return None;
    }
    let (scale, rotation, translation) = transform.to_scale_rotation_translation();
    let rebuilt = DMat4::from_scale_rotation_translation(scale, rotation, translation);
    rebuilt
        .abs_diff_eq(transform, 1e-6 * transform.to_cols_array().iter().fold(1.0f64, |m, v| m.max(v.abs())))
        .then_some((translation, rotation, scale, inverse))
}

/// A GLB being written: the JSON document, the binary chunk, the extensions used and the
/// scene's nodes.
#[derive(Default)]
struct GlbWriter {
    root: json::Root,
    bin: BinBuilder,
    extensions_used: Vec<String>,
    nodes: Vec<json::Index<json::Node>>,
}

/// Per (material, base colour) pair the meshes use: its glTF material, and what was written.
#[derive(Default)]
struct Materials {
    written: Vec<WrittenMaterial>,
    index: BTreeMap<(u32, [u32; 3]), json::Index<json::Material>>,
}

fn add_extension(used: &mut Vec<String>, name: &str) {
    if !used.iter().any(|e| e == name) {
        used.push(name.to_string());
    }
}

impl GlbWriter {
    fn use_extension(&mut self, name: &str) {
        add_extension(&mut self.extensions_used, name);
    }

    /// The lightmap as a PNG texture, and the extension object materials carry to use it.
    fn lightmap(&mut self, lightmap: &ExportLightmap) -> serde_json::Value {
        let view = self.bin.view(&mut self.root, lightmap.png, json::buffer::Target::ArrayBuffer);
        // Images in a buffer view take no target.
        self.root.buffer_views[view.value()].target = None;
        let image = self.root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType("image/png".into())),
            name: Some("lightmap (RGBM)".into()),
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        let sampler = self.root.push(json::texture::Sampler {
            mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
            min_filter: Some(Valid(json::texture::MinFilter::Linear)),
            wrap_s: Valid(json::texture::WrappingMode::ClampToEdge),
            wrap_t: Valid(json::texture::WrappingMode::ClampToEdge),
            ..Default::default()
        });
        let texture = self.root.push(json::Texture {
            sampler: Some(sampler),
            source: image,
            name: Some("lightmap".into()),
            extensions: None,
            extras: Default::default(),
        });
        serde_json::json!({
            "lightmapTexture": { "index": texture.value(), "texCoord": 1 },
            "encoding": "RGBM",
            "range": lightmap.range,
            "exr": lightmap.exr_name,
        })
    }

    /// The glTF material of mesh `mesh`'s material and base colour, written the first time a
    /// pair is used (a material tinted differently by several objects is one per tint).
    fn material(
        &mut self,
        scene: &ExportScene,
        mesh: &crate::mesh::Mesh,
        slot: u32,
        materials: &mut Materials,
        lightmap: Option<&serde_json::Value>,
    ) -> Result<json::Index<json::Material>, String> {
        let (name, source) = scene.materials.get(slot as usize).ok_or("a mesh names a material the frame lacks")?;
        let key = (slot, mesh.base_color.map(f32::to_bits));
        if let Some(index) = materials.index.get(&key) {
            return Ok(*index);
        }
        let fit = super::material_fit::fit(source, mesh.base_color);
        let uses = materials.written.iter().filter(|w| w.source == *name).count();
        let written_name = match (uses, name.is_empty()) {
            (0, false) => name.clone(),
            (0, true) => "default".into(),
            (n, _) => format!("{} {}", if name.is_empty() { "default" } else { name }, n + 1),
        };
        let mut material = gltf_material(&fit, &written_name, &mut |n| add_extension(&mut self.extensions_used, n));
        if let (Some(extension), Some(extensions)) = (lightmap, material.extensions.as_mut()) {
            extensions.others.insert(LIGHTMAP_EXTENSION.into(), extension.clone());
        }
        let index = self.root.push(material);
        let model = source.model.to_string();
        materials.written.push(WrittenMaterial { name: written_name, source: name.clone(), model, fit });
        materials.index.insert(key, index);
        Ok(index)
    }

    /// Mesh `m` of the scene, its vertices' baked light (`light`, one per vertex, divided by
    /// `scale`) in `COLOR_0`, under a node with the object's transform.
    fn mesh(
        &mut self,
        scene: &ExportScene,
        m: usize,
        light: &[[f32; 3]],
        scale: f32,
        material: json::Index<json::Material>,
        anisotropic: bool,
    ) {
        let mesh = &scene.meshes.meshes[m];
        let count = mesh.positions.len();
        // Geometry in object space under a node with the object's transform.
        let transform = DMat4::from_cols_array(&mesh.transform);
        let (trs, to_object) = match decompose(transform) {
            Some((t, r, s, inverse)) => (Some((t, r, s)), inverse),
            None => (None, DMat4::IDENTITY),
        };
        let normal_to_object = DMat3::from_mat4(if trs.is_some() { transform } else { DMat4::IDENTITY }).transpose();
        // With a lightmap, the atlas's vertices (seams duplicated) replace the mesh's.
        let atlas = scene.lightmap.as_ref().map(|l| &l.atlas.meshes[m]);
        let remap: Vec<usize> = match atlas {
            Some(a) => a.xref.iter().map(|&i| i as usize).collect(),
            None => (0..count).collect(),
        };
        let count = remap.len();
        let pick = |values: &[[f32; 3]]| -> Vec<[f32; 3]> { remap.iter().map(|&i| values[i]).collect() };
        let positions: Vec<[f32; 3]> = pick(&mesh.positions)
            .iter()
            .map(|p| to_object.transform_point3(DVec3::from(p.map(f64::from))).as_vec3().to_array())
            .collect();
        let normals: Vec<[f32; 3]> = pick(&mesh.normals)
            .iter()
            .map(|n| (normal_to_object * DVec3::from(n.map(f64::from))).normalize_or(DVec3::Y).as_vec3().to_array())
            .collect();
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &positions {
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        use json::accessor::{ComponentType::*, Type::*};
        use json::buffer::Target::*;
        use json::mesh::Semantic;
        let mut attributes = BTreeMap::new();
        let view = self.bin.view(&mut self.root, &floats(&positions), ArrayBuffer);
        attributes.insert(Valid(Semantic::Positions), accessor(&mut self.root, view, count, F32, Vec3, Some((lo, hi))));
        let view = self.bin.view(&mut self.root, &floats(&normals), ArrayBuffer);
        attributes.insert(Valid(Semantic::Normals), accessor(&mut self.root, view, count, F32, Vec3, None));
        if mesh.uvs.len() == mesh.positions.len() {
            let uvs: Vec<[f32; 2]> = remap.iter().map(|&i| mesh.uvs[i]).collect();
            let view = self.bin.view(&mut self.root, &floats(&uvs), ArrayBuffer);
            attributes.insert(Valid(Semantic::TexCoords(0)), accessor(&mut self.root, view, count, F32, Vec2, None));
        }
        if let Some(a) = atlas {
            let view = self.bin.view(&mut self.root, &floats(&a.uvs), ArrayBuffer);
            let uv1 = accessor(&mut self.root, view, count, F32, Vec2, None);
            // glTF numbers texture coordinates from 0 without gaps: a mesh without its own
            // shares the lightmap's.
            attributes.entry(Valid(Semantic::TexCoords(0))).or_insert(uv1);
            attributes.insert(Valid(Semantic::TexCoords(1)), uv1);
        }
        let light: Vec<[f32; 3]> = pick(light).iter().map(|l| l.map(|c| (c / scale).clamp(0.0, 1.0))).collect();
        let view = self.bin.view(&mut self.root, &floats(&light), ArrayBuffer);
        attributes.insert(Valid(Semantic::Colors(0)), accessor(&mut self.root, view, count, F32, Vec3, None));
        if anisotropic {
            let world = if mesh.tangents.len() == mesh.positions.len() {
                mesh.tangents.clone()
            } else {
                crate::mesh::vertex_tangents(mesh)
            };
            let tangents: Vec<[f32; 4]> = pick(&world)
                .iter()
                .zip(&normals)
                .map(|(t, n)| {
                    let t = to_object.transform_vector3(DVec3::from(t.map(f64::from)));
                    let n = DVec3::from(n.map(f64::from));
                    let t = (t - n * n.dot(t)).normalize_or(n.any_orthonormal_vector()).as_vec3();
                    [t.x, t.y, t.z, 1.0]
                })
                .collect();
            let view = self.bin.view(&mut self.root, &floats(&tangents), ArrayBuffer);
            attributes.insert(Valid(Semantic::Tangents), accessor(&mut self.root, view, count, F32, Vec4, None));
        }
        // The world-space mesh already flipped a mirroring transform's winding; glTF flips it
        // again for a node whose transform mirrors, so undo ours.
        let mut indices = atlas.map_or_else(|| mesh.indices.clone(), |a| a.indices.clone());
        if trs.is_some() && transform.determinant() < 0.0 {
            for t in indices.chunks_mut(3) {
                t.swap(1, 2);
            }
        }
        let indices: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.bin.view(&mut self.root, &indices, ElementArrayBuffer);
        let indices = accessor(&mut self.root, view, mesh.indices.len(), U32, Scalar, None);
        let gltf_mesh = self.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(mesh.name.clone()),
            primitives: vec![json::mesh::Primitive {
                attributes,
                extensions: None,
                extras: Default::default(),
                indices: Some(indices),
                material: Some(material),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            }],
            weights: None,
        });
        let f32s = |v: DVec3| v.as_vec3().to_array();
        self.nodes.push(self.root.push(json::Node {
            mesh: Some(gltf_mesh),
            name: Some(mesh.name.clone()),
            translation: trs.map(|(t, _, _)| f32s(t)),
            rotation: trs.map(|(_, r, _)| json::scene::UnitQuaternion(r.as_quat().normalize().to_array())),
            scale: trs.map(|(_, _, s)| f32s(s)),
            ..Default::default()
        }));
    }

    /// Point lights as `KHR_lights_punctual` point lights, spots as spot lights.
    fn point_lights(&mut self, lights: &[PointLight]) {
        self.use_extension("KHR_lights_punctual");
        for (i, light) in lights.iter().enumerate() {
            use json::extensions::scene::khr_lights_punctual as punctual;
            // A profiled light within a hemisphere keeps its beam as a glTF spot (its profile
            // within the beam is not carried), or else its mean intensity as a point light.
            let (intensity, spot) = match light.profile.as_deref() {
                None => (light.intensity, None),
                Some(p) => match p.cone {
                    Some((inner, outer)) => (light.intensity, Some((inner, outer, p.frame.z_axis))),
                    None => (light.flux().map(|f| f / (4.0 * std::f64::consts::PI)), None),
                },
            };
            let peak = intensity.iter().fold(0.0f64, |m, &c| m.max(c));
            let color = intensity.map(|c| if peak > 0.0 { (c / peak) as f32 } else { 1.0 });
            let lights: &mut Vec<punctual::Light> = self.root.as_mut();
            lights.push(punctual::Light {
                color,
                extensions: None,
                extras: Some(json_raw(&serde_json::json!({ "lightloom": { "baked": true } }))),
                intensity: peak as f32,
                name: Some(format!("point light {}", i + 1)),
                range: None,
                spot: spot.map(|(inner, outer, _)| {
                    let outer = outer.min(std::f64::consts::FRAC_PI_2);
                    punctual::Spot { inner_cone_angle: inner.min(outer * 0.999) as f32, outer_cone_angle: outer as f32 }
                }),
                type_: Valid(if spot.is_some() { punctual::Type::Spot } else { punctual::Type::Point }),
            });
            // glTF lights shine along their node's −Z.
            let rotation = spot.map(|(_, _, axis)| {
                json::scene::UnitQuaternion(
                    DQuat::from_rotation_arc(DVec3::NEG_Z, axis).as_quat().normalize().to_array(),
                )
            });
            self.nodes.push(self.root.push(json::Node {
                name: Some(format!("point light {}", i + 1)),
                translation: Some(light.position.map(|c| c as f32)),
                rotation,
                extensions: Some(json::extensions::scene::Node {
                    khr_lights_punctual: Some(json::extensions::scene::khr_lights_punctual::KhrLightsPunctual {
                        light: json::Index::new(i as u32),
                    }),
                    ..Default::default()
                }),
                ..Default::default()
            }));
        }
    }

    // Square lights as KHR directional lights: intensity is the irradiance on a surface facing
    // the light (radiance × solid angle, the "lux" of the extension in the project's units);
    // its size goes into extras: solid angle and the radius of the cone of equal solid angle.
    fn directional_lights(&mut self, lights: &[DirectionalLight]) {
        self.use_extension("KHR_lights_punctual");
        for (k, light) in lights.iter().enumerate() {
            use json::extensions::scene::khr_lights_punctual as punctual;
            let index = AsRef::<[punctual::Light]>::as_ref(&self.root).len();
            let peak = light.radiance.iter().fold(0.0f64, |m, &c| m.max(c));
            let color = light.radiance.map(|c| if peak > 0.0 { (c / peak) as f32 } else { 1.0 });
            let radius = (1.0 - light.solid_angle / (2.0 * std::f64::consts::PI)).clamp(-1.0, 1.0).acos();
            let name = format!("square light {}", k + 1);
            let lights: &mut Vec<punctual::Light> = self.root.as_mut();
            lights.push(punctual::Light {
                color,
                extensions: None,
                extras: Some(json_raw(&serde_json::json!({ "lightloom": {
                    "baked": true,
                    "solidAngle": light.solid_angle,
                    "angularRadius": radius,
                    "shape": "square",
                } }))),
                intensity: (peak * light.solid_angle) as f32,
                name: Some(name.clone()),
                range: None,
                spot: None,
                type_: Valid(punctual::Type::Directional),
            });
            // A directional light shines down its node's -Z: +Z points at the light.
            let towards = DVec3::from(light.direction).normalize_or(DVec3::Y);
            let rotation = DQuat::from_rotation_arc(DVec3::Z, towards);
            self.nodes.push(self.root.push(json::Node {
                name: Some(name),
                rotation: Some(json::scene::UnitQuaternion(rotation.as_quat().normalize().to_array())),
                extensions: Some(json::extensions::scene::Node {
                    khr_lights_punctual: Some(json::extensions::scene::khr_lights_punctual::KhrLightsPunctual {
                        light: json::Index::new(index as u32),
                    }),
                    ..Default::default()
                }),
                ..Default::default()
            }));
        }
    }

    /// The project's camera.
    fn camera(&mut self, camera: &ExportCamera) {
        let eye = DVec3::from(camera.position);
        let target = DVec3::from(camera.target);
        let forward = (target - eye).normalize_or(DVec3::NEG_Z);
        let up = if forward.cross(DVec3::Y).length() < 1e-6 { DVec3::Z } else { DVec3::Y };
        // glTF cameras look down their node's -Z with +Y up.
        let right = forward.cross(up).normalize();
        let rotation = DQuat::from_mat3(&DMat3::from_cols(right, right.cross(forward), -forward));
        let index = self.root.push(json::Camera {
            name: Some(camera.name.clone()),
            orthographic: None,
            perspective: Some(json::camera::Perspective {
                aspect_ratio: Some(camera.aspect as f32),
                yfov: camera.fov_y_deg.to_radians() as f32,
                zfar: None,
                znear: 0.01,
                extensions: None,
                extras: Default::default(),
            }),
            type_: Valid(json::camera::Type::Perspective),
            extensions: None,
            extras: Default::default(),
        });
        self.nodes.push(self.root.push(json::Node {
            camera: Some(index),
            name: Some(camera.name.clone()),
            translation: Some(eye.as_vec3().to_array()),
            rotation: Some(json::scene::UnitQuaternion(rotation.as_quat().normalize().to_array())),
            ..Default::default()
        }));
    }

    /// The GLB's bytes: the scene of every node, the buffer, the JSON and BIN chunks.
    fn finish(mut self, scale: f32) -> Result<Vec<u8>, String> {
        let scene_index = self.root.push(json::Scene {
            extensions: None,
            extras: Some(json_raw(&serde_json::json!({ "lightloom": { "vertexLightScale": scale } }))),
            name: Some("baked".into()),
            nodes: self.nodes,
        });
        self.root.scene = Some(scene_index);
        self.root.extensions_used = self.extensions_used;
        self.root.push(json::Buffer {
            byte_length: USize64::from(self.bin.data.len()),
            extensions: None,
            extras: Default::default(),
            name: None,
            uri: None,
        });
        let json_bytes = json::serialize::to_vec(&self.root).map_err(|e| format!("glTF JSON: {e}"))?;
        let mut json_padded = json_bytes;
        while !json_padded.len().is_multiple_of(4) {
            json_padded.push(b' ');
        }
        let length = 12 + 8 + json_padded.len() + 8 + self.bin.data.len();
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header {
                magic: *b"glTF",
                version: 2,
                length: u32::try_from(length).map_err(|_| "the scene is over the 4 GiB a GLB can hold")?,
            },
            json: Cow::Owned(json_padded),
            bin: Some(Cow::Owned(self.bin.data)),
        };
        let bytes = glb.to_vec().map_err(|e| format!("GLB: {e}"))?;
        Ok(bytes)
    }
}

/// Writes `scene` as a GLB.
pub fn write_glb(scene: &ExportScene) -> Result<Glb, String> {
    let mut writer = GlbWriter::default();
    writer.root.asset.generator = Some(format!("Lightloom {}", env!("CARGO_PKG_VERSION")));
    let lightmap = scene.lightmap.as_ref().map(|l| writer.lightmap(l));
    if lightmap.is_some() {
        writer.use_extension(LIGHTMAP_EXTENSION);
    }
    let mut materials = Materials::default();
    let mut first_vertex = 0usize;
    let scale = vertex_light_scale(scene.vertex_light);
    for (m, mesh) in scene.meshes.meshes.iter().enumerate() {
        let count = mesh.positions.len();
        let light = scene
            .vertex_light
            .get(first_vertex..first_vertex + count)
            .ok_or("the baked light covers fewer vertices than the scene has")?;
        first_vertex += count;
        if count == 0 || mesh.indices.is_empty() {
            continue;
        }
        let slot = scene.mesh_materials.get(m).copied().unwrap_or(0);
        let material = writer.material(scene, mesh, slot, &mut materials, lightmap.as_ref())?;
        let anisotropic = materials.written[material.value()].fit.anisotropy.is_some();
        writer.mesh(scene, m, light, scale, material, anisotropic);
    }
    if !scene.lights.is_empty() {
        writer.use_extension("KHR_lights_punctual");
        writer.point_lights(scene.lights);
    }
    if !scene.directional.is_empty() {
        writer.use_extension("KHR_lights_punctual");
        writer.directional_lights(scene.directional);
    }
    if let Some(camera) = &scene.camera {
        writer.camera(camera);
    }
    let bytes = writer.finish(scale)?;
    Ok(Glb { bytes, materials: materials.written, vertex_light_scale: scale })
}

/// The smallest power of two at least the largest channel of `light` (1 for a dark scene).
pub fn vertex_light_scale(light: &[[f32; 3]]) -> f32 {
    let peak = light.iter().flatten().fold(0.0f32, |m, &c| if c.is_finite() { m.max(c) } else { m });
    if peak <= 0.0 { 1.0 } else { 2f32.powi(peak.log2().ceil() as i32) }
}

fn json_raw(value: &serde_json::Value) -> Box<serde_json::value::RawValue> {
    serde_json::value::to_raw_value(value).expect("a JSON value serialises")
}

/// `fit` as a glTF material named `name`.
fn gltf_material(fit: &MaterialFit, name: &str, use_extension: &mut impl FnMut(&str)) -> json::Material {
    let mut material = json::Material {
        name: Some(if name.is_empty() { "default".into() } else { name.into() }),
        ..Default::default()
    };
    let [r, g, b] = fit.base_color.map(|c| c.clamp(0.0, 1.0) as f32);
    material.pbr_metallic_roughness.base_color_factor = json::material::PbrBaseColorFactor([r, g, b, 1.0]);
    material.pbr_metallic_roughness.metallic_factor = json::material::StrengthFactor(fit.metallic as f32);
    material.pbr_metallic_roughness.roughness_factor = json::material::StrengthFactor(fit.roughness as f32);
    let mut extensions = json::extensions::material::Material::default();
    use_extension("KHR_materials_specular");
    extensions.specular = Some(json::extensions::material::Specular {
        specular_factor: json::extensions::material::SpecularFactor(fit.specular_factor as f32),
        specular_texture: None,
        specular_color_factor: json::extensions::material::SpecularColorFactor(fit.specular_color.map(|c| c as f32)),
        specular_color_texture: None,
        extras: Default::default(),
    });
    if let Some((strength, rotation)) = fit.anisotropy {
        use_extension("KHR_materials_anisotropy");
        extensions.others.insert(
            "KHR_materials_anisotropy".into(),
            serde_json::json!({ "anisotropyStrength": strength, "anisotropyRotation": rotation }),
        );
    }
    material.extensions = Some(extensions);
    material
}
