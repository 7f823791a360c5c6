//! The BRDF integral over a square light by summed-area tables (Xu et al. 2006 §4.2, §5.1).
//!
//! Eq. 8: `1/|S| ∫_S ρ cos dω ≈ 1/|R| ∫_R ρ cos dp`, with `R` the axis-aligned square of area
//! `Ω/2` centred on the light's image in the equal-area plane ([`super::plane`]), so the mean
//! over the light is four lookups of a summed-area table (Eq. 2, Crow 1984).
//!
//! - Tables are 32² over `[-1, 1]²`; texels hold the **area average** of `ρ cos θ` (4×4
//!   stratified samples; 2×2 for the anisotropic table's 1024 slices), zero below the horizon,
//!   and the SAT is stored at texel corners, so a bilinear lookup at fractional corners is
//!   exact for that piecewise-constant table ([`crate::sat`]). `R` is clipped to the table
//!   and divided by its full area (notes §2).
//! - Every model is `albedo/π + specular · lobe`: one view-independent table of `cos θ/π` and
//!   one table of `lobe · cos θ` per view slice; colours multiply at lookup, so a colour edit
//!   rebuilds nothing but the values.
//! - **Isotropic** lobes: 32 slices of the view's polar angle `θ₀` (0 to 89.5°, linear
//!   interpolation), light directions turned about the normal so the view has azimuth 0.
//!   **Anisotropic** lobes (GGX and Ward with `α_x ≠ α_y`): 32×32 view slices over the same
//!   plane (a 4D table), bilinear between slice centres, in the tangent frame; the lobes are
//!   mirror-symmetric in x and in y, so one quadrant of slices is tabulated and mirrored.
//! - The 32 view slices and 5° texels blur lobes sharper than about Phong 200 (notes §2); the
//!   error is reported by the reference comparison, not hidden.

use super::plane::{from_plane, square_edge, to_plane, to_texels};
use crate::brdf::{Brdf, Lobe};
use crate::engine::{CancelToken, StageError};
use crate::sat::SummedAreaTable;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

crate::stage_type!(BrdfSat, "BRDF summed-area tables", |v| (v.lobes.len() + 1) * (v.size + 1).pow(2) * 8);

/// Texels per side of each table (the paper's 32).
pub const TABLE_SIZE: usize = 32;
/// View slices: `θ₀` values of the isotropic table, and slices per side of the anisotropic one.
pub const VIEW_SLICES: usize = 32;
/// The largest tabulated view polar angle (a view at the horizon sees no lobe).
const MAX_VIEW_ANGLE: f64 = 89.5 * std::f64::consts::PI / 180.0;

/// The sharpest Phong lobe the tables resolve: its full width at half maximum
/// (`2√(2 ln 2 / n)`) spans two texels at the pole, where a texel is `√2 · 2/32` rad (about
/// Phong 180 at 32²; notes §2). Sharper lobes are drawn broader and dimmer.
pub fn sharpest_phong() -> f64 {
    let texel = std::f64::consts::SQRT_2 * 2.0 / TABLE_SIZE as f64;
    8.0 * std::f64::consts::LN_2 / (2.0 * texel).powi(2)
}

/// How view directions are tabulated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewGrid {
    /// `slices` values of `θ₀` (azimuth aligned to 0).
    Isotropic { slices: usize },
    /// `size × size` view directions over the plane (a 4D table).
    Anisotropic { size: usize },
}

/// A BRDF's tables.
#[derive(Clone, Debug)]
pub struct BrdfSat {
    pub size: usize,
    pub views: ViewGrid,
    pub diffuse: [f64; 3],
    pub specular: [f64; 3],
    /// SAT of `cos θ / π`.
    pub cosine: SummedAreaTable,
    /// SAT of `lobe(ω, ω₀) cos θ` per view slice (empty without a lobe).
    pub lobes: Vec<SummedAreaTable>,
}

/// The view grid a BRDF needs: anisotropic only when its lobe is.
pub fn view_grid_for(brdf: &Brdf) -> ViewGrid {
    match brdf.lobe {
        Lobe::Ggx { alpha_x, alpha_y } | Lobe::Ward { alpha_x, alpha_y } if alpha_x != alpha_y => {
            ViewGrid::Anisotropic { size: VIEW_SLICES }
        }
        _ => ViewGrid::Isotropic { slices: VIEW_SLICES },
    }
}

/// The SAT of `f` area-averaged over each texel of an `n × n` grid on `[-1, 1]²`
/// (`samples²` stratified points per texel; `f` is zero below the horizon).
fn tabulate(n: usize, samples: usize, f: impl Fn(DVec3) -> f64) -> SummedAreaTable {
    SummedAreaTable::new(n, n, &texel_means(n, samples, f))
}

/// `f` area-averaged over each texel of an `n × n` grid on `[-1, 1]²`, row-major.
fn texel_means(n: usize, samples: usize, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
    let texel = 2.0 / n as f64;
    let mut values = vec![0.0; n * n];
    for (i, v) in values.iter_mut().enumerate() {
        let (x, y) = (i % n, i / n);
        let mut sum = 0.0;
        for s in 0..samples * samples {
            let (sx, sy) = (s % samples, s / samples);
            let p = DVec2::new(
                -1.0 + texel * (x as f64 + (sx as f64 + 0.5) / samples as f64),
                -1.0 + texel * (y as f64 + (sy as f64 + 0.5) / samples as f64),
            );
            if p.length_squared() < 1.0 {
                sum += f(from_plane(p));
            }
        }
        *v = sum / (samples * samples) as f64;
    }
    values
}

/// View direction of slice `j` of an isotropic table.
fn isotropic_view(j: usize, slices: usize) -> DVec3 {
    let theta = MAX_VIEW_ANGLE * j as f64 / (slices - 1).max(1) as f64;
    DVec3::new(theta.sin(), 0.0, theta.cos())
}

/// View direction at the centre of slice `(i, j)` of an anisotropic table, pulled just inside
/// the horizon so slices near the rim interpolate towards grazing views, not to zero.
fn anisotropic_view(i: usize, j: usize, size: usize) -> DVec3 {
    let centre = |k: usize| (k as f64 + 0.5) / size as f64 * 2.0 - 1.0;
    let p = DVec2::new(centre(i), centre(j));
    let limit = (1.0 - MAX_VIEW_ANGLE.cos()).sqrt();
    from_plane(if p.length() > limit { p * (limit / p.length()) } else { p })
}

impl BrdfSat {
    /// Tables for `brdf` at the paper's resolution (3D for isotropic lobes, 4D otherwise).
    pub fn build(brdf: &Brdf, cancel: &CancelToken) -> Result<Self, StageError> {
        Self::build_with(brdf, view_grid_for(brdf), TABLE_SIZE, cancel)
    }

    pub fn build_with(brdf: &Brdf, views: ViewGrid, size: usize, cancel: &CancelToken) -> Result<Self, StageError> {
        let cosine = tabulate(size, 4, |w| w.z.max(0.0) / std::f64::consts::PI);
        let view_list: Vec<DVec3> = match views {
            ViewGrid::Isotropic { slices } => (0..slices).map(|j| isotropic_view(j, slices)).collect(),
            ViewGrid::Anisotropic { size: s } => (0..s * s).map(|k| anisotropic_view(k % s, k / s, s)).collect(),
        };
        let samples = if matches!(views, ViewGrid::Anisotropic { .. }) { 2 } else { 4 };
        let has_lobe = brdf.lobe != Lobe::None && brdf.specular.max_element() > 0.0;
        let lobes = if !has_lobe {
            Vec::new()
        } else if let ViewGrid::Anisotropic { size: s } = views {
            // Every lobe here is symmetric under mirroring x (or y) in both directions at once,
            // so one quadrant of view slices is tabulated and the others are its mirror images.
            let half = s / 2;
            let quadrant: Vec<Vec<f64>> = (0..(s - half) * (s - half))
                .into_par_iter()
                .map(|k| {
                    cancel.check()?;
                    let wo = view_list[(half + k / (s - half)) * s + half + k % (s - half)];
                    Ok(texel_means(size, samples, |wi| brdf.lobe_value(wi, wo) * wi.z.max(0.0)))
                })
                .collect::<Result<_, StageError>>()?;
            (0..s * s)
                .into_par_iter()
                .map(|k| {
                    let (i, j) = (k % s, k / s);
                    let (si, sj) = (i.max(s - 1 - i), j.max(s - 1 - j));
                    let source = &quadrant[(sj - half) * (s - half) + si - half];
                    let (flip_x, flip_y) = (i != si, j != sj);
                    let values: Vec<f64> = (0..size * size)
                        .map(|t| {
                            let (x, y) = (t % size, t / size);
                            let x = if flip_x { size - 1 - x } else { x };
                            let y = if flip_y { size - 1 - y } else { y };
                            source[y * size + x]
                        })
                        .collect();
                    SummedAreaTable::new(size, size, &values)
                })
                .collect()
        } else {
            view_list
                .par_iter()
                .map(|&wo| {
                    cancel.check()?;
                    Ok(tabulate(size, samples, |wi| brdf.lobe_value(wi, wo) * wi.z.max(0.0)))
                })
                .collect::<Result<Vec<_>, StageError>>()?
        };
        Ok(Self {
            size,
            views,
            diffuse: (brdf.diffuse).to_array(),
            specular: if has_lobe { brdf.specular.to_array() } else { [0.0; 3] },
            cosine,
            lobes,
        })
    }

    /// Mean of `f` over the plane square of a light of solid angle `omega` centred on `p`.
    fn square_mean(&self, table: &SummedAreaTable, p: DVec2, omega: f64) -> f64 {
        let half = square_edge(omega) * 0.5;
        let n = self.size;
        let (x0, x1) = (to_texels(p.x - half, n), to_texels(p.x + half, n));
        let (y0, y1) = (to_texels(p.y - half, n), to_texels(p.y + half, n));
        let area = (x1 - x0) * (y1 - y0);
        if area <= 0.0 { 0.0 } else { table.integral(x0, y0, x1, y1) / area }
    }

    /// `1/|S| ∫_S ρ cos θ dω` (RGB) for a square light of solid angle `omega` centred on
    /// `light`, seen from `view`; both unit vectors in the shading frame (normal `+z`, tangent
    /// `+x`).
    pub fn mean(&self, light: DVec3, omega: f64, view: DVec3) -> DVec3 {
        let (cos_mean, lobe_mean) = self.means(light, omega, view);
        DVec3::from(self.diffuse) * cos_mean + DVec3::from(self.specular) * lobe_mean
    }

    /// The means of `cos θ/π` and of `lobe · cos θ` over the light's square.
    pub fn means(&self, light: DVec3, omega: f64, view: DVec3) -> (f64, f64) {
        let cos_mean = self.square_mean(&self.cosine, to_plane(light), omega);
        if self.lobes.is_empty() || view.z <= 0.0 {
            return (cos_mean, 0.0);
        }
        let lobe_mean = match self.views {
            ViewGrid::Isotropic { slices } => {
                // Turn about the normal so the view has azimuth 0.
                let azimuth = view.y.atan2(view.x);
                let (s, c) = azimuth.sin_cos();
                let turned = DVec3::new(light.x * c + light.y * s, -light.x * s + light.y * c, light.z);
                let p = to_plane(turned);
                let t = (view.z.clamp(-1.0, 1.0).acos() / MAX_VIEW_ANGLE).min(1.0) * (slices - 1) as f64;
                let j = (t.floor() as usize).min(slices - 2);
                let f = t - j as f64;
                let a = self.square_mean(&self.lobes[j], p, omega);
                let b = if f > 0.0 { self.square_mean(&self.lobes[j + 1], p, omega) } else { 0.0 };
                a * (1.0 - f) + b * f
            }
            ViewGrid::Anisotropic { size } => {
                let p = to_plane(light);
                let v = to_plane(view);
                let coord = |c: f64| (to_texels(c, size) - 0.5).clamp(0.0, (size - 1) as f64);
                let (u, w) = (coord(v.x), coord(v.y));
                let (i, j) = ((u.floor() as usize).min(size - 2), (w.floor() as usize).min(size - 2));
                let (fu, fw) = (u - i as f64, w - j as f64);
                let mut sum = 0.0;
                for (di, dj, weight) in
                    [(0, 0, (1.0 - fu) * (1.0 - fw)), (1, 0, fu * (1.0 - fw)), (0, 1, (1.0 - fu) * fw), (1, 1, fu * fw)]
                {
                    if weight > 0.0 {
                        sum += weight * self.square_mean(&self.lobes[(j + dj) * size + i + di], p, omega);
                    }
                }
                sum
            }
        };
        (cos_mean, lobe_mean)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Material;
    use crate::sampling::test_rng;
    use rand::Rng;

    fn brdf(model: &str, exponent: f64, roughness: f64, anisotropy: f64) -> Brdf {
        Brdf::from_material(&Material {
            model: model.parse().unwrap(),
            albedo: [0.6, 0.5, 0.4],
            specular: [1.0, 0.9, 0.8],
            roughness,
            exponent,
            anisotropy,
            f0: 0.5,
        })
    }

    fn build(b: &Brdf) -> BrdfSat {
        BrdfSat::build(b, &CancelToken::default()).unwrap()
    }

    #[test]
    fn lambert_table_integrates_to_one() {
        // 2 ∫_disc cos θ/π dp = ∫ cos θ/π dω = 1, up to the texels' quadrature.
        let sat = build(&brdf("lambert", 1.0, 0.5, 0.0));
        let n = sat.size as f64;
        let plane_integral = sat.cosine.integral(0.0, 0.0, n, n) * (2.0 / n).powi(2);
        assert!((2.0 * plane_integral - 1.0).abs() < 2e-3, "{}", 2.0 * plane_integral);
        assert!(sat.lobes.is_empty());
    }

    /// Monte Carlo mean of `ρ cos` over the spherical square of side `side` (tangent-plane
    /// units, gnomonic) centred on `c` and turned by `turn`, with its solid angle.
    fn spherical_square_mean(
        b: &Brdf,
        c: DVec3,
        side: f64,
        turn: f64,
        view: DVec3,
        rng: &mut impl Rng,
    ) -> (DVec3, f64) {
        let t0 = c.any_orthonormal_vector();
        let t1 = c.cross(t0);
        let (s, co) = turn.sin_cos();
        let (e0, e1) = (t0 * co + t1 * s, t1 * co - t0 * s);
        let (mut sum, mut weights) = (DVec3::ZERO, 0.0);
        let count = 20_000;
        for _ in 0..count {
            let (u, v) = ((rng.random::<f64>() - 0.5) * side, (rng.random::<f64>() - 0.5) * side);
            let w = 1.0 / (1.0 + u * u + v * v).powf(1.5);
            let d = (c + e0 * u + e1 * v).normalize();
            sum += b.eval(d, view) * d.z.max(0.0) * w;
            weights += w;
        }
        (sum / weights, weights / count as f64 * side * side)
    }

    fn mean_relative_error(b: &Brdf, side: f64, seed: u64) -> f64 {
        let sat = build(b);
        let mut rng = test_rng(seed);
        let mut total = 0.0;
        let trials = 40;
        for _ in 0..trials {
            let c = loop {
                let d = crate::sampling::random_unit_vector(&mut rng);
                if d.z > 0.3 {
                    break d;
                }
            };
            let view = loop {
                let d = crate::sampling::random_unit_vector(&mut rng);
                if d.z > 0.2 {
                    break d;
                }
            };
            let (mc, omega) = spherical_square_mean(b, c, side, rng.random::<f64>(), view, &mut rng);
            let got = sat.mean(c, omega, view);
            total += (got - mc).length() / mc.length().max(1e-3);
        }
        total / trials as f64
    }

    #[test]
    fn square_means_match_monte_carlo_and_improve_as_squares_shrink() {
        for (label, b) in [
            ("lambert", brdf("lambert", 1.0, 0.5, 0.0)),
            ("phong 20", brdf("phong", 20.0, 0.5, 0.0)),
            ("ggx 0.6", brdf("ggx", 1.0, 0.6, 0.0)),
            ("ward aniso", brdf("ward", 1.0, 0.6, 0.6)),
        ] {
            let errors: Vec<f64> = [0.08, 0.3, 0.8].iter().map(|&side| mean_relative_error(&b, side, 11)).collect();
            println!("{label}: mean relative error at sides 0.08 / 0.3 / 0.8: {errors:.4?}");
            assert!(errors[0] < 0.06, "{label}: small squares off by {:.3}", errors[0]);
            assert!(errors[0] <= errors[2] + 0.01, "{label}: error grew as squares shrank: {errors:?}");
        }
    }

    #[test]
    fn isotropic_and_anisotropic_tables_agree_on_an_isotropic_lobe() {
        let b = brdf("ggx", 1.0, 0.7, 0.0);
        let iso = build(&b);
        let aniso = BrdfSat::build_with(&b, ViewGrid::Anisotropic { size: 32 }, 32, &CancelToken::default()).unwrap();
        let mut rng = test_rng(5);
        let mut worst: f64 = 0.0;
        for _ in 0..200 {
            let light = crate::sampling::random_unit_vector(&mut rng);
            let view = crate::sampling::random_unit_vector(&mut rng);
            if light.z < 0.2 || view.z < 0.3 {
                continue;
            }
            let (a, b) = (iso.mean(light, 0.05, view), aniso.mean(light, 0.05, view));
            worst = worst.max((a - b).length() / a.length());
        }
        assert!(worst < 0.08, "iso and aniso tables differ by {worst:.3}");
    }

    #[test]
    fn mirrored_anisotropic_slices_equal_directly_tabulated_ones() {
        let b = brdf("ward", 1.0, 0.5, 0.7);
        let sat = build(&b);
        let ViewGrid::Anisotropic { size: s } = sat.views else { panic!("anisotropic") };
        for (i, j) in [(0, 0), (3, 20), (31, 1), (16, 15)] {
            let direct = tabulate(sat.size, 2, |wi| b.lobe_value(wi, anisotropic_view(i, j, s)) * wi.z.max(0.0));
            let n = sat.size as f64;
            let mirrored = &sat.lobes[j * s + i];
            for (x0, y0, x1, y1) in [(0.0, 0.0, n, n), (3.5, 7.25, 20.0, 9.0), (16.0, 16.0, 17.5, 30.0)] {
                let (a, b) = (mirrored.integral(x0, y0, x1, y1), direct.integral(x0, y0, x1, y1));
                assert!((a - b).abs() <= 1e-9 * (1.0 + b.abs()), "slice ({i}, {j}): {a} vs {b}");
            }
        }
    }

    #[test]
    fn squares_below_the_horizon_see_nothing_and_clipped_ones_keep_their_full_area() {
        let sat = build(&brdf("lambert", 1.0, 0.5, 0.0));
        assert_eq!(sat.mean(-DVec3::Z, 0.1, DVec3::Z), DVec3::ZERO);
        // A square centred on the horizon: half of it is below, where ρcos is zero anyway,
        // and the mean divides by the whole square: it is small, not the upper half's mean.
        let horizon = sat.mean(DVec3::X, 0.1, DVec3::Z);
        assert!(horizon.x > 0.0 && horizon.x < 0.6 * 0.1, "{horizon}");
    }
}
