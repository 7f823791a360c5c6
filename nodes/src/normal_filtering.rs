//! Normal-map filtering in the frequency domain (Sun 2008 thesis ch. 5.1; Han et al. 2007).
//!
//! A pixel that covers many texels of a normal map reflects through all their normals: its
//! effective BRDF is the BRDF convolved with the texels' normal distribution (NDF)
//! `γ(n) = (1/N) Σ_q δ(n − n_q)` (eqs. 5.4–5.6). For BRDFs radially symmetric about the normal,
//! `ρ(ω·n)` (Lambert, Blinn-Phong, half-vector microfacet lobes; eq. 5.3), the convolution is a
//! product per SH band, `ρ^eff_lm = ρ̂_l γ_lm` with `ρ̂_l = √(4π/(2l+1)) f_l` (eq. 5.7). The
//! NDF's SH coefficients are linear in the texels, so they MIP-map by plain averaging,
//! which averaging normals does not.
//!
//! For sharp lobes the SH of an NDF need many bands; the NDF is then a mixture of von
//! Mises–Fisher lobes `α κ/(4π sinh κ) e^{κ μ·n}`, fitted by spherical EM (Banerjee et al.
//! 2005; the thesis's Fig. 5.2 uses six). One lobe from the MIP-mapped mean normal is Toksvig's
//! filter.

mod moments;

pub use moments::{
    MAX_VMF_PIXELS, MomentLevel, MomentPyramid, NdfMoments, VMF_LOBES, VmfLevel, VmfPyramid, normal_cdf,
};

use crate::sh::ShBasis;
use glam::DVec3;
use std::f64::consts::PI;

crate::stage_type!(NormalMap, "normal map", |v| v.normals.len() * 24);

/// A tangent-space normal map: unit normals, row by row from the top (empty: no map).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NormalMap {
    pub width: usize,
    pub height: usize,
    pub normals: Vec<DVec3>,
}

impl NormalMap {
    /// From 8-bit RGB texels encoding `n = 2·rgb − 1` (OpenGL convention, +Y up). Texels whose
    /// vector is too short to have a direction are taken as flat.
    pub fn from_rgb8(width: usize, height: usize, rgb: &[[u8; 3]]) -> Result<Self, String> {
        if width == 0 || height == 0 || rgb.len() != width * height {
            return Err(format!("a {width}×{height} normal map needs {} texels, not {}", width * height, rgb.len()));
        }
        let normals = rgb
            .iter()
            .map(|t| {
                let n = DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64) / 127.5 - 1.0;
                n.try_normalize().unwrap_or(DVec3::Z)
            })
            .collect();
        Ok(Self { width, height, normals })
    }

    /// The map with its tilts scaled by `strength` (glTF's `normalTexture.scale`: the
    /// tangent-plane components scaled, then renormalised; 0 flattens it).
    pub fn with_strength(mut self, strength: f64) -> Self {
        if strength != 1.0 {
            for n in &mut self.normals {
                *n = DVec3::new(n.x * strength, n.y * strength, n.z).try_normalize().unwrap_or(DVec3::Z);
            }
        }
        self
    }

    /// The flat map: every normal along the surface normal.
    pub fn flat(width: usize, height: usize) -> Self {
        Self { width, height, normals: vec![DVec3::Z; width * height] }
    }

    /// The tangent-space normal at `uv` (the map repeating, `v` down its rows), bilinear
    /// between texel centres and renormalised: what the Monte Carlo reference shades with, at
    /// its many samples a pixel (the supersampled ground truth filtering is measured against).
    pub fn sample(&self, uv: [f64; 2]) -> DVec3 {
        if self.normals.is_empty() {
            return DVec3::Z;
        }
        let (x, y) = (uv[0] * self.width as f64 - 0.5, uv[1] * self.height as f64 - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |dx: i64, dy: i64| {
            let xi = (x0 as i64 + dx).rem_euclid(self.width as i64) as usize;
            let yi = (y0 as i64 + dy).rem_euclid(self.height as i64) as usize;
            self.normals[yi * self.width + xi]
        };
        let blended =
            (at(0, 0) * (1.0 - fx) + at(1, 0) * fx) * (1.0 - fy) + (at(0, 1) * (1.0 - fx) + at(1, 1) * fx) * fy;
        blended.try_normalize().unwrap_or(DVec3::Z)
    }
}

/// The most texels a normal map may have (4096², whose 3-band NDF pyramid holds about 1.2 GB).
pub const MAX_NORMAL_MAP_PIXELS: u64 = 4096 * 4096;

/// Loads a normal map from an image file (PNG at 8 or 16 bits, JPEG, or EXR), its values taken as
/// stored (normal maps are linear, not sRGB) and decoded as `n = 2·rgb − 1`. Texels with no
/// direction (or not finite) are taken as flat.
pub fn load_normal_map(path: &std::path::Path) -> Result<NormalMap, String> {
    let named = |e: &dyn std::fmt::Display| format!("normal map {}: {e}", path.display());
    // Its messages name the file already.
    crate::limits::check_regular_file(path, crate::limits::MAX_FILE_BYTES).map_err(|e| format!("normal map: {e}"))?;
    let open = || image::ImageReader::open(path).and_then(|r| r.with_guessed_format()).map_err(|e| named(&e));
    decode_normal_map(open()?, open()?).map_err(|e| named(&e))
}

/// A glTF material's normal map ([`load_gltf_normal_map`]).
#[derive(Clone, Debug, PartialEq)]
pub struct GltfNormalMap {
    pub map: NormalMap,
    /// `normalTexture.scale`.
    pub scale: f64,
    /// The material it was taken from, and whether by the name asked for (else the first
    /// material with a normal texture).
    pub material: String,
    pub named: bool,
    /// What the glTF asks of the texture that the map does not do.
    pub warnings: Vec<String>,
}

/// The normal map of a glTF material (see [`crate::gltf_import::normal_texture`]).
pub fn load_gltf_normal_map(path: &std::path::Path, material: &str) -> Result<GltfNormalMap, String> {
    let texture = crate::gltf_import::normal_texture(path, material)?;
    let open = || image::ImageReader::new(std::io::Cursor::new(&texture.image[..])).with_guessed_format();
    let named =
        |e: &dyn std::fmt::Display| format!("normal map of material `{}` in {}: {e}", texture.material, path.display());
    let map =
        decode_normal_map(open().map_err(|e| named(&e))?, open().map_err(|e| named(&e))?).map_err(|e| named(&e))?;
    Ok(GltfNormalMap {
        map,
        scale: texture.scale,
        material: texture.material,
        named: texture.named,
        warnings: texture.warnings,
    })
}

/// Decodes an image into a normal map: `probe` reads its header, `reader` (the same image)
/// decodes it under limits set from the header.
fn decode_normal_map<R: std::io::BufRead + std::io::Seek>(
    probe: image::ImageReader<R>,
    mut reader: image::ImageReader<R>,
) -> Result<NormalMap, String> {
    if probe.format().is_none() {
        return Err("not an image this program reads (PNG, JPEG or EXR)".into());
    }
    let (width, height) = probe.into_dimensions().map_err(|e| e.to_string())?;
    if width == 0 || height == 0 || u64::from(width) * u64::from(height) > MAX_NORMAL_MAP_PIXELS {
        return Err(format!("{width} × {height} texels (at most {MAX_NORMAL_MAP_PIXELS}, and at least one)"));
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    limits.max_alloc = Some(MAX_NORMAL_MAP_PIXELS * 16);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| e.to_string())?.to_rgb32f();
    let normals = decoded
        .pixels()
        .map(|p| {
            let n = DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])) * 2.0 - 1.0;
            n.try_normalize().unwrap_or(DVec3::Z)
        })
        .collect();
    Ok(NormalMap { width: width as usize, height: height as usize, normals })
}

/// One MIP level of an NDF pyramid: per texel the NDF's SH coefficients (`bands²`) and the
/// mean of its unit normals (unnormalised: its length says how spread they are).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NdfLevel {
    pub width: usize,
    pub height: usize,
    pub bands: usize,
    /// `γ_lm` per texel, `bands²` each.
    pub sh: Vec<f64>,
    pub mean_normal: Vec<DVec3>,
}

impl NdfLevel {
    pub fn sh_of(&self, x: usize, y: usize) -> &[f64] {
        let n = self.bands * self.bands;
        &self.sh[(y * self.width + x) * n..][..n]
    }

    /// The next level: each texel the plain average of the (up to) four it covers.
    fn halved(&self) -> Self {
        let (width, height) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let n = self.bands * self.bands;
        let mut sh = vec![0.0; width * height * n];
        let mut mean_normal = vec![DVec3::ZERO; width * height];
        for y in 0..height {
            for x in 0..width {
                let children: Vec<(usize, usize)> = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .map(|(dx, dy)| (2 * x + dx, 2 * y + dy))
                    .filter(|&(cx, cy)| cx < self.width && cy < self.height)
                    .collect();
                let share = 1.0 / children.len() as f64;
                let out = &mut sh[(y * width + x) * n..][..n];
                for &(cx, cy) in &children {
                    for (o, c) in out.iter_mut().zip(self.sh_of(cx, cy)) {
                        *o += share * c;
                    }
                    mean_normal[y * width + x] += share * self.mean_normal[cy * self.width + cx];
                }
            }
        }
        Self { width, height, bands: self.bands, sh, mean_normal }
    }
}

/// The NDF pyramid of a normal map, from its texels (level 0) to one texel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NdfPyramid {
    pub levels: Vec<NdfLevel>,
}

impl NdfPyramid {
    /// Level 0 holds each texel's `Y_lm(n_q)` (the SH of a delta), each level above the
    /// average of the texels below it (so, for power-of-two maps, exactly the SH of the union).
    pub fn build(map: &NormalMap, bands: usize) -> Self {
        let basis = ShBasis::new(bands);
        let n = bands * bands;
        let mut sh = vec![0.0; map.normals.len() * n];
        for (out, normal) in sh.chunks_exact_mut(n).zip(&map.normals) {
            basis.eval(*normal, out);
        }
        let mut levels =
            vec![NdfLevel { width: map.width, height: map.height, bands, sh, mean_normal: map.normals.clone() }];
        while levels.last().is_some_and(|l| l.width > 1 || l.height > 1) {
            let next = levels.last().expect("non-empty").halved();
            levels.push(next);
        }
        Self { levels }
    }
}

/// Per level of a normal map's MIP pyramid (as [`NdfPyramid`]'s), per texel, a mixture of up
/// to `lobes` vMF lobes fitted by [`fit_vmf_mixture`] to the normals it covers: the map's
/// bilinear field, at twice the texel density in the two finest levels. A texel covering
/// more than `max_normals` of them fits about `max_normals` at the points of a low-discrepancy
/// sequence over its block (a grid of every `k`-th row and column aliased maps periodic in `k`),
/// which bounds the cost of each level by the map's size. A level of texels of
/// [`VMF_COARSE_SPAN`] map texels a side or more fits twice as many lobes where those fits'
/// log-likelihood over the level's normals gains more than the Bayesian information criterion
/// charges for the extra lobes, and at least half a nat a normal: a rib's few distinct slopes
/// gain several nats a normal, a dimple's disc of slopes a few hundredths.
pub fn vmf_pyramid(map: &NormalMap, lobes: usize, iterations: usize, max_normals: usize) -> Vec<Vec<Vec<Vmf>>> {
    vmf_pyramid_cancellable(map, lobes, iterations, max_normals, &crate::engine::CancelToken::default())
        .expect("never cancelled")
}

/// [`vmf_pyramid`], given up (`None`) once `cancel` is.
pub fn vmf_pyramid_cancellable(
    map: &NormalMap,
    lobes: usize,
    iterations: usize,
    max_normals: usize,
    cancel: &crate::engine::CancelToken,
) -> Option<Vec<Vec<Vec<Vmf>>>> {
    use rayon::prelude::*;
    let mut levels = Vec::new();
    let mut size = 1usize;
    loop {
        let (width, height) = (map.width.div_ceil(size), map.height.div_ceil(size));
        // The block's normals as the surface has them: the map's bilinear field
        // ([`NormalMap::sample`]), at twice the texel density in blocks of a texel or two (so
        // they have the spread between their texels, as delta lobes at the texels would not),
        // at the texels' own density above; blocks of more than `max_normals` take as many as a
        // stride `k` in rows and columns would keep.
        let density = if size <= 2 { 2 } else { 1 };
        let side = size * density;
        let stride = ((side * side) as f64 / max_normals.max(1) as f64).sqrt().ceil().max(1.0) as usize;
        type Fits = (Vec<Vmf>, Option<(Vec<Vmf>, f64, f64)>);
        let fits: Vec<Fits> = (0..width * height)
            .into_par_iter()
            .map(|t| {
                if cancel.is_cancelled() {
                    return (Vec::new(), None);
                }
                let (x, y) = (t % width, t / width);
                let mut normals = Vec::new();
                let (map_width, map_height) = ((map.width * density) as f64, (map.height * density) as f64);
                let (x0, y0) = ((x * side) as f64, (y * side) as f64);
                let (x1, y1) = (map_width.min(((x + 1) * side) as f64), map_height.min(((y + 1) * side) as f64));
                let mut take = |px: f64, py: f64| normals.push((map.sample([px / map_width, py / map_height]), 1.0));
                if stride == 1 {
                    // Every sample, at its centre.
                    for py in (y0 as usize..y1 as usize).map(|p| p as f64 + 0.5) {
                        for px in (x0 as usize..x1 as usize).map(|p| p as f64 + 0.5) {
                            take(px, py);
                        }
                    }
                } else {
                    // As many points as the stride keeps, spread over the block by Roberts' R2
                    // low-discrepancy sequence: a regular grid sees a map periodic in the
                    // stride (ribs, a grid of dimples) at a few phases of its period, and random
                    // points vary the fit from one draw to the next. Every texel takes the same
                    // points (texels of a tiled map then fit alike).
                    let count = ((x1 - x0) / stride as f64).ceil() * ((y1 - y0) / stride as f64).ceil();
                    for i in 0..count as usize {
                        let (a, b) = r2_point(i);
                        take(x0 + a * (x1 - x0), y0 + b * (y1 - y0));
                    }
                }
                // Per texel: its fit of `lobes`, and where the level may take more, that fit, and
                // the log-likelihood the larger one gains and what it must gain to be worth it.
                let fine = fit_vmf_mixture(&normals, lobes, iterations);
                let more = lobes_at(lobes, size);
                if more == lobes {
                    return (fine, None);
                }
                let coarse = fit_vmf_mixture(&normals, more, iterations);
                let gain = log_likelihood(&coarse, &normals) - log_likelihood(&fine, &normals);
                let n = normals.len() as f64;
                // The Bayesian information criterion's price of the extra lobes' 4 parameters
                // each, and at least half a nat a normal.
                let price = ((4 * (more - lobes)) as f64 / 2.0 * n.ln()).max(0.5 * n);
                (fine, Some((coarse, gain, price)))
            })
            .collect();
        if cancel.is_cancelled() {
            return None;
        }
        // The whole level takes the larger fits where they pay over its texels together: a map
        // whose features are few distinct slopes (ribs) gains several nats a normal, a smooth
        // one (dimples) a few hundredths, with a rare texel at a rim gaining more.
        let (gain, price) =
            fits.iter().filter_map(|(_, c)| c.as_ref()).fold((0.0, 0.0), |(g, p), c| (g + c.1, p + c.2));
        let larger = gain > price;
        let texels: Vec<Vec<Vmf>> = fits
            .into_iter()
            .map(|(fine, coarse)| match coarse {
                Some((coarse, _, _)) if larger => coarse,
                _ => fine,
            })
            .collect();
        levels.push(texels);
        if width == 1 && height == 1 {
            return Some(levels);
        }
        size *= 2;
    }
}

/// `Σ w ln p(n)` of weighted normals under a mixture.
fn log_likelihood(mixture: &[Vmf], normals: &[(DVec3, f64)]) -> f64 {
    normals.iter().map(|(n, w)| w * mixture.iter().map(|l| l.density(*n)).sum::<f64>().max(1e-300).ln()).sum()
}

/// Map texels a side from which a [`vmf_pyramid`] level may fit twice the lobes: there a pixel
/// sees the NDF of many of the map's features at once (the far field), which six lobes can draw
/// poorly (`tools/normal_map_far_field.py` puts the far pixel of the ribbed map at 29–39% with
/// six lobes and 1% with twelve; the dimples' at 16% and 14%).
pub const VMF_COARSE_SPAN: usize = 8;

/// The lobes a [`vmf_pyramid`] level of texels `size` map texels a side fits, `lobes` at the
/// finest.
pub fn lobes_at(lobes: usize, size: usize) -> usize {
    if size >= VMF_COARSE_SPAN { 2 * lobes } else { lobes }
}

/// Point `i` of Roberts' R2 sequence in the unit square (the plastic number's powers as
/// irrational steps): low-discrepancy, so `n` of its points cover a square about as evenly as an
/// `√n × √n` grid, without the grid's alignment to rows and columns.
fn r2_point(i: usize) -> (f64, f64) {
    const G: f64 = 1.324_717_957_244_746;
    let i = i as f64;
    ((0.5 + i / G).fract(), (0.5 + i / (G * G)).fract())
}

/// The effective BRDF's SH coefficients for a lobe `f(ω·n)` of zonal coefficients `f_l`
/// (about the normal) under an NDF `γ_lm`: `ρ̂_l γ_lm` (eq. 5.7).
pub fn effective_lobe(zonal: &[f64], ndf: &[f64]) -> Vec<f64> {
    let factors = crate::sh::zonal_convolution_factors(zonal);
    ndf.iter().enumerate().map(|(i, g)| factors.get(crate::sh::band_of(i)).copied().unwrap_or(0.0) * g).collect()
}

/// A von Mises–Fisher lobe on the sphere: `weight · κ/(4π sinh κ) · e^{κ μ·n}`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vmf {
    pub weight: f64,
    pub kappa: f64,
    pub mean: DVec3,
}

/// The largest concentration a lobe is given (about 0.06° wide): beyond it every normal is
/// the same.
pub const MAX_KAPPA: f64 = 1e6;

impl Vmf {
    /// `ln(κ/(4π sinh κ))`, stable for large `κ` and equal to `ln(1/4π)` at 0.
    pub fn log_normalisation(kappa: f64) -> f64 {
        if kappa < 1e-6 {
            return -(4.0 * PI).ln();
        }
        // sinh κ = e^κ (1 − e^{−2κ}) / 2.
        kappa.ln() - (2.0 * PI).ln() - kappa - (-(-2.0 * kappa).exp()).ln_1p()
    }

    /// The lobe's density at unit `n` (its weight included).
    pub fn density(&self, n: DVec3) -> f64 {
        self.weight * (Self::log_normalisation(self.kappa) + self.kappa * self.mean.dot(n)).exp()
    }

    /// The concentration whose mean resultant length is `r` (the length of the mean of unit
    /// normals drawn from the lobe), by Banerjee et al.'s closed form `(3r − r³)/(1 − r²)`,
    /// the one Toksvig's filter and Han et al. take from a MIP-mapped normal's length.
    pub fn kappa_from_mean_length(r: f64) -> f64 {
        let r = r.clamp(0.0, 1.0);
        if r >= 1.0 {
            return MAX_KAPPA;
        }
        ((3.0 * r - r * r * r) / (1.0 - r * r)).min(MAX_KAPPA)
    }

    /// Toksvig's filter: one lobe about the mean normal, as concentrated as its length says.
    pub fn toksvig(mean_normal: DVec3) -> Self {
        let r = mean_normal.length();
        let mean = mean_normal.try_normalize().unwrap_or(DVec3::Z);
        Self { weight: 1.0, kappa: Self::kappa_from_mean_length(r), mean }
    }

    /// The lobe's SH attenuation per band, `e^{−l(l+1)/2κ}` (the heat-kernel form of
    /// Han et al.'s `e^{−l²/2κ}`, exact in its first two bands as `κ` grows).
    pub fn band_attenuation(&self, l: usize) -> f64 {
        (-((l * (l + 1)) as f64) / (2.0 * self.kappa.max(1e-9))).exp()
    }

    /// The lobe's SH coefficients as an NDF, `weight · λ_l Y_lm(μ)` (a delta's are `Y_lm(μ)`).
    pub fn sh(&self, bands: usize) -> Vec<f64> {
        let y = ShBasis::new(bands).eval_vec(self.mean);
        y.iter().enumerate().map(|(i, y)| self.weight * self.band_attenuation(crate::sh::band_of(i)) * y).collect()
    }
}

/// A glossy lobe `e^{s(h·n − 1)}` about the normal (Blinn-Phong of exponent `s` in its vMF
/// form, Han et al.) averaged over an NDF given as vMF lobes, at half vector `h`: each lobe
/// convolved with the BRDF's is a lobe of concentration `κs/(κ + s)`, so the sum is
/// `Σ α_j (2π/s) vMF_{κ_j s/(κ_j + s)}(h·μ_j)`. One lobe from the mean normal is Toksvig's
/// filter; a delta NDF gives the unfiltered lobe (to `1/(1 − e^{−2s})`).
pub fn filtered_glossy(ndf: &[Vmf], exponent: f64, h: DVec3) -> f64 {
    let s = exponent.max(1e-9);
    ndf.iter()
        .map(|lobe| {
            let kappa = lobe.kappa * s / (lobe.kappa + s);
            2.0 * PI / s * Vmf { kappa, ..*lobe }.density(h)
        })
        .sum()
}

/// `1 − cos` of the least angle (about 0.8°) between two seeds of a mixture: normals closer
/// than that to every seed are one lobe's spread, not a lobe of their own.
const MIN_SEED_SEPARATION: f64 = 1e-4;

/// Fits `lobes` vMF lobes to weighted unit normals by spherical EM (Banerjee et al. 2005):
/// responsibilities from each lobe's density, then each lobe's weight, mean direction and
/// concentration (from its weighted mean resultant length) from them. Lobes start on the
/// normals farthest apart; at most `iterations` rounds, fewer once no lobe moves. Fewer
/// distinct normals (more than [`MIN_SEED_SEPARATION`] apart) than lobes give fewer lobes.
pub fn fit_vmf_mixture(normals: &[(DVec3, f64)], lobes: usize, iterations: usize) -> Vec<Vmf> {
    let total: f64 = normals.iter().map(|(_, w)| w.max(0.0)).sum();
    if normals.is_empty() || lobes == 0 || total <= 0.0 {
        return Vec::new();
    }
    // Seeds: the heaviest normal, then repeatedly the normal farthest from every seed.
    let mut seeds: Vec<DVec3> = Vec::new();
    let first = normals.iter().max_by(|a, b| a.1.total_cmp(&b.1)).expect("non-empty").0;
    seeds.push(first);
    while seeds.len() < lobes {
        let (farthest, distance) = normals
            .iter()
            .map(|(n, _)| (*n, seeds.iter().map(|s| 1.0 - s.dot(*n)).fold(f64::INFINITY, f64::min)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .expect("non-empty");
        if distance <= MIN_SEED_SEPARATION {
            break;
        }
        seeds.push(farthest);
    }
    let mut mixture: Vec<Vmf> =
        seeds.iter().map(|&mean| Vmf { weight: 1.0 / seeds.len() as f64, kappa: 10.0, mean }).collect();
    let mut responsibility = vec![0.0; mixture.len()];
    for _ in 0..iterations {
        let mut sums = vec![(0.0, DVec3::ZERO); mixture.len()];
        for (n, w) in normals {
            // Log densities, normalised against the largest so none underflows.
            for (r, lobe) in responsibility.iter_mut().zip(&mixture) {
                *r = lobe.weight.max(1e-300).ln() + Vmf::log_normalisation(lobe.kappa) + lobe.kappa * lobe.mean.dot(*n);
            }
            let top = responsibility.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let sum: f64 = responsibility.iter().map(|r| (r - top).exp()).sum();
            for ((r, s), _) in responsibility.iter().zip(&mut sums).zip(&mixture) {
                let share = (r - top).exp() / sum * w.max(0.0);
                s.0 += share;
                s.1 += share * *n;
            }
        }
        let before = mixture.clone();
        for (lobe, (mass, resultant)) in mixture.iter_mut().zip(&sums) {
            if *mass <= total * 1e-12 {
                lobe.weight = 0.0;
                continue;
            }
            lobe.weight = mass / total;
            lobe.mean = resultant.try_normalize().unwrap_or(lobe.mean);
            lobe.kappa = Vmf::kappa_from_mean_length(resultant.length() / mass);
        }
        // Converged when no lobe moved its weight, direction or (relative) concentration by
        // more than 1e-5.
        let settled = mixture.iter().zip(&before).all(|(a, b)| {
            (a.weight - b.weight).abs() < 1e-5
                && (1.0 - a.mean.dot(b.mean)) < 1e-10
                && (a.kappa - b.kappa).abs() < 1e-5 * b.kappa
        });
        mixture.retain(|l| l.weight > 0.0);
        responsibility.truncate(mixture.len());
        if settled {
            break;
        }
    }
    mixture
}

#[cfg(test)]
mod tests;
