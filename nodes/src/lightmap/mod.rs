//! Lightmaps: a second UV set unwrapped by `uvunwrap` (chart segmentation, LSCM, packing with
//! padding, never overlapping), the texels it covers as receivers, and the light per texel
//! written as a float EXR and as RGBM in a PNG for browsers.
//!
//! Every texel whose centre lies in a triangle becomes a receiver at the interpolated position,
//! normal and tangent; its light is computed as the vertex light is (the mode's environment
//! light from its own transport, point lights with shadow rays). Empty texels next to charts
//! take the mean of their filled neighbours, `padding` rings deep, so bilinear filtering at a
//! chart's edge reads light from that chart.

pub mod square_light_texels;

use crate::mesh::MeshSet;
use crate::transport::Receivers;
use serde::{Deserialize, Serialize};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(LightmapAtlas, "lightmap atlas", |v| v.approx_bytes());

/// Largest lightmap side.
pub const MAX_LIGHTMAP_SIZE: u32 = 4096;

/// One mesh's vertices in the atlas: seam vertices are duplicated.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AtlasMesh {
    /// Per atlas vertex: the mesh vertex it copies.
    pub xref: Vec<u32>,
    /// Per atlas vertex: lightmap UV in 0..1, `v` down the image (glTF's convention).
    pub uvs: Vec<[f32; 2]>,
    /// The mesh's triangles over the atlas vertices, in the mesh's order.
    pub indices: Vec<u32>,
}

/// The scene's lightmap layout and its texels as receivers.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LightmapAtlas {
    pub width: u32,
    pub height: u32,
    pub texels_per_metre: f32,
    pub padding: u32,
    pub meshes: Vec<AtlasMesh>,
    /// One receiver per covered texel.
    pub receivers: Receivers,
    /// Per receiver: its texel `y · width + x`.
    pub texels: Vec<u32>,
    /// Per receiver: `(mesh, triangle, barycentric weights)` it lies in.
    pub sources: Vec<(u32, u32, [f32; 3])>,
    /// Fraction of texels covered by charts.
    pub utilization: f32,
}

impl LightmapAtlas {
    pub fn approx_bytes(&self) -> usize {
        self.meshes.iter().map(|m| m.xref.len() * 12 + m.indices.len() * 4).sum::<usize>()
            + self.receivers.len() * (36 + 4 + 20)
    }

    /// Unwraps `meshes` (world space, so `texels_per_metre` is uniform across the scene).
    /// `progress` gets fractions and returns `false` to cancel.
    pub fn build(
        meshes: &MeshSet,
        texels_per_metre: f32,
        padding: u32,
        progress: &(dyn Fn(f64) -> bool + Sync),
    ) -> Result<Self, String> {
        let inputs: Vec<uvunwrap::MeshInput> =
            meshes.meshes.iter().map(|m| uvunwrap::MeshInput::new(&m.positions, &m.indices)).collect();
        let options = uvunwrap::Options {
            density: uvunwrap::Density::Fixed { texels_per_unit: texels_per_metre, page_size: None },
            padding,
            ..Default::default()
        };
        let atlas = uvunwrap::generate_with_progress(&inputs, &options, |p| {
            let stage = match p.stage {
                uvunwrap::Stage::Segmenting => 0.0,
                uvunwrap::Stage::Parameterizing => 0.25,
                uvunwrap::Stage::Packing => 0.5,
                _ => 0.75,
            };
            let within = p.total.map_or(0.0, |t| p.done as f64 / t.max(1) as f64);
            progress(stage + 0.25 * within)
        })
        .map_err(|e| format!("lightmap unwrap: {e}"))?;
        if atlas.width > MAX_LIGHTMAP_SIZE || atlas.height > MAX_LIGHTMAP_SIZE || atlas.page_count > 1 {
            return Err(format!(
                "the lightmap would be {}×{} texels (at most {MAX_LIGHTMAP_SIZE} a side): lower the texel density \
                 ({texels_per_metre} per metre)",
                atlas.width, atlas.height
            ));
        }
        let mut out = LightmapAtlas {
            width: atlas.width,
            height: atlas.height,
            texels_per_metre: atlas.texels_per_unit,
            padding,
            utilization: atlas.utilization,
            ..Default::default()
        };
        for (mesh, unwrapped) in meshes.meshes.iter().zip(&atlas.meshes) {
            out.meshes.push(AtlasMesh {
                xref: unwrapped.vertices.iter().map(|v| v.xref).collect(),
                uvs: unwrapped.vertices.iter().map(|v| v.uv).collect(),
                indices: unwrapped.indices.clone(),
            });
            debug_assert_eq!(unwrapped.indices.len(), mesh.indices.len());
        }
        out.rasterize(meshes);
        Ok(out)
    }

    /// Every texel whose centre a triangle covers becomes a receiver (the first triangle wins;
    /// charts never overlap, so only shared edges are contested).
    fn rasterize(&mut self, meshes: &MeshSet) {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut covered = vec![false; w * h];
        let mut receivers = Receivers::default();
        for (m, (mesh, atlas)) in meshes.meshes.iter().zip(&self.meshes).enumerate() {
            receivers.mesh_offsets.push(receivers.len());
            let tangents = crate::mesh::vertex_tangents(mesh);
            for (t, tri) in atlas.indices.chunks_exact(3).enumerate() {
                let uv = [0, 1, 2].map(|k| {
                    let p = atlas.uvs[tri[k] as usize];
                    [p[0] as f64 * w as f64, p[1] as f64 * h as f64]
                });
                let corners = [0, 1, 2].map(|k| atlas.xref[tri[k] as usize] as usize);
                crate::transport::for_each_covered_texel(uv, (w, h), |x, y, b| {
                    if !std::mem::replace(&mut covered[y * w + x], true) {
                        receivers.push_interpolated(mesh, &tangents, corners, b);
                        self.texels.push((y * w + x) as u32);
                        self.sources.push((m as u32, t as u32, b.map(|v| v as f32)));
                    }
                });
            }
        }
        self.receivers = receivers;
    }

    /// Per receiver: the per-vertex `values` (in [`MeshSet`] order) interpolated at it.
    pub fn interpolate(&self, meshes: &MeshSet, values: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let mut first = Vec::with_capacity(meshes.meshes.len());
        let mut n = 0;
        for m in &meshes.meshes {
            first.push(n);
            n += m.positions.len();
        }
        self.sources
            .iter()
            .map(|&(m, t, b)| {
                // The atlas's triangle `t`, its corners as the mesh's vertices (the unwrap may
                // reorder both).
                let atlas = &self.meshes[m as usize];
                let tri = &atlas.indices[t as usize * 3..t as usize * 3 + 3];
                let vertex = |k: usize| first[m as usize] + atlas.xref[tri[k] as usize] as usize;
                std::array::from_fn(|c| (0..3).map(|k| b[k] * values[vertex(k)][c]).sum())
            })
            .collect()
    }

    /// The image (rows top to bottom) of per-receiver `values`, dilated into the padding.
    pub fn image(&self, values: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut image = vec![[0.0f32; 3]; w * h];
        let mut filled = vec![false; w * h];
        for (&texel, v) in self.texels.iter().zip(values) {
            image[texel as usize] = *v;
            filled[texel as usize] = true;
        }
        for _ in 0..self.padding.max(1) {
            let mut next = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    if filled[y * w + x] {
                        continue;
                    }
                    let (mut sum, mut count) = ([0.0f32; 3], 0);
                    for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1), (-1, -1), (1, -1), (-1, 1), (1, 1)] {
                        let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                        if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                            continue;
                        }
                        let i = ny as usize * w + nx as usize;
                        if filled[i] {
                            for c in 0..3 {
                                sum[c] += image[i][c];
                            }
                            count += 1;
                        }
                    }
                    if count > 0 {
                        next.push((y * w + x, sum.map(|s| s / count as f32)));
                    }
                }
            }
            for (i, v) in next {
                image[i] = v;
                filled[i] = true;
            }
        }
        image
    }
}

/// RGBM in 8 bits: `value = rgb × a × range`, linear (no sRGB curve). `range` is the smallest
/// power of two at least the image's peak, so the encoding adapts to the scene's brightness.
pub fn encode_rgbm(image: &[[f32; 3]], range: f32) -> Vec<[u8; 4]> {
    image
        .iter()
        .map(|p| {
            let peak = p.iter().fold(0.0f32, |m, &c| m.max(c)) / range;
            let a = (peak.clamp(0.0, 1.0) * 255.0).ceil().max(1.0);
            let scale = range * a / 255.0;
            let q = |c: f32| ((c / scale).clamp(0.0, 1.0) * 255.0).round() as u8;
            [q(p[0]), q(p[1]), q(p[2]), a as u8]
        })
        .collect()
}

/// [`encode_rgbm`]'s inverse.
pub fn decode_rgbm(p: [u8; 4], range: f32) -> [f32; 3] {
    let scale = range * f32::from(p[3]) / 255.0;
    [0, 1, 2].map(|c| f32::from(p[c]) / 255.0 * scale)
}

/// A PNG of RGBM texels.
pub fn png_bytes(rgbm: &[[u8; 4]], width: u32, height: u32) -> Result<Vec<u8>, String> {
    let raw: Vec<u8> = rgbm.iter().flatten().copied().collect();
    let image = image::RgbaImage::from_raw(width, height, raw).ok_or("lightmap size mismatch")?;
    let mut bytes = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
        .map_err(|e| format!("lightmap PNG: {e}"))?;
    Ok(bytes)
}

/// A 32-bit float RGB EXR of `image`.
pub fn exr_bytes(image: &[[f32; 3]], width: u32, height: u32) -> Result<Vec<u8>, String> {
    use exr::prelude::*;
    let w = width as usize;
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let v = image[p.1 * w + p.0];
        (v[0], v[1], v[2])
    });
    let mut bytes = Vec::new();
    Image::from_channels((width as usize, height as usize), channels)
        .write()
        .to_buffered(std::io::Cursor::new(&mut bytes))
        .map_err(|e| format!("lightmap EXR: {e}"))?;
    Ok(bytes)
}
