//! An SH irradiance probe grid over the scene's bounds, for lighting dynamic objects the way
//! Unity's light probes and Godot's LightmapGI probes do: per probe, the radiance arriving at
//! that point projected onto real SH (L2, 9 coefficients by default), visibility-aware (a
//! direction the scene blocks brings nothing; no interreflection, as in every mode).
//!
//! The environment is integrated texel by texel over its cube map box-filtered to 32² faces
//! (every texel's energy kept, so a sun is neither missed nor aliased), one shadow ray per
//! texel; point lights add their delta `I/d² Y_lm(ω_l)` when unblocked, and painted area
//! lights their texels (in blocks of at most [`AREA_CELLS`]² cells, each `L A cos θ_l / d²`
//! when unblocked). Through fog (Sun 2008 §3.6.4, as the modes shade surfaces) the
//! environment's light is attenuated by `e^{−βD}` and the medium's scattered environment light
//! (unshadowed) added; the lights' direct light is attenuated by `e^{−βd}` (their airlight,
//! which varies along every view ray, is left to the game engine's fog). A probe that sees
//! nothing but geometry (inside an object) is marked invalid.

use crate::cubemap::CubeMap;
use crate::engine::{CancelToken, StageError};
use crate::light::PointLight;
use crate::raycast::RayScene;
use crate::sh::ShBasis;
use glam::{DVec3, Vec3A};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(ProbeGrid, "SH probe grid", |v| v.coefficients.len() * 12 + v.valid.len());

/// Most probes a grid may have.
pub const MAX_PROBES: usize = 1 << 18;

/// Face size of the environment as probes integrate it.
const ENVIRONMENT_FACE: usize = 32;

/// Cells a side an area light is integrated in, at most.
pub const AREA_CELLS: usize = 16;

/// What lights the probes besides the environment, and the medium they see it through.
#[derive(Default)]
pub struct ProbeLighting<'a> {
    pub points: &'a [PointLight],
    pub areas: Vec<&'a crate::reference::AreaEmitter>,
    /// The medium's scattering coefficient (1/m) and the environment's light through it.
    pub fog: Option<([f64; 3], &'a crate::single_scattering::FoggedEnvironment)>,
}

/// A regular grid of SH radiance probes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProbeGrid {
    /// Position of probe `(0, 0, 0)`, metres.
    pub origin: [f64; 3],
    pub spacing: f64,
    /// Probes along x, y, z; x varies fastest.
    pub counts: [usize; 3],
    pub bands: usize,
    /// Per probe, `bands²` RGB radiance coefficients `L_lm`.
    pub coefficients: Vec<[f32; 3]>,
    /// Per probe: whether it sees anything but geometry.
    pub valid: Vec<bool>,
}

impl ProbeGrid {
    pub fn len(&self) -> usize {
        self.valid.len()
    }

    pub fn is_empty(&self) -> bool {
        self.valid.is_empty()
    }

    /// Position of probe `i`.
    pub fn position(&self, i: usize) -> DVec3 {
        let [nx, ny, _] = self.counts;
        let index = DVec3::new((i % nx) as f64, ((i / nx) % ny) as f64, (i / (nx * ny)) as f64);
        DVec3::from(self.origin) + index * self.spacing
    }

    /// Probe `i`'s coefficients.
    pub fn probe(&self, i: usize) -> &[[f32; 3]] {
        let n = self.bands * self.bands;
        &self.coefficients[i * n..(i + 1) * n]
    }

    /// Irradiance `E(n) = Σ Â_l L_lm Y_lm(n)` of probe `i` for a surface facing `normal`.
    pub fn irradiance(&self, i: usize, normal: DVec3) -> DVec3 {
        irradiance_of(self.probe(i), self.bands, normal)
    }

    /// The coefficients at `p`, trilinearly interpolated from the valid probes of its cell
    /// (clamped to the grid).
    pub fn interpolate(&self, p: DVec3) -> Vec<[f32; 3]> {
        let n = self.bands * self.bands;
        let local = (p - DVec3::from(self.origin)) / self.spacing;
        let mut base = [0usize; 3];
        let mut frac = [0.0f64; 3];
        for a in 0..3 {
            let last = self.counts[a].saturating_sub(1) as f64;
            let x = local[a].clamp(0.0, last);
            base[a] = (x.floor() as usize).min(self.counts[a].saturating_sub(2));
            frac[a] = if self.counts[a] > 1 { x - base[a] as f64 } else { 0.0 };
        }
        let mut out = vec![[0.0f32; 3]; n];
        let mut total = 0.0;
        for corner in 0..8 {
            let offset = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let mut weight = 1.0;
            let mut index = [0usize; 3];
            for a in 0..3 {
                index[a] = (base[a] + offset[a]).min(self.counts[a] - 1);
                weight *= if offset[a] == 1 { frac[a] } else { 1.0 - frac[a] };
            }
            let i = index[0] + self.counts[0] * (index[1] + self.counts[1] * index[2]);
            if weight <= 0.0 || !self.valid[i] {
                continue;
            }
            total += weight;
            for (o, c) in out.iter_mut().zip(self.probe(i)) {
                for k in 0..3 {
                    o[k] += (weight as f32) * c[k];
                }
            }
        }
        if total > 0.0 {
            for o in &mut out {
                for k in 0..3 {
                    o[k] /= total as f32;
                }
            }
        }
        out
    }
}

/// `E(n)` from radiance coefficients.
pub fn irradiance_of(coefficients: &[[f32; 3]], bands: usize, normal: DVec3) -> DVec3 {
    let basis = ShBasis::new(bands);
    let y = basis.eval_vec(normal);
    let mut e = DVec3::ZERO;
    for (i, c) in coefficients.iter().enumerate() {
        let a = crate::sh::clamped_cosine_factor(crate::sh::band_of(i));
        e += DVec3::from(c.map(f64::from)) * a * y[i];
    }
    e
}

/// The grid over `bounds` (min, max) at `spacing`, centred so no probe sits on the bounds.
pub fn layout(bounds: ([f32; 3], [f32; 3]), spacing: f64) -> Result<([f64; 3], [usize; 3]), String> {
    let mut origin = [0.0; 3];
    let mut counts = [1usize; 3];
    for a in 0..3 {
        let (lo, hi) = (f64::from(bounds.0[a]), f64::from(bounds.1[a]));
        let extent = (hi - lo).max(0.0);
        counts[a] = ((extent / spacing).ceil() as usize).max(1);
        origin[a] = (lo + hi) / 2.0 - (counts[a] - 1) as f64 * spacing / 2.0;
    }
    let total = counts.iter().product::<usize>();
    if total > MAX_PROBES {
        return Err(format!(
            "a probe spacing of {spacing} m gives {total} probes over the scene (at most {MAX_PROBES}): raise the spacing"
        ));
    }
    Ok((origin, counts))
}

/// Bakes the grid: `environment` (as the modes see it, rotated) and `lights`, shadowed by
/// `scene`.
#[allow(clippy::too_many_arguments)]
pub fn bake(
    scene: &RayScene,
    bounds: ([f32; 3], [f32; 3]),
    spacing: f64,
    bands: usize,
    environment: Option<&CubeMap>,
    lighting: &ProbeLighting,
    cancel: &CancelToken,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<ProbeGrid, StageError> {
    let (origin, counts) = layout(bounds, spacing).map_err(StageError::Failed)?;
    let mut grid = ProbeGrid { origin, spacing, counts, bands, ..Default::default() };
    let total = counts.iter().product::<usize>();
    let basis = ShBasis::new(bands);
    let texels: Vec<(DVec3, f64, [f64; 3], Vec<f64>)> = environment
        .map(|env| {
            env.box_downsampled(ENVIRONMENT_FACE.min(env.size))
                .samples()
                .map(|(dir, omega, radiance)| (dir, omega, radiance, basis.eval_vec(dir)))
                .collect()
        })
        .unwrap_or_default();
    // Area lights as small patches: (centre, radiance × area, the light's facing).
    let patches: Vec<(DVec3, [f64; 3], DVec3)> =
        lighting.areas.iter().flat_map(|e| area_patches(e).into_iter().map(|(c, p)| (c, p, e.facing()))).collect();
    let attenuation = |d: f64| lighting.fog.map_or([1.0; 3], |(beta, _)| beta.map(|b| (-b * d).exp()));
    let environment_attenuation = lighting.fog.map_or([1.0; 3], |(_, f)| f.fog.attenuation);
    // The medium's scattered environment light, unshadowed, on the probes' bands.
    let scattered: Vec<[f64; 3]> = match lighting.fog {
        Some((_, f)) => {
            (0..basis.len()).map(|k| std::array::from_fn(|c| f.scattered.coeffs.get(k).map_or(0.0, |v| v[c]))).collect()
        }
        None => vec![[0.0; 3]; basis.len()],
    };
    // Directions that tell whether a probe is inside geometry (without an environment too).
    let probe_dirs = crate::transport::fibonacci_directions(64);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let per_probe: Vec<(Vec<[f32; 3]>, bool)> = (0..total)
        .into_par_iter()
        .map(|i| {
            cancel.check()?;
            let p = grid.position(i);
            let origin = Vec3A::from(p.as_vec3());
            let mut sum = vec![[0.0f64; 3]; basis.len()];
            for (dir, omega, radiance, y) in &texels {
                if scene.occluded(origin, dir.as_vec3().into(), f32::INFINITY) {
                    continue;
                }
                for (s, y) in sum.iter_mut().zip(y) {
                    for c in 0..3 {
                        s[c] += radiance[c] * environment_attenuation[c] * omega * y;
                    }
                }
            }
            for (s, add) in sum.iter_mut().zip(&scattered) {
                for c in 0..3 {
                    s[c] += add[c];
                }
            }
            for (centre, power, facing) in &patches {
                let to = *centre - p;
                let d = to.length();
                // A patch lights only what lies in front of its light.
                let cos_light = -to.dot(*facing) / d.max(1e-300);
                if d <= 1e-6 || cos_light <= 0.0 {
                    continue;
                }
                let l = to / d;
                if scene.occluded(origin, l.as_vec3().into(), (d * (1.0 - 1e-4)) as f32) {
                    continue;
                }
                let (y, fade) = (basis.eval_vec(l), attenuation(d));
                let solid_angle_per_area = cos_light / (d * d);
                for (s, y) in sum.iter_mut().zip(&y) {
                    for c in 0..3 {
                        s[c] += power[c] * solid_angle_per_area * fade[c] * y;
                    }
                }
            }
            for light in lighting.points {
                let to_light = DVec3::from(light.position) - p;
                let d = to_light.length();
                if d <= 1e-6 {
                    continue;
                }
                let l = to_light / d;
                if scene.occluded(origin, l.as_vec3().into(), (d * (1.0 - 1e-4)) as f32) {
                    continue;
                }
                let (y, fade) = (basis.eval_vec(l), attenuation(d));
                let intensity = light.intensity_toward(-l);
                for (s, y) in sum.iter_mut().zip(&y) {
                    for c in 0..3 {
                        s[c] += intensity[c] * fade[c] / (d * d) * y;
                    }
                }
            }
            let open = probe_dirs.iter().any(|d| !scene.occluded(origin, d.as_vec3().into(), f32::INFINITY));
            let finished = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            if finished.is_multiple_of(64) {
                progress(finished as f64 / total as f64);
            }
            Ok((sum.into_iter().map(|s| s.map(|c| c as f32)).collect(), open))
        })
        .collect::<Result<_, StageError>>()?;
    for (coefficients, valid) in per_probe {
        grid.coefficients.extend(coefficients);
        grid.valid.push(valid);
    }
    Ok(grid)
}

/// `emitter`'s texels in blocks of at most [`AREA_CELLS`] a side: each block's centre and its
/// radiance × area.
fn area_patches(emitter: &crate::reference::AreaEmitter) -> Vec<(DVec3, [f64; 3])> {
    let side = emitter.side.max(1);
    let cells = side.min(AREA_CELLS);
    let block = side.div_ceil(cells);
    let texel_area = emitter.width * emitter.depth / (side * side) as f64;
    let mut patches = Vec::new();
    for by in (0..side).step_by(block) {
        for bx in (0..side).step_by(block) {
            let mut power = [0.0; 3];
            for j in by..(by + block).min(side) {
                for i in bx..(bx + block).min(side) {
                    let l = emitter.radiance.get(j * side + i).copied().unwrap_or_default();
                    for c in 0..3 {
                        power[c] += l[c] * texel_area;
                    }
                }
            }
            if power.iter().any(|&p| p > 0.0) {
                let width = ((bx + block).min(side) - bx) as f64;
                let depth = ((by + block).min(side) - by) as f64;
                let centre =
                    emitter.point((bx as f64 + width / 2.0) / side as f64, (by as f64 + depth / 2.0) / side as f64);
                patches.push((centre, power));
            }
        }
    }
    patches
}

/// `probes.json` (layout and conventions) and `probes.bin` (the numbers) for `grid`.
pub fn files(grid: &ProbeGrid) -> (Vec<u8>, Vec<u8>) {
    let mut bin: Vec<u8> = grid.coefficients.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
    let valid_offset = bin.len();
    bin.extend(grid.valid.iter().map(|&v| u8::from(v)));
    let json = serde_json::json!({
        "format": "lightloom SH probe grid",
        "version": 1,
        "origin": grid.origin,
        "spacing": grid.spacing,
        "counts": grid.counts,
        "order": "probe (i, j, k) at origin + spacing * (i, j, k); x fastest, then y, then z",
        "bands": grid.bands,
        "binary": "probes.bin",
        "coefficients": {
            "offset": 0,
            "layout": "per probe, bands^2 coefficients in SH index order, each RGB float32 little-endian",
        },
        "valid": {
            "offset": valid_offset,
            "layout": "one byte per probe: 1 when the probe sees more than geometry, 0 inside an object (skip it)",
        },
        "convention": "real orthonormal SH of world directions, index l(l+1)+m, no Condon-Shortley phase \
                       (Y1,-1 = 0.488603 y, Y1,0 = 0.488603 z, Y1,1 = 0.488603 x; +Y up). The coefficients are the \
                       radiance L_lm arriving at the probe: irradiance E(n) = sum A_l L_lm Y_lm(n) with A_0 = pi, \
                       A_1 = 2pi/3, A_2 = pi/4; E/pi is what COLOR_0 and the lightmap store. Unity's \
                       SphericalHarmonicsL2 and Godot's probes use other bases and scalings: convert with these \
                       definitions",
        "includes": "the environment (shadowed by the scene), point lights and painted area lights (shadowed); \
                     through fog, the environment attenuated by exp(-beta D) plus the medium's scattered light, \
                     and the lights' direct light attenuated by exp(-beta d); no interreflection",
    });
    let mut text = serde_json::to_vec_pretty(&json).expect("the probe description serialises");
    text.push(b'\n');
    (text, bin)
}
