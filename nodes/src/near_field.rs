//! Near-field relighting by textured planar area lights (Sun 2008 §4.5), on the affine Haar
//! products of [`crate::wavelet::affine`].
//!
//! - **Light.** A horizontal rectangle at height `h`, facing down, spanning `[x₀, x₀ + w₁]` ×
//!   `[z₀, z₀ + w₂]`, with an angularly uniform radiance texture `F` on `[0, 1)²`.
//! - **Top face (§4.5.4).** Directions from a receiver are parameterised by their intercept
//!   `v` with the plane one unit above it: `ω = (v₁, 1, v₂)/√(1 + |v|²)`. The face keeps
//!   `v ∈ [−a/2, a/2]²` (`a` the face size) at `order²` cells, `v̂ = v/a + ½ ∈ [0, 1)²`.
//! - **Propagation (Eq. 4.34).** A receiver at depth `z = h − y` below the light sees
//!   `L(v̂) = F(s v̂ + o)` per axis with `s = z a / w`, `o = (x − x₀ − z a/2)/w` (the notes'
//!   normalisation), so its light on the face is `L_k = Σ_i F_i D_ik(s, o)` (Eq. 4.35).
//! - **Transport.** `T̂(v̂) = a² V(ω) max(0, ω·n) (1 + |v|²)^{−3/2}` per cell (the Jacobian
//!   `dω = a² dv̂ / (1 + |v|²)^{3/2}` folded in), in 2D Haar. The irradiance is then the
//!   double product `E = Σ_k L_k T_k` (Eq. 4.36); a Lambertian surface reflects `ρ E / π`.
//! - **Compression (§4.5.5).** The source keeps its largest coefficients (per channel, by
//!   magnitude, which is L²-optimal for an orthonormal basis); the target keeps all nonzero
//!   `L_k` (found by the breakpoint fan-out) or a fraction picked by the constant-light
//!   prediction `L̃_k = D_{φk₁} D_{φk₂}` (Eq. 4.38), ties coarse first.

use crate::wavelet::affine::{Affine, CouplingGrid, haar_forward_2d, level_offset};
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Cells per side of the receivers' top face (the thesis's 32 × 32).
pub const FACE_ORDER: usize = 32;

/// The expanded top face: `order × order` cells over `v ∈ [−size/2, size/2]²`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TopFace {
    pub order: usize,
    pub size: f64,
}

impl TopFace {
    /// The plane-intercept `v` at face coordinates `v̂ ∈ [0, 1)²`.
    fn intercept(&self, v_hat: [f64; 2]) -> [f64; 2] {
        v_hat.map(|c| (c - 0.5) * self.size)
    }

    /// The centre `v̂` of cell `c` (row-major, `c = row · order + column`).
    fn cell_centre(&self, c: usize) -> [f64; 2] {
        let n = self.order;
        [((c % n) as f64 + 0.5) / n as f64, ((c / n) as f64 + 0.5) / n as f64]
    }

    /// `T̂` at `v̂` for a receiver with normal `n`, before visibility.
    fn weight(&self, v_hat: [f64; 2], normal: DVec3) -> (DVec3, f64) {
        let [v1, v2] = self.intercept(v_hat);
        let q = 1.0 + v1 * v1 + v2 * v2;
        let direction = DVec3::new(v1, 1.0, v2) / q.sqrt();
        let cosine = direction.dot(normal).max(0.0);
        (direction, self.size * self.size * cosine * q.powf(-1.5))
    }
}

/// Per receiver, the transport on the top face in 2D Haar (`order²` coefficients each).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaceTransport {
    pub face: TopFace,
    pub coefficients: Vec<f32>,
}

crate::stage_type!(FaceTransport, "top-face transport", |v| v.coefficients.len() * 4 + 32);

impl FaceTransport {
    pub fn receivers(&self) -> usize {
        self.coefficients.len() / (self.face.order * self.face.order).max(1)
    }

    fn of(&self, receiver: usize) -> &[f32] {
        let n = self.face.order * self.face.order;
        &self.coefficients[receiver * n..(receiver + 1) * n]
    }
}

/// The transport of each receiver (`positions`, unit `normals`): each cell's `T̂` averaged over
/// `samples²` points, the points' rays tested with `unoccluded(origin, direction)`.
pub fn face_transport(
    face: TopFace,
    positions: &[DVec3],
    normals: &[DVec3],
    samples: usize,
    unoccluded: impl Fn(DVec3, DVec3) -> bool + Sync,
) -> FaceTransport {
    let n = face.order;
    let samples = samples.max(1);
    let coefficients = positions
        .par_iter()
        .zip(normals)
        .flat_map_iter(|(&x, &normal)| {
            let mut cells = vec![0.0; n * n];
            for (c, cell) in cells.iter_mut().enumerate() {
                let mut sum = 0.0;
                for k in 0..samples * samples {
                    let v_hat = [
                        ((c % n) as f64 + ((k % samples) as f64 + 0.5) / samples as f64) / n as f64,
                        ((c / n) as f64 + ((k / samples) as f64 + 0.5) / samples as f64) / n as f64,
                    ];
                    let (direction, weight) = face.weight(v_hat, normal);
                    if weight > 0.0 && unoccluded(x, direction) {
                        sum += weight;
                    }
                }
                *cell = sum / (samples * samples) as f64;
            }
            haar_forward_2d(&mut cells, n);
            cells.into_iter().map(|c| c as f32)
        })
        .collect();
    FaceTransport { face, coefficients }
}

/// Per receiver, the top-face cells light can arrive through: above the receiver's horizon and
/// unoccluded, one ray per cell centre, a bit per cell. Transports for any weight follow from
/// it without new rays ([`visible_transport`]): the diffuse one, and a glossy one per view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaceVisibility {
    pub face: TopFace,
    pub bits: Vec<u64>,
}

impl FaceVisibility {
    fn words(face: &TopFace) -> usize {
        (face.order * face.order).div_ceil(64)
    }

    fn visible(&self, receiver: usize, cell: usize) -> bool {
        self.bits[receiver * Self::words(&self.face) + cell / 64] >> (cell % 64) & 1 == 1
    }
}

/// The cells of each receiver (`origins`, unit `normals`) that see past `unoccluded(origin,
/// direction)`, cells below the horizon left unset without a ray.
pub fn face_visibility(
    face: TopFace,
    origins: &[DVec3],
    normals: &[DVec3],
    unoccluded: impl Fn(DVec3, DVec3) -> bool + Sync,
) -> FaceVisibility {
    let n = face.order;
    let words = FaceVisibility::words(&face);
    let bits = origins
        .par_iter()
        .zip(normals)
        .flat_map_iter(|(&x, &normal)| {
            let mut bits = vec![0u64; words];
            for c in 0..n * n {
                let (direction, weight) = face.weight(face.cell_centre(c), normal);
                if weight > 0.0 && unoccluded(x, direction) {
                    bits[c / 64] |= 1 << (c % 64);
                }
            }
            bits
        })
        .collect();
    FaceVisibility { face, bits }
}

/// The transport of `receivers` (indices into `visibility` and `normals`) with a per-direction
/// factor: `T̂(v̂) = a² V(ω) factor(r, ω) max(0, ω·n) (1 + |v|²)^{−3/2}` at each cell centre, in
/// 2D Haar (`order²` values per receiver, in order). `factor` 1 gives the irradiance transport
/// ([`face_transport`] with one sample per cell, the same bits); the specular lobe toward a
/// viewer gives the radiance a glossy surface reflects toward it (Sun 2008 §4.9).
pub fn visible_transport(
    visibility: &FaceVisibility,
    receivers: std::ops::Range<usize>,
    normals: &[DVec3],
    factor: impl Fn(usize, DVec3) -> f64 + Sync,
) -> Vec<f32> {
    let face = visibility.face;
    let n = face.order;
    receivers
        .into_par_iter()
        .flat_map_iter(|r| {
            let mut cells = vec![0.0; n * n];
            for (c, cell) in cells.iter_mut().enumerate() {
                if visibility.visible(r, c) {
                    let (direction, weight) = face.weight(face.cell_centre(c), normals[r]);
                    *cell = weight * factor(r, direction);
                }
            }
            haar_forward_2d(&mut cells, n);
            cells.into_iter().map(|c| c as f32)
        })
        .collect()
}

/// A light texture's kept Haar coefficients: `((i₁, i₂), rgb)`, the union of each channel's
/// largest, in index order.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LightSource {
    pub order: usize,
    pub coefficients: Vec<((u16, u16), [f32; 3])>,
    /// `‖F_kept‖² / ‖F‖²` over the three channels (Parseval).
    pub retained_energy: f64,
}

crate::stage_type!(LightSource, "area light coefficients", |v| v.coefficients.len() * 16 + 32);

/// The 2D Haar transform of an `order × order` linear RGB texture (row `y` along `z`), keeping
/// each channel's `keep` largest coefficients (all when `keep ≥ order²`).
pub fn light_source(texture: &[[f64; 3]], order: usize, keep: usize) -> LightSource {
    let mut channels: [Vec<f64>; 3] = std::array::from_fn(|c| texture.iter().map(|t| t[c]).collect());
    let mut kept = vec![false; order * order];
    let (mut total, mut retained) = (0.0, 0.0);
    for channel in &mut channels {
        haar_forward_2d(channel, order);
        let mut ranked: Vec<usize> = (0..channel.len()).filter(|&i| channel[i] != 0.0).collect();
        ranked.sort_by(|&a, &b| channel[b].abs().total_cmp(&channel[a].abs()).then(a.cmp(&b)));
        for &i in ranked.iter().take(keep) {
            kept[i] = true;
        }
        total += channel.iter().map(|v| v * v).sum::<f64>();
    }
    let coefficients: Vec<((u16, u16), [f32; 3])> = (0..order * order)
        .filter(|&i| kept[i])
        .map(|i| ((i % order) as u16, (i / order) as u16))
        .map(|(i1, i2)| {
            let k = usize::from(i2) * order + usize::from(i1);
            ((i1, i2), std::array::from_fn(|c| channels[c][k] as f32))
        })
        .collect();
    for channel in &channels {
        retained += (0..order * order).filter(|&i| kept[i]).map(|i| channel[i] * channel[i]).sum::<f64>();
    }
    let retained_energy = if total > 0.0 { retained / total } else { 1.0 };
    LightSource { order, coefficients, retained_energy }
}

/// Where a light is: its plane's height and its rectangle's corner and extent on `x` and `z`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightPlacement {
    pub height: f64,
    pub corner: [f64; 2],
    pub extent: [f64; 2],
}

impl LightPlacement {
    /// A `width × depth` light centred over `(x, z)`.
    pub fn centred(height: f64, centre: [f64; 2], size: [f64; 2]) -> Self {
        Self { height, corner: [centre[0] - size[0] / 2.0, centre[1] - size[1] / 2.0], extent: size }
    }

    /// The per-axis affine maps from a receiver's top face to the texture; `None` for a
    /// receiver on or above the light's plane (it receives nothing).
    pub fn maps(&self, face: &TopFace, x: DVec3) -> Option<[Affine; 2]> {
        let depth = self.height - x.y;
        if depth <= 0.0 {
            return None;
        }
        let along = [x.x, x.z];
        Some(std::array::from_fn(|q| Affine {
            s: depth * face.size / self.extent[q],
            o: (along[q] - self.corner[q] - depth * face.size / 2.0) / self.extent[q],
        }))
    }
}

/// Which propagated coefficients `L_k` enter the shading.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum TargetKeep {
    /// Every nonzero `L_k`.
    All,
    /// This fraction of the face's coefficients, ranked by the constant-light prediction.
    Predicted(f64),
    /// This fraction, the largest propagated `|L_k|` (summed over the channels): every `L_k`
    /// is computed first, so it costs the full propagation.
    Largest(f64),
}

/// Where the shading takes its affine coupling coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum AccMode {
    /// Exactly, at each receiver's own maps (closed form, no quantisation).
    #[default]
    Analytic,
    /// At the nearest point of a [`CouplingGrid`] of this many steps: nearby receivers share
    /// their couplings, at the cost of a small shift of the light.
    Table(u32),
}

impl AccMode {
    /// The maps the couplings are taken at.
    pub fn maps(self, maps: [Affine; 2]) -> [Affine; 2] {
        match self {
            AccMode::Analytic => maps,
            AccMode::Table(steps) => maps.map(|m| CouplingGrid { steps }.snap(m)),
        }
    }
}

/// How a light is shaded: which top-face coefficients, and how the couplings are found.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Shading {
    pub keep: TargetKeep,
    pub acc: AccMode,
}

impl From<TargetKeep> for Shading {
    fn from(keep: TargetKeep) -> Self {
        Shading { keep, acc: AccMode::Analytic }
    }
}

/// Reusable buffers for [`propagate_into`] (one per thread).
pub struct Propagation {
    step1: Vec<[f64; 3]>,
    touched: Vec<bool>,
    rows: Vec<usize>,
    couplings: CouplingCache,
    axis: Vec<(usize, f64, u32)>,
    ranked: Vec<(f64, u32, usize)>,
    kept: Vec<usize>,
    selected: FaceSet,
    /// Every face index, coarse first then in index order: the predicted set's fill order.
    coarse_first: Vec<usize>,
    /// Each face index's position in `coarse_first`.
    coarse_rank: Vec<u32>,
    /// The adjoint's lanes: per axis the face indices of the receiver's [`Footprint`], the kept
    /// transport over them (`k₂` lanes of `k₁` lanes) and one row's partial sums per `k₁` lane.
    lanes: [Vec<u32>; 2],
    kept_transport: Vec<f64>,
    row_sums: Vec<f64>,
    /// One receiver's responses, when [`irradiance`] sums them at once.
    responses: Vec<f64>,
    /// `L_{k₁k₂}` at `k₂·order + k₁`, valid after [`propagate_into`].
    pub light: Vec<[f64; 3]>,
}

impl Propagation {
    pub fn new(face_order: usize) -> Self {
        Self {
            step1: vec![[0.0; 3]; face_order],
            touched: vec![false; face_order],
            rows: Vec::new(),
            couplings: CouplingCache::default(),
            axis: Vec::new(),
            ranked: Vec::new(),
            kept: Vec::new(),
            selected: FaceSet::default(),
            coarse_first: Vec::new(),
            coarse_rank: Vec::new(),
            lanes: [Vec::new(), Vec::new()],
            kept_transport: Vec::new(),
            row_sums: Vec::new(),
            responses: Vec::new(),
            light: vec![[0.0; 3]; face_order * face_order],
        }
    }
}

impl Propagation {
    /// `coarse_first` and `coarse_rank` for an `n × n` face.
    fn coarse_orders(&mut self, n: usize) {
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
enum KeptTargets {
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
    fn keeps(self, k1: u32, k2: u32, k: usize, coarse_rank: &[u32], selected: &FaceSet) -> bool {
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
fn kept_targets(slots: [u32; 2], n: usize, fraction: f64, scratch: &mut Propagation) -> KeptTargets {
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

/// A set of indices below a size, emptied in O(1) by moving to a new stamp.
#[derive(Default)]
struct FaceSet {
    stamps: Vec<u32>,
    stamp: u32,
}

impl FaceSet {
    fn clear(&mut self, size: usize) {
        if self.stamps.len() != size {
            self.stamps = vec![0; size];
            self.stamp = 0;
        }
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.stamps.fill(0);
            self.stamp = 1;
        }
    }

    /// Whether `k` was new.
    fn insert(&mut self, k: usize) -> bool {
        let new = self.stamps[k] != self.stamp;
        self.stamps[k] = self.stamp;
        new
    }

    fn contains(&self, k: usize) -> bool {
        self.stamps[k] == self.stamp
    }
}

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
const LANES: usize = 4;

/// `len` rounded up to whole blocks of [`LANES`].
fn padded(len: usize) -> usize {
    len.div_ceil(LANES) * LANES
}

/// `Σ a_l b_l` over whole blocks: one partial sum per lane, then `(s₀ + s₁) + (s₂ + s₃)`.
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
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
struct Coupling {
    k: u32,
    lane: u32,
    d: f64,
}

/// Levels a [`Footprint`] holds (faces up to 2¹⁶ cells per side).
const FOOTPRINT_LEVELS: usize = 16;

/// The face indices one axis's map can carry light to: `φ`, then per level the cells from the
/// one holding the image of the texture's start to the one holding the image of its end. Every
/// source index's fan-out lies inside (its breakpoints map into that interval, monotonically),
/// so the adjoint sums over these lanes densely. Which lanes there are changes no sum, only
/// where it is stored.
#[derive(Clone, Copy, Debug, Default)]
struct Footprint {
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

    fn len(&self) -> usize {
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
    fn indices(&self, out: &mut Vec<u32>) {
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
struct CouplingCache {
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
    fn receiver_slots(&mut self, maps: [Affine; 2], order: usize) -> [u32; 2] {
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
    fn nonzero_predictions(&mut self, slot: u32, order: usize) -> (u64, f64) {
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
    fn fan_out(&mut self, slot: u32, i: usize, order: usize) -> &[Coupling] {
        let FanOut { start, len, .. } = self.located(slot, i, order);
        &self.entries[start as usize..(start + len) as usize]
    }

    /// [`Self::fan_out`] over the slot's footprint lanes, zero elsewhere ([`padded`]).
    #[inline]
    fn dense_fan_out(&mut self, slot: u32, i: usize, order: usize) -> &[f64] {
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

    fn footprint(&self, slot: u32) -> Footprint {
        self.footprints[slot as usize]
    }
}

/// The light on a receiver's top face, `L_{k₁k₂}` for every face coefficient
/// (`k₂·order + k₁`), by the two separable steps of §4.5.5 over the fan-out only.
pub fn propagate(source: &LightSource, maps: [Affine; 2], face_order: usize) -> Vec<[f64; 3]> {
    let mut scratch = Propagation::new(face_order);
    propagate_into(source, maps, face_order, &mut scratch);
    scratch.light
}

/// [`propagate`] into reused buffers.
pub fn propagate_into(source: &LightSource, maps: [Affine; 2], face_order: usize, scratch: &mut Propagation) {
    let n = face_order;
    let Propagation { step1, touched, rows, couplings, light, .. } = scratch;
    light.iter_mut().for_each(|l| *l = [0.0; 3]);
    // One source row `i₂` at a time (the coefficients come in index order, so grouped by
    // `i₂`; any order gives the same sums, this one the same bits on every run).
    let coefficients = &source.coefficients;
    let slots = couplings.receiver_slots(maps, n);
    let mut start = 0;
    while start < coefficients.len() {
        let i2 = coefficients[start].0.1;
        let end = start + coefficients[start..].iter().take_while(|c| c.0.1 == i2).count();
        // Step 1: Z_{i₂k₁} = Σ_{i₁} F_{i₁i₂} D_{i₁k₁}; `rows` lists the `k₁` it touched.
        rows.clear();
        for &((i1, _), f) in &coefficients[start..end] {
            for &Coupling { k: k1, d, .. } in couplings.fan_out(slots[0], usize::from(i1), n) {
                let k1 = k1 as usize;
                if !touched[k1] {
                    touched[k1] = true;
                    rows.push(k1);
                }
                for c in 0..3 {
                    step1[k1][c] += d * f64::from(f[c]);
                }
            }
        }
        // Step 2: L_{k₁k₂} += Z_{i₂k₁} D_{i₂k₂}, by ascending `k₁`.
        rows.sort_unstable();
        let row = couplings.fan_out(slots[1], usize::from(i2), n);
        for &k1 in rows.iter() {
            let z = step1[k1];
            for &Coupling { k: k2, d, .. } in row {
                let k2 = k2 as usize;
                let l = &mut light[k2 * n + k1];
                for c in 0..3 {
                    l[c] += d * z[c];
                }
            }
            step1[k1] = [0.0; 3];
            touched[k1] = false;
        }
        start = end;
    }
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
fn largest_target_set(n: usize, fraction: f64, scratch: &mut Propagation) {
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
fn predicted_target_set(maps: [Affine; 2], n: usize, fraction: f64, scratch: &mut Propagation) {
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

/// Irradiance `E = Σ_k L_k T_k` (RGB) at each receiver from one light; 0 above its plane.
///
/// `All` and `Predicted` targets take the adjoint order of the same sum, through each source
/// coefficient's [`responses`]: `E = Σ_i F_i G_i`. `Largest` needs every `L_k` to rank them,
/// so it propagates first ([`propagate_into`]).
pub fn irradiance(
    source: &LightSource,
    placement: &LightPlacement,
    transport: &FaceTransport,
    positions: &[DVec3],
    shading: impl Into<Shading>,
) -> Vec<[f64; 3]> {
    let Shading { keep, acc } = shading.into();
    let face = transport.face;
    let TargetKeep::Largest(fraction) = keep else {
        // Each receiver's responses, summed in the light's order: the bits of [`shade`].
        let fraction = if let TargetKeep::Predicted(fraction) = keep { Some(fraction) } else { None };
        let indices: Vec<(u16, u16)> = source.coefficients.iter().map(|c| c.0).collect();
        return positions
            .par_iter()
            .enumerate()
            .map(|(r, &x)| {
                let Some(maps) = placement.maps(&face, x).map(|m| acc.maps(m)) else {
                    return [0.0; 3];
                };
                with_scratch(face.order, |scratch| {
                    let mut g = std::mem::take(&mut scratch.responses);
                    g.resize(indices.len(), 0.0);
                    adjoint_responses(&indices, maps, face.order, transport.of(r), fraction, scratch, &mut g);
                    let mut e = [0.0; 3];
                    for ((_, f), g) in source.coefficients.iter().zip(&g) {
                        for c in 0..3 {
                            e[c] += f64::from(f[c]) * g;
                        }
                    }
                    scratch.responses = g;
                    e
                })
            })
            .collect();
    };
    positions
        .par_iter()
        .enumerate()
        .map(|(r, &x)| {
            let Some(maps) = placement.maps(&face, x).map(|m| acc.maps(m)) else {
                return [0.0; 3];
            };
            with_scratch(face.order, |scratch| {
                propagate_into(source, maps, face.order, scratch);
                largest_target_set(face.order, fraction, scratch);
                propagated_irradiance(transport.of(r), true, scratch)
            })
        })
        .collect()
}

/// `E_r = Σ_j F_j G_j(r)` per receiver, in coefficient order, with `G_j(r)` from `response(r, j)`
/// ([`responses`], kept per coefficient or all at once: the same sum, the same bits).
pub fn shade(source: &LightSource, receivers: usize, response: impl Fn(usize, usize) -> f64 + Sync) -> Vec<[f64; 3]> {
    let mut e = vec![[0.0; 3]; receivers];
    accumulate(&mut e, &source.coefficients, response);
    e
}

/// Adds `Σ_j F_j G_j(r)` over `coefficients` (a run of a light's, in order) to each `e[r]`:
/// runs added one after another give the bits of [`shade`].
pub fn accumulate(
    e: &mut [[f64; 3]],
    coefficients: &[((u16, u16), [f32; 3])],
    response: impl Fn(usize, usize) -> f64 + Sync,
) {
    e.par_iter_mut().enumerate().for_each(|(r, e)| {
        for (j, (_, f)) in coefficients.iter().enumerate() {
            let g = response(r, j);
            for c in 0..3 {
                e[c] += f64::from(f[c]) * g;
            }
        }
    });
}

/// Bytes of responses computed at once (one batch's `G`).
const RESPONSE_BATCH_BYTES: usize = 64 << 20;

/// Coefficients per batch of [`responses`] for this many receivers.
pub fn response_batch(receivers: usize) -> usize {
    (RESPONSE_BATCH_BYTES / (receivers.max(1) * 8)).max(1)
}

/// Each source coefficient's share of each receiver's irradiance per unit coefficient,
/// `G_i = Σ_{k₁} D_{i₁k₁} Σ_{k₂} D_{i₂k₂} T̃_{k₁k₂}` (`T̃` the kept transport), for `indices`
/// `(i₁, i₂)` in the source's order (by `i₂`, then `i₁`); at `r · indices.len() + j`.
///
/// `E` is linear in the light for `All` and `Predicted` targets (the kept set depends on the
/// placement alone), so a repainted light reuses the responses of the coefficients it keeps and
/// a stroke computes only those it adds. `None` for `Largest`, whose kept set follows the light.
pub fn responses(
    indices: &[(u16, u16)],
    placement: &LightPlacement,
    transport: &FaceTransport,
    positions: &[DVec3],
    shading: impl Into<Shading>,
) -> Option<Vec<f64>> {
    let Shading { keep, acc } = shading.into();
    let fraction = match keep {
        TargetKeep::All => None,
        TargetKeep::Predicted(fraction) => Some(fraction),
        TargetKeep::Largest(_) => return None,
    };
    let face = transport.face;
    let mut g = vec![0.0; positions.len() * indices.len()];
    if indices.is_empty() {
        return Some(g);
    }
    g.par_chunks_mut(indices.len()).enumerate().for_each(|(r, out)| {
        let Some(maps) = placement.maps(&face, positions[r]).map(|m| acc.maps(m)) else {
            return;
        };
        with_scratch(face.order, |scratch| {
            adjoint_responses(indices, maps, face.order, transport.of(r), fraction, scratch, out);
        });
    });
    Some(g)
}

thread_local! {
    /// Each thread's buffers and coupling cache, kept from one evaluation to the next: a stroke
    /// finds the couplings of an unchanged placement already computed (the cached values are the
    /// computed ones, so results do not depend on what a thread did before).
    static SCRATCH: std::cell::RefCell<Option<Propagation>> = const { std::cell::RefCell::new(None) };
}

/// Runs `f` with this thread's [`Propagation`] for a face of `order`.
fn with_scratch<R>(order: usize, f: impl FnOnce(&mut Propagation) -> R) -> R {
    SCRATCH.with(|cell| {
        let mut slot = cell.borrow_mut();
        if slot.as_ref().is_none_or(|p| p.light.len() != order * order) {
            *slot = Some(Propagation::new(order));
        }
        f(slot.as_mut().expect("just made"))
    })
}

/// `Σ_k L_k T_k` over the propagated light in `scratch.light`, in index order, over
/// `scratch.selected` when `masked`: the forward definition the adjoint must equal.
fn propagated_irradiance(t: &[f32], masked: bool, scratch: &Propagation) -> [f64; 3] {
    let mut e = [0.0; 3];
    for (k, l) in scratch.light.iter().enumerate() {
        if !masked || scratch.selected.contains(k) {
            for c in 0..3 {
                e[c] += l[c] * f64::from(t[k]);
            }
        }
    }
    e
}

/// The transport over the lanes, 0 where `keep(k₁, k₂, k)` is false: per `k₂` lane, its
/// `k₁` lanes [`padded`] with zeros.
#[inline(always)]
fn lay_out(
    out: &mut Vec<f64>,
    (lanes1, lanes2): (&[u32], &[u32]),
    n: usize,
    t: &[f32],
    keep: impl Fn(u32, u32, usize) -> bool,
) {
    let width = padded(lanes1.len());
    out.clear();
    out.resize(width * lanes2.len(), 0.0);
    for (values, &k2) in out.chunks_exact_mut(width).zip(lanes2) {
        let row = &t[k2 as usize * n..][..n];
        for (value, &k1) in values.iter_mut().zip(lanes1) {
            if keep(k1, k2, k2 as usize * n + k1 as usize) {
                *value = f64::from(row[k1 as usize]);
            }
        }
    }
}

/// `H = Σ_c d_c T̃[lane_c]` over one row's fan-out, in its order, for `B` blocks of lanes held
/// in registers.
#[inline(always)]
fn row_sums_of<const B: usize>(row: &[Coupling], transport: &[[f64; LANES]], out: &mut [[f64; LANES]]) {
    let mut sums = [[0.0; LANES]; B];
    for c in row {
        let t: &[[f64; LANES]; B] = transport[c.lane as usize * B..][..B].try_into().expect("B blocks");
        for (sum, t) in sums.iter_mut().zip(t) {
            for l in 0..LANES {
                sum[l] += c.d * t[l];
            }
        }
    }
    out.copy_from_slice(&sums);
}

/// One receiver's [`responses`], over the predicted targets of `fraction` when given. The
/// kept transport is laid over the two maps' [`Footprint`]s; per source row `i₂`,
/// `H_{k₁} = Σ_{k₂} D_{i₂k₂} T̃_{k₁k₂}` is summed for every `k₁` lane at once (in the fan-out's
/// order), then `G_i = Σ_{k₁} D_{i₁k₁} H_{k₁}` in the fan-out's order: a coefficient's response
/// has the same bits whichever others are computed with it.
fn adjoint_responses(
    indices: &[(u16, u16)],
    maps: [Affine; 2],
    n: usize,
    t: &[f32],
    fraction: Option<f64>,
    scratch: &mut Propagation,
    out: &mut [f64],
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: this CPU has AVX2, checked just above.
        return unsafe { adjoint_responses_avx2(indices, maps, n, t, fraction, scratch, out) };
    }
    adjoint_responses_portable(indices, maps, n, t, fraction, scratch, out);
}

/// [`adjoint_responses`] compiled for AVX2: four lanes per instruction. The same operations in
/// the same order (no fused multiply-adds), so the same bits as the portable build.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn adjoint_responses_avx2(
    indices: &[(u16, u16)],
    maps: [Affine; 2],
    n: usize,
    t: &[f32],
    fraction: Option<f64>,
    scratch: &mut Propagation,
    out: &mut [f64],
) {
    adjoint_responses_portable(indices, maps, n, t, fraction, scratch, out);
}

#[inline(always)]
fn adjoint_responses_portable(
    indices: &[(u16, u16)],
    maps: [Affine; 2],
    n: usize,
    t: &[f32],
    fraction: Option<f64>,
    scratch: &mut Propagation,
    out: &mut [f64],
) {
    let slots = scratch.couplings.receiver_slots(maps, n);
    let footprints = slots.map(|slot| scratch.couplings.footprint(slot));
    let width = padded(footprints[0].len());
    if width == 0 || footprints[1].len() == 0 {
        out.fill(0.0);
        return;
    }
    let kept = fraction.map_or(KeptTargets::All, |fraction| kept_targets(slots, n, fraction, scratch));
    let Propagation { couplings, selected, coarse_rank, lanes, kept_transport, row_sums, .. } = scratch;
    for q in 0..2 {
        footprints[q].indices(&mut lanes[q]);
    }
    let lanes = (&lanes[0][..], &lanes[1][..]);
    // One loop per kind of set, each with its own test inlined.
    match kept {
        KeptTargets::All => lay_out(kept_transport, lanes, n, t, |_, _, _| true),
        KeptTargets::Fill { nonzero, cutoff } => lay_out(kept_transport, lanes, n, t, |k1, k2, k| {
            KeptTargets::Fill { nonzero, cutoff }.keeps(k1, k2, k, coarse_rank, selected)
        }),
        KeptTargets::Selected => lay_out(kept_transport, lanes, n, t, |k1, k2, k| {
            KeptTargets::Selected.keeps(k1, k2, k, coarse_rank, selected)
        }),
    }
    row_sums.resize(width, 0.0);
    let (transport_blocks, blocks) = (kept_transport.as_chunks::<LANES>().0, width / LANES);
    let mut start = 0;
    while start < indices.len() {
        let i2 = indices[start].1;
        let end = start + indices[start..].iter().take_while(|c| c.1 == i2).count();
        let row = couplings.fan_out(slots[1], usize::from(i2), n);
        let sums = row_sums.as_chunks_mut::<LANES>().0;
        match sums.len() {
            1 => row_sums_of::<1>(row, transport_blocks, sums),
            2 => row_sums_of::<2>(row, transport_blocks, sums),
            3 => row_sums_of::<3>(row, transport_blocks, sums),
            4 => row_sums_of::<4>(row, transport_blocks, sums),
            5 => row_sums_of::<5>(row, transport_blocks, sums),
            6 => row_sums_of::<6>(row, transport_blocks, sums),
            _ => {
                for (block, h) in sums.iter_mut().enumerate() {
                    let mut sum = [0.0; LANES];
                    for c in row {
                        let t = transport_blocks[c.lane as usize * blocks + block];
                        for l in 0..LANES {
                            sum[l] += c.d * t[l];
                        }
                    }
                    *h = sum;
                }
            }
        }
        for (j, &(i1, _)) in indices.iter().enumerate().take(end).skip(start) {
            out[j] = dot(couplings.dense_fan_out(slots[0], usize::from(i1), n), row_sums);
        }
        start = end;
    }
}

#[cfg(test)]
mod tests;
