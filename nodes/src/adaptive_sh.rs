//! Locally adaptive high-order SH products (Lee 2014, ch. 4–5; reading notes Part B).
//!
//! The glossy path of SH relighting needs the incident radiance `R = L·V` per vertex, the
//! product projection `R_i = Σ_j L̂_ij V_j` with the light product matrix
//! `L̂_ij = Σ_k L_k C_ijk` (Lee eq. 2.2, the Gaunt tensor). At level 10 (121 coefficients)
//! that is 14,641 multiply-adds per channel and vertex; most vertices do not need it.
//!
//! * **Multi-level filtering** (Algorithm 1, with the notes' corrections): every glossy vertex
//!   gets the base level ([`BASE_LEVEL`]); then level by level the products of the next band
//!   are added incrementally (Algorithm 3 in the notes' corrected form: new rows over all
//!   columns, new columns for the old rows). A vertex stops rising (leaves that level's region
//!   of interest, ROI) at the first level whose own change, as its shading sees it, is below
//!   the threshold; that level is not kept, so threshold ∞ is the base image and threshold 0
//!   the full one.
//! * **Region-of-interest refinement** (§5.2.1): a breadth-first search from the ROI computes
//!   its neighbours to the full level and adds those whose change is significant.
//! * **Smoothing** (§5.2.2): two tiers outside the ROI get the ROI's higher bands,
//!   extrapolated from their neighbours and attenuated by tier (`2/3`, `1/3`; the thesis
//!   gives no weights).
//! * **Hysteresis** against the flicker of Lee's Fig. 6.5 (the notes' remedy; not in the
//!   thesis): a vertex drops a level it had in the previous evaluation only below
//!   `hysteresis × threshold`.
//!
//! "As its shading sees it": the glossy exit radiance is `w Σ_lm f_l R_lm Y_lm(r)` with the
//! material's lobe factors `f_l` and weight `w` ([`crate::prt`]). Its mean square over all
//! mirror directions `r` is `w² Σ f_l² R_lm² / 4π` (orthonormality), so differences are measured
//! as that view-averaged RMS: one number per vertex that any camera sees on average, so camera
//! moves need no recomputation. The PSNR against the full computation uses the same measure
//! ([`view_psnr`]). The diffuse sum `Σ T_k L_k` costs `n` per vertex and is left to the GPU at
//! the full level.

use crate::engine::{CancelToken, StageError};
use crate::prt::IncidentSh;
use crate::sh::{GauntTable, ShRgb, band_of};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::{Arc, Mutex, OnceLock};

crate::stage_type!(AdaptiveIncident, "adaptive incident radiance SH", |v| v.incident.coeffs.len() * 4
    + v.levels.len() * 2);

/// Level every glossy vertex gets (bands 0..=2, nine coefficients; Lee after Ramamoorthi).
pub const BASE_LEVEL: usize = 2;

/// A Gaunt table per band count, built once (`L̂` is rebuilt from it on every lighting change).
fn gaunt(bands: usize) -> Arc<GauntTable> {
    static TABLES: OnceLock<Mutex<Vec<Option<Arc<GauntTable>>>>> = OnceLock::new();
    let mut tables = TABLES.get_or_init(Default::default).lock().unwrap();
    if tables.len() <= bands {
        tables.resize(bands + 1, None);
    }
    tables[bands].get_or_insert_with(|| Arc::new(GauntTable::new(bands, bands, bands))).clone()
}

/// The light product matrices `L̂` (one per channel, `n × n`, symmetric) for `bands` bands.
#[derive(Clone, Debug)]
pub struct LightProducts {
    pub bands: usize,
    n: usize,
    matrices: [Vec<f32>; 3],
}

impl LightProducts {
    /// `light` is truncated or zero-padded to `bands`.
    pub fn new(light: &ShRgb, bands: usize) -> Self {
        let light = crate::prt::light_to_bands(light, bands);
        let table = gaunt(bands);
        let matrices =
            std::array::from_fn(|c| table.product_matrix(&light.channel(c)).into_iter().map(|x| x as f32).collect());
        Self { bands, n: bands * bands, matrices }
    }

    /// Multiply-adds (all channels) of the full product at `level`: `3 (l+1)⁴`.
    pub fn full_macs(level: usize) -> u64 {
        3 * ((level + 1) as u64).pow(4)
    }

    /// The full product `R = L̂ V` on all bands, interleaved `k·3 + c`: one dense dot product
    /// per row (faster here than the level-by-level kernel, which reads half of the symmetric
    /// `L̂` but does two multiply-adds per entry read). `v` holds at least `n` coefficients.
    pub fn full(&self, v: &[f32], out: &mut [f32]) {
        let n = self.n;
        for (c, m) in self.matrices.iter().enumerate() {
            for i in 0..n {
                out[i * 3 + c] = dot(&m[i * n..i * n + n], &v[..n]);
            }
        }
    }

    /// The increment of `level` to a product truncated to `level - 1` (the notes' corrected
    /// Algorithm 3), planar per channel into `d[c][..(level+1)²]`: new rows `i ∈ [l², (l+1)²)`
    /// over every column `j < (l+1)²`, and for the old rows the new columns `j ∈ [l², (l+1)²)`
    /// (`L̂` is symmetric, so those are rows too).
    fn increment(&self, level: usize, v: &[f32], d: &mut Planar) {
        let (n, lo, hi) = (self.n, level * level, (level + 1) * (level + 1));
        for (m, d) in self.matrices.iter().zip(d.iter_mut()) {
            let (old, new) = d.split_at_mut(lo);
            old.fill(0.0);
            // One pass over each new row serves both: its dot product with `v`, and (by
            // symmetry) its share of the old rows' new columns.
            for (i, out) in (lo..hi).zip(new.iter_mut()) {
                let row = &m[i * n..i * n + hi];
                let (head, tail) = row.split_at(lo);
                let vi = v[i];
                let mut acc = [0.0f32; 8];
                let (hm, hv, hd) = (head.chunks_exact(8), v[..lo].chunks_exact(8), old.chunks_exact_mut(8));
                let (rm, rv) = (hm.remainder(), hv.remainder());
                let rest = lo - rm.len();
                for ((mm, vv), dd) in hm.zip(hv).zip(hd) {
                    for k in 0..8 {
                        acc[k] += mm[k] * vv[k];
                        dd[k] += mm[k] * vi;
                    }
                }
                let mut sum = acc.iter().sum::<f32>();
                for (k, (mm, vv)) in rm.iter().zip(rv).enumerate() {
                    sum += mm * vv;
                    old[rest + k] += mm * vi;
                }
                *out = sum + dot(tail, &v[lo..hi]);
            }
        }
    }

    /// The product truncated to `level`, planar, by dense rows (zeros above).
    fn block(&self, level: usize, v: &[f32], r: &mut Planar) {
        let (n, k) = (self.n, (level + 1) * (level + 1));
        for (m, r) in self.matrices.iter().zip(r.iter_mut()) {
            for (i, out) in r.iter_mut().enumerate() {
                *out = if i < k { dot(&m[i * n..i * n + k], &v[..k]) } else { 0.0 };
            }
        }
    }

    /// Raises `r` (planar, at `from`) to `to`, adding the total change to `change`.
    fn raise(&self, from: usize, to: usize, v: &[f32], r: &mut Planar, d: &mut Planar, change: &mut Planar) {
        for level in from + 1..=to {
            self.increment(level, v, d);
            let used = (level + 1) * (level + 1);
            for c in 0..3 {
                for i in 0..used {
                    r[c][i] += d[c][i];
                    change[c][i] += d[c][i];
                }
            }
        }
    }
}

/// Per channel, `n` coefficients.
type Planar = [Vec<f32>; 3];

fn planar(n: usize) -> Planar {
    std::array::from_fn(|_| vec![0.0; n])
}

fn add_planar(r: &mut Planar, d: &Planar, used: usize) {
    for (r, d) in r.iter_mut().zip(d) {
        r[..used].iter_mut().zip(&d[..used]).for_each(|(r, d)| *r += d);
    }
}

/// Interleaves the first `used` coefficients of `r` into `out` (`k·3 + c`).
fn interleave(r: &Planar, used: usize, out: &mut [f32]) {
    for c in 0..3 {
        for i in 0..used {
            out[i * 3 + c] = r[c][i];
        }
    }
}

/// Dot product with eight independent sums (vectorises; the order differs from a plain sum
/// only by rounding).
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut sum = acc.iter().sum::<f32>();
    for (x, y) in ra.iter().zip(rb) {
        sum += x * y;
    }
    sum
}

/// How one vertex's glossy shading weighs its incident radiance: per band and channel
/// `w_c² f_l² / 4π`, so that `Σ_i weight[l(i)][c] ΔR_ic²` is the mean square change of its
/// glossy exit radiance over all mirror directions.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadingWeights {
    pub per_band: Vec<[f32; 3]>,
}

impl ShadingWeights {
    /// From a lobe's per-band factors `f_l` and RGB weight `w` (see [`crate::prt::GlossyLobe`]).
    pub fn new(factors: &[f64], weight: [f64; 3], bands: usize) -> Self {
        let per_band = (0..bands)
            .map(|l| {
                let f = factors.get(l).copied().unwrap_or(0.0);
                std::array::from_fn(|c| (weight[c] * weight[c] * f * f / (4.0 * std::f64::consts::PI)) as f32)
            })
            .collect();
        Self { per_band }
    }

    /// View-averaged RMS of the difference `a - b` (interleaved, the larger channel).
    pub fn rms(&self, a: &[f32], b: &[f32]) -> f64 {
        let mut sum = [0.0f64; 3];
        for (i, (x, y)) in a.chunks_exact(3).zip(b.chunks_exact(3)).enumerate() {
            let w = self.per_band[band_of(i)];
            for c in 0..3 {
                let d = (x[c] - y[c]) as f64;
                sum[c] += w[c] as f64 * d * d;
            }
        }
        sum.into_iter().fold(0.0, f64::max).sqrt()
    }

    /// View-averaged RMS of a planar change on its first `used` coefficients.
    fn rms_planar(&self, d: &Planar, used: usize) -> f64 {
        let mut worst = 0.0f32;
        for (c, d) in d.iter().enumerate() {
            let mut sum = 0.0f32;
            for (l, w) in self.per_band.iter().enumerate() {
                let band = &d[(l * l).min(used)..((l + 1) * (l + 1)).min(used)];
                sum += w[c] * band.iter().map(|x| x * x).sum::<f32>();
            }
            worst = worst.max(sum);
        }
        (worst as f64).sqrt()
    }
}

/// The knobs of the adaptive product.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveSettings {
    /// A vertex stops at the first level whose own change is below this (radiance units; the
    /// view-averaged RMS of its glossy shading). 0: the full product; infinite: the base level.
    pub threshold: f64,
    /// Highest level (`bands - 1`).
    pub level: usize,
    pub refine: bool,
    pub smooth: bool,
    /// Members of the previous ROI leave it below `hysteresis × threshold` (1: none).
    pub hysteresis: f64,
}

/// What the adaptive product did, for the UI and the benchmark.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveStats {
    /// Vertices with a glossy material (the others need no incident radiance).
    pub glossy: usize,
    /// Vertices that reached the top level (Lee's ROI).
    pub roi: usize,
    /// Vertices raised by the refinement search because it changed them significantly.
    pub refined: usize,
    /// Vertices outside the ROI given extrapolated higher bands.
    pub smoothed: usize,
    /// Multiply-adds done, and what the full product of every glossy vertex costs.
    pub macs: u64,
    pub full_macs: u64,
    /// Vertices whose level changed since the previous evaluation (when there was one).
    pub flips: Option<usize>,
    /// Glossy vertices per final level (index = level).
    pub per_level: Vec<usize>,
}

/// Per-vertex incident radiance at adaptive levels (zeros above each vertex's level).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveIncident {
    pub incident: IncidentSh,
    /// Per vertex: its level (`u8::MAX` for vertices without a glossy lobe).
    pub levels: Vec<u8>,
    pub stats: AdaptiveStats,
    /// What it was computed with (a later evaluation reuses its levels only under the same).
    pub settings: Option<AdaptiveSettings>,
}

/// Vertex neighbours in compressed rows: vertex `v`'s are `neighbours[offsets[v]..offsets[v+1]]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Adjacency {
    pub offsets: Vec<u32>,
    pub neighbours: Vec<u32>,
}
crate::stage_type!(Adjacency, "vertex adjacency", |v| (v.offsets.len() + v.neighbours.len()) * 4);

impl Adjacency {
    /// From triangle lists over one vertex array per mesh (`meshes`: vertex count and
    /// indices, in the order the receivers are flattened).
    pub fn from_triangles<'a>(meshes: impl IntoIterator<Item = (usize, &'a [u32])>) -> Self {
        let mut edges: Vec<(u32, u32)> = Vec::new();
        let mut total = 0u32;
        for (count, indices) in meshes {
            for t in indices.chunks_exact(3) {
                for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    if a != b && (a as usize) < count && (b as usize) < count {
                        edges.push((total + a, total + b));
                        edges.push((total + b, total + a));
                    }
                }
            }
            total += count as u32;
        }
        edges.sort_unstable();
        edges.dedup();
        let mut offsets = vec![0u32; total as usize + 1];
        for &(a, _) in &edges {
            offsets[a as usize + 1] += 1;
        }
        for v in 0..total as usize {
            offsets[v + 1] += offsets[v];
        }
        Self { offsets, neighbours: edges.into_iter().map(|(_, b)| b).collect() }
    }

    pub fn of(&self, v: usize) -> &[u32] {
        match (self.offsets.get(v), self.offsets.get(v + 1)) {
            (Some(&a), Some(&b)) => &self.neighbours[a as usize..b as usize],
            _ => &[],
        }
    }
}

/// The inputs of one adaptive product.
pub struct AdaptiveInputs<'a> {
    pub products: &'a LightProducts,
    /// Per vertex `stride` SH visibility coefficients (`stride ≥ products.bands²`).
    pub visibility: &'a [f32],
    pub stride: usize,
    /// Per vertex: an index into `weights`, or `None` without a glossy lobe.
    pub lobe_of: &'a [Option<u16>],
    pub weights: &'a [ShadingWeights],
    pub adjacency: &'a Adjacency,
    /// The previous evaluation's levels (under the same settings, the lighting having moved),
    /// for hysteresis and as the starting level of each vertex.
    pub previous_levels: Option<&'a [u8]>,
}

/// The full product for every glossy vertex (the reference the adaptive one is measured
/// against, and its threshold-0 limit).
pub fn full_incident(inputs: &AdaptiveInputs, cancel: &CancelToken) -> Result<IncidentSh, StageError> {
    let p = inputs.products;
    let n = p.n;
    let count = inputs.lobe_of.len();
    let mut coeffs = vec![0.0f32; count * n * 3];
    coeffs.par_chunks_mut(n * 3 * 256).enumerate().try_for_each(|(chunk, out)| {
        cancel.check()?;
        for (k, r) in out.chunks_exact_mut(n * 3).enumerate() {
            let v = chunk * 256 + k;
            if inputs.lobe_of[v].is_some() {
                p.full(&inputs.visibility[v * inputs.stride..], r);
            }
        }
        Ok::<_, StageError>(())
    })?;
    Ok(IncidentSh { bands: p.bands, coeffs })
}

/// Lee's adaptive product: multi-level filtering, ROI refinement, smoothing, hysteresis.
pub fn adaptive_incident(
    inputs: &AdaptiveInputs,
    settings: &AdaptiveSettings,
    cancel: &CancelToken,
) -> Result<AdaptiveIncident, StageError> {
    let p = inputs.products;
    let (n, top) = (p.n, p.bands.saturating_sub(1).min(settings.level));
    let count = inputs.lobe_of.len();
    let base = BASE_LEVEL.min(top);
    let mut coeffs = vec![0.0f32; count * n * 3];
    let mut levels = vec![u8::MAX; count];
    // Hysteresis: levels a vertex had in the previous evaluation are kept down to the lower
    // threshold.
    let previous = inputs.previous_levels.filter(|p| p.len() == count);
    let threshold_of = |v: usize, level: usize| {
        let kept = previous.is_some_and(|p| p[v] != u8::MAX && level <= p[v] as usize);
        if kept { settings.threshold * settings.hysteresis.clamp(0.05, 1.0) } else { settings.threshold }
    };
    // Phase 1: per vertex, raise the level while each level's change is significant. With the
    // previous evaluation's level `q` (temporal coherence: the lighting moved a little), levels
    // below `q` are taken at once as a dense block (the fast kernel) and only `q` itself and
    // above are tested, so a vertex drops at most one level per evaluation.
    let macs: u64 = coeffs
        .par_chunks_mut(n * 3 * 256)
        .zip(levels.par_chunks_mut(256))
        .enumerate()
        .map(|(chunk, (out, lv))| {
            cancel.check()?;
            let mut macs = 0u64;
            let (mut r, mut d) = (planar(n), planar(n));
            for (k, (out, level)) in out.chunks_exact_mut(n * 3).zip(lv.iter_mut()).enumerate() {
                let v = chunk * 256 + k;
                let Some(lobe) = inputs.lobe_of[v] else { continue };
                let weights = &inputs.weights[lobe as usize];
                let vis = &inputs.visibility[v * inputs.stride..];
                let start = previous
                    .map(|p| p[v])
                    .filter(|&q| q != u8::MAX)
                    .map_or(base, |q| (q as usize).clamp(base + 1, top.max(base + 1)) - 1)
                    .min(top);
                p.block(start, vis, &mut r);
                macs += LightProducts::full_macs(start);
                *level = start as u8;
                for l in start + 1..=top {
                    p.increment(l, vis, &mut d);
                    macs += LightProducts::full_macs(l) - LightProducts::full_macs(l - 1);
                    let used = (l + 1) * (l + 1);
                    if weights.rms_planar(&d, used) < threshold_of(v, l) {
                        break;
                    }
                    add_planar(&mut r, &d, used);
                    *level = l as u8;
                }
                interleave(&r, (*level as usize + 1).pow(2), out);
            }
            Ok::<_, StageError>(macs)
        })
        .try_reduce(|| 0, |a, b| Ok(a + b))?;
    let mut stats =
        AdaptiveStats { glossy: inputs.lobe_of.iter().filter(|l| l.is_some()).count(), macs, ..Default::default() };
    stats.full_macs = stats.glossy as u64 * LightProducts::full_macs(top);
    // Phase 2: breadth-first refinement. Lee searches outward from the ROI of the top level;
    // with graded orders every level's ROI has a border, so the seeds are the vertices two or
    // more levels above a neighbour. A neighbour is raised to the seed's level, and joins
    // (seeding the search further) when that changes it significantly.
    if settings.refine && top > base {
        let glossy = |u: usize| u < count && inputs.lobe_of[u].is_some();
        let mut tested = vec![false; count];
        let mut frontier: Vec<u32> = (0..count as u32)
            .filter(|&v| {
                let lv = levels[v as usize];
                glossy(v as usize)
                    && inputs
                        .adjacency
                        .of(v as usize)
                        .iter()
                        .any(|&u| glossy(u as usize) && levels[u as usize] + 2 <= lv)
            })
            .collect();
        while !frontier.is_empty() {
            cancel.check()?;
            let mut candidates: Vec<(u32, u8)> = Vec::new();
            for &v in &frontier {
                let lv = levels[v as usize];
                for &u in inputs.adjacency.of(v as usize) {
                    let u_us = u as usize;
                    if glossy(u_us) && !tested[u_us] && levels[u_us] + 2 <= lv {
                        tested[u_us] = true;
                        candidates.push((u, lv));
                    }
                }
            }
            let computed: Vec<(u32, u8, Vec<f32>, bool, u64)> = candidates
                .par_iter()
                .map_init(
                    || (planar(n), planar(n), planar(n)),
                    |(r, d, change), &(u, target)| {
                        let u = u as usize;
                        let current = &coeffs[u * n * 3..(u + 1) * n * 3];
                        let vis = &inputs.visibility[u * inputs.stride..];
                        for c in 0..3 {
                            for i in 0..n {
                                r[c][i] = current[i * 3 + c];
                            }
                            change[c].fill(0.0);
                        }
                        let from = levels[u] as usize;
                        p.raise(from, target as usize, vis, r, d, change);
                        let mut raised = vec![0.0f32; n * 3];
                        interleave(r, n, &mut raised);
                        let weights = &inputs.weights[inputs.lobe_of[u].unwrap_or(0) as usize];
                        let significant = weights.rms_planar(change, n) >= threshold_of(u, target as usize);
                        let macs = LightProducts::full_macs(target as usize) - LightProducts::full_macs(from);
                        (u as u32, target, raised, significant, macs)
                    },
                )
                .collect();
            frontier.clear();
            for (u, target, raised, significant, macs) in computed {
                let u = u as usize;
                stats.macs += macs;
                // An insignificant raise is dropped, as an insignificant level is in phase 1
                // (keeping it would ratchet the levels up from one evaluation to the next).
                if significant {
                    coeffs[u * n * 3..(u + 1) * n * 3].copy_from_slice(&raised);
                    levels[u] = target;
                    stats.refined += 1;
                    frontier.push(u as u32);
                }
            }
        }
    }
    // Phase 3: extrapolate the ROI's higher bands two tiers outward.
    if settings.smooth && top > base {
        stats.smoothed = smooth_borders(&mut coeffs, &levels, inputs.adjacency, n, top);
    }
    stats.roi = levels.iter().filter(|&&l| l as usize == top).count();
    stats.flips = inputs
        .previous_levels
        .filter(|p| p.len() == count)
        .map(|p| p.iter().zip(&levels).filter(|(a, b)| a != b).count());
    stats.per_level = vec![0; top + 1];
    for &l in &levels {
        if let Some(c) = stats.per_level.get_mut(l as usize) {
            *c += 1;
        }
    }
    Ok(AdaptiveIncident { incident: IncidentSh { bands: p.bands, coeffs }, levels, stats, settings: Some(*settings) })
}

/// Tier 1 (vertices with a neighbour of a higher level: the border of some level's ROI) gets
/// `2/3` of the mean of those neighbours' coefficients above its own level; tier 2 (their
/// other neighbours) gets `1/3` of the mean of its tier-1 neighbours' means. Returns how many
/// vertices changed.
fn smooth_borders(coeffs: &mut [f32], levels: &[u8], adjacency: &Adjacency, n: usize, top: usize) -> usize {
    let count = levels.len();
    let below_top = |v: usize| levels[v] != u8::MAX && (levels[v] as usize) < top;
    let higher = |u: usize, v: usize| levels.get(u).is_some_and(|&l| l != u8::MAX && l > levels[v]);
    // Interleaved floats from the first coefficient above a vertex's level, and up to a level.
    let above = |v: usize| (levels[v] as usize + 1).pow(2) * 3;
    let upto = |level: u8| (level as usize + 1).pow(2) * 3;
    // Every mean is computed before any vertex changes; each covers only the coefficients a
    // vertex lacks and its neighbours have (`(start, values)`).
    let snapshot: &[f32] = coeffs;
    let tier1: Vec<(usize, Band)> = (0..count)
        .into_par_iter()
        .filter(|&v| below_top(v))
        .filter_map(|v| {
            let from = above(v);
            let parts = adjacency.of(v).iter().map(|&u| u as usize).filter(|&u| higher(u, v)).map(|u| {
                let base = u * n * 3;
                (from, &snapshot[base + from..base + upto(levels[u])])
            });
            mean_of(from, parts).map(|m| (v, m))
        })
        .collect();
    let mut means: Vec<Option<usize>> = vec![None; count];
    for (k, (v, _)) in tier1.iter().enumerate() {
        means[*v] = Some(k);
    }
    let tier2: Vec<(usize, Band)> = (0..count)
        .into_par_iter()
        .filter(|&v| below_top(v) && means[v].is_none())
        .filter_map(|v| {
            let from = above(v);
            let parts =
                adjacency.of(v).iter().filter_map(|&u| means.get(u as usize).copied().flatten()).filter_map(|k| {
                    let (start, values) = &tier1[k].1;
                    let skip = from.saturating_sub(*start);
                    (skip < values.len()).then(|| (start + skip, &values[skip..]))
                });
            mean_of(from, parts).map(|m| (v, m))
        })
        .collect();
    let mut changed = 0;
    for (tier, weight) in [(&tier1, 2.0 / 3.0), (&tier2, 1.0 / 3.0)] {
        for (v, (start, values)) in tier.iter() {
            let r = &mut coeffs[v * n * 3 + start..v * n * 3 + start + values.len()];
            for (x, m) in r.iter_mut().zip(values) {
                *x += weight * m;
            }
            changed += 1;
        }
    }
    changed
}

/// A run of interleaved coefficients from a start index.
type Band = (usize, Vec<f32>);

/// The mean, from index `from`, of runs of coefficients each given with its start (missing
/// entries count as zeros); `None` without any run.
fn mean_of<'a>(from: usize, parts: impl Iterator<Item = (usize, &'a [f32])>) -> Option<Band> {
    let mut sum: Vec<f32> = Vec::new();
    let mut k = 0;
    for (start, values) in parts {
        let offset = start - from;
        if sum.len() < offset + values.len() {
            sum.resize(offset + values.len(), 0.0);
        }
        sum[offset..offset + values.len()].iter_mut().zip(values).for_each(|(s, x)| *s += x);
        k += 1;
    }
    (k > 0).then(|| (from, sum.into_iter().map(|s| s / k as f32).collect()))
}

/// Mean square of the view-averaged glossy difference between two per-vertex incident
/// radiances, over all vertices (those without a lobe count as exact) and channels.
pub fn view_mse(a: &IncidentSh, b: &IncidentSh, lobe_of: &[Option<u16>], weights: &[ShadingWeights]) -> f64 {
    let n = a.bands * a.bands * 3;
    if a.bands != b.bands || lobe_of.is_empty() || a.coeffs.len() != b.coeffs.len() {
        return f64::NAN;
    }
    let sum: f64 = (0..lobe_of.len())
        .into_par_iter()
        .map(|v| match lobe_of[v] {
            None => 0.0,
            Some(l) => {
                let rms = weights[l as usize].rms(&a.coeffs[v * n..(v + 1) * n], &b.coeffs[v * n..(v + 1) * n]);
                rms * rms
            }
        })
        .sum();
    sum / lobe_of.len() as f64
}

/// PSNR in dB of a mean square error against a peak value (`white`: the radiance the display
/// shows as full white).
pub fn view_psnr(mse: f64, white: f64) -> f64 {
    if mse <= 0.0 { f64::INFINITY } else { 10.0 * (white * white / mse).log10() }
}

#[cfg(test)]
mod tests;
