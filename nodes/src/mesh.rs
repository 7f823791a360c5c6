//! Triangle meshes and the built-in procedural shapes (plane, sphere, box, torus, Cornell
//! box), so projects need no files.

use glam::{DMat3, DMat4, DVec3};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(MeshSet, "meshes", |v| v.approx_bytes());
crate::stage_type!(VertexFrames, "vertex tangent frames", |v| v.tangents.len() * 16);

/// Per vertex of every mesh of a set, in order: the normal-map frame's unit tangent
/// ([`vertex_tangents`]) and, as `w`, the bitangent's sign ([`vertex_bitangent_signs`]), or
/// [`NO_TEXTURE_COORDINATES`] on a mesh without them, where a normal map does not apply (the
/// viewport draws it unmapped, as the reference does).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexFrames {
    pub tangents: Vec<[f32; 4]>,
}

/// The `w` of a [`VertexFrames`] tangent on a mesh without texture coordinates: outside the
/// signs' ±1, and out of reach of interpolating them across a triangle (`normal_map.wgsl`
/// `surface_ndf` reads `w > 1.5` as "no map").
pub const NO_TEXTURE_COORDINATES: f32 = 2.0;

impl VertexFrames {
    pub fn of(set: &MeshSet) -> Self {
        let mut tangents = Vec::with_capacity(set.meshes.iter().map(|m| m.positions.len()).sum());
        for mesh in &set.meshes {
            let frames = vertex_tangents(mesh);
            let signs = bitangent_signs_with(mesh, || frames.clone());
            let mapped = mesh.uvs.len() == mesh.positions.len();
            let no_map = NO_TEXTURE_COORDINATES;
            tangents
                .extend(frames.iter().zip(signs).map(|([x, y, z], w)| [*x, *y, *z, if mapped { w } else { no_map }]));
        }
        Self { tangents }
    }
}

/// An indexed triangle mesh in world space (counter-clockwise front faces).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mesh {
    pub name: String,
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    /// Authored unit tangents (glTF `TANGENT`), or empty: [`vertex_tangents`] derives them.
    #[serde(default)]
    pub tangents: Vec<[f32; 3]>,
    /// Authored handedness of each tangent frame (glTF `TANGENT.w`: the bitangent is
    /// `w · n × t`), or empty: [`vertex_bitangent_signs`] derives it from the UVs.
    #[serde(default)]
    pub bitangent_signs: Vec<f32>,
    pub indices: Vec<u32>,
    /// Linear RGB base colour (multiplies the material albedo).
    pub base_color: [f32; 3],
    /// Receives a per-texel visibility texture over its UVs (needs non-overlapping UVs).
    #[serde(default)]
    pub visibility_texture: bool,
    /// Name of the material that shades it (a BRDF editor node id, or a glTF material name);
    /// empty for the first material.
    #[serde(default)]
    pub material: String,
    /// The object transform its world-space data went through (column-major; identity for
    /// object-space meshes): the bake writes object-space geometry under it.
    #[serde(default = "identity_transform")]
    pub transform: [f64; 16],
}

fn identity_transform() -> [f64; 16] {
    DMat4::IDENTITY.to_cols_array()
}

/// Empty, white.
impl Default for Mesh {
    fn default() -> Self {
        Self {
            name: String::new(),
            positions: Vec::new(),
            normals: Vec::new(),
            uvs: Vec::new(),
            tangents: Vec::new(),
            bitangent_signs: Vec::new(),
            indices: Vec::new(),
            base_color: [1.0; 3],
            visibility_texture: false,
            material: String::new(),
            transform: identity_transform(),
        }
    }
}

impl Mesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Applies an affine transform (normals by the inverse transpose).
    pub fn transformed(mut self, transform: DMat4) -> Self {
        let normal_matrix = DMat3::from_mat4(transform).inverse().transpose();
        for p in &mut self.positions {
            *p = transform.transform_point3(DVec3::from(p.map(f64::from))).as_vec3().to_array();
        }
        for n in &mut self.normals {
            *n = (normal_matrix * DVec3::from(n.map(f64::from))).normalize_or_zero().as_vec3().to_array();
        }
        let linear = DMat3::from_mat4(transform);
        for t in &mut self.tangents {
            *t = (linear * DVec3::from(t.map(f64::from))).normalize_or_zero().as_vec3().to_array();
        }
        // A mirroring transform flips the winding, and the handedness of authored frames.
        if transform.determinant() < 0.0 {
            for s in &mut self.bitangent_signs {
                *s = -*s;
            }
            for t in self.indices.chunks_mut(3) {
                t.swap(1, 2);
            }
        }
        self
    }

    /// Gives a mesh without texture coordinates box-projected ones (a mesh with its own keeps
    /// them): each triangle takes the two axes across its face normal's largest component, in
    /// units of `size` after `scale` (the object's scale per axis, so that a tile is `size`
    /// metres on the object whatever its units). A vertex whose triangles face different axes is
    /// split, one copy per axis, so every triangle interpolates one projection; the seams lie
    /// where the main axis changes, as in any box mapping. The coordinates of opposite faces
    /// overlap, so they suit a tiled map, not a per-texel visibility texture.
    pub fn box_projected(mut self, size: f64, scale: [f64; 3]) -> Self {
        if self.uvs.len() == self.positions.len() || size.is_nan() || size <= 0.0 {
            return self;
        }
        // The two axes each main axis projects on (x → (z, y), y → (x, z), z → (x, y)); a face
        // on the negative side mirrors the first. The frames (tangent along u, bitangent against
        // v, their handedness from the coordinates) light every face consistently; a map that is
        // not symmetric reads mirrored or turned on some faces, as in any plain box mapping.
        const ACROSS: [[usize; 2]; 3] = [[2, 1], [0, 2], [0, 1]];
        let positions = std::mem::take(&mut self.positions);
        let normals = std::mem::take(&mut self.normals);
        let indices = std::mem::take(&mut self.indices);
        let smooth = normals.len() == positions.len();
        self.uvs.clear();
        // Frames follow the new coordinates.
        self.tangents.clear();
        self.bitangent_signs.clear();
        let mut copies: std::collections::HashMap<(u32, usize), u32> = std::collections::HashMap::new();
        for triangle in indices.chunks_exact(3) {
            if triangle.iter().any(|&i| i as usize >= positions.len()) {
                continue;
            }
            let p: [DVec3; 3] =
                std::array::from_fn(|k| triangle[k]).map(|i| DVec3::from(positions[i as usize].map(f64::from)));
            let normal = (p[1] - p[0]).cross(p[2] - p[0]);
            let axis = normal.abs().max_position();
            let mirrored = normal[axis] < 0.0;
            for &i in triangle {
                let index = *copies.entry((i, 2 * axis + usize::from(mirrored))).or_insert_with(|| {
                    let q = positions[i as usize];
                    let [a, b] = ACROSS[axis];
                    let u = f64::from(q[a]) * scale[a] / size;
                    let v = f64::from(q[b]) * scale[b] / size;
                    self.positions.push(q);
                    let face = normal.normalize_or(DVec3::Y).as_vec3().to_array();
                    self.normals.push(if smooth { normals[i as usize] } else { face });
                    self.uvs.push([(if mirrored { -u } else { u }) as f32, v as f32]);
                    (self.positions.len() - 1) as u32
                });
                self.indices.push(index);
            }
        }
        self
    }

    /// Axis-aligned bounds `(min, max)`.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::MAX; 3];
        let mut hi = [f32::MIN; 3];
        for p in &self.positions {
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        (lo, hi)
    }

    fn push_vertex(&mut self, p: DVec3, n: DVec3, uv: [f64; 2]) -> u32 {
        self.positions.push(p.as_vec3().to_array());
        self.normals.push(n.normalize().as_vec3().to_array());
        self.uvs.push([uv[0] as f32, uv[1] as f32]);
        (self.positions.len() - 1) as u32
    }

    /// A `rows × cols` grid of vertices from `f(u, v) -> (position, normal)`, triangulated.
    fn grid(&mut self, cols: usize, rows: usize, f: impl Fn(f64, f64) -> (DVec3, DVec3)) {
        let base = self.positions.len() as u32;
        for j in 0..=rows {
            for i in 0..=cols {
                let (u, v) = (i as f64 / cols as f64, j as f64 / rows as f64);
                let (p, n) = f(u, v);
                self.push_vertex(p, n, [u, v]);
            }
        }
        let stride = cols as u32 + 1;
        for j in 0..rows as u32 {
            for i in 0..cols as u32 {
                let a = base + j * stride + i;
                let (b, c, d) = (a + 1, a + stride, a + stride + 1);
                self.indices.extend_from_slice(&[a, c, b, b, c, d]);
            }
        }
    }
}

/// Per-vertex unit tangents orthogonal to the normals: the authored ones where the mesh has
/// them, else from the UV parameterisation where it is usable (Lengyel's method, accumulated
/// over adjacent triangles), else any vector orthogonal to the normal.
pub fn vertex_tangents(mesh: &Mesh) -> Vec<[f32; 3]> {
    let mut acc = vec![DVec3::ZERO; mesh.positions.len()];
    if mesh.tangents.len() == mesh.positions.len() {
        for (a, t) in acc.iter_mut().zip(&mesh.tangents) {
            *a = DVec3::from(t.map(f64::from));
        }
    } else if mesh.uvs.len() == mesh.positions.len() {
        acc = uv_gradients(mesh, |dp_du, _| dp_du);
    }
    acc.iter()
        .zip(&mesh.normals)
        .map(|(t, n)| {
            let n = DVec3::from(n.map(f64::from)).normalize_or(DVec3::Y);
            let t = (*t - n * n.dot(*t)).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
            t.as_vec3().to_array()
        })
        .collect()
}

/// Per vertex, the sum over its triangles of `pick(∂p/∂u, ∂p/∂v)`, each triangle's UV gradients
/// (Lengyel's method; triangles whose UVs are degenerate add nothing). The mesh has UVs.
fn uv_gradients(mesh: &Mesh, pick: impl Fn(DVec3, DVec3) -> DVec3) -> Vec<DVec3> {
    let mut acc = vec![DVec3::ZERO; mesh.positions.len()];
    for t in mesh.indices.chunks_exact(3) {
        let p = |i: u32| DVec3::from(mesh.positions[i as usize].map(f64::from));
        let uv = |i: u32| mesh.uvs[i as usize].map(f64::from);
        let (e1, e2) = (p(t[1]) - p(t[0]), p(t[2]) - p(t[0]));
        let (a, b, c) = (uv(t[0]), uv(t[1]), uv(t[2]));
        let (du1, dv1, du2, dv2) = (b[0] - a[0], b[1] - a[1], c[0] - a[0], c[1] - a[1]);
        let det = du1 * dv2 - du2 * dv1;
        if det.abs() < 1e-20 {
            continue;
        }
        let gradient = pick((e1 * dv2 - e2 * dv1) / det, (e2 * du1 - e1 * du2) / det);
        for &i in t {
            acc[i as usize] += gradient;
        }
    }
    acc
}

/// Per vertex, the handedness of the normal-map frame: the bitangent, where a map's +Y
/// (up in the image, towards decreasing v) points, is `sign · n × t`. Authored signs where the
/// mesh has them, else the side `-∂p/∂v` lies on (so mirrored UV islands get −1), else +1.
pub fn vertex_bitangent_signs(mesh: &Mesh) -> Vec<f32> {
    bitangent_signs_with(mesh, || vertex_tangents(mesh))
}

/// [`vertex_bitangent_signs`], with the mesh's [`vertex_tangents`] from `tangents` if needed.
fn bitangent_signs_with(mesh: &Mesh, tangents: impl FnOnce() -> Vec<[f32; 3]>) -> Vec<f32> {
    if mesh.bitangent_signs.len() == mesh.positions.len() {
        return mesh.bitangent_signs.iter().map(|s| if *s < 0.0 { -1.0 } else { 1.0 }).collect();
    }
    if mesh.uvs.len() != mesh.positions.len() {
        return vec![1.0; mesh.positions.len()];
    }
    let dp_dv = uv_gradients(mesh, |_, dp_dv| dp_dv);
    tangents()
        .iter()
        .zip(&mesh.normals)
        .zip(&dp_dv)
        .map(|((t, n), dp_dv)| {
            let (t, n) = (DVec3::from(t.map(f64::from)), DVec3::from(n.map(f64::from)));
            if n.cross(t).dot(-*dp_dv) < 0.0 { -1.0 } else { 1.0 }
        })
        .collect()
}

/// All meshes of a scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshSet {
    pub meshes: Vec<Mesh>,
}

impl MeshSet {
    pub fn approx_bytes(&self) -> usize {
        self.meshes.iter().map(|m| m.positions.len() * 32 + m.indices.len() * 4).sum()
    }

    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(Mesh::triangle_count).sum()
    }

    /// The mesh holding triangle `index` of the set (triangles numbered mesh after mesh).
    pub fn mesh_of_triangle(&self, index: usize) -> Option<usize> {
        let mut first = 0;
        for (i, m) in self.meshes.iter().enumerate() {
            first += m.triangle_count();
            if index < first {
                return Some(i);
            }
        }
        None
    }

    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        union_bounds(&self.meshes)
    }
}

/// A square in the XZ plane, normal +Y, side `size`, centred at the origin.
pub fn plane(size: f64, segments: usize) -> Mesh {
    let mut m = Mesh::default();
    let h = size / 2.0;
    m.grid(segments.max(1), segments.max(1), |u, v| (DVec3::new(-h + size * u, 0.0, -h + size * v), DVec3::Y));
    m
}

/// A UV sphere of `radius` centred at the origin.
pub fn sphere(radius: f64, segments: usize) -> Mesh {
    let mut m = Mesh::default();
    let (cols, rows) = (segments.max(3) * 2, segments.max(2));
    m.grid(cols, rows, |u, v| {
        let (theta, phi) = (PI * v, 2.0 * PI * u);
        let n = DVec3::new(theta.sin() * phi.sin(), theta.cos(), theta.sin() * phi.cos());
        (n * radius, n)
    });
    m
}

/// A torus around +Y with major radius `major` and tube radius `minor`.
pub fn torus(major: f64, minor: f64, segments: usize) -> Mesh {
    let mut m = Mesh::default();
    let (cols, rows) = (segments.max(3) * 2, segments.max(3));
    m.grid(cols, rows, |u, v| {
        let (phi, theta) = (2.0 * PI * u, -2.0 * PI * v);
        let ring = DVec3::new(phi.sin(), 0.0, phi.cos());
        let n = ring * theta.cos() + DVec3::Y * theta.sin();
        (ring * major + n * minor, n)
    });
    m
}

/// An axis-aligned box of `size`, centred at the origin, normals outwards (or inwards).
pub fn cuboid(size: [f64; 3], segments: usize, inward: bool) -> Mesh {
    let mut m = Mesh::default();
    let h = DVec3::from(size) / 2.0;
    let s = segments.max(1);
    for (face, (axis, sign)) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0)].into_iter().enumerate()
    {
        let normal = {
            let mut n = DVec3::ZERO;
            n[axis] = sign;
            n
        };
        // Tangent directions chosen so (t1 × t2) = normal (counter-clockwise seen from outside).
        let t1 = {
            let mut t = DVec3::ZERO;
            t[(axis + 1) % 3] = 1.0;
            t
        };
        let t2 = normal.cross(t1);
        let (n_out, flip) = if inward { (-normal, true) } else { (normal, false) };
        let first = m.indices.len();
        let first_vertex = m.uvs.len();
        m.grid(s, s, |u, v| {
            let local =
                normal * h[axis] + t1 * (u - 0.5) * 2.0 * h[(axis + 1) % 3] + t2 * (v - 0.5) * 2.0 * h[(axis + 2) % 3];
            (local, n_out)
        });
        // UV atlas of 3 × 2 cells, one per face, so the UVs never overlap.
        for uv in &mut m.uvs[first_vertex..] {
            *uv = [((face % 3) as f32 + uv[0]) / 3.0, ((face / 3) as f32 + uv[1]) / 2.0];
        }
        // grid winds (u, v) counter-clockwise about u × v = t1 × t2 = -normal, so flip for outward.
        if !flip {
            for t in m.indices[first..].chunks_mut(3) {
                t.swap(1, 2);
            }
        }
    }
    m
}

/// A Cornell-style box: floor, ceiling, back wall (white), left wall red, right wall green;
/// open towards +Z, normals inwards. `size` is the side length; the floor is at y = 0.
pub fn cornell_box(size: f64, segments: usize) -> Vec<Mesh> {
    let h = size / 2.0;
    let wall = |name: &str, color: [f32; 3], rot: DMat4| {
        let mut m = plane(size, segments).transformed(rot);
        m.name = name.to_string();
        m.base_color = color;
        m
    };
    let lift = DMat4::from_translation(DVec3::new(0.0, h, 0.0));
    vec![
        wall("floor", [0.73, 0.73, 0.73], DMat4::IDENTITY),
        wall("ceiling", [0.73, 0.73, 0.73], lift * DMat4::from_translation(DVec3::Y * h) * DMat4::from_rotation_x(PI)),
        wall(
            "back",
            [0.73, 0.73, 0.73],
            lift * DMat4::from_translation(-DVec3::Z * h) * DMat4::from_rotation_x(PI / 2.0),
        ),
        wall(
            "left",
            [0.63, 0.065, 0.05],
            lift * DMat4::from_translation(-DVec3::X * h) * DMat4::from_rotation_z(-PI / 2.0),
        ),
        wall(
            "right",
            [0.14, 0.45, 0.091],
            lift * DMat4::from_translation(DVec3::X * h) * DMat4::from_rotation_z(PI / 2.0),
        ),
    ]
}

/// Axis-aligned bounds `(min, max)` of several meshes (inverted bounds when there are none).
pub fn union_bounds<'a>(meshes: impl IntoIterator<Item = &'a Mesh>) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for m in meshes {
        let (a, b) = m.bounds();
        for c in 0..3 {
            lo[c] = lo[c].min(a[c]);
            hi[c] = hi[c].max(b[c]);
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cuboid stripped of its coordinates, box-projected: each face's vertices carry its own
    /// projection (the two axes across its normal, over `size` after the scale), a vertex on
    /// an edge is split between its faces, and the normal-map frames follow: each face's
    /// tangent runs along u's gradient and its bitangent (`w · n × t`) against v's, as on a
    /// mesh whose coordinates were authored so.
    #[test]
    fn box_projection_gives_each_face_its_axes() {
        let mut bare = cuboid([2.0, 1.0, 3.0], 2, false);
        bare.uvs.clear();
        let scale = [0.5, 2.0, 1.0];
        let projected = bare.clone().box_projected(4.0, scale);
        assert_eq!(projected.indices.len(), bare.indices.len());
        assert_eq!(projected.uvs.len(), projected.positions.len());
        // On a sphere, whose triangles share vertices, those where the main axis changes split.
        let mut ball = sphere(1.0, 16);
        ball.uvs.clear();
        let split = ball.clone().box_projected(1.0, [1.0; 3]);
        assert!(split.positions.len() > ball.positions.len() && split.indices.len() == ball.indices.len());
        let frames = VertexFrames::of(&MeshSet { meshes: vec![projected.clone()] });
        for triangle in projected.indices.chunks_exact(3) {
            let p: [DVec3; 3] =
                std::array::from_fn(|k| DVec3::from(projected.positions[triangle[k] as usize].map(f64::from)));
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            let axis = normal.abs().max_position();
            let across = [[2, 1], [0, 2], [0, 1]][axis];
            let mirror = if normal[axis] < 0.0 { -1.0 } else { 1.0 };
            for (&i, q) in triangle.iter().zip(&p) {
                let uv = projected.uvs[i as usize];
                let want = [mirror * q[across[0]] * scale[across[0]] / 4.0, q[across[1]] * scale[across[1]] / 4.0];
                assert!((f64::from(uv[0]) - want[0]).abs() < 1e-6 && (f64::from(uv[1]) - want[1]).abs() < 1e-6);
                let [tx, ty, tz, w] = frames.tangents[i as usize];
                let t = DVec3::new(tx.into(), ty.into(), tz.into());
                let b = f64::from(w) * normal.cross(t);
                let mut du = DVec3::ZERO;
                du[across[0]] = mirror;
                let mut dv = DVec3::ZERO;
                dv[across[1]] = 1.0;
                // glTF's frame: the bitangent runs against v (its images' rows run down).
                assert!(t.dot(du) > 0.99 && b.dot(-dv) > 0.99, "face {normal}: frame {t} {b}");
            }
        }
        // A mesh with its own coordinates keeps them.
        let authored = cuboid([2.0, 1.0, 3.0], 2, false);
        assert_eq!(authored.clone().box_projected(4.0, scale), authored);
    }

    #[test]
    fn picking_a_ray_finds_the_mesh_it_hits() {
        // Two spheres side by side: the ray's closest triangle belongs to the nearer mesh.
        let set = MeshSet {
            meshes: vec![
                sphere(1.0, 16).transformed(DMat4::from_translation(glam::DVec3::new(-2.0, 0.0, 0.0))),
                sphere(1.0, 16).transformed(DMat4::from_translation(glam::DVec3::new(2.0, 0.0, 0.0))),
            ],
        };
        let scene = crate::raycast::RayScene::build(&set);
        let hit = |x: f32| {
            let (_, t) = scene.closest(glam::Vec3A::new(x, 0.0, 10.0), glam::Vec3A::new(0.0, 0.0, -1.0))?;
            set.mesh_of_triangle(t as usize)
        };
        assert_eq!(hit(-2.0), Some(0));
        assert_eq!(hit(2.0), Some(1));
        assert_eq!(hit(0.0), None);
        assert_eq!(set.mesh_of_triangle(set.triangle_count()), None);
    }

    /// Signed volume by the divergence theorem; positive for outward-facing closed meshes.
    fn volume(m: &Mesh) -> f64 {
        m.indices
            .chunks(3)
            .map(|t| {
                let p = |i: u32| DVec3::from(m.positions[i as usize].map(f64::from));
                p(t[0]).dot(p(t[1]).cross(p(t[2]))) / 6.0
            })
            .sum()
    }

    fn area(m: &Mesh) -> f64 {
        m.indices
            .chunks(3)
            .map(|t| {
                let p = |i: u32| DVec3::from(m.positions[i as usize].map(f64::from));
                0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length()
            })
            .sum()
    }

    #[test]
    fn closed_shapes_have_their_analytic_volumes_and_outward_winding() {
        assert!((volume(&sphere(2.0, 64)) - 4.0 / 3.0 * PI * 8.0).abs() < 0.01 * 4.0 / 3.0 * PI * 8.0);
        assert!((volume(&cuboid([1.0, 2.0, 3.0], 2, false)) - 6.0).abs() < 1e-5);
        assert!((volume(&cuboid([1.0, 2.0, 3.0], 2, true)) + 6.0).abs() < 1e-5);
        let t = torus(2.0, 0.5, 64);
        let exact = 2.0 * PI * PI * 2.0 * 0.25;
        assert!((volume(&t) - exact).abs() < 0.01 * exact, "{} vs {exact}", volume(&t));
        assert!((area(&plane(3.0, 4)) - 9.0).abs() < 1e-5);
    }

    #[test]
    fn normals_agree_with_the_winding() {
        for m in [sphere(1.0, 16), cuboid([1.0, 1.0, 1.0], 1, false), torus(1.0, 0.3, 12), plane(1.0, 2)] {
            for t in m.indices.chunks(3) {
                let p = |i: u32| DVec3::from(m.positions[i as usize].map(f64::from));
                let face = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
                if face.length() < 1e-9 {
                    continue; // degenerate pole triangles
                }
                let n = DVec3::from(m.normals[t[0] as usize].map(f64::from));
                assert!(face.dot(n) > 0.0);
            }
        }
        for wall in cornell_box(2.0, 1) {
            let centre =
                (DVec3::from(wall.bounds().0.map(f64::from)) + DVec3::from(wall.bounds().1.map(f64::from))) / 2.0;
            let n = DVec3::from(wall.normals[0].map(f64::from));
            // Inward: the normal points towards the box centre (0, 1, 0).
            assert!(n.dot(DVec3::new(0.0, 1.0, 0.0) - centre) > 0.0, "{}", wall.name);
        }
    }

    #[test]
    fn transforms_move_points_and_keep_normals_unit() {
        let m = sphere(1.0, 8).transformed(DMat4::from_scale_rotation_translation(
            DVec3::new(2.0, 1.0, 1.0),
            glam::DQuat::from_rotation_y(0.3),
            DVec3::new(5.0, 0.0, 0.0),
        ));
        let (lo, hi) = m.bounds();
        assert!(lo[0] > 2.9 && hi[0] < 7.1);
        assert!(m.normals.iter().all(|n| (DVec3::from(n.map(f64::from)).length() - 1.0).abs() < 1e-5));
    }

    #[test]
    fn authored_tangents_follow_the_transform_and_stay_orthogonal() {
        let mut m = plane(2.0, 2);
        // Authored tangents along +Z (the UV-derived ones would follow +X).
        m.tangents = vec![[0.0, 0.0, 1.0]; m.positions.len()];
        let rotation = DMat4::from_rotation_y(0.5) * DMat4::from_scale(DVec3::new(2.0, 1.0, 1.0));
        let moved = m.clone().transformed(rotation);
        let expected = (DMat3::from_mat4(rotation) * DVec3::Z).normalize();
        for (t, n) in vertex_tangents(&moved).iter().zip(&moved.normals) {
            let (t, n) = (DVec3::from(t.map(f64::from)), DVec3::from(n.map(f64::from)));
            assert!((t - expected).length() < 1e-6, "{t} vs {expected}");
            assert!(t.dot(n).abs() < 1e-6);
        }
        // Without authored tangents they come from the UVs: u runs along +X on the plane.
        for t in vertex_tangents(&plane(2.0, 2)) {
            assert!((DVec3::from(t.map(f64::from)) - DVec3::X).length() < 1e-6, "{t:?}");
        }
    }

    /// The bitangent `sign · n × t` points up the image (towards decreasing v) on the built-in
    /// shapes, on a UV layout mirrored in u, and through a mirroring transform; authored
    /// signs are kept, and flip with a mirroring transform.
    #[test]
    fn bitangent_signs_point_up_the_image() {
        let up_the_image = |m: &Mesh| {
            let signs = vertex_bitangent_signs(m);
            let tangents = vertex_tangents(m);
            // Per triangle, the frame's bitangent against the UV gradient -∂p/∂v.
            m.indices.chunks_exact(3).all(|t| {
                let p = |i: u32| DVec3::from(m.positions[i as usize].map(f64::from));
                let uv = |i: u32| m.uvs[i as usize].map(f64::from);
                let (e1, e2) = (p(t[1]) - p(t[0]), p(t[2]) - p(t[0]));
                let (a, b, c) = (uv(t[0]), uv(t[1]), uv(t[2]));
                let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
                let dp_dv = (e2 * (b[0] - a[0]) - e1 * (c[0] - a[0])) / det;
                let dp_du = (e1 * (c[1] - a[1]) - e2 * (b[1] - a[1])) / det;
                det.abs() < 1e-12
                    || t.iter().all(|&i| {
                        let n = DVec3::from(m.normals[i as usize].map(f64::from));
                        let t = DVec3::from(tangents[i as usize].map(f64::from));
                        // Poles, where the vertex's tangent is not the triangle's, have no side.
                        dp_du.try_normalize().is_none_or(|along_u| t.dot(along_u) < 0.7)
                            || (n.cross(t) * f64::from(signs[i as usize])).dot(-dp_dv) > 0.0
                    })
            })
        };
        for shape in [plane(2.0, 3), sphere(1.0, 8), torus(1.0, 0.3, 8)] {
            assert!(up_the_image(&shape), "{} vertices", shape.positions.len());
            assert!(vertex_bitangent_signs(&shape).iter().all(|s| *s == 1.0));
        }
        let mut mirrored = plane(2.0, 3);
        for uv in &mut mirrored.uvs {
            uv[0] = 1.0 - uv[0];
        }
        assert!(up_the_image(&mirrored));
        assert!(vertex_bitangent_signs(&mirrored).iter().all(|s| *s == -1.0));
        let flipped = plane(2.0, 3).transformed(DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0)));
        assert!(up_the_image(&flipped));
        let mut authored = plane(2.0, 1);
        authored.bitangent_signs = vec![-1.0; authored.positions.len()];
        assert!(vertex_bitangent_signs(&authored).iter().all(|s| *s == -1.0));
        let authored = authored.transformed(DMat4::from_scale(DVec3::new(1.0, 1.0, -1.0)));
        assert!(vertex_bitangent_signs(&authored).iter().all(|s| *s == 1.0));
    }
}
