//! Which top-face coefficients the shading keeps (Sun 2008 §4.5.5): the constant-light
//! prediction `L̃_k = D_{φk₁} D_{φk₂}` (Eq. 4.38), ties coarse first, as a ranking and as the
//! coarse-first fill the shading counts without ranking; and the largest propagated `|L_k|`.

use super::*;

impl Propagation {
    /// `coarse_first` and `coarse_rank` for an `n × n` face.
    pub(super) fn coarse_orders(&mut self, n: usize) {
        if self.coarse_first.len() != n * n {
            self.coarse_first = coarse_first_order(n);
            self.coarse_rank = vec![0; n * n];
            for (rank, &k) in self.coarse_first.iter().enumerate() {
                self.coarse_rank[k] = rank as u32;
            }
        }
    }
}

/// The kept targets of the predicted set, as a test on `(k₁, k₂)`.
#[derive(Clone, Copy)]
pub(super) enum KeptTargets {
    All,
    /// The nonzero predictions (per axis, the face indices whose `D_{φk}` is nonzero as bits)
    /// and the zero ones ranked before `cutoff` in coarse-first order: the set when the
    /// nonzero predictions number no more than the kept count, found without ranking them.
    Fill {
        nonzero: [u64; 2],
        cutoff: u32,
    },
    /// Those marked in `Propagation::selected`.
    Selected,
}

impl KeptTargets {
    /// Whether face index `k = k₂·n + k₁` is kept (`coarse_rank` and `selected` from the
    /// [`Propagation`] that found the set).
    #[inline(always)]
    pub(super) fn keeps(self, k1: u32, k2: u32, k: usize, coarse_rank: &[u32], selected: &FaceSet) -> bool {
        match self {
            KeptTargets::All => true,
            KeptTargets::Fill { nonzero, cutoff } => {
                (nonzero[0] >> k1 & 1 != 0 && nonzero[1] >> k2 & 1 != 0) || coarse_rank[k] < cutoff
            }
            KeptTargets::Selected => selected.contains(k),
        }
    }
}

/// The predicted targets for the maps in `slots`: [`predicted_target_set`]'s set (asserted
/// equal), as the fill of the coarse-first order where it can be.
pub(super) fn kept_targets(slots: [u32; 2], n: usize, fraction: f64, scratch: &mut Propagation) -> KeptTargets {
    let count = target_count(n, fraction);
    scratch.coarse_orders(n);
    if n <= 64 && n.is_power_of_two() {
        let [(nonzero0, smallest0), (nonzero1, smallest1)] =
            slots.map(|slot| scratch.couplings.nonzero_predictions(slot, n));
        let (nonzero, smallest) = ([nonzero0, nonzero1], [smallest0, smallest1]);
        let predicted = nonzero[0].count_ones() as usize * nonzero[1].count_ones() as usize;
        // Every nonzero prediction kept (none rounds to zero), then zero ones, coarse first.
        if predicted <= count && smallest[0] * smallest[1] > 0.0 {
            let cutoff = fill_cutoff(nonzero, n, count - predicted, &scratch.coarse_rank);
            return KeptTargets::Fill { nonzero, cutoff };
        }
    }
    predicted_target_set_at(slots, n, fraction, scratch);
    KeptTargets::Selected
}

/// The coarse-first rank just past the `fill`-th face index whose prediction is zero (0 for
/// none), given the axes' nonzero predictions as bits. Counted per level, then per row, then
/// per column of [`fill_coarse_first`]'s order, never walking the face.
fn fill_cutoff(nonzero: [u64; 2], n: usize, fill: usize, coarse_rank: &[u32]) -> u32 {
    if fill == 0 {
        return 0;
    }
    // Nonzero predictions on axis `q` among the indices below `span`.
    let below = |q: usize, span: usize| {
        let bits = if span >= 64 { u64::MAX } else { (1u64 << span) - 1 };
        (nonzero[q] & bits).count_ones() as usize
    };
    let mut before = 0;
    for c in 0..=n.max(1).ilog2() {
        // Coarseness at most `c`: indices below `span` on each axis.
        let span = (1usize << c).min(n);
        let zero = span * span - below(0, span) * below(1, span);
        if zero >= fill {
            let inner = if c == 0 { 0 } else { (1usize << (c - 1)).min(n) };
            let mut left = fill - before;
            for k2 in 0..span {
                // The row's indices of coarseness exactly `c`.
                let first = if k2 >= inner { 0 } else { inner };
                let row_nonzero = nonzero[1] >> k2 & 1 != 0;
                let zero_in_row = (span - first) - if row_nonzero { below(0, span) - below(0, first) } else { 0 };
                if left > zero_in_row {
                    left -= zero_in_row;
                    continue;
                }
                for k1 in first..span {
                    if !(row_nonzero && nonzero[0] >> k1 & 1 != 0) {
                        left -= 1;
                        if left == 0 {
                            return coarse_rank[k2 * n + k1] + 1;
                        }
                    }
                }
            }
        }
        before = zero;
    }
    (n * n) as u32
}

/// Coarseness of a 1D index: 0 for `φ`, `l + 1` for a wavelet at level `l`.
fn coarseness(k: usize) -> u32 {
    level_offset(k).map_or(0, |(l, _)| l + 1)
}

/// The face coefficients `fraction` keeps, by the constant-light prediction (Eq. 4.38):
/// `|D_{φk₁}(s₁, o₁) D_{φk₂}(s₂, o₂)|` largest first, ties (the zero predictions among
/// them) coarse first, then by index. Only the at most `(2L + 1)²` nonzero predictions are
/// ranked; the rest follow in coarse-first order.
pub fn predicted_targets(maps: [Affine; 2], face_order: usize, fraction: f64) -> Vec<usize> {
    let n = face_order;
    let count = target_count(n, fraction);
    let mut ranked = Vec::new();
    let mut couplings = CouplingCache::default();
    let slots = couplings.receiver_slots(maps, n);
    rank_predictions(slots, n, &mut couplings, &mut Vec::new(), &mut ranked);
    ranked.sort_by(by_prediction);
    let mut kept: Vec<usize> = ranked.iter().take(count).map(|r| r.2).collect();
    fill_coarse_first(&mut kept, count, n, &mut Vec::new());
    kept
}

fn target_count(n: usize, fraction: f64) -> usize {
    ((fraction.clamp(0.0, 1.0) * (n * n) as f64).round() as usize).min(n * n)
}

/// Largest prediction first, then coarse first, then by index: a total order.
fn by_prediction(a: &(f64, u32, usize), b: &(f64, u32, usize)) -> std::cmp::Ordering {
    b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2))
}

/// Every nonzero prediction `(|D_{φk₁} D_{φk₂}|, coarseness, k₂·n + k₁)` for the maps in
/// `slots`, unordered.
fn rank_predictions(
    slots: [u32; 2],
    n: usize,
    couplings: &mut CouplingCache,
    axis0: &mut Vec<(usize, f64, u32)>,
    ranked: &mut Vec<(f64, u32, usize)>,
) {
    ranked.clear();
    axis0.clear();
    axis0.extend(
        couplings
            .fan_out(slots[0], 0, n)
            .iter()
            .filter(|c| c.d != 0.0)
            .map(|c| (c.k as usize, c.d.abs(), coarseness(c.k as usize))),
    );
    for &Coupling { k: k2, d: d2, .. } in couplings.fan_out(slots[1], 0, n) {
        let k2 = k2 as usize;
        let (d2, c2) = (d2.abs(), coarseness(k2));
        if d2 > 0.0 {
            ranked.extend(axis0.iter().map(|&(k1, d1, c1)| (d1 * d2, c1.max(c2), k2 * n + k1)));
        }
    }
    ranked.retain(|r| r.0 > 0.0);
}

/// Every index of an `n × n` face in [`fill_coarse_first`]'s order.
fn coarse_first_order(n: usize) -> Vec<usize> {
    let mut order = Vec::with_capacity(n * n);
    fill_coarse_first(&mut order, n * n, n, &mut Vec::new());
    order
}

/// Tops `kept` up to `count` with the indices it lacks, coarse first then in index order.
fn fill_coarse_first(kept: &mut Vec<usize>, count: usize, n: usize, chosen: &mut Vec<bool>) {
    if kept.len() >= count {
        return;
    }
    chosen.clear();
    chosen.resize(n * n, false);
    kept.iter().for_each(|&k| chosen[k] = true);
    'fill: for c in 0..=n.max(1).ilog2() {
        let span = (1usize << c).min(n);
        for k2 in 0..span {
            for k1 in 0..span {
                if coarseness(k1).max(coarseness(k2)) != c || chosen[k2 * n + k1] {
                    continue;
                }
                kept.push(k2 * n + k1);
                if kept.len() == count {
                    break 'fill;
                }
            }
        }
    }
}

/// The `fraction` of face coefficients with the largest propagated `|L_k|` (ties by index),
/// marked in `scratch.selected`.
pub(super) fn largest_target_set(n: usize, fraction: f64, scratch: &mut Propagation) {
    let count = target_count(n, fraction);
    let Propagation { ranked, selected, light, .. } = scratch;
    ranked.clear();
    ranked.extend(light.iter().enumerate().map(|(k, l)| (l[0].abs() + l[1].abs() + l[2].abs(), 0, k)));
    if ranked.len() > count && count > 0 {
        ranked.select_nth_unstable_by(count - 1, by_prediction);
    }
    selected.clear(n * n);
    ranked.iter().take(count).for_each(|r| {
        selected.insert(r.2);
    });
}

/// [`predicted_targets`] as a set, into `scratch`'s buffers: `kept` (in no order) and the
/// mask `selected` over the face. It selects the kept predictions without ranking them all.
#[cfg(test)]
pub(super) fn predicted_target_set(maps: [Affine; 2], n: usize, fraction: f64, scratch: &mut Propagation) {
    let slots = scratch.couplings.receiver_slots(maps, n);
    predicted_target_set_at(slots, n, fraction, scratch);
}

/// [`predicted_target_set`] for the maps in `slots`.
fn predicted_target_set_at(slots: [u32; 2], n: usize, fraction: f64, scratch: &mut Propagation) {
    let count = target_count(n, fraction);
    scratch.coarse_orders(n);
    let Propagation { couplings, axis, ranked, kept, selected, coarse_first, .. } = scratch;
    rank_predictions(slots, n, couplings, axis, ranked);
    if ranked.len() > count && count > 0 {
        ranked.select_nth_unstable_by(count - 1, by_prediction);
    }
    kept.clear();
    selected.clear(n * n);
    for r in ranked.iter().take(count) {
        kept.push(r.2);
        selected.insert(r.2);
    }
    for &k in coarse_first.iter() {
        if kept.len() >= count {
            break;
        }
        if selected.insert(k) {
            kept.push(k);
        }
    }
}
