//! `lightloom bench --only rays`: visibility rays on the engine model (2CylinderEngine.glb,
//! 121k triangles), 3,024 receivers with 256 and 1,024 Fibonacci directions each, over their
//! upper hemispheres: the transport stages' rays. One ray at a time (obvhs's 8-wide BVH) and
//! one bundle per receiver (the ray stream the transports use), beside Embree's rate on the
//! same rays. `--rays-dump DIR` writes the mesh and the rays with our answers, for
//! `tools/rays/compare_mitsuba.py` to trace them with Mitsuba 3 (Embree) and compare.

use anyhow::{Context, Result};
use glam::Vec3A;
use lightloom_nodes::mesh::MeshSet;
use lightloom_nodes::raycast::RayScene;
use lightloom_nodes::transport::{self, Receivers};
use rayon::prelude::*;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// The engine model, as the engine sample reads it (built into the program).
const ENGINE_MODEL: &str = "assets/gltf/assimp-glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";

/// One bundle per receiver: its origin and its rays (directions above its surface).
struct Bundles {
    origins: Vec<Vec3A>,
    rays: Vec<Vec<u32>>,
    directions: Vec<Vec3A>,
}

impl Bundles {
    fn new(scene: &RayScene, receivers: &Receivers, count: usize) -> Self {
        let directions: Vec<Vec3A> =
            transport::fibonacci_directions(count).iter().map(|d| d.as_vec3().into()).collect();
        let (origins, rays) = (0..receivers.len())
            .map(|i| {
                let (p, n) = receivers.point(i);
                let above = (0..count as u32).filter(|&k| directions[k as usize].as_dvec3().dot(n) > 0.0).collect();
                (scene.leave_surface(p, n), above)
            })
            .unzip();
        Self { origins, rays, directions }
    }

    fn count(&self) -> usize {
        self.rays.iter().map(Vec::len).sum()
    }

    /// Blocked flags, receiver by receiver, one ray at a time.
    fn single(&self, scene: &RayScene) -> Vec<Vec<bool>> {
        (0..self.origins.len())
            .into_par_iter()
            .map(|i| {
                let rays = &self.rays[i];
                rays.iter()
                    .map(|&k| scene.occluded(self.origins[i], self.directions[k as usize], f32::INFINITY))
                    .collect()
            })
            .collect()
    }

    /// Blocked flags, receiver by receiver, one bundle each.
    fn bundled(&self, scene: &RayScene) -> Vec<Vec<bool>> {
        (0..self.origins.len())
            .into_par_iter()
            .map(|i| {
                let mut blocked = vec![false; self.directions.len()];
                scene.occlude_bundle(self.origins[i], &self.directions, &self.rays[i], f32::INFINITY, &mut blocked);
                self.rays[i].iter().map(|&k| blocked[k as usize]).collect()
            })
            .collect()
    }
}

/// Best of `runs` timings (the machine is shared: the best is the least disturbed).
fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (T, f64) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..runs {
        let start = Instant::now();
        out = Some(f());
        best = best.min(start.elapsed().as_secs_f64());
    }
    (out.expect("at least one run"), best)
}

pub fn ray_figures(dump: Option<&Path>) -> Result<()> {
    let model = crate::samples::file(ENGINE_MODEL)?;
    let scene = lightloom_nodes::gltf_import::import(&model).map_err(|e| anyhow::anyhow!(e))?;
    let meshes = MeshSet { meshes: scene.meshes };
    let start = Instant::now();
    let rays = RayScene::build(&meshes);
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let receivers = Receivers::from_meshes(&meshes).every_nth(3000);
    println!(
        "Visibility rays, 2CylinderEngine.glb ({} triangles, BVH build {build_ms:.0} ms), {} receivers:",
        rays.triangle_count(),
        receivers.len()
    );
    if let Some(dir) = dump {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        write_ply(&meshes, &dir.join("scene.ply"))?;
    }
    for count in [256, 1024] {
        let bundles = Bundles::new(&rays, &receivers, count);
        let cast = bundles.count() as f64;
        let (single, single_s) = best_of(3, || bundles.single(&rays));
        let (bundled, bundled_s) = best_of(3, || bundles.bundled(&rays));
        let differ: usize =
            single.iter().zip(&bundled).map(|(a, b)| a.iter().zip(b).filter(|(a, b)| a != b).count()).sum();
        let rate = cast / bundled_s / 1e6;
        let embree = super::anchors::embree(count).map_or(String::new(), |a| a.beside(rate));
        println!(
            "  {count:>4} directions, {cast} rays: one at a time {:.2} M rays/s, bundles {rate:.2} M rays/s ({:.1}× single), \
             {embree}; {differ} rays differ between the two ({:.3}%)",
            cast / single_s / 1e6,
            single_s / bundled_s,
            100.0 * differ as f64 / cast
        );
        if let Some(dir) = dump {
            write_rays(&bundles, &bundled, &dir.join(format!("rays_{count}.bin")))?;
            let timing = serde_json::json!({
                "rays": bundles.count(),
                "receivers": receivers.len(),
                "lightloom_bundle_seconds": bundled_s,
                "lightloom_single_seconds": single_s,
            });
            std::fs::write(dir.join(format!("rays_{count}.json")), serde_json::to_vec_pretty(&timing)?)?;
        }
    }
    if let Some(dir) = dump {
        println!(
            "  rays written to {}: compare with `python3 tools/rays/compare_mitsuba.py {}`",
            dir.display(),
            dir.display()
        );
    }
    Ok(())
}

/// The mesh as binary little-endian PLY (float positions, int triangle lists), world space.
fn write_ply(meshes: &MeshSet, path: &Path) -> Result<()> {
    let vertices: usize = meshes.meshes.iter().map(|m| m.positions.len()).sum();
    let faces: usize = meshes.meshes.iter().map(|m| m.indices.len() / 3).sum();
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
    )?;
    for m in &meshes.meshes {
        for p in &m.positions {
            out.write_all(bytemuck::cast_slice(p))?;
        }
    }
    let mut base = 0i32;
    for m in &meshes.meshes {
        for t in m.indices.chunks_exact(3) {
            out.write_all(&[3u8])?;
            for &i in t {
                out.write_all(&(base + i as i32).to_le_bytes())?;
            }
        }
        base += m.positions.len() as i32;
    }
    out.flush()?;
    Ok(())
}

/// Rays as little-endian f32 records (origin xyz, direction xyz, our blocked flag as 0 or 1).
fn write_rays(bundles: &Bundles, blocked: &[Vec<bool>], path: &Path) -> Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for (i, rays) in bundles.rays.iter().enumerate() {
        let o = bundles.origins[i];
        for (j, &k) in rays.iter().enumerate() {
            let d = bundles.directions[k as usize];
            let record = [o.x, o.y, o.z, d.x, d.y, d.z, if blocked[i][j] { 1.0 } else { 0.0 }];
            out.write_all(bytemuck::cast_slice(&record))?;
        }
    }
    out.flush()?;
    Ok(())
}
