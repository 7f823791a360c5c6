//! glTF 2.0 (`.gltf`, `.glb`) import with the `gltf` crate: every triangle primitive of the
//! default scene, with node transforms, normals (generated when missing or broken), UVs and
//! base colour. Textures are not decoded.
//!
//! Bad input never panics: schema errors, missing buffers, accessors that point outside
//! their buffers, wrong accessor types, indices out of range and node cycles are errors that
//! name the file and the mesh; non-finite vertices and zero/NaN normals are repaired (the
//! triangles dropped, the normals regenerated) and reported as warnings.

use crate::mesh::Mesh;
use glam::{DMat4, DVec3};
use gltf::accessor::{DataType, Dimensions};
use std::path::{Path, PathBuf};

/// Meshes in world space and what was repaired.
#[derive(Clone, Debug, Default)]
pub struct ImportedScene {
    pub meshes: Vec<Mesh>,
    pub warnings: Vec<String>,
}

/// Deepest node hierarchy accepted (guards against cycles and absurd files).
const MAX_DEPTH: usize = 256;

/// The glTF at `path` (its name for messages), every index checked, and its GLB chunk.
fn open(path: &Path) -> Result<(String, gltf::Document, Option<Vec<u8>>), String> {
    let name = path.display().to_string();
    let bytes = crate::limits::read_regular_file(path, crate::limits::MAX_FILE_BYTES)?;
    let invalid = |e: gltf::Error| format!("{name}: not a valid glTF 2.0 file: {e}");
    let gltf = gltf::Gltf::from_slice_without_validation(&bytes).map_err(invalid)?;
    drop(bytes);
    // The gltf crate's validation and accessors index without checking: every index is
    // checked here first.
    check_indices(gltf.document.as_json()).map_err(|e| format!("{name}: {e}"))?;
    let document = gltf::Document::from_json(gltf.document.into_json()).map_err(invalid)?;
    Ok((name, document, gltf.blob))
}

pub fn import(path: &Path) -> Result<ImportedScene, String> {
    let (name, document, blob) = open(path)?;
    let buffers = load_buffers(&document, path.parent().unwrap_or(Path::new(".")), blob)
        .map_err(|e| format!("{name}: cannot load the glTF's buffers: {e}"))?;
    let document = &document;
    let roots: Vec<gltf::Node> = match document.default_scene().or_else(|| document.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            // No scene: take every node that is nobody's child.
            let children: std::collections::HashSet<usize> =
                document.nodes().flat_map(|n| n.children().map(|c| c.index()).collect::<Vec<_>>()).collect();
            document.nodes().filter(|n| !children.contains(&n.index())).collect()
        }
    };
    let mut out = ImportedScene::default();
    let (mut visits, mut instances, mut triangles) = (0usize, 0usize, 0usize);
    let mut stack: Vec<(gltf::Node, DMat4, usize, Vec<usize>)> =
        roots.into_iter().map(|n| (n, DMat4::IDENTITY, 0, Vec::new())).collect();
    while let Some((node, parent, depth, mut path_nodes)) = stack.pop() {
        if path_nodes.contains(&node.index()) {
            return Err(format!("{name}: node {} is its own ancestor (the node hierarchy has a cycle)", node.index()));
        }
        if depth > MAX_DEPTH {
            return Err(format!("{name}: node hierarchy deeper than {MAX_DEPTH} levels"));
        }
        visits += 1;
        if visits > crate::limits::MAX_GLTF_NODE_VISITS {
            return Err(format!(
                "{name}: the node hierarchy expands to more than {} nodes (nodes listed more than once multiply)",
                crate::limits::MAX_GLTF_NODE_VISITS
            ));
        }
        path_nodes.push(node.index());
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        if !world.is_finite() {
            return Err(format!("{name}: node {} has a non-finite transform", node.index()));
        }
        if let Some(mesh) = node.mesh() {
            instances += 1;
            if instances > crate::limits::MAX_GLTF_INSTANCES {
                return Err(format!(
                    "{name}: the node hierarchy places more than {} mesh instances (nodes listed more than once \
                     multiply); the limit keeps memory bounded",
                    crate::limits::MAX_GLTF_INSTANCES
                ));
            }
            for (p, primitive) in mesh.primitives().enumerate() {
                let label =
                    format!("{name}: mesh {} ({}) primitive {p}", mesh.index(), mesh.name().unwrap_or("unnamed"));
                if primitive.mode() != gltf::mesh::Mode::Triangles {
                    out.warnings.push(format!(
                        "{label}: {:?} primitives are skipped (only triangles are lit)",
                        primitive.mode()
                    ));
                    continue;
                }
                let m = read_primitive(&primitive, &buffers, &label, &mut out.warnings)?;
                triangles += m.triangle_count();
                if triangles > crate::limits::MAX_TRIANGLES {
                    return Err(format!(
                        "{name}: more than {} triangles in the scene (the limit)",
                        crate::limits::MAX_TRIANGLES
                    ));
                }
                if !m.indices.is_empty() {
                    let mut m = m.transformed(world);
                    m.name = mesh.name().map(str::to_string).unwrap_or_else(|| format!("mesh{}", mesh.index()));
                    out.meshes.push(m);
                }
            }
        }
        for child in node.children() {
            stack.push((child, world, depth + 1, path_nodes.clone()));
        }
    }
    if out.meshes.is_empty() {
        out.warnings.push(format!("{name}: no triangle geometry found"));
    }
    Ok(out)
}

/// Checks every index the document holds (accessors, views, buffers, meshes, nodes), and each
/// view's stride, so the gltf crate's unchecked lookups cannot panic.
fn check_indices(root: &gltf::json::Root) -> Result<(), String> {
    let check = |what: &str, index: usize, len: usize| {
        if index < len { Ok(()) } else { Err(format!("{what} refers to item {index}, but there are only {len}")) }
    };
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let what = format!("mesh {m} primitive {p}");
            for index in primitive.attributes.values() {
                check(&format!("{what}: an attribute"), index.value(), root.accessors.len())?;
            }
            if let Some(index) = &primitive.indices {
                check(&format!("{what}: indices"), index.value(), root.accessors.len())?;
            }
            for target in primitive.targets.iter().flatten() {
                for index in [&target.positions, &target.normals, &target.tangents].into_iter().flatten() {
                    check(&format!("{what}: a morph target"), index.value(), root.accessors.len())?;
                }
            }
            if let Some(index) = &primitive.material {
                check(&format!("{what}: material"), index.value(), root.materials.len())?;
            }
        }
    }
    for (a, accessor) in root.accessors.iter().enumerate() {
        if let Some(view) = &accessor.buffer_view {
            check(&format!("accessor {a}: bufferView"), view.value(), root.buffer_views.len())?;
        }
        if let Some(sparse) = &accessor.sparse {
            check(
                &format!("accessor {a}: sparse indices"),
                sparse.indices.buffer_view.value(),
                root.buffer_views.len(),
            )?;
            check(&format!("accessor {a}: sparse values"), sparse.values.buffer_view.value(), root.buffer_views.len())?;
        }
    }
    for (v, view) in root.buffer_views.iter().enumerate() {
        check(&format!("bufferView {v}: buffer"), view.buffer.value(), root.buffers.len())?;
        if let Some(stride) = view.byte_stride
            && !(4..=252).contains(&stride.0)
        {
            return Err(format!("bufferView {v}: byteStride {} is outside 4..=252", stride.0));
        }
    }
    for (m, material) in root.materials.iter().enumerate() {
        let pbr = &material.pbr_metallic_roughness;
        let textures = [
            pbr.base_color_texture.as_ref().map(|t| t.index.value()),
            pbr.metallic_roughness_texture.as_ref().map(|t| t.index.value()),
            material.normal_texture.as_ref().map(|t| t.index.value()),
            material.occlusion_texture.as_ref().map(|t| t.index.value()),
            material.emissive_texture.as_ref().map(|t| t.index.value()),
        ];
        let specular = material.extensions.as_ref().and_then(|e| e.specular.as_ref());
        let specular = specular.into_iter().flat_map(|s| [&s.specular_texture, &s.specular_color_texture]);
        let textures = textures.into_iter().chain(specular.map(|t| t.as_ref().map(|t| t.index.value())));
        for index in textures.flatten() {
            check(&format!("material {m}: a texture"), index, root.textures.len())?;
        }
    }
    for (t, texture) in root.textures.iter().enumerate() {
        check(&format!("texture {t}: source"), texture.source.value(), root.images.len())?;
        if let Some(sampler) = &texture.sampler {
            check(&format!("texture {t}: sampler"), sampler.value(), root.samplers.len())?;
        }
    }
    for (i, image) in root.images.iter().enumerate() {
        if let Some(view) = &image.buffer_view {
            check(&format!("image {i}: bufferView"), view.value(), root.buffer_views.len())?;
        }
    }
    for (n, node) in root.nodes.iter().enumerate() {
        if let Some(mesh) = &node.mesh {
            check(&format!("node {n}: mesh"), mesh.value(), root.meshes.len())?;
        }
        for child in node.children.iter().flatten() {
            check(&format!("node {n}: a child"), child.value(), root.nodes.len())?;
        }
        if let Some(camera) = &node.camera {
            check(&format!("node {n}: camera"), camera.value(), root.cameras.len())?;
        }
        if let Some(skin) = &node.skin {
            check(&format!("node {n}: skin"), skin.value(), root.skins.len())?;
        }
    }
    for (s, scene) in root.scenes.iter().enumerate() {
        for node in &scene.nodes {
            check(&format!("scene {s}: a node"), node.value(), root.nodes.len())?;
        }
    }
    if let Some(scene) = &root.scene {
        check("the default scene", scene.value(), root.scenes.len())?;
    }
    Ok(())
}

/// The document's buffers: the GLB chunk, `data:` URIs, or regular files next to the glTF
/// (never special files, never more than [`crate::limits::MAX_FILE_BYTES`]).
fn load_buffers(
    document: &gltf::Document,
    base: &Path,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<gltf::buffer::Data>, String> {
    document.buffers().map(|buffer| load_buffer(&buffer, base, &mut blob)).collect()
}

/// One buffer, padded to a multiple of four bytes; the GLB chunk is taken from `blob`.
fn load_buffer(buffer: &gltf::Buffer, base: &Path, blob: &mut Option<Vec<u8>>) -> Result<gltf::buffer::Data, String> {
    let declared = buffer.length();
    let what = format!("buffer {}", buffer.index());
    if declared as u64 > crate::limits::MAX_FILE_BYTES {
        return Err(format!("{what} declares {} MiB", declared >> 20));
    }
    let mut data = match buffer.source() {
        gltf::buffer::Source::Bin => {
            blob.take().ok_or_else(|| format!("{what} refers to a GLB chunk the file lacks"))?
        }
        // A file may carry a little padding past byteLength, never much more.
        gltf::buffer::Source::Uri(uri) => read_uri(uri, base, declared as u64 + (1 << 20), &what)?,
    };
    if data.len() < declared {
        return Err(format!("{what} holds {} bytes; the glTF declares {declared}", data.len()));
    }
    while data.len() % 4 != 0 {
        data.push(0);
    }
    Ok(gltf::buffer::Data(data))
}

/// The files a `.gltf` refers to (its buffers' and images' relative URIs, percent-decoded,
/// resolved against its folder), so a stage's key can follow them. Empty for other files and
/// for a `.gltf` that cannot be read (the import reports why).
pub fn referenced_files(path: &Path) -> Vec<PathBuf> {
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gltf")) {
        return Vec::new();
    }
    let Ok(text) = crate::limits::read_regular_file(path, crate::limits::MAX_GLTF_JSON_BYTES) else {
        return Vec::new();
    };
    let Ok(json) = serde_json::from_slice::<serde_json::Value>(&text) else { return Vec::new() };
    let dir = path.parent().unwrap_or(Path::new("."));
    ["buffers", "images"]
        .iter()
        .filter_map(|k| json.get(k)?.as_array())
        .flatten()
        .filter_map(|entry| entry.get("uri")?.as_str())
        .filter(|uri| !uri.starts_with("data:"))
        .map(|uri| uri.strip_prefix("file://").unwrap_or(uri))
        .filter(|uri| !uri.contains(':'))
        .filter_map(|uri| urlencoding::decode(uri).ok().map(|d| dir.join(d.as_ref())))
        .collect()
}

/// The bytes a buffer or image URI names: a base64 `data:` URI, or a regular file relative to
/// `base`, of at most `limit` bytes (and never more than [`crate::limits::MAX_FILE_BYTES`]).
fn read_uri(uri: &str, base: &Path, limit: u64, what: &str) -> Result<Vec<u8>, String> {
    let limit = limit.min(crate::limits::MAX_FILE_BYTES);
    if uri.starts_with("data:") {
        let (_, payload) =
            uri.split_once(";base64,").ok_or_else(|| format!("{what}: only base64 data URIs are supported"))?;
        if payload.len() as u64 / 4 * 3 > limit + 3 {
            return Err(format!("{what}: the data URI holds more than {limit} bytes"));
        }
        return base64::decode(payload).map_err(|e| format!("{what}: bad base64 data: {e}"));
    }
    let relative = uri.strip_prefix("file://").unwrap_or(uri);
    if relative.contains(':') {
        return Err(format!("{what}: unsupported URI `{uri}`"));
    }
    let decoded = urlencoding::decode(relative).map_err(|e| format!("{what}: URI `{uri}`: {e}"))?;
    let path = base.join(decoded.as_ref());
    if !path.exists() {
        return Err(format!("{what}: missing file {uri} next to it"));
    }
    crate::limits::read_regular_file(&path, limit)
}

/// A material's normal texture as its glTF stores it.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalTexture {
    /// The material it belongs to (its name, or `material N`).
    pub material: String,
    /// Whether that material bears the name asked for (else it is the first with a normal
    /// texture).
    pub named: bool,
    /// The encoded image (PNG or JPEG, as the glTF's images are).
    pub image: Vec<u8>,
    /// `normalTexture.scale`: how far the map's tilts are scaled.
    pub scale: f64,
    /// What the glTF asks of the texture that the map does not do (a texture transform, a
    /// wrap other than repeat).
    pub warnings: Vec<String>,
}

/// The normal texture of the material named `material` in the glTF at `path`, or, when no
/// material has that name, of the first material that has one. Its image may be a file next
/// to the glTF, a `data:` URI or a buffer view (as in GLB files), under the same limits as the
/// glTF's buffers. Only `TEXCOORD_0` is imported, so a texture on another set is refused.
pub fn normal_texture(path: &Path, material: &str) -> Result<NormalTexture, String> {
    let (name, document, mut blob) = open(path)?;
    let label =
        |m: &gltf::Material| m.name().map_or_else(|| format!("material {}", m.index().unwrap_or(0)), str::to_string);
    let named = document.materials().find(|m| m.name() == Some(material));
    let named_found = named.is_some();
    let chosen = match named {
        Some(m) => m,
        None => document
            .materials()
            .find(|m| m.normal_texture().is_some())
            .ok_or_else(|| format!("{name}: no material has a normal texture (normalTexture)"))?,
    };
    let label = label(&chosen);
    let normal = chosen
        .normal_texture()
        .ok_or_else(|| format!("{name}: material `{label}` has no normal texture (normalTexture)"))?;
    if normal.tex_coord() != 0 {
        return Err(format!(
            "{name}: material `{label}`'s normal texture uses TEXCOORD_{}; only TEXCOORD_0 is imported",
            normal.tex_coord()
        ));
    }
    let scale = f64::from(normal.scale());
    if !scale.is_finite() {
        return Err(format!("{name}: material `{label}`'s normal texture scale is not a finite number"));
    }
    let root = document.as_json();
    let mut warnings = Vec::new();
    let transformed = chosen
        .index()
        .and_then(|m| root.materials[m].normal_texture.as_ref())
        .is_some_and(|t| t.extensions.as_ref().is_some_and(|e| e.others.contains_key("KHR_texture_transform")));
    if transformed {
        warnings.push(format!(
            "material `{label}`'s normal texture has a KHR_texture_transform, which is not applied (Normal tiling \
             repeats the map)"
        ));
    }
    let sampler = root.textures[normal.texture().index()].sampler.and_then(|s| root.samplers.get(s.value()));
    let repeats = |wrap: &gltf::json::validation::Checked<gltf::json::texture::WrappingMode>| {
        matches!(wrap, gltf::json::validation::Checked::Valid(gltf::json::texture::WrappingMode::Repeat))
    };
    if sampler.is_some_and(|s| !repeats(&s.wrap_s) || !repeats(&s.wrap_t)) {
        warnings.push(format!("material `{label}`'s normal texture clamps or mirrors at its edges; the map repeats"));
    }
    let image = normal.texture().source();
    let what = format!("image {} of material `{label}`'s normal texture", image.index());
    let base = path.parent().unwrap_or(Path::new("."));
    // From the JSON: the crate's `Image::source` unwraps a missing mimeType or URI.
    let json = &root.images[image.index()];
    let view = json.buffer_view.as_ref().and_then(|v| document.views().nth(v.value()));
    let encoded = match (view, &json.uri) {
        (None, None) => return Err(format!("{name}: {what} has neither a uri nor a bufferView")),
        (None, Some(uri)) => {
            read_uri(uri, base, crate::limits::MAX_FILE_BYTES, &what).map_err(|e| format!("{name}: {e}"))?
        }
        (Some(view), _) => {
            let buffer = load_buffer(&view.buffer(), base, &mut blob).map_err(|e| format!("{name}: {what}: {e}"))?;
            let end = view.offset().checked_add(view.length()).filter(|end| *end <= buffer.len());
            let end = end.ok_or_else(|| {
                format!(
                    "{name}: {what}: bufferView {} ({} bytes at {}) lies outside its buffer of {} bytes",
                    view.index(),
                    view.length(),
                    view.offset(),
                    buffer.len()
                )
            })?;
            buffer.0[view.offset()..end].to_vec()
        }
    };
    Ok(NormalTexture { material: label, named: named_found, image: encoded, scale, warnings })
}

/// Checks that an accessor has the expected layout and lies inside its buffer.
fn check_accessor(
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    what: &str,
    types: &[DataType],
    dims: Dimensions,
) -> Result<(), String> {
    if !types.contains(&accessor.data_type()) || accessor.dimensions() != dims {
        return Err(format!(
            "{what} accessor {} is {:?} {:?}, expected {:?} of {:?}",
            accessor.index(),
            accessor.dimensions(),
            accessor.data_type(),
            dims,
            types
        ));
    }
    if accessor.sparse().is_some() {
        return Err(format!("{what} accessor {} is sparse, which is not supported", accessor.index()));
    }
    let view = accessor.view().ok_or_else(|| format!("{what} accessor {} has no buffer view", accessor.index()))?;
    let buffer = buffers
        .get(view.buffer().index())
        .ok_or_else(|| format!("{what} accessor {}: buffer {} is missing", accessor.index(), view.buffer().index()))?;
    let element = accessor.size();
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(format!(
            "{what} accessor {}: its view's byteStride {stride} is smaller than one element ({element} bytes)",
            accessor.index()
        ));
    }
    let needed = if accessor.count() == 0 { 0 } else { accessor.offset() + stride * (accessor.count() - 1) + element };
    if view.offset() + view.length() > buffer.len() || needed > view.length() {
        return Err(format!(
            "{what} accessor {} reads outside its data ({} bytes needed, view of {} bytes at {} in a buffer of {})",
            accessor.index(),
            needed,
            view.length(),
            view.offset(),
            buffer.len()
        ));
    }
    Ok(())
}

fn read_primitive(
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    label: &str,
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    use gltf::Semantic;
    let err = |e: String| format!("{label}: {e}");
    let positions_accessor =
        primitive.get(&Semantic::Positions).ok_or_else(|| err("has no POSITION attribute".into()))?;
    check_accessor(&positions_accessor, buffers, "POSITION", &[DataType::F32], Dimensions::Vec3).map_err(err)?;
    let normals_ok = match primitive.get(&Semantic::Normals) {
        Some(a) => {
            check_accessor(&a, buffers, "NORMAL", &[DataType::F32], Dimensions::Vec3).map_err(err)?;
            a.count() == positions_accessor.count()
        }
        None => false,
    };
    let uvs_ok = match primitive.get(&Semantic::TexCoords(0)) {
        Some(a) => {
            check_accessor(&a, buffers, "TEXCOORD_0", &[DataType::F32, DataType::U8, DataType::U16], Dimensions::Vec2)
                .map_err(err)?;
            a.count() == positions_accessor.count()
        }
        None => false,
    };
    let tangents_ok = match primitive.get(&Semantic::Tangents) {
        Some(a) => {
            check_accessor(&a, buffers, "TANGENT", &[DataType::F32], Dimensions::Vec4).map_err(err)?;
            a.count() == positions_accessor.count()
        }
        None => false,
    };
    if let Some(a) = primitive.indices() {
        check_accessor(&a, buffers, "index", &[DataType::U8, DataType::U16, DataType::U32], Dimensions::Scalar)
            .map_err(err)?;
    }
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let positions: Vec<[f32; 3]> =
        reader.read_positions().ok_or_else(|| err("POSITION data unreadable".into()))?.collect();
    let count = positions.len();
    let indices: Vec<u32> = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..count as u32).collect(),
    };
    if let Some(bad) = indices.iter().find(|i| **i as usize >= count) {
        return Err(err(format!("index {bad} is out of range ({count} vertices)")));
    }
    if !indices.len().is_multiple_of(3) {
        return Err(err(format!("{} indices do not form whole triangles", indices.len())));
    }
    // Repair: drop triangles touching non-finite or absurdly distant vertices.
    let sane = |p: &[f32; 3]| p.iter().all(|v| v.is_finite() && v.abs() <= crate::limits::MAX_COORDINATE);
    let finite = |i: u32| sane(&positions[i as usize]);
    let before = indices.len() / 3;
    let indices: Vec<u32> =
        indices.chunks_exact(3).filter(|t| t.iter().all(|i| finite(*i))).flatten().copied().collect();
    if indices.len() / 3 < before {
        warnings.push(format!(
            "{label}: {} triangle(s) with non-finite vertices (or beyond {} m) were dropped",
            before - indices.len() / 3,
            crate::limits::MAX_COORDINATE
        ));
    }
    let positions: Vec<[f32; 3]> = positions.into_iter().map(|p| if sane(&p) { p } else { [0.0; 3] }).collect();
    let uvs: Vec<[f32; 2]> =
        if uvs_ok { reader.read_tex_coords(0).map(|t| t.into_f32().collect()).unwrap_or_default() } else { Vec::new() };
    let mut normals: Vec<[f32; 3]> =
        if normals_ok { reader.read_normals().map(|n| n.collect()).unwrap_or_default() } else { Vec::new() };
    let broken = normals.len() != count
        || normals.iter().any(|n| !n.iter().all(|v| v.is_finite()) || DVec3::from(n.map(f64::from)).length() < 1e-6);
    if broken {
        if normals_ok {
            warnings.push(format!("{label}: zero or non-finite normals were regenerated from the geometry"));
        }
        normals = smooth_normals(&positions, &indices);
    }
    // Authored tangents are kept when usable; otherwise `vertex_tangents` derives them from UVs.
    let authored: Vec<[f32; 4]> =
        if tangents_ok { reader.read_tangents().map(|t| t.collect()).unwrap_or_default() } else { Vec::new() };
    let (mut tangents, mut bitangent_signs): (Vec<[f32; 3]>, Vec<f32>) =
        authored.iter().map(|t| ([t[0], t[1], t[2]], if t[3] < 0.0 { -1.0 } else { 1.0 })).unzip();
    if tangents.iter().any(|t| !t.iter().all(|v| v.is_finite()) || DVec3::from(t.map(f64::from)).length() < 1e-6) {
        warnings.push(format!("{label}: zero or non-finite tangents were ignored and derived from the UVs"));
        tangents.clear();
        bitangent_signs.clear();
    }
    let base = primitive.material().pbr_metallic_roughness().base_color_factor();
    let base_color = [base[0], base[1], base[2]].map(|c| if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.8 });
    let material = primitive.material().name().unwrap_or_default().to_string();
    Ok(Mesh {
        name: String::new(),
        positions,
        normals,
        uvs,
        tangents,
        bitangent_signs,
        indices,
        base_color,
        visibility_texture: false,
        material,
        ..Default::default()
    })
}

/// Area-weighted vertex normals.
fn smooth_normals(positions: &[[f32; 3]], indices: &[u32]) -> Vec<[f32; 3]> {
    let mut acc = vec![DVec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let p = |i: u32| DVec3::from(positions[i as usize].map(f64::from));
        let n = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
        for &i in t {
            acc[i as usize] += n;
        }
    }
    acc.into_iter().map(|n| n.normalize_or(DVec3::Y).as_vec3().to_array()).collect()
}

#[cfg(test)]
mod tests;
