//! The receivers' top-face transport (Sun 2008 §4.5.4): per receiver, which of the face's cells
//! light can arrive through (one ray per cell, and [`SUB`]² on an occluder's silhouette), and the
//! transport `T̂` over them for any per-direction weight, kept as the box of its nonzero cells.

use super::TopFace;
use super::box_responses::Cells;
use crate::wavelet::affine::haar_forward_2d;
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Per receiver, the transport on the top face: `T̂` at each of its `order²` cells, kept as
/// the box of its nonzero cells (row `k₂` after row). The shading with every face coefficient
/// kept sums these cells directly ([`box_responses`]); the truncating paths take their 2D Haar
/// transform ([`Self::haar_of`]). A receiver the face sends nothing (occluded, or facing away)
/// holds no cell and costs nothing to shade.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaceTransport {
    pub face: TopFace,
    /// Every receiver's box of cells, one receiver after another.
    pub cells: Vec<f32>,
    /// Where each receiver's box starts in `cells` (one more than the receivers: the end).
    pub offsets: Vec<u64>,
    /// Per receiver, its box: `k₁ ∈ [b₀, b₁)`, `k₂ ∈ [b₂, b₃)` (empty for no nonzero cell).
    pub bounds: Vec<[u16; 4]>,
}

crate::stage_type!(FaceTransport, "top-face transport", |v| v.cells.len() * 4 + v.bounds.len() * 16 + 32);

/// Receivers per task when transports are built.
const TRANSPORT_TASK: usize = 256;

impl FaceTransport {
    /// A transport of no receiver yet.
    pub fn empty(face: TopFace) -> Self {
        Self { face, cells: Vec::new(), offsets: vec![0], bounds: Vec::new() }
    }

    /// The transport of receivers whose whole faces are `cells`, `order²` each.
    pub fn new(face: TopFace, cells: &[f32]) -> Self {
        let n2 = face.order * face.order;
        Self::gather(face, cells.len() / n2.max(1), |r, out| out.copy_from_slice(&cells[r * n2..(r + 1) * n2]))
    }

    /// The transport of `receivers` receivers, each face's `order²` cells written by
    /// `fill(receiver, cells)` (in parallel, in tasks of consecutive receivers).
    fn gather(face: TopFace, receivers: usize, fill: impl Fn(usize, &mut [f32]) + Sync) -> Self {
        let n2 = face.order * face.order;
        let parts: Vec<Self> = (0..receivers.div_ceil(TRANSPORT_TASK))
            .into_par_iter()
            .map(|task| {
                let mut part = Self::empty(face);
                let mut cells = vec![0.0; n2];
                for r in task * TRANSPORT_TASK..((task + 1) * TRANSPORT_TASK).min(receivers) {
                    fill(r, &mut cells);
                    part.push(&cells);
                }
                part
            })
            .collect();
        let mut out = Self::empty(face);
        for part in parts {
            out.append(part);
        }
        out
    }

    /// Adds a receiver whose whole face is `cells`.
    fn push(&mut self, cells: &[f32]) {
        let n = self.face.order;
        let bounds = nonzero_bounds(cells, n);
        let [lo1, hi1, lo2, hi2] = bounds.map(usize::from);
        for k2 in lo2..hi2 {
            self.cells.extend_from_slice(&cells[k2 * n + lo1..k2 * n + hi1]);
        }
        self.bounds.push(bounds);
        self.offsets.push(self.cells.len() as u64);
    }

    /// Adds `other`'s receivers after these.
    pub fn append(&mut self, other: Self) {
        let base = self.offsets.last().copied().unwrap_or(0);
        self.cells.extend(other.cells);
        self.offsets.extend(other.offsets[1..].iter().map(|o| o + base));
        self.bounds.extend(other.bounds);
    }

    pub fn receivers(&self) -> usize {
        self.bounds.len()
    }

    /// One receiver's box of cells.
    pub(super) fn cells_of(&self, receiver: usize) -> Cells<'_> {
        let (from, to) = (self.offsets[receiver] as usize, self.offsets[receiver + 1] as usize);
        Cells { n: self.face.order, values: &self.cells[from..to], bounds: self.bounds[receiver] }
    }

    /// One receiver's transport in 2D Haar, `T_k`, into `out`.
    pub fn haar_of(&self, receiver: usize, out: &mut Vec<f32>) {
        let Cells { n, values, bounds } = self.cells_of(receiver);
        let [lo1, hi1, lo2, hi2] = bounds.map(usize::from);
        let mut full = vec![0.0; n * n];
        for (k2, row) in (lo2..hi2).zip(values.chunks_exact((hi1 - lo1).max(1))) {
            for (cell, &v) in full[k2 * n + lo1..k2 * n + hi1].iter_mut().zip(row) {
                *cell = f64::from(v);
            }
        }
        haar_forward_2d(&mut full, n);
        out.clear();
        out.extend(full.into_iter().map(|c| c as f32));
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
    FaceTransport::gather(face, positions.len(), |r, cells| {
        let (x, normal) = (positions[r], normals[r]);
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
            *cell = (sum / (samples * samples) as f64) as f32;
        }
    })
}

/// The smallest box of an `n × n` receiver's cells holding every nonzero one ([`FaceTransport::bounds`]).
fn nonzero_bounds(cells: &[f32], n: usize) -> [u16; 4] {
    let (mut bounds, mut any) = ([n, 0, n, 0], false);
    for (k2, row) in cells.chunks(n).enumerate() {
        let Some(first) = row.iter().position(|&v| v != 0.0) else {
            continue;
        };
        let last = row.iter().rposition(|&v| v != 0.0).unwrap_or(first);
        bounds = [bounds[0].min(first), bounds[1].max(last + 1), bounds[2].min(k2), k2 + 1];
        any = true;
    }
    if any { bounds.map(|b| b as u16) } else { [0; 4] }
}

/// Per receiver, the top-face cells light can arrive through: above the receiver's horizon and
/// unoccluded, one ray per cell centre, a bit per cell; on an occluder's silhouette (a cell whose
/// neighbour's ray went the other way), the share of [`SUB`]² rays spread over the cell that
/// get through. Transports for any weight follow from it without new rays
/// ([`visible_transport`]): the diffuse one, and a glossy one per view.
///
/// One ray per cell makes a soft shadow a staircase where a light spans few cells (a receiver
/// far from it, or seeing it at a grazing angle): each cell's ray flips at one place as the
/// receiver moves. The silhouette's cells, traced again more finely, make the steps finer where
/// the steps are.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaceVisibility {
    pub face: TopFace,
    pub bits: Vec<u64>,
    /// Per receiver, where its silhouette cells start in `partial` (one entry more than there
    /// are receivers).
    pub partial_offsets: Vec<u64>,
    /// Each receiver's silhouette cells in increasing order, as `cell << 8 | clear rays`
    /// (of [`SUB`]²); their bit is set when any ray got through.
    pub partial: Vec<u32>,
}

/// Rays per side of a silhouette cell.
pub const SUB: usize = 4;

/// Most silhouette cells one receiver traces finer: a quarter of its face. A face that is more
/// silhouette than that (a grille, foliage) keeps one ray per cell, so a receiver casts at most
/// [`rays_per_receiver`].
pub fn max_silhouette(face: &TopFace) -> usize {
    face.order * face.order / 4
}

/// The most rays [`face_visibility`] casts for one receiver of `face`.
pub fn rays_per_receiver(face: &TopFace) -> usize {
    face.order * face.order + max_silhouette(face) * SUB * SUB
}

impl FaceVisibility {
    fn words(face: &TopFace) -> usize {
        (face.order * face.order).div_ceil(64)
    }

    /// No receiver yet, for [`Self::append`].
    pub fn empty(face: TopFace) -> Self {
        Self { face, bits: Vec::new(), partial_offsets: vec![0], partial: Vec::new() }
    }

    /// `other`'s receivers after these.
    pub fn append(&mut self, other: Self) {
        let base = self.partial.len() as u64;
        self.bits.extend(other.bits);
        self.partial_offsets.extend(other.partial_offsets[1..].iter().map(|o| o + base));
        self.partial.extend(other.partial);
    }

    fn visible(&self, receiver: usize, cell: usize) -> bool {
        self.bits[receiver * Self::words(&self.face) + cell / 64] >> (cell % 64) & 1 == 1
    }

    /// Receiver `r`'s silhouette cells, `cell << 8 | clear rays`.
    fn partial_of(&self, receiver: usize) -> &[u32] {
        let range = self.partial_offsets[receiver] as usize..self.partial_offsets[receiver + 1] as usize;
        &self.partial[range]
    }
}

/// A receiver's buffers while its face is traced.
#[derive(Default)]
struct Tracing {
    cells: Vec<usize>,
    directions: Vec<DVec3>,
    blocked: Vec<bool>,
    /// Per cell: 0 below the horizon, 1 clear, 2 blocked.
    state: Vec<u8>,
    /// The silhouette's cells.
    silhouette: Vec<usize>,
}

/// The cells of each receiver (`origins`, unit `normals`) whose rays `occlude` leaves clear,
/// cells below the horizon left unset without a ray, and the silhouette cells' shares
/// ([`FaceVisibility`]). `occlude(origin, directions, blocked)` sets `blocked[i]` for each
/// direction blocked before it has risen one unit per unit of its parameter, and leaves set
/// the flags that are set already (sub-rays below the receiver's horizon): the directions are
/// plane intercepts `(v₁, 1, v₂)`, not unit vectors, so every ray of a receiver reaches the
/// plane `h` above it at the same parameter `h`, and they can be traced as one bundle with one
/// reach.
pub fn face_visibility(
    face: TopFace,
    origins: &[DVec3],
    normals: &[DVec3],
    occlude: impl Fn(DVec3, &[DVec3], &mut [bool]) + Sync,
) -> FaceVisibility {
    let n = face.order;
    let words = FaceVisibility::words(&face);
    let per_receiver: Vec<(Vec<u64>, Vec<u32>)> = origins
        .par_iter()
        .zip(normals)
        .map_init(Tracing::default, |t, (&x, &normal)| {
            t.cells.clear();
            t.directions.clear();
            for c in 0..n * n {
                let v_hat = face.cell_centre(c);
                if face.weight(v_hat, normal).1 > 0.0 {
                    let [v1, v2] = face.intercept(v_hat);
                    t.cells.push(c);
                    t.directions.push(DVec3::new(v1, 1.0, v2));
                }
            }
            t.blocked.clear();
            t.blocked.resize(t.directions.len(), false);
            if !t.directions.is_empty() {
                occlude(x, &t.directions, &mut t.blocked);
            }
            t.state.clear();
            t.state.resize(n * n, 0);
            for (&c, &b) in t.cells.iter().zip(&t.blocked) {
                t.state[c] = 1 + u8::from(b);
            }
            // The silhouette: traced cells with a traced 4-neighbour whose ray went the other way.
            t.silhouette.clear();
            for &c in &t.cells {
                let (i, j) = (c % n, c / n);
                let differs = |ni: usize, nj: usize| {
                    let s = t.state[nj * n + ni];
                    s != 0 && s != t.state[c]
                };
                if (i > 0 && differs(i - 1, j))
                    || (i + 1 < n && differs(i + 1, j))
                    || (j > 0 && differs(i, j - 1))
                    || (j + 1 < n && differs(i, j + 1))
                {
                    t.silhouette.push(c);
                }
            }
            if t.silhouette.len() > max_silhouette(&face) {
                t.silhouette.clear();
            }
            // Their SUB² rays each, a sub-ray below the horizon counted as blocked.
            t.directions.clear();
            for &c in &t.silhouette {
                let centre = face.cell_centre(c);
                for k in 0..SUB * SUB {
                    let v_hat = [
                        centre[0] + ((k % SUB) as f64 + 0.5 - SUB as f64 / 2.0) / (SUB * n) as f64,
                        centre[1] + ((k / SUB) as f64 + 0.5 - SUB as f64 / 2.0) / (SUB * n) as f64,
                    ];
                    let [v1, v2] = face.intercept(v_hat);
                    t.directions.push(DVec3::new(v1, 1.0, v2));
                }
            }
            t.blocked.clear();
            t.blocked.resize(t.directions.len(), false);
            for (d, blocked) in t.directions.iter().zip(t.blocked.iter_mut()) {
                *blocked = face.weight([d.x / face.size + 0.5, d.z / face.size + 0.5], normal).1 <= 0.0;
            }
            if !t.directions.is_empty() {
                occlude(x, &t.directions, &mut t.blocked);
            }
            let mut bits = vec![0u64; words];
            for &c in &t.cells {
                if t.state[c] == 1 {
                    bits[c / 64] |= 1 << (c % 64);
                }
            }
            let mut partial = Vec::with_capacity(t.silhouette.len());
            for (s, &c) in t.silhouette.iter().enumerate() {
                let clear = t.blocked[s * SUB * SUB..(s + 1) * SUB * SUB].iter().filter(|b| !**b).count();
                if clear > 0 {
                    bits[c / 64] |= 1 << (c % 64);
                } else {
                    bits[c / 64] &= !(1 << (c % 64));
                }
                if clear > 0 && clear < SUB * SUB {
                    partial.push((c as u32) << 8 | clear as u32);
                }
            }
            (bits, partial)
        })
        .collect();
    let mut visibility = FaceVisibility::empty(face);
    for (bits, partial) in per_receiver {
        visibility.bits.extend(bits);
        visibility.partial.extend(partial);
        visibility.partial_offsets.push(visibility.partial.len() as u64);
    }
    visibility
}

/// The transport of `receivers` (indices into `visibility` and `normals`) with a per-direction
/// factor: `T̂(v̂) = a² V(ω) factor(r, ω) max(0, ω·n) (1 + |v|²)^{−3/2}` at each cell centre
/// (`order²` cells per receiver, kept as [`FaceTransport`] keeps them). `factor` 1 gives the irradiance transport
/// ([`face_transport`] with one sample per cell, the same bits off the silhouettes, whose cells
/// take the share of their rays that get through); the specular lobe toward a viewer gives the
/// radiance a glossy surface reflects toward it (Sun 2008 §4.9).
pub fn visible_transport(
    visibility: &FaceVisibility,
    receivers: std::ops::Range<usize>,
    normals: &[DVec3],
    factor: impl Fn(usize, DVec3) -> f64 + Sync,
) -> FaceTransport {
    let face = visibility.face;
    FaceTransport::gather(face, receivers.len(), |j, cells| {
        let r = receivers.start + j;
        let mut partial = visibility.partial_of(r).iter().peekable();
        for (c, cell) in cells.iter_mut().enumerate() {
            // The share of a silhouette cell's rays that got through.
            let share = match partial.next_if(|p| (**p >> 8) as usize == c) {
                Some(p) => (p & 0xff) as f64 / (SUB * SUB) as f64,
                None => 1.0,
            };
            *cell = if visibility.visible(r, c) {
                let (direction, weight) = face.weight(face.cell_centre(c), normals[r]);
                (share * weight * factor(r, direction)) as f32
            } else {
                0.0
            };
        }
    })
}
