//! The light a receiver's top face misses: the part of a light outside `v ∈ [−a/2, a/2]²`.
//!
//! The top face (§4.5.4) keeps the directions within `a/2` of vertical per unit of depth, so a
//! receiver farther than `depth · a/2` from a light's edge sees none of it through the Haar
//! products, and the floor beyond goes dark where the truth falls off smoothly to the horizon.
//! The thesis leaves the rest of the hemisphere out; here it is added in closed form:
//!
//! - The light's rectangle is split into `CELLS × CELLS` cells, each with its texture's mean
//!   radiance `F̄_c` (of the kept Haar coefficients, so both parts see one light).
//! - Each cell's part outside the receiver's face square (in the light's plane, the square
//!   `x ± depth·a/2`) lights the receiver by the exact polygon form factor of a uniform
//!   Lambertian emitter, `E = ½ Σ_i θ_i (Γ̂_i · n)` (Lambert's formula; the polygon clipped to
//!   the receiver's horizon; where the whole light is above the horizon the cells share their
//!   edges), or by the point form `A cos θ cos θ' / d²` where every part of the light is small
//!   next to its distance.
//! - Its visibility is one ray per quadrant of the light (`VISIBILITY × VISIBILITY` rays), to the
//!   centroid of that quadrant's part outside the face.
//!
//! `E_beyond = Σ_c F̄_c R_c` with the responses `R_c` (the light's placement, the face and the
//! rays alone), so a stroke only re-weights them and a move of the light re-traces them.

use super::{LightPlacement, LightSource, TopFace};
use crate::wavelet::affine::haar_inverse_2d;
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Cells per side of the light for the part beyond the face.
pub const CELLS: usize = 4;
/// Visibility rays per side of the light (each quadrant of `CELLS / VISIBILITY` cells shares one).
pub const VISIBILITY: usize = 2;
/// The point form stands in for the polygon once a cell's distance exceeds this many diagonals.
const POINT_FORM_DISTANCE: f64 = 8.0;

/// Per receiver, each light cell's irradiance per unit radiance outside the receiver's top face,
/// its visibility applied: `CELLS²` values per receiver (row `z`, then column `x`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BeyondFace {
    pub responses: Vec<f32>,
}

crate::stage_type!(BeyondFace, "light beyond the top face", |v| v.responses.len() * 4 + 16);

impl BeyondFace {
    /// `E = Σ_c F̄_c R_c` per receiver with the cells' mean radiances `means`.
    pub fn irradiance(&self, means: &[[f64; 3]]) -> Vec<[f64; 3]> {
        self.responses
            .chunks_exact(CELLS * CELLS)
            .map(|r| {
                let mut e = [0.0; 3];
                for (&g, m) in r.iter().zip(means) {
                    for c in 0..3 {
                        e[c] += f64::from(g) * m[c];
                    }
                }
                e
            })
            .collect()
    }
}

/// An axis-aligned rectangle in the light's plane: `[x₀, x₁] × [z₀, z₁]`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Rect {
    x: [f64; 2],
    z: [f64; 2],
}

impl Rect {
    fn area(&self) -> f64 {
        (self.x[1] - self.x[0]).max(0.0) * (self.z[1] - self.z[0]).max(0.0)
    }

    fn centre(&self) -> [f64; 2] {
        [(self.x[0] + self.x[1]) / 2.0, (self.z[0] + self.z[1]) / 2.0]
    }

    fn intersect(&self, other: &Rect) -> Rect {
        Rect {
            x: [self.x[0].max(other.x[0]), self.x[1].min(other.x[1])],
            z: [self.z[0].max(other.z[0]), self.z[1].min(other.z[1])],
        }
    }

    fn corners(&self, height: f64) -> [DVec3; 4] {
        [
            DVec3::new(self.x[0], height, self.z[0]),
            DVec3::new(self.x[1], height, self.z[0]),
            DVec3::new(self.x[1], height, self.z[1]),
            DVec3::new(self.x[0], height, self.z[1]),
        ]
    }
}

/// The cell `(i, j)` of `n × n` over the light (`i` along `x`, `j` along `z`).
fn cell(placement: &LightPlacement, n: usize, i: usize, j: usize) -> Rect {
    let [x0, z0] = placement.corner;
    let [w, d] = placement.extent;
    Rect {
        x: [x0 + w * i as f64 / n as f64, x0 + w * (i + 1) as f64 / n as f64],
        z: [z0 + d * j as f64 / n as f64, z0 + d * (j + 1) as f64 / n as f64],
    }
}

/// Irradiance at `point` (unit `normal`) per unit radiance of a uniform Lambertian polygon
/// (`corners`, convex, in order), clipped to the receiver's upper half-space: Lambert's
/// `½ Σ_i θ_i (Γ̂_i · n)`, `θ_i` the angle the edge `i → i+1` subtends and `Γ̂_i` its plane's
/// unit normal.
pub fn polygon_irradiance(point: DVec3, normal: DVec3, corners: &[DVec3]) -> f64 {
    // Sutherland–Hodgman against the plane `normal · (y − point) ≥ 0`.
    let mut clipped: Vec<DVec3> = Vec::with_capacity(corners.len() + 1);
    for (k, &a) in corners.iter().enumerate() {
        let b = corners[(k + 1) % corners.len()];
        let (da, db) = (normal.dot(a - point), normal.dot(b - point));
        if da >= 0.0 {
            clipped.push(a - point);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            clipped.push(a + (b - a) * t - point);
        }
    }
    if clipped.len() < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for (k, a) in clipped.iter().enumerate() {
        let b = clipped[(k + 1) % clipped.len()];
        let (ua, ub) = (a.normalize_or_zero(), b.normalize_or_zero());
        let cross = ua.cross(ub);
        let length = cross.length();
        if length < 1e-15 {
            continue;
        }
        let theta = length.atan2(ua.dot(ub));
        sum += theta * cross.dot(normal) / length;
    }
    0.5 * sum.abs()
}

/// [`polygon_irradiance`] of a horizontal rectangle at `height`, or its point form when it is
/// small next to its distance (within about 1% there).
fn rect_irradiance(point: DVec3, normal: DVec3, rect: &Rect, height: f64) -> f64 {
    let area = rect.area();
    if area <= 0.0 {
        return 0.0;
    }
    let [cx, cz] = rect.centre();
    let to = DVec3::new(cx, height, cz) - point;
    let distance2 = to.length_squared();
    let diagonal2 = (rect.x[1] - rect.x[0]).powi(2) + (rect.z[1] - rect.z[0]).powi(2);
    if distance2 > POINT_FORM_DISTANCE * POINT_FORM_DISTANCE * diagonal2 {
        // The light faces down: its cosine is the depth over the distance.
        let cos_light = to.y / distance2.sqrt();
        let cos_receiver = normal.dot(to) / distance2.sqrt();
        return (area * cos_light.max(0.0) * cos_receiver.max(0.0) / distance2).max(0.0);
    }
    polygon_irradiance(point, normal, &rect.corners(height))
}

/// The face's square in the light's plane for a receiver at `point`.
fn face_square(face: &TopFace, placement: &LightPlacement, point: DVec3) -> Rect {
    let half = (placement.height - point.y) * face.size / 2.0;
    Rect { x: [point.x - half, point.x + half], z: [point.z - half, point.z + half] }
}

/// Lambert's term of one edge `a → b` (unit directions from the receiver): `θ (Γ̂ · n)`.
fn edge_term(a: DVec3, b: DVec3, normal: DVec3) -> f64 {
    let cross = a.cross(b);
    let length = cross.length();
    if length < 1e-15 {
        return 0.0;
    }
    length.atan2(a.dot(b)) * cross.dot(normal) / length
}

/// [`rect_irradiance`] of every one of the light's cells (row `z`, then column `x`). Where the
/// whole light lies above the receiver's horizon and near enough for the polygon form, the
/// cells share their edges: Lambert's sum over the grid's 40 edges, each once, instead of 64.
fn cell_irradiances(point: DVec3, normal: DVec3, placement: &LightPlacement) -> [f64; CELLS * CELLS] {
    let mut out = [0.0; CELLS * CELLS];
    let [x0, z0] = placement.corner;
    let [w, d] = placement.extent;
    let n = CELLS as f64;
    let grid: [[DVec3; CELLS + 1]; CELLS + 1] = std::array::from_fn(|a| {
        std::array::from_fn(|b| DVec3::new(x0 + w * a as f64 / n, placement.height, z0 + d * b as f64 / n) - point)
    });
    let diagonal2 = (w * w + d * d) / (n * n);
    let near =
        grid.iter().flatten().any(|p| p.length_squared() <= POINT_FORM_DISTANCE * POINT_FORM_DISTANCE * diagonal2);
    let above = grid.iter().flatten().all(|p| normal.dot(*p) > 0.0);
    if !(near && above) {
        for j in 0..CELLS {
            for i in 0..CELLS {
                out[j * CELLS + i] = rect_irradiance(point, normal, &cell(placement, CELLS, i, j), placement.height);
            }
        }
        return out;
    }
    let unit = grid.map(|row| row.map(|p| p.normalize()));
    // Edges along x (a → a+1 at b) and along z (b → b+1 at a).
    let along_x: [[f64; CELLS + 1]; CELLS] =
        std::array::from_fn(|a| std::array::from_fn(|b| edge_term(unit[a][b], unit[a + 1][b], normal)));
    let along_z: [[f64; CELLS]; CELLS + 1] =
        std::array::from_fn(|a| std::array::from_fn(|b| edge_term(unit[a][b], unit[a][b + 1], normal)));
    for j in 0..CELLS {
        for i in 0..CELLS {
            // The cell's corners in [`Rect::corners`]' order: (i, j), (i+1, j), (i+1, j+1), (i, j+1).
            let sum = along_x[i][j] + along_z[i + 1][j] - along_x[i][j + 1] - along_z[i][j];
            out[j * CELLS + i] = 0.5 * sum.abs();
        }
    }
    out
}

/// The responses of each receiver (`points`, unit `normals`, rays leaving from `origins`) to
/// the light's cells beyond its top face; `unoccluded(origin, target)` says whether the segment
/// between them is clear. A receiver on or above the light's plane receives nothing, and one
/// whose face holds the whole light costs no more than that.
pub fn beyond_face(
    face: &TopFace,
    placement: &LightPlacement,
    points: &[DVec3],
    normals: &[DVec3],
    origins: &[DVec3],
    unoccluded: impl Fn(DVec3, DVec3) -> bool + Sync,
) -> BeyondFace {
    let per_quadrant = CELLS / VISIBILITY;
    let light = Rect {
        x: [placement.corner[0], placement.corner[0] + placement.extent[0]],
        z: [placement.corner[1], placement.corner[1] + placement.extent[1]],
    };
    let responses = (0..points.len())
        .into_par_iter()
        .flat_map_iter(|r| {
            let (point, normal) = (points[r], normals[r]);
            let mut out = [0.0f32; CELLS * CELLS];
            if placement.height - point.y <= 0.0 {
                return out;
            }
            let square = face_square(face, placement, point);
            if light.intersect(&square) == light {
                return out;
            }
            let whole_irradiance = cell_irradiances(point, normal, placement);
            for qj in 0..VISIBILITY {
                for qi in 0..VISIBILITY {
                    // The quadrant's part beyond the face: its cells' responses and centroid.
                    let mut lit = [(0, 0.0); (CELLS / VISIBILITY) * (CELLS / VISIBILITY)];
                    let mut count = 0;
                    let (mut area, mut moment) = (0.0, [0.0; 2]);
                    for j in qj * per_quadrant..(qj + 1) * per_quadrant {
                        for i in qi * per_quadrant..(qi + 1) * per_quadrant {
                            let whole = cell(placement, CELLS, i, j);
                            let inside = whole.intersect(&square);
                            let beyond = whole.area() - inside.area();
                            if beyond <= 1e-12 * whole.area() {
                                continue;
                            }
                            let e = whole_irradiance[j * CELLS + i]
                                - rect_irradiance(point, normal, &inside, placement.height);
                            if e <= 0.0 {
                                continue;
                            }
                            let (cw, ci) = (whole.centre(), inside.centre());
                            for q in 0..2 {
                                moment[q] += cw[q] * whole.area() - ci[q] * inside.area();
                            }
                            area += beyond;
                            lit[count] = (j * CELLS + i, e);
                            count += 1;
                        }
                    }
                    if count == 0 {
                        continue;
                    }
                    let target = DVec3::new(moment[0] / area, placement.height, moment[1] / area);
                    if unoccluded(origins[r], target) {
                        for &(c, e) in &lit[..count] {
                            out[c] = e as f32;
                        }
                    }
                }
            }
            out
        })
        .collect();
    BeyondFace { responses }
}

/// `responses` with each cell's weighted by `weight(receiver, ω)`, `ω` the direction to the
/// cell's centre: what a specular lobe toward a viewer makes of the light beyond the face
/// (Sun 2008 §4.9 for the part the face misses), the lobe taken constant over each cell.
pub fn weighted(
    responses: &BeyondFace,
    placement: &LightPlacement,
    points: &[DVec3],
    weight: impl Fn(usize, DVec3) -> f64 + Sync,
) -> BeyondFace {
    let responses = responses
        .responses
        .par_chunks_exact(CELLS * CELLS)
        .enumerate()
        .flat_map_iter(|(r, cells)| {
            let mut out = [0.0f32; CELLS * CELLS];
            for (c, (&g, out)) in cells.iter().zip(&mut out).enumerate() {
                if g != 0.0 {
                    let [x, z] = cell(placement, CELLS, c % CELLS, c / CELLS).centre();
                    let direction = (DVec3::new(x, placement.height, z) - points[r]).normalize();
                    *out = (f64::from(g) * weight(r, direction)) as f32;
                }
            }
            out
        })
        .collect();
    BeyondFace { responses }
}

/// The whole light's unshadowed irradiance per unit radiance of each cell (a face of size 0,
/// every ray clear): closed form, no ray, what a viewport shows while the shadows are traced.
pub fn unshadowed(placement: &LightPlacement, points: &[DVec3], normals: &[DVec3]) -> BeyondFace {
    let none = TopFace { order: 0, size: 0.0 };
    beyond_face(&none, placement, points, normals, points, |_, _| true)
}

/// The mean radiance of each of the light's `CELLS × CELLS` cells, from its kept Haar
/// coefficients (the texture the face's products see), row `z` then column `x`.
pub fn cell_means(source: &LightSource) -> Vec<[f64; 3]> {
    let n = source.order;
    let mut means = vec![[0.0; 3]; CELLS * CELLS];
    if n == 0 || !n.is_power_of_two() || n < CELLS {
        return means;
    }
    let block = n / CELLS;
    for channel in 0..3 {
        let mut image = vec![0.0; n * n];
        for &((i1, i2), rgb) in &source.coefficients {
            image[usize::from(i2) * n + usize::from(i1)] = f64::from(rgb[channel]);
        }
        haar_inverse_2d(&mut image, n);
        for (y, row) in image.chunks_exact(n).enumerate() {
            for (x, &v) in row.iter().enumerate() {
                means[(y / block) * CELLS + x / block][channel] += v / (block * block) as f64;
            }
        }
    }
    means
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::near_field::{TargetKeep, face_transport, irradiance, light_source};

    /// `∫ F cos θ_x cos θ_l / r² dA` over the light on `samples²` points, `texture` (`order²`,
    /// row `z`) piecewise constant, nothing in the way.
    fn quadrature(
        light: &LightPlacement,
        texture: &[[f64; 3]],
        order: usize,
        receiver: (DVec3, DVec3),
        samples: usize,
    ) -> [f64; 3] {
        crate::near_field::tests::light_integral(texture, order, light, receiver, &|_, _| true, samples, |_| 1.0)
    }

    /// Lambert's formula, clipped to the horizon, against quadrature over the light: under it,
    /// beside it with a tilted normal whose horizon cuts it, and far away.
    #[test]
    fn lamberts_formula_matches_quadrature() {
        let light = LightPlacement::centred(1.5, [0.2, -0.1], [2.0, 1.0]);
        let uniform = [[1.0; 3]];
        let rect = Rect { x: [light.corner[0], light.corner[0] + 2.0], z: [light.corner[1], light.corner[1] + 1.0] };
        for (x, n) in [
            (DVec3::ZERO, DVec3::Y),
            (DVec3::new(1.0, 0.3, 0.4), DVec3::new(0.8, 0.6, 0.0)),
            (DVec3::new(-0.5, 1.2, 0.0), DVec3::new(-0.6, 0.0, 0.8)),
            (DVec3::new(9.0, 0.0, -4.0), DVec3::Y),
            (DVec3::new(25.0, 0.0, 3.0), DVec3::new(-0.6, 0.8, 0.0)),
        ] {
            let exact = polygon_irradiance(x, n, &rect.corners(light.height));
            let summed = quadrature(&light, &uniform, 1, (x, n), 600)[0];
            assert!(
                (exact - summed).abs() <= 2e-3 * summed.max(1e-6),
                "at {x} facing {n}: Lambert {exact}, quadrature {summed}"
            );
            let cut = rect_irradiance(x, n, &rect, light.height);
            assert!((cut - exact).abs() <= 0.01 * exact.max(1e-9), "point form {cut} against {exact}");
        }
    }

    /// A 2 × 2 light 1 m up with a smooth texture, no occluders: the face's Haar products plus
    /// the part beyond the face match quadrature under the light and out to 8 m beside it,
    /// where the face alone sees nothing.
    #[test]
    fn the_face_and_beyond_it_add_up_to_the_whole_light() {
        face_and_beyond_against_quadrature(1.0, 0.03);
    }

    /// The same light 0.3 m over the floor, closer than a sixth of its size: under it the face
    /// holds only its middle, and most of it lies beyond the face.
    #[test]
    fn a_light_close_to_the_floor_adds_up_too() {
        face_and_beyond_against_quadrature(0.3, 0.03);
    }

    fn face_and_beyond_against_quadrature(height: f64, tolerance: f64) {
        let order = 32;
        let light = LightPlacement::centred(height, [0.0, 0.0], [2.0, 2.0]);
        let texture: Vec<[f64; 3]> = (0..order * order)
            .map(|k| {
                let (u, v) = ((k % order) as f64 / order as f64, (k / order) as f64 / order as f64);
                [1.0 + 0.5 * u, 1.0 + 0.4 * (3.0 * v).sin(), 0.6 + u * v]
            })
            .collect();
        let source = light_source(&texture, order, order * order);
        let face = TopFace { order, size: 4.0 };
        // Along x, and off the axis on both sides in z (a flip of the cells' rows would show).
        let points: Vec<DVec3> = (0..33)
            .map(|k| DVec3::new(0.25 * k as f64, 0.0, 0.3))
            .chain((0..12).flat_map(|k| [-1.0, 1.0].map(|side| DVec3::new(0.5 * k as f64 - 2.0, 0.0, side * 3.0))))
            .collect();
        let normals = vec![DVec3::Y; points.len()];
        let transport = face_transport(face, &points, &normals, 2, |_, _| true);
        let inside = irradiance(&source, &light, &transport, &points, TargetKeep::All);
        let beyond =
            beyond_face(&face, &light, &points, &normals, &points, |_, _| true).irradiance(&cell_means(&source));
        for (k, &x) in points.iter().enumerate() {
            let truth = quadrature(&light, &texture, order, (x, DVec3::Y), 400);
            let offset = x.x - 1.0;
            if offset > 2.0 * height {
                assert!(inside[k][0].abs() < 1e-9, "the face reaches {offset} m beyond the light's edge");
            }
            for c in 0..3 {
                let total = inside[k][c] + beyond[k][c];
                assert!(
                    (total - truth[c]).abs() <= tolerance * truth[c],
                    "at {x}: face {} + beyond {} = {total}, quadrature {}",
                    inside[k][c],
                    beyond[k][c],
                    truth[c]
                );
            }
        }
    }

    /// Unshadowed, the whole light (every cell, no face) is Lambert's formula of its rectangle.
    #[test]
    fn unshadowed_is_the_whole_rectangle() {
        let light = LightPlacement::centred(1.5, [0.3, 0.0], [1.2, 0.8]);
        let corners = Rect { x: [-0.3, 0.9], z: [-0.4, 0.4] }.corners(1.5);
        for (x, n) in [(DVec3::ZERO, DVec3::Y), (DVec3::new(2.0, 0.5, 1.0), DVec3::new(-0.6, 0.8, 0.0))] {
            let e = unshadowed(&light, &[x], &[n]).irradiance(&vec![[1.0; 3]; CELLS * CELLS])[0][0];
            let truth = polygon_irradiance(x, n, &corners);
            assert!((e - truth).abs() < 1e-3 * truth, "{e} against {truth}");
        }
    }

    /// A wall between a far receiver and the light takes the part beyond the face away; the
    /// rays go to the light's quadrants, so a wall hiding half the light hides half of it.
    #[test]
    fn beyond_the_face_is_shadowed_by_what_hides_the_light() {
        let light = LightPlacement::centred(2.0, [0.0, 0.0], [2.0, 2.0]);
        let face = TopFace { order: 32, size: 2.0 };
        let x = DVec3::new(6.0, 0.0, 0.0);
        let open = beyond_face(&face, &light, &[x], &[DVec3::Y], &[x], |_, _| true);
        // A wall in the plane x = 3 up to z = 0: it hides the quadrants with z < 0.
        let walled = beyond_face(&face, &light, &[x], &[DVec3::Y], &[x], |o, t| {
            let t_wall = (3.0 - o.x) / (t.x - o.x);
            !(0.0..1.0).contains(&t_wall) || o.z + t_wall * (t.z - o.z) > 0.0
        });
        let sum = |b: &BeyondFace| b.responses.iter().map(|&v| f64::from(v)).sum::<f64>();
        assert!(sum(&open) > 0.0);
        assert!((sum(&walled) / sum(&open) - 0.5).abs() < 0.02, "{} of {}", sum(&walled), sum(&open));
        let means = vec![[1.0; 3]; CELLS * CELLS];
        let truth = polygon_irradiance(x, DVec3::Y, &Rect { x: [-1.0, 1.0], z: [-1.0, 1.0] }.corners(2.0));
        assert!((open.irradiance(&means)[0][0] - truth).abs() < 0.01 * truth);
    }
}
