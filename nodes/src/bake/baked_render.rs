//! Lightloom's own picture of baked lighting: primary rays through the scene's BVH, each hit
//! shaded `albedo × base colour × light`, the light interpolated from the vertices (`COLOR_0`)
//! or read bilinearly from the lightmap at the hit's `TEXCOORD_1`. The bake's consumers (a
//! game engine, three.js) draw the same thing, so their pictures are compared with this one.

use crate::lightmap::LightmapAtlas;
use crate::mesh::MeshSet;
use crate::raycast::RayScene;
use crate::reference::PinholeCamera;
use glam::{DVec3, Vec3A};
use rayon::prelude::*;

/// Where a baked picture reads its light.
pub enum BakedLight<'a> {
    /// `E/π` per vertex, in [`MeshSet`] order.
    Vertex(&'a [[f32; 3]]),
    /// The lightmap image (rows top to bottom) over the atlas's UVs.
    Lightmap { atlas: &'a LightmapAtlas, image: &'a [[f32; 3]] },
}

/// A linear picture and which pixels show a surface.
pub struct BakedPicture {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
    pub surface: Vec<bool>,
}

/// Renders `light` on `meshes` from `camera`: one ray through each pixel centre; `albedo[m]`
/// is mesh `m`'s diffuse colour (material albedo × the mesh's base colour).
pub fn render(
    meshes: &MeshSet,
    scene: &RayScene,
    albedo: &[[f32; 3]],
    light: &BakedLight,
    camera: &PinholeCamera,
    (width, height): (usize, usize),
) -> BakedPicture {
    let mut first_triangle = Vec::with_capacity(meshes.meshes.len());
    let mut first_vertex = Vec::with_capacity(meshes.meshes.len());
    let (mut t, mut v) = (0, 0);
    for m in &meshes.meshes {
        first_triangle.push(t);
        first_vertex.push(v);
        t += m.triangle_count();
        v += m.positions.len();
    }
    let shaded: Vec<Option<[f32; 3]>> = (0..width * height)
        .into_par_iter()
        .map(|i| {
            let dir = camera.ray((i % width) as f64 + 0.5, (i / width) as f64 + 0.5, width, height);
            let origin = Vec3A::from(camera.position.as_vec3());
            let (distance, triangle) = scene.closest(origin, dir.as_vec3().into())?;
            let m = meshes.mesh_of_triangle(triangle as usize)?;
            let local = triangle as usize - first_triangle[m];
            let mesh = &meshes.meshes[m];
            let corners = [0, 1, 2].map(|k| mesh.indices[local * 3 + k] as usize);
            let p = camera.position + dir * f64::from(distance);
            let b = barycentric(p, corners.map(|c| DVec3::from(mesh.positions[c].map(f64::from))));
            let e: [f32; 3] = match light {
                BakedLight::Vertex(values) => {
                    std::array::from_fn(|c| (0..3).map(|k| b[k] as f32 * values[first_vertex[m] + corners[k]][c]).sum())
                }
                BakedLight::Lightmap { atlas, image } => {
                    let a = &atlas.meshes[m];
                    let uv = (0..3).fold([0.0f64; 2], |acc, k| {
                        let t = a.uvs[a.indices[local * 3 + k] as usize];
                        [acc[0] + b[k] * f64::from(t[0]), acc[1] + b[k] * f64::from(t[1])]
                    });
                    bilinear(image, atlas.width as usize, atlas.height as usize, uv)
                }
            };
            let a = albedo.get(m).copied().unwrap_or([0.8; 3]);
            Some([0, 1, 2].map(|c| a[c] * e[c]))
        })
        .collect();
    BakedPicture {
        width,
        height,
        surface: shaded.iter().map(Option::is_some).collect(),
        pixels: shaded.into_iter().map(|p| p.unwrap_or([0.0; 3])).collect(),
    }
}

/// Barycentric weights of `p` (on the triangle's plane) in triangle `t`.
fn barycentric(p: DVec3, t: [DVec3; 3]) -> [f64; 3] {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det.abs() < 1e-300 {
        return [1.0, 0.0, 0.0];
    }
    let b1 = (d22 * d1 - d12 * d2) / det;
    let b2 = (d11 * d2 - d12 * d1) / det;
    [1.0 - b1 - b2, b1, b2]
}

/// Bilinear lookup with texel centres at `(x + 0.5)/w` and clamping at the edges, as a GPU
/// sampler with linear filtering and clamp-to-edge does.
pub fn bilinear(image: &[[f32; 3]], w: usize, h: usize, uv: [f64; 2]) -> [f32; 3] {
    let x = (uv[0] * w as f64 - 0.5).clamp(0.0, (w - 1) as f64);
    let y = (uv[1] * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let at = |x: usize, y: usize| image[y * w + x];
    std::array::from_fn(|c| {
        let top = at(x0, y0)[c] * (1.0 - fx) + at(x1, y0)[c] * fx;
        let bottom = at(x0, y1)[c] * (1.0 - fx) + at(x1, y1)[c] * fx;
        top * (1.0 - fy) + bottom * fy
    })
}
