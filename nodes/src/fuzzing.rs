//! Entry points shared by the fuzz targets (`fuzz/fuzz_targets/`) and the regression corpus
//! replayed by `cargo test` (`fuzz_corpus_replays_without_panics`): each takes arbitrary bytes
//! through one loader as the program would, and must return (an error is fine) without
//! panicking, hanging or allocating without bound.

use std::path::{Path, PathBuf};

/// A project file: RON parsing, migration and graph building.
pub fn project(bytes: &[u8]) {
    let path = Path::new("fuzz.ron");
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    if let Ok(project) = crate::project::Project::from_ron(text, path) {
        let _ = project.graph(path);
        let _ = project.to_ron();
    }
}

/// An environment map: the first byte picks the format (EXR or Radiance HDR); the rest is
/// the file, loaded and projected to SH.
pub fn envmap(bytes: &[u8]) {
    let Some((format, file)) = bytes.split_first() else { return };
    let name = if format % 2 == 0 { "map.exr" } else { "map.hdr" };
    let path = scratch_file(name, file);
    if let Ok(loaded) = crate::envmap_io::load_equirect(&path) {
        let sh = crate::sh::project_samples(3, loaded.image.samples());
        assert!(sh.coeffs.iter().flatten().all(|c| c.is_finite()), "a loaded map projects to non-finite SH");
    }
}

/// A glTF (JSON or binary) imported and built into the ray-tracing BVH.
pub fn gltf(bytes: &[u8]) {
    let name = if bytes.starts_with(b"glTF") { "model.glb" } else { "model.gltf" };
    let path = scratch_file(name, bytes);
    if let Ok(scene) = crate::gltf_import::import(&path) {
        let meshes = crate::mesh::MeshSet { meshes: scene.meshes };
        let _ = crate::raycast::RayScene::build(&meshes);
        // Blocker sets fit spheres to models: a coarse fit must refuse or succeed, never panic.
        let _ = crate::sphere_set::fit_spheres(&meshes, 8, 16, &crate::engine::CancelToken::default());
    }
}

/// A painted light: the first byte picks a paint log (RON, replayed at 32²) or an image file
/// (PNG, EXR, HDR) imported into one, as the area light painter's `texture` stage does.
pub fn light_texture(bytes: &[u8]) {
    use crate::light_texture::{PaintOp, load_image, render};
    let Some((pick, rest)) = bytes.split_first() else { return };
    let result = match pick % 4 {
        0 => {
            let Ok(text) = std::str::from_utf8(rest) else { return };
            let Ok(ops) = ron::from_str::<Vec<PaintOp>>(text) else { return };
            render(&ops, 32, &mut |_| Err("no files here".into()))
        }
        k => {
            let path = scratch_file(["", "light.png", "light.exr", "light.hdr"][k as usize], rest);
            let import = PaintOp::Import { path: path.display().to_string(), intensity: 1.0 };
            render(&[import], 32, &mut |p| load_image(Path::new(p)))
        }
    };
    if let Ok(texture) = result {
        assert!(texture.emission().iter().flatten().all(|v| v.is_finite()), "a replayed light is not finite");
    }
}

/// A normal map (the first byte picks PNG, EXR, or a glTF or GLB whose material's normal
/// texture is read), loaded and, when small enough to be quick, filtered into its NDF pyramid
/// and vMF mixtures.
pub fn normal_map(bytes: &[u8]) {
    use crate::normal_filtering::{NdfPyramid, load_gltf_normal_map, load_normal_map, vmf_pyramid};
    let Some((format, file)) = bytes.split_first() else { return };
    let name = ["normals.png", "normals.exr", "normals.gltf", "normals.glb"][*format as usize % 4];
    let path = scratch_file(name, file);
    let loaded = match format % 4 {
        0 | 1 => load_normal_map(&path),
        _ => load_gltf_normal_map(&path, "normals").map(|loaded| {
            assert!(loaded.scale.is_finite(), "a non-finite normal texture scale");
            loaded.map
        }),
    };
    if let Ok(map) = loaded {
        assert!(map.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-9), "a loaded normal is not unit");
        if map.normals.len() <= 64 * 64 {
            let pyramid = NdfPyramid::build(&map, 3);
            assert!(pyramid.levels.iter().all(|l| l.sh.iter().all(|c| c.is_finite())), "a non-finite NDF");
            let mixtures = vmf_pyramid(&map, 3, 5, 16);
            assert!(mixtures.iter().flatten().flatten().all(|l| l.kappa.is_finite() && l.weight.is_finite()));
        }
    }
}

/// A GLB file of `json` and `bin`: header, JSON chunk, BIN chunk (each padded to four bytes),
/// for tests and corpora that embed data in one.
pub fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    for word in [2, total, json.len(), 0x4E4F_534A] {
        out.extend_from_slice(&(word as u32).to_le_bytes());
    }
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
    out.extend_from_slice(&bin);
    out
}

/// A disk-cache entry decoded as each persisted type the first byte picks.
pub fn disk_entry(bytes: &[u8]) {
    use crate::engine::Codec;
    let Some((pick, entry)) = bytes.split_first() else { return };
    let codecs = [
        Codec::of::<crate::transport::ShTransport>(),
        Codec::of::<crate::transport::SphericalTransport>(),
        Codec::of::<crate::triple_product::LocalProducts>(),
        Codec::of::<Vec<crate::single_scattering::FTable>>(),
        Codec::of::<crate::sphere_set::SphereSetFit>(),
    ];
    let codec = &codecs[*pick as usize % codecs.len()];
    let dir = scratch_dir().join("cache");
    let cache = crate::engine::cache::DiskCache::with_budget(&dir, 1 << 30);
    let key = 0x5eed;
    let path = cache.path_for(key);
    std::fs::create_dir_all(path.parent().expect("entries live in a folder")).expect("scratch folder");
    std::fs::write(&path, entry).expect("scratch file");
    let _ = cache.load(key, codec);
}

/// A per-process scratch folder (on tmpfs where there is one).
fn scratch_dir() -> PathBuf {
    let base = if Path::new("/dev/shm").is_dir() { PathBuf::from("/dev/shm") } else { std::env::temp_dir() };
    let dir = base.join(format!("lightloom-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

fn scratch_file(name: &str, bytes: &[u8]) -> PathBuf {
    let path = scratch_dir().join(name);
    std::fs::write(&path, bytes).expect("scratch file");
    path
}
