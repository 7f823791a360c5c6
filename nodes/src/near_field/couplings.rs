//! The affine coupling coefficients `D_ik(s, o)` (Eq. 4.8) a receiver's two maps need, kept
//! per thread: per map its fan-outs, and the footprint lanes the adjoint sums over.

use super::*;
/// Coupling entries one thread keeps before its [`CouplingCache`] starts afresh (about 24 MB
/// with the slots; kept between evaluations).
const COUPLING_CACHE_ENTRIES: usize = 1 << 20;

/// Distinct maps one thread keeps before its [`CouplingCache`] starts afresh.
const COUPLING_CACHE_MAPS: usize = 1 << 16;

/// Where one fan-out lies: its couplings at `start..start + len` in `entries`, and the same
/// couplings laid over its map's footprint lanes at `dense` in `dense`.
#[derive(Clone, Copy, PartialEq)]
struct FanOut {
    start: u32,
    len: u32,
    dense: u32,
}

/// A map's exact bits and its face's order.
type MapKey = (u64, u64, usize);

/// A fan-out not computed yet.
const UNSET: FanOut = FanOut { start: u32::MAX, len: 0, dense: 0 };

/// The adjoint's block of lanes: footprints are padded to whole blocks, so its sums run in
/// fixed-width blocks the compiler vectorises, in the same order on every machine.
pub(super) const LANES: usize = 4;

/// `len` rounded up to whole blocks of [`LANES`].
pub(super) fn padded(len: usize) -> usize {
    len.div_ceil(LANES) * LANES
}

/// `Σ a_l b_l` over whole blocks: one partial sum per lane, then `(s₀ + s₁) + (s₂ + s₃)`.
#[inline(always)]
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut sums = [0.0; LANES];
    for (a, b) in a.as_chunks::<LANES>().0.iter().zip(b.as_chunks::<LANES>().0) {
        let (a, b) = (*a, *b);
        for l in 0..LANES {
            sums[l] += a[l] * b[l];
        }
    }
    (sums[0] + sums[1]) + (sums[2] + sums[3])
}

/// One coupling of a fan-out: the face index `k`, its lane in the map's [`Footprint`], and
/// `D_ik`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Coupling {
    pub(super) k: u32,
    pub(super) lane: u32,
    pub(super) d: f64,
}

/// Levels a [`Footprint`] holds (faces up to 2¹⁶ cells per side).
const FOOTPRINT_LEVELS: usize = 16;

/// The face indices one axis's map can carry light to: `φ`, then per level the cells from the
/// one holding the image of the texture's start to the one holding the image of its end. Every
/// source index's fan-out lies inside (its breakpoints map into that interval, monotonically),
/// so the adjoint sums over these lanes densely. Which lanes there are changes no sum, only
/// where it is stored.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Footprint {
    levels: usize,
    /// Per level, its first cell; per level, its first lane (`lane[levels]` lanes in all, none
    /// when the light misses the face).
    first: [u32; FOOTPRINT_LEVELS],
    lane: [u32; FOOTPRINT_LEVELS + 1],
}

impl Footprint {
    fn of(map: Affine, order: usize) -> Self {
        let (a, b) = ((0.0 - map.o) / map.s, (1.0 - map.o) / map.s);
        let (lo, hi) = (a.min(b), a.max(b));
        let mut footprint = Footprint::default();
        if !(hi > 0.0 && lo < 1.0) {
            return footprint;
        }
        footprint.levels = (order.max(1).ilog2() as usize).min(FOOTPRINT_LEVELS);
        footprint.lane[0] = 1;
        for l in 0..footprint.levels {
            let cells = f64::from(1u32 << l);
            let first = (lo.max(0.0) * cells).floor().min(cells - 1.0);
            let last = (hi * cells).floor().clamp(first, cells - 1.0);
            footprint.first[l] = first as u32;
            footprint.lane[l + 1] = footprint.lane[l] + (last - first) as u32 + 1;
        }
        footprint
    }

    pub(super) fn len(&self) -> usize {
        self.lane[self.levels] as usize
    }

    /// The lane of face index `k` (inside the footprint).
    fn lane(&self, k: usize) -> u32 {
        match level_offset(k) {
            None => 0,
            Some((l, t)) => self.lane[l as usize] + t - self.first[l as usize],
        }
    }

    /// The face index of every lane, in order.
    pub(super) fn indices(&self, out: &mut Vec<u32>) {
        out.clear();
        if self.len() == 0 {
            return;
        }
        out.push(0);
        for l in 0..self.levels {
            let start = (1u32 << l) + self.first[l];
            out.extend(start..start + self.lane[l + 1] - self.lane[l]);
        }
    }
}

/// One axis's fan-out and couplings `(k, D_ik(s, o))` per exact map `(s, o)` and source index
/// `i`: receivers that share a depth and a coordinate along an axis (a floor's rows and
/// columns, or any receivers under the table couplings) share them, so they are computed once.
/// A receiver looks its two maps up once ([`Self::receiver_slots`]); each fan-out is then an
/// array index. Cached values are the computed ones, bit for bit.
#[derive(Default)]
pub(super) struct CouplingCache {
    slots: rustc_hash::FxHashMap<MapKey, u32>,
    /// Per slot: its map, its footprint and, per source index, where its fan-out lies.
    maps: Vec<Affine>,
    footprints: Vec<Footprint>,
    ranges: Vec<Vec<FanOut>>,
    predictions: Vec<Option<(u64, f64)>>,
    entries: Vec<Coupling>,
    /// Each fan-out over its footprint's lanes, [`padded`].
    dense: Vec<f64>,
    targets: Vec<usize>,
    /// Per axis, the last map looked up and its slot: neighbouring receivers often share one.
    recent: [Option<(MapKey, u32)>; 2],
}

impl CouplingCache {
    /// The slots of one receiver's two maps on a face of `order`, valid until the next call
    /// (the only place the cache starts afresh, its memory given back).
    pub(super) fn receiver_slots(&mut self, maps: [Affine; 2], order: usize) -> [u32; 2] {
        if self.entries.len() > COUPLING_CACHE_ENTRIES
            || self.dense.len() > COUPLING_CACHE_ENTRIES
            || self.maps.len() > COUPLING_CACHE_MAPS
        {
            *self = Self { targets: std::mem::take(&mut self.targets), ..Default::default() };
        }
        let mut slots = [0; 2];
        for (q, map) in maps.into_iter().enumerate() {
            let key = (map.s.to_bits(), map.o.to_bits(), order);
            if let Some((recent, slot)) = self.recent[q]
                && recent == key
            {
                slots[q] = slot;
                continue;
            }
            let next = self.maps.len() as u32;
            let slot = *self.slots.entry(key).or_insert(next);
            if slot == next {
                self.maps.push(map);
                self.footprints.push(Footprint::of(map, order));
                self.ranges.push(Vec::new());
                self.predictions.push(None);
            }
            self.recent[q] = Some((key, slot));
            slots[q] = slot;
        }
        slots
    }

    /// The face indices (as bits) where the slot's constant-light prediction `D_{φk}` is
    /// nonzero, and its smallest magnitude there (faces up to 64 cells per side).
    pub(super) fn nonzero_predictions(&mut self, slot: u32, order: usize) -> (u64, f64) {
        if let Some(predictions) = self.predictions[slot as usize] {
            return predictions;
        }
        let mut predictions = (0u64, f64::INFINITY);
        for c in self.fan_out(slot, 0, order) {
            if c.d != 0.0 {
                predictions.0 |= 1 << c.k;
                predictions.1 = predictions.1.min(c.d.abs());
            }
        }
        self.predictions[slot as usize] = Some(predictions);
        predictions
    }

    /// The fan-out of source index `i` under the map in `slot`.
    #[inline]
    pub(super) fn fan_out(&mut self, slot: u32, i: usize, order: usize) -> &[Coupling] {
        let FanOut { start, len, .. } = self.located(slot, i, order);
        &self.entries[start as usize..(start + len) as usize]
    }

    /// [`Self::fan_out`] over the slot's footprint lanes, zero elsewhere ([`padded`]).
    #[inline]
    pub(super) fn dense_fan_out(&mut self, slot: u32, i: usize, order: usize) -> &[f64] {
        let width = padded(self.footprints[slot as usize].len());
        let FanOut { dense, .. } = self.located(slot, i, order);
        &self.dense[dense as usize..dense as usize + width]
    }

    #[inline]
    fn located(&mut self, slot: u32, i: usize, order: usize) -> FanOut {
        match self.ranges[slot as usize].get(i) {
            Some(&fan_out) if fan_out != UNSET => fan_out,
            _ => self.compute(slot, i, order),
        }
    }

    #[cold]
    fn compute(&mut self, slot: u32, i: usize, order: usize) -> FanOut {
        let (map, footprint) = (self.maps[slot as usize], self.footprints[slot as usize]);
        map.targets(i, order, &mut self.targets);
        let start = self.entries.len();
        self.entries.extend(self.targets.iter().map(|&k| Coupling {
            k: k as u32,
            lane: footprint.lane(k),
            d: map.coupling(i, k),
        }));
        let dense = self.dense.len();
        self.dense.resize(dense + padded(footprint.len()), 0.0);
        for c in &self.entries[start..] {
            self.dense[dense + c.lane as usize] = c.d;
        }
        let fan_out = FanOut { start: start as u32, len: self.targets.len() as u32, dense: dense as u32 };
        let ranges = &mut self.ranges[slot as usize];
        if ranges.len() <= i {
            ranges.resize(i + 1, UNSET);
        }
        ranges[i] = fan_out;
        fan_out
    }

    pub(super) fn footprint(&self, slot: u32) -> Footprint {
        self.footprints[slot as usize]
    }
}
