//! The environment for image-based lighting, as a game engine takes it (Filament's `cmgen` is
//! the model): its SH (radiance, L2) for diffuse light, and a GGX-prefiltered specular cube map
//! with one roughness per mip level, in KTX2 (`VK_FORMAT_R16G16B16A16_SFLOAT`).
//!
//! Mip `m` of `M` holds the split-sum prefiltered radiance (Karis 2013) for perceptual
//! roughness `r = m/(M−1)` (GGX `α = r²`), with `n = v = r` and `n·l` weights:
//! `∫ L(l) D(h) (n·l)₊ dl / ∫ D(h) (n·l)₊ dl`, `h = normalize(n + l)`. The brightest texels
//! (a sun: each above 100 times the mean) are summed exactly, since GGX's long tail carries
//! their light far from the lobe's peak where no importance sample goes; the rest by GGX
//! importance sampling with filtered importance sampling (Křivánek and Colbert 2008), each
//! sample reading a box-filtered level of the source whose texel matches its solid angle. Faces are in the cube map order of OpenGL, Vulkan and KTX (+X −X +Y −Y +Z −Z, each
//! face's texel rows as `glTexImage2D` takes them), looked up with world directions as they are.

use crate::cubemap::{CubeMap, FACES, face_uv_to_dir};
use crate::engine::{CancelToken, StageError};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// GGX importance samples per output texel.
const SAMPLES: usize = 256;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(SpecularCube, "prefiltered specular cube", |v| v
    .levels
    .iter()
    .map(|l| l.texels.len() * 12)
    .sum::<usize>());
crate::stage_type!(EnvironmentBake, "baked environment", |v| v
    .cube
    .levels
    .iter()
    .map(|l| l.texels.len() * 12)
    .sum::<usize>());

/// What a bake writes for the environment: its SH and the specular cube.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentBake {
    pub sh: crate::sh::ShRgb,
    pub cube: SpecularCube,
}

/// The prefiltered mip chain: level `m` has faces of `size >> m`.
#[derive(Clone, Debug, PartialEq)]
pub struct SpecularCube {
    pub levels: Vec<CubeMap>,
}

/// Perceptual roughness of mip `level` of `levels`.
pub fn level_roughness(level: usize, levels: usize) -> f64 {
    if levels <= 1 { 0.0 } else { level as f64 / (levels - 1) as f64 }
}

/// Prefilters `source` into mips from `size` (at most the source's size; a power of two)
/// down to 4×4 faces.
pub fn prefilter(source: &CubeMap, size: usize, cancel: &CancelToken) -> Result<SpecularCube, StageError> {
    let size = size.min(source.size).max(4).next_power_of_two().min(source.size.next_power_of_two());
    let base = if source.size == size { source.clone() } else { resampled(source, size) };
    // The bright texels, at up to 64² a face, taken out of the sampled source.
    let coarse = base.box_downsampled(64.min(size));
    let mean = coarse.samples().map(|(_, omega, l)| omega * luminance(l)).sum::<f64>() / (4.0 * PI);
    let bright: Vec<(DVec3, f64, [f64; 3])> =
        coarse.samples().filter(|(_, _, l)| luminance(*l) > 100.0 * mean).collect();
    let mut dimmed = base.clone();
    if !bright.is_empty() {
        let factor = size / coarse.size;
        for i in 0..dimmed.texels.len() {
            let (f, x, y) = (i / (size * size), i % size, (i / size) % size);
            let c = (f * coarse.size + y / factor) * coarse.size + x / factor;
            if luminance(coarse.texels[c].map(f64::from)) > 100.0 * mean {
                dimmed.texels[i] = [0.0; 3];
            }
        }
    }
    // The rest as box-filtered levels: size, size/2, ... 1 (each keeps its energy).
    let mut chain = vec![dimmed];
    while chain.last().unwrap().size > 1 {
        let last = chain.last().unwrap();
        chain.push(last.box_downsampled(last.size / 2));
    }
    let levels = (size.trailing_zeros() as usize).saturating_sub(1).max(1);
    let mut out = Vec::with_capacity(levels);
    for level in 0..levels {
        cancel.check()?;
        let face = size >> level;
        let roughness = level_roughness(level, levels);
        let texels: Vec<[f32; 3]> = (0..FACES * face * face)
            .into_par_iter()
            .map(|i| {
                let (f, x, y) = (i / (face * face), i % face, (i / face) % face);
                let n = face_uv_to_dir(f, (x as f64 + 0.5) / face as f64, (y as f64 + 0.5) / face as f64);
                if level == 0 {
                    return base.sample(n).map(|c| c as f32);
                }
                prefiltered(&chain, &bright, n, roughness * roughness).map(|c| c as f32)
            })
            .collect();
        out.push(CubeMap::new(face, texels));
    }
    Ok(SpecularCube { levels: out })
}

/// Bilinear resampling of `source` to faces of `size`, box-filtered first when shrinking.
fn resampled(source: &CubeMap, size: usize) -> CubeMap {
    let filtered = if source.size > size && source.size.is_multiple_of(size) {
        source.box_downsampled(size)
    } else {
        source.clone()
    };
    CubeMap::from_fn(size, 1, |d| filtered.sample(d))
}

/// The isotropic GGX distribution at `cos θ_h`.
fn ggx(cos_h: f64, alpha: f64) -> f64 {
    let c = cos_h.clamp(0.0, 1.0);
    crate::brdf::ggx_distribution(DVec3::new((1.0 - c * c).sqrt(), 0.0, c), alpha, alpha)
}

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// One texel of a GGX-prefiltered level at `α`: the `bright` texels `(direction, solid angle,
/// radiance)` summed exactly, the rest (`chain`) by filtered importance sampling, both over
/// the same normalisation `∫ D (n·l)₊ dl`, itself estimated by the same samples.
fn prefiltered(chain: &[CubeMap], bright: &[(DVec3, f64, [f64; 3])], n: DVec3, alpha: f64) -> [f64; 3] {
    let (t, b) = n.any_orthonormal_pair();
    let base = chain[0].size as f64;
    let texel_solid_angle = 4.0 * PI / (6.0 * base * base);
    // With pdf(l) = D/4 (v = n), `∫ f D (n·l)₊ dl` is estimated by `(4/N) Σ f (n·l)₊`.
    let (mut sum, mut weight) = ([0.0; 3], 0.0);
    for i in 0..SAMPLES {
        // Hammersley point, GGX half vector (Walter et al. 2007 eq. 35).
        let u1 = (i as f64 + 0.5) / SAMPLES as f64;
        let u2 = (i as u32).reverse_bits() as f64 / 4294967296.0;
        let cos_h = ((1.0 - u1) / (1.0 + (alpha * alpha - 1.0) * u1)).sqrt();
        let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
        let phi = 2.0 * PI * u2;
        let h = t * (sin_h * phi.cos()) + b * (sin_h * phi.sin()) + n * cos_h;
        let l = 2.0 * n.dot(h) * h - n;
        let n_l = n.dot(l);
        if n_l <= 0.0 {
            continue;
        }
        // pdf over l with v = n: D(h)/4.
        let d = ggx(cos_h, alpha);
        let pdf = d / 4.0;
        let sample_solid_angle = 1.0 / (SAMPLES as f64 * pdf);
        let lod = (0.5 * (sample_solid_angle / texel_solid_angle).log2() + 1.0).clamp(0.0, (chain.len() - 1) as f64);
        let radiance = trilinear(chain, l, lod);
        for c in 0..3 {
            sum[c] += radiance[c] * n_l;
        }
        weight += n_l;
    }
    let scale = 4.0 / SAMPLES as f64;
    let (mut sum, weight) = (sum.map(|s| s * scale), weight * scale);
    for (l, omega, radiance) in bright {
        let n_l = n.dot(*l);
        if n_l <= 0.0 {
            continue;
        }
        let h = (n + *l).normalize();
        let w = ggx(n.dot(h), alpha) * n_l * omega;
        for c in 0..3 {
            sum[c] += radiance[c] * w;
        }
    }
    if weight > 0.0 { sum.map(|s| s / weight) } else { [0.0; 3] }
}

fn trilinear(chain: &[CubeMap], dir: DVec3, lod: f64) -> [f64; 3] {
    let lo = lod.floor() as usize;
    let hi = (lo + 1).min(chain.len() - 1);
    let f = lod - lo as f64;
    let (a, b) = (chain[lo].sample(dir), chain[hi].sample(dir));
    std::array::from_fn(|c| a[c] * (1.0 - f) + b[c] * f)
}

/// The KTX2 file of `cube`: RGBA16F, 6 faces, its levels (alpha 1).
pub fn ktx2_bytes(cube: &SpecularCube) -> Vec<u8> {
    const VK_FORMAT_R16G16B16A16_SFLOAT: u32 = 97;
    let levels = cube.levels.len();
    let level_data: Vec<Vec<u8>> = cube
        .levels
        .iter()
        .map(|l| {
            l.texels
                .iter()
                .flat_map(|t| [t[0], t[1], t[2], 1.0])
                .flat_map(|c| half::f16::from_f32(c).to_le_bytes())
                .collect()
        })
        .collect();
    // Data Format Descriptor: one basic block, four float samples (R, G, B, A).
    let mut dfd = Vec::new();
    let block_size: u32 = 24 + 16 * 4;
    dfd.extend((4 + block_size).to_le_bytes());
    dfd.extend(0u32.to_le_bytes()); // vendor 0 (Khronos), descriptor type 0 (basic)
    dfd.extend(((block_size << 16) | 2).to_le_bytes()); // size, version 2 (KDF 1.3)
    dfd.extend([1u8, 1, 1, 0]); // RGBSDA, BT.709 primaries, linear, straight alpha
    dfd.extend([0u8; 4]); // 1×1×1×1 texel blocks
    dfd.extend([8u8, 0, 0, 0, 0, 0, 0, 0]); // 8 bytes per texel in plane 0
    for (i, channel) in [0u8, 1, 2, 15].into_iter().enumerate() {
        let bit_offset = (i * 16) as u32;
        let channel_type = channel | 0x80 | 0x40; // float, signed
        dfd.extend((bit_offset | (15 << 16) | (u32::from(channel_type) << 24)).to_le_bytes());
        dfd.extend([0u8; 4]); // sample position
        dfd.extend(0xBF80_0000u32.to_le_bytes()); // lower: -1.0
        dfd.extend(0x3F80_0000u32.to_le_bytes()); // upper: 1.0
    }
    // Key/value data: the writer.
    let mut kvd = Vec::new();
    let entry = b"KTXwriter\0Lightloom\0";
    kvd.extend((entry.len() as u32).to_le_bytes());
    kvd.extend(entry);
    while !kvd.len().is_multiple_of(4) {
        kvd.push(0);
    }
    let header_len = 12 + 9 * 4 + 4 * 4 + 2 * 8 + levels * 24;
    let dfd_offset = header_len;
    let kvd_offset = dfd_offset + dfd.len();
    let data_start = kvd_offset + kvd.len();
    // Levels are stored smallest first, each aligned to 8 bytes (lcm of texel size and 4).
    let mut offsets = vec![0usize; levels];
    let mut body = Vec::new();
    for level in (0..levels).rev() {
        while !(data_start + body.len()).is_multiple_of(8) {
            body.push(0);
        }
        offsets[level] = data_start + body.len();
        body.extend(&level_data[level]);
    }
    let size = cube.levels[0].size as u32;
    let mut out = Vec::with_capacity(header_len + dfd.len() + kvd.len() + body.len());
    out.extend([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A]);
    for v in [VK_FORMAT_R16G16B16A16_SFLOAT, 2, size, size, 0, 0, 6, levels as u32, 0] {
        out.extend(v.to_le_bytes());
    }
    for v in [dfd_offset as u32, dfd.len() as u32, kvd_offset as u32, kvd.len() as u32] {
        out.extend(v.to_le_bytes());
    }
    out.extend(0u64.to_le_bytes());
    out.extend(0u64.to_le_bytes());
    for level in 0..levels {
        let len = level_data[level].len() as u64;
        out.extend((offsets[level] as u64).to_le_bytes());
        out.extend(len.to_le_bytes());
        out.extend(len.to_le_bytes());
    }
    out.extend(&dfd);
    out.extend(&kvd);
    out.extend(&body);
    out
}

/// `environment.json`: the SH (radiance, with `E(n) = Σ Â_l L_lm Y_lm(n)`) and the specular
/// cube's conventions.
pub fn json_bytes(sh: &crate::sh::ShRgb, cube: &SpecularCube, ktx2_name: &str) -> Vec<u8> {
    let coefficients: Vec<serde_json::Value> = (0..sh.bands)
        .flat_map(|l| (-(l as i64)..=l as i64).map(move |m| (l, m)))
        .map(|(l, m)| serde_json::json!({ "l": l, "m": m, "rgb": sh.coeffs[crate::sh::index(l, m)] }))
        .collect();
    let json = serde_json::json!({
        "sh": {
            "bands": sh.bands,
            "coefficients": coefficients,
            "convention": "real orthonormal SH of world directions, index l(l+1)+m, no Condon-Shortley phase \
                           (Y1,-1 = 0.488603 y, Y1,0 = 0.488603 z, Y1,1 = 0.488603 x; +Y up); radiance L_lm (as \
                           `lightloom sh` prints); irradiance E(n) = sum A_l L_lm Y_lm(n), A_0 = pi, A_1 = 2pi/3, \
                           A_2 = pi/4. Unshadowed: the environment alone, rotated and scaled as the project draws it",
        },
        "specular": {
            "file": ktx2_name,
            "format": "KTX2, VK_FORMAT_R16G16B16A16_SFLOAT, cube map, linear radiance",
            "size": cube.levels[0].size,
            "levels": cube.levels.len(),
            "roughness": (0..cube.levels.len()).map(|m| level_roughness(m, cube.levels.len())).collect::<Vec<_>>(),
            "convention": "mip m holds the radiance prefiltered with GGX at perceptual roughness m/(levels-1) \
                           (alpha = roughness^2), split-sum with n = v = r and n.l weights (Karis 2013), as Filament's \
                           cmgen; sample level roughness*(levels-1) along the reflected direction. Faces in the \
                           OpenGL/Vulkan/KTX order (+X -X +Y -Y +Z -Z), looked up with world directions",
        },
    });
    let mut bytes = serde_json::to_vec_pretty(&json).expect("the environment description serialises");
    bytes.push(b'\n');
    bytes
}

/// The brute-force twin of a prefiltered texel: `∫ L(l) D(h) (n·l)₊ dl / ∫ D(h) (n·l)₊ dl`
/// summed over every texel of `source` (the test's ground truth).
pub fn brute_force(source: &CubeMap, n: DVec3, alpha: f64) -> [f64; 3] {
    let (mut sum, mut weight) = ([0.0; 3], 0.0);
    for (l, omega, radiance) in source.samples() {
        let n_l = n.dot(l);
        if n_l <= 0.0 {
            continue;
        }
        let h = (n + l).normalize();
        let w = ggx(n.dot(h), alpha) * n_l * omega;
        for c in 0..3 {
            sum[c] += radiance[c] * w;
        }
        weight += w;
    }
    sum.map(|s| s / weight)
}
