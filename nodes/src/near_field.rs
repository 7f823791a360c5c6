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
//! - **Shading.** In the adjoint order `E = Σ_i F_i G_i`, each source coefficient's response
//!   `G_i` kept apart so that a stroke computes only the coefficients it adds. With every
//!   target kept, `G_i` is a sum of the face's cells under the preimage of `Ψ_i`'s boxes
//!   ([`box_responses`], Parseval); a truncated target goes through the couplings `D_ik` over
//!   the transport's Haar transform. The transport is stored as cells, with the box of its
//!   nonzero ones, so a receiver the face sends nothing costs nothing.

use crate::wavelet::affine::{Affine, CouplingGrid, haar_forward_2d, level_offset};
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub mod beyond_face;
mod box_responses;
mod couplings;
mod frame;
mod targets;
mod transport;

use box_responses::*;
use couplings::*;
pub use frame::{LightFrame, light_orientation};
pub use targets::predicted_targets;
use targets::*;
pub use transport::*;

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

/// Where a light is, in its own frame ([`LightFrame`]: the world's for a light that is not
/// tilted): its plane's height and its rectangle's corner and extent on `x` and `z`. Every
/// function here takes receivers in that frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightPlacement {
    pub height: f64,
    pub corner: [f64; 2],
    pub extent: [f64; 2],
    pub frame: LightFrame,
}

impl LightPlacement {
    /// [`Self::maps`] as `acc` takes its couplings at.
    fn shading_maps(&self, face: &TopFace, acc: AccMode, x: DVec3) -> Option<[Affine; 2]> {
        self.maps(face, x).map(|maps| acc.maps(maps))
    }

    /// A level `width × depth` light centred over `(x, z)`.
    pub fn centred(height: f64, centre: [f64; 2], size: [f64; 2]) -> Self {
        Self {
            height,
            corner: [centre[0] - size[0] / 2.0, centre[1] - size[1] / 2.0],
            extent: size,
            frame: LightFrame::default(),
        }
    }

    /// A light of bounding rectangle `size` (in its frame) centred at world point `centre`.
    pub fn oriented(centre: [f64; 3], size: [f64; 2], frame: LightFrame) -> Self {
        let c = frame.to_light() * DVec3::from(centre);
        Self { frame, ..Self::centred(c.y, [c.x, c.z], size) }
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

impl TargetKeep {
    /// For the keeps whose kept set depends on the placement alone (the shading is linear in
    /// the light), the predicted fraction (`None` for all); `None` for [`TargetKeep::Largest`].
    fn linear_fraction(self) -> Option<Option<f64>> {
        match self {
            TargetKeep::All => Some(None),
            TargetKeep::Predicted(fraction) => Some(Some(fraction)),
            TargetKeep::Largest(_) => None,
        }
    }
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
    /// One receiver's transport in 2D Haar, for the truncating paths.
    haar: Vec<f32>,
    boxes: BoxScratch,
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
            haar: Vec::new(),
            boxes: BoxScratch::default(),
            light: vec![[0.0; 3]; face_order * face_order],
        }
    }
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
        let fraction = keep.linear_fraction().flatten();
        let indices: Vec<(u16, u16)> = source.coefficients.iter().map(|c| c.0).collect();
        return positions
            .par_iter()
            .enumerate()
            .map(|(r, &x)| {
                let Some(maps) = placement.shading_maps(&face, acc, x) else {
                    return [0.0; 3];
                };
                with_scratch(face.order, |scratch| {
                    let mut g = std::mem::take(&mut scratch.responses);
                    g.resize(indices.len(), 0.0);
                    receiver_responses(&indices, maps, transport, r, fraction, scratch, &mut g);
                    let mut e = [0.0; 3];
                    add_shading(&mut e, &source.coefficients, |j| g[j]);
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
            let Some(maps) = placement.shading_maps(&face, acc, x) else {
                return [0.0; 3];
            };
            with_scratch(face.order, |scratch| {
                propagate_into(source, maps, face.order, scratch);
                largest_target_set(face.order, fraction, scratch);
                let mut haar = std::mem::take(&mut scratch.haar);
                transport.haar_of(r, &mut haar);
                let e = propagated_irradiance(&haar, true, scratch);
                scratch.haar = haar;
                e
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

/// [`shade`] from responses kept one column per coefficient (`columns[j][r]`): the same sums in
/// the same order, the same bits, taken by blocks of receivers so that each column streams.
pub fn shade_columns(source: &LightSource, columns: &[&[f64]], receivers: usize) -> Vec<[f64; 3]> {
    const BLOCK: usize = 512;
    let mut e = vec![[0.0; 3]; receivers];
    e.par_chunks_mut(BLOCK).enumerate().for_each(|(b, block)| {
        let (first, len) = (b * BLOCK, block.len());
        for (column, (_, f)) in columns.iter().zip(&source.coefficients) {
            for (e, &g) in block.iter_mut().zip(&column[first..first + len]) {
                for c in 0..3 {
                    e[c] += f64::from(f[c]) * g;
                }
            }
        }
    });
    e
}

/// Adds `Σ_j F_j G_j(r)` over `coefficients` (a run of a light's, in order) to each `e[r]`:
/// runs added one after another give the bits of [`shade`].
pub fn accumulate(
    e: &mut [[f64; 3]],
    coefficients: &[((u16, u16), [f32; 3])],
    response: impl Fn(usize, usize) -> f64 + Sync,
) {
    e.par_iter_mut().enumerate().for_each(|(r, e)| add_shading(e, coefficients, |j| response(r, j)));
}

/// Adds `Σ_j F_j G_j` over `coefficients`, in order, to `e`.
fn add_shading(e: &mut [f64; 3], coefficients: &[((u16, u16), [f32; 3])], response: impl Fn(usize) -> f64) {
    for (j, (_, f)) in coefficients.iter().enumerate() {
        let g = response(j);
        for c in 0..3 {
            e[c] += f64::from(f[c]) * g;
        }
    }
}

/// Bytes of responses computed at once (one batch's `G`).
const RESPONSE_BATCH_BYTES: usize = 64 << 20;

/// Coefficients per batch of [`responses`] for this many receivers.
pub fn response_batch(receivers: usize) -> usize {
    (RESPONSE_BATCH_BYTES / (receivers.max(1) * 8)).max(1)
}

/// Receivers per task of [`responses`]: each task writes its slice of every column.
const RESPONSE_CHUNK: usize = 256;

/// Each source coefficient's share of each receiver's irradiance per unit coefficient,
/// `G_i = Σ_{k₁} D_{i₁k₁} Σ_{k₂} D_{i₂k₂} T̃_{k₁k₂}` (`T̃` the kept transport), for `indices`
/// `(i₁, i₂)` in the source's order (by `i₂`, then `i₁`): one column per index, one value per
/// receiver.
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
) -> Option<Vec<Vec<f64>>> {
    let Shading { keep, acc } = shading.into();
    let fraction = keep.linear_fraction()?;
    let face = transport.face;
    let mut columns: Vec<Vec<f64>> = indices.iter().map(|_| vec![0.0; positions.len()]).collect();
    let mut tasks: Vec<Vec<&mut [f64]>> =
        (0..positions.len().div_ceil(RESPONSE_CHUNK)).map(|_| Vec::with_capacity(indices.len())).collect();
    for column in &mut columns {
        for (task, piece) in tasks.iter_mut().zip(column.chunks_mut(RESPONSE_CHUNK)) {
            task.push(piece);
        }
    }
    tasks.into_par_iter().enumerate().for_each(|(t, mut pieces)| {
        with_scratch(face.order, |scratch| {
            let mut g = std::mem::take(&mut scratch.responses);
            g.resize(indices.len(), 0.0);
            let first = t * RESPONSE_CHUNK;
            for r in first..(first + RESPONSE_CHUNK).min(positions.len()) {
                // A receiver the face sends nothing responds with zeros, as the columns hold.
                let [lo1, hi1, lo2, hi2] = transport.bounds[r];
                if hi1 <= lo1 || hi2 <= lo2 {
                    continue;
                }
                let Some(maps) = placement.shading_maps(&face, acc, positions[r]) else {
                    continue;
                };
                receiver_responses(indices, maps, transport, r, fraction, scratch, &mut g);
                for (piece, &value) in pieces.iter_mut().zip(&g) {
                    piece[r - first] = value;
                }
            }
            scratch.responses = g;
        });
    });
    Some(columns)
}

/// Receiver `r`'s responses to `indices` under `maps`: from its cells when every face
/// coefficient is kept ([`box_responses`]), else through the coupling coefficients over the
/// predicted targets of `fraction` in its Haar transport ([`adjoint_responses`]).
fn receiver_responses(
    indices: &[(u16, u16)],
    maps: [Affine; 2],
    transport: &FaceTransport,
    r: usize,
    fraction: Option<f64>,
    scratch: &mut Propagation,
    out: &mut [f64],
) {
    let n = transport.face.order;
    let Some(fraction) = fraction else {
        return box_responses(indices, maps, transport.cells_of(r), &mut scratch.boxes, out);
    };
    let mut haar = std::mem::take(&mut scratch.haar);
    transport.haar_of(r, &mut haar);
    adjoint_responses(Receiver { indices, maps, order: n, transport: &haar }, Some(fraction), scratch, out);
    scratch.haar = haar;
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

/// What [`adjoint_responses`] shades: the light's coefficient `indices` (by `i₂`, then `i₁`) at
/// one receiver, its two maps and its top-face transport (`order²` coefficients).
#[derive(Clone, Copy)]
struct Receiver<'a> {
    indices: &'a [(u16, u16)],
    maps: [Affine; 2],
    order: usize,
    transport: &'a [f32],
}

/// One receiver's [`responses`], over the predicted targets of `fraction` when given. The
/// kept transport is laid over the two maps' [`Footprint`]s; per source row `i₂`,
/// `H_{k₁} = Σ_{k₂} D_{i₂k₂} T̃_{k₁k₂}` is summed for every `k₁` lane at once (in the fan-out's
/// order), then `G_i = Σ_{k₁} D_{i₁k₁} H_{k₁}` in the fan-out's order: a coefficient's response
/// has the same bits whichever others are computed with it.
fn adjoint_responses(receiver: Receiver, fraction: Option<f64>, scratch: &mut Propagation, out: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: this CPU has AVX2, checked just above.
        return unsafe { adjoint_responses_avx2(receiver, fraction, scratch, out) };
    }
    adjoint_responses_portable(receiver, fraction, scratch, out);
}

/// [`adjoint_responses`] compiled for AVX2: four lanes per instruction. The same operations in
/// the same order (no fused multiply-adds), so the same bits as the portable build.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn adjoint_responses_avx2(receiver: Receiver, fraction: Option<f64>, scratch: &mut Propagation, out: &mut [f64]) {
    adjoint_responses_portable(receiver, fraction, scratch, out);
}

#[inline(always)]
fn adjoint_responses_portable(receiver: Receiver, fraction: Option<f64>, scratch: &mut Propagation, out: &mut [f64]) {
    let Receiver { indices, maps, order: n, transport: t } = receiver;
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
