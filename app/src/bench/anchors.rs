//! The figures `lightloom bench` measures itself against: the papers' throughputs, Embree's
//! ray rate, and the memory-bandwidth bound of a per-vertex relight. Each is printed beside
//! the measured figure as a ratio (above 1: we are faster).

use rayon::prelude::*;
use std::time::Instant;

/// A published (or separately measured) throughput.
pub struct Anchor {
    /// Where it comes from, in words.
    pub source: &'static str,
    /// In the unit of the row it is printed beside.
    pub rate: f64,
    pub unit: &'static str,
}

impl Anchor {
    /// "1.23× <source> (<rate> <unit>)": the measured rate over the anchor's.
    pub fn beside(&self, measured: f64) -> String {
        format!("{:.2}× {} ({:.2} {})", measured / self.rate, self.source, self.rate, self.unit)
    }
}

/// Ma et al., Table 3 (ATI X1900 XTX, 1024×768): the 25k-vertex Dragon with per-vertex
/// (interpolated) visibility at 21.5 fps with 80 coefficients and 8.5 fps with 320, in vertex
/// relights per second (the paper recomputes every product every frame).
pub fn ma_interpolated(coefficients: usize) -> Option<Anchor> {
    let fps = match coefficients {
        80 => 21.5,
        320 => 8.5,
        _ => return None,
    };
    Some(Anchor { source: "Ma Table 3, Dragon 25k per-vertex visibility", rate: 25_000.0 * fps / 1e6, unit: "M/s" })
}

/// Sun 2008, Fig. 4.11 (fertility, 39,391 vertices, 3.0 GHz dual quad-core of 2008): vertex
/// relights per second at a source / target keep in percent, on 8 threads and on 1.
pub fn sun_area_relights(source_pct: f64, target_pct: f64) -> Option<(Anchor, Anchor)> {
    let (eight, one) = match (source_pct as u32, target_pct as u32) {
        (1, 1) => (151.86, 32.79),
        (1, 20) => (38.71, 7.58),
        (5, 40) => (24.83, 4.17),
        (20, 70) => (13.78, 2.17),
        (100, 100) => (7.04, 1.08),
        _ => return None,
    };
    let anchor = |fps: f64, source| Anchor { source, rate: 39_391.0 * fps / 1e6, unit: "M/s" };
    Some((anchor(eight, "Sun Fig. 4.11, 8 threads"), anchor(one, "Sun Fig. 4.11, 1 thread")))
}

/// Xu et al. 2006, Table 1 (GeForce 7800): the 45k-vertex Buddha under 30 square lights at
/// 27 fps, in million vertex·light evaluations per second.
pub const XU_TABLE_1: Anchor =
    Anchor { source: "Xu Table 1, Buddha 45k × 30 lights at 27 fps", rate: 36.5, unit: "M vertex-RSL/s" };

/// Embree 3.13 through Mitsuba 3.9.1's `ray_test` (LLVM variant) on the rays section's rays on
/// this machine (2 cores), best of 5 (`tools/rays/compare_mitsuba.py`): 256 and 1,024
/// directions per receiver. The fastest of its runs on different days (12.1 and 12.9 on a
/// busier one): the script's side-by-side run is the fair ratio.
pub fn embree(directions: usize) -> Option<Anchor> {
    let rate = match directions {
        256 => 16.6,
        1024 => 19.0,
        _ => return None,
    };
    Some(Anchor { source: "Embree (Mitsuba 3.9.1 ray_test)", rate, unit: "M rays/s" })
}

/// This machine's memory bandwidth: bytes read plus bytes written per second by a parallel
/// `copy_from_slice` of 256 MiB (best of 5).
pub fn copy_bandwidth() -> f64 {
    const BYTES: usize = 256 << 20;
    const CHUNK: usize = 1 << 20;
    let source = vec![1u8; BYTES];
    let mut target = vec![0u8; BYTES];
    let best = (0..5)
        .map(|_| {
            let start = Instant::now();
            target.par_chunks_mut(CHUNK).zip(source.par_chunks(CHUNK)).for_each(|(t, s)| t.copy_from_slice(s));
            std::hint::black_box(&target);
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min);
    2.0 * BYTES as f64 / best
}

/// The least time a relight can take that must read and write `bytes_per_vertex` for each of
/// `vertices` at `bandwidth` bytes per second, in milliseconds.
pub fn bandwidth_bound_ms(vertices: usize, bytes_per_vertex: usize, bandwidth: f64) -> f64 {
    (vertices * bytes_per_vertex) as f64 / bandwidth * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anchors_are_the_papers_throughputs() {
        // Ma Table 3: 25k vertices at 21.5 fps.
        assert!((ma_interpolated(80).unwrap().rate - 0.5375).abs() < 1e-9);
        // Sun Fig. 4.11 at 1% / 20%: 39,391 × 38.71 fps ≈ the thesis's "about 1.5 M/s".
        let (eight, one) = sun_area_relights(1.0, 20.0).unwrap();
        assert!((eight.rate - 1.5248).abs() < 1e-3, "{}", eight.rate);
        assert!(one.rate < eight.rate);
        // Xu Table 1: 45k × 30 × 27.
        assert!((45_000.0 * 30.0 * 27.0 / 1e6 - XU_TABLE_1.rate).abs() < 0.1);
        assert!(ma_interpolated(1280).is_none() && sun_area_relights(1.0, 100.0).is_none());
        assert_eq!(XU_TABLE_1.beside(73.0).split('×').next(), Some("2.00"));
    }

    #[test]
    fn the_bandwidth_bound_is_the_traffic_over_the_bandwidth() {
        assert_eq!(bandwidth_bound_ms(1000, 1000, 1e9), 1.0);
    }
}
