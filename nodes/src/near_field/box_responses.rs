//! Each source coefficient's response from the top face's cells, with every face coefficient
//! kept: the adjoint of Eq. 4.35–4.36 without the affine coupling coefficients.
//!
//! `G_i = Σ_k D_ik T_k` with `D_ik = ∫ Ψ_i(s v̂ + o) ψ_k(v̂) dv̂` and `T_k = ∫ T̂ ψ_k` is, by
//! Parseval (both bases orthonormal on the unit square), `G_i = ∫ Ψ_i(s v̂ + o) T̂(v̂) dv̂`.
//! `Ψ_i = ψ_{i₁} ⊗ ψ_{i₂}` is constant on at most 2 × 2 boxes of the texture, whose preimages
//! on the face are boxes too (the maps are affine per axis), and `T̂` is constant per cell. So
//! `G_i = Σ_{k₁k₂} w_{i₁}(k₁) w_{i₂}(k₂) T̂_{k₁k₂}`, with `w_i(k)` the signed length of cell `k`
//! that `ψ_i`'s pieces cover (times their height): overlaps of intervals, no closed-form
//! coupling to evaluate. Per source row `i₂`, `H_{k₁} = Σ_{k₂} w_{i₂}(k₂) T̂_{k₁k₂}` over the
//! light's footprint, then `G_i = Σ_{k₁} w_{i₁}(k₁) H_{k₁}`; both sums run over the few cells a
//! piece covers, in cell order, so a coefficient's response has the same bits whichever others
//! are computed with it.

use crate::wavelet::affine::{Affine, level_offset};

/// Reusable buffers for [`box_responses`] (one per thread).
#[derive(Default)]
pub(super) struct BoxScratch {
    /// Per source index `i₁` of this receiver: when its weights were computed (`stamp`), and
    /// where they lie in `weights` (first cell, count, offset).
    stamps: Vec<u32>,
    stamp: u32,
    spans: Vec<Span>,
    weights: Vec<f64>,
    /// One row's weights on axis 2, and its sums `H` over the footprint on axis 1.
    row: Vec<f64>,
    sums: Vec<f64>,
}

/// Where an index's weights lie: cells `first..first + len`, at `at` in the weights.
#[derive(Clone, Copy, Default)]
struct Span {
    first: u32,
    len: u32,
    at: u32,
}

/// One axis's map from the texture to the face in cell units: `v = u · scale + shift`
/// (`scale = n/s`, `shift = −o·n/s`).
#[derive(Clone, Copy)]
struct CellMap {
    scale: f64,
    shift: f64,
}

impl CellMap {
    fn new(map: Affine, n: usize) -> Self {
        let scale = n as f64 / map.s;
        Self { scale, shift: -map.o * scale }
    }
}

/// `2^{l/2}`, the height of a level-`l` Haar wavelet on the unit interval.
fn height(l: u32) -> f64 {
    let even = f64::from(1u32 << (l / 2));
    if l.is_multiple_of(2) { even } else { even * std::f64::consts::SQRT_2 }
}

/// The cells of a face of `n` cells per side that `ψ_i(s v̂ + o)` covers on one axis, and
/// their weights (appended to `out`): per piece of `ψ_i`, its height times the length of the
/// cell inside the piece's preimage. `None` where `ψ_i`'s support misses the face.
#[inline]
fn axis_weights(i: usize, map: CellMap, n: usize, out: &mut Vec<f64>) -> Option<(usize, usize)> {
    let nf = n as f64;
    let (x0, width, h) = match level_offset(i) {
        None => (0.0, 1.0, 1.0),
        Some((l, t)) => {
            let width = 1.0 / f64::from(1u32 << l);
            (f64::from(t) * width, width, height(l))
        }
    };
    // The breakpoints' preimages, clamped to the face (so non-negative: `as` is the floor).
    let at = |u: f64| (u * map.scale + map.shift).clamp(0.0, nf);
    let (v0, v2) = (at(x0), at(x0 + width));
    if v0.is_nan() || v2.is_nan() || v2 <= v0 {
        return None;
    }
    let ceil = |v: f64| v as usize + usize::from(v > (v as usize) as f64);
    let first = (v0 as usize).min(n - 1);
    let last = ceil(v2).clamp(first + 1, n);
    let start = out.len();
    out.resize(start + last - first, 0.0);
    let weights = &mut out[start..];
    // One piece `[a, b)` of height `h`: its first and last cells partly, those between whole.
    let mut piece = |a: f64, b: f64, h: f64| {
        if b <= a {
            return;
        }
        let (ka, kb) = ((a as usize).min(n - 1), (ceil(b) - 1).max(a as usize).min(n - 1));
        if ka == kb {
            weights[ka - first] += h * (b - a);
            return;
        }
        weights[ka - first] += h * ((ka + 1) as f64 - a);
        for w in &mut weights[ka + 1 - first..kb - first] {
            *w += h;
        }
        weights[kb - first] += h * (b - kb as f64);
    };
    if i == 0 {
        piece(v0, v2, 1.0 / nf);
    } else {
        let v1 = at(x0 + 0.5 * width);
        piece(v0, v1, h / nf);
        piece(v1, v2, -h / nf);
    }
    Some((first, last - first))
}

/// One receiver's top-face transport on a face of `n × n` cells: the box holding its nonzero
/// cells (`k₁ ∈ [b₀, b₁)`, `k₂ ∈ [b₂, b₃)`) and the box's cells, row `k₂` after row.
#[derive(Clone, Copy)]
pub(super) struct Cells<'a> {
    pub(super) n: usize,
    pub(super) values: &'a [f32],
    pub(super) bounds: [u16; 4],
}

/// One receiver's responses `G_j` (into `out`, in the order of `indices`, sorted by `i₂` then
/// `i₁`) to the light's coefficients under `maps`, from its top-face `cells`. Only cells inside
/// the nonzero box are summed (the others add zeros).
pub(super) fn box_responses(
    indices: &[(u16, u16)],
    maps: [Affine; 2],
    cells: Cells,
    scratch: &mut BoxScratch,
    out: &mut [f64],
) {
    let Cells { n, values, bounds } = cells;
    let [lo1, hi1, lo2, hi2] = bounds.map(usize::from);
    if hi1 <= lo1 || hi2 <= lo2 {
        out.fill(0.0);
        return;
    }
    let BoxScratch { stamps, stamp, spans, weights, row, sums } = scratch;
    let maps = maps.map(|map| CellMap::new(map, n));
    weights.clear();
    let largest = indices.iter().map(|&(i1, _)| usize::from(i1) + 1).max().unwrap_or(0);
    if stamps.len() < largest {
        stamps.resize(largest, 0);
        spans.resize(largest, Span::default());
    }
    *stamp = stamp.wrapping_add(1);
    if *stamp == 0 {
        stamps.fill(0);
        *stamp = 1;
    }
    let mut start = 0;
    while start < indices.len() {
        let i2 = indices[start].1;
        let end = start + indices[start..].iter().take_while(|c| c.1 == i2).count();
        out[start..end].fill(0.0);
        row.clear();
        // The row's cells on axis 2, within the nonzero box.
        let Some((first2, width2)) = axis_weights(usize::from(i2), maps[1], n, row) else {
            start = end;
            continue;
        };
        let (from2, to2) = (first2.max(lo2), (first2 + width2).min(hi2));
        // The cells on axis 1 this row's coefficients cover, within the nonzero box.
        let (mut lo, mut hi) = (usize::MAX, 0);
        for &(i1, _) in &indices[start..end] {
            let i1 = usize::from(i1);
            if stamps[i1] != *stamp {
                stamps[i1] = *stamp;
                let at = weights.len();
                spans[i1] = match axis_weights(i1, maps[0], n, weights) {
                    Some((first, len)) => Span { first: first as u32, len: len as u32, at: at as u32 },
                    None => Span::default(),
                };
            }
            let Span { first, len, .. } = spans[i1];
            if len > 0 {
                lo = lo.min(first as usize);
                hi = hi.max((first + len) as usize);
            }
        }
        let (lo, hi) = (lo.max(lo1), hi.min(hi1));
        if hi <= lo || to2 <= from2 {
            start = end;
            continue;
        }
        // H_{k₁} = Σ_{k₂} w_{i₂}(k₂) T̂_{k₁k₂} over those cells, one cell row at a time (each
        // H_{k₁} sums in k₂ order, whichever cells are needed beside it).
        sums.clear();
        sums.resize(hi - lo, 0.0);
        for k2 in from2..to2 {
            let w = row[k2 - first2];
            let cells_row = &values[(k2 - lo2) * (hi1 - lo1)..];
            for (h, &t) in sums.iter_mut().zip(&cells_row[lo - lo1..hi - lo1]) {
                *h += w * f64::from(t);
            }
        }
        for (j, &(i1, _)) in indices.iter().enumerate().take(end).skip(start) {
            let Span { first, len, at } = spans[usize::from(i1)];
            let (first, at) = (first as usize, at as usize);
            let (from, to) = (first.max(lo), (first + len as usize).min(hi));
            if from < to {
                let w = &weights[at + from - first..at + to - first];
                out[j] = w.iter().zip(&sums[from - lo..to - lo]).map(|(w, h)| w * h).sum();
            }
        }
        start = end;
    }
}
