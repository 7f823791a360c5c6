//! The bundle walk's tests with two rays per 8-lane AVX instruction: the first ray in the low
//! four lanes, the second in the high four, each against the same four boxes or triangles. The
//! arithmetic is [`super::OneRay`]'s, operation for operation (no fused multiply-adds), so the
//! flags are the same bits.

use super::{Boxes, Kernel, TrianglePack};
use glam::{Vec3A, Vec4};
use std::arch::x86_64::*;

pub(super) struct Pairs;

/// One 4-lane value in both halves.
#[target_feature(enable = "avx2")]
#[inline]
fn both(v: Vec4) -> __m256 {
    let m: __m128 = v.into();
    _mm256_set_m128(m, m)
}

/// `a` in the low four lanes, `b` in the high four.
#[target_feature(enable = "avx2")]
#[inline]
fn halves(a: f32, b: f32) -> __m256 {
    _mm256_set_m128(_mm_set1_ps(b), _mm_set1_ps(a))
}

/// `values[i]`, unchecked: the walk checked every listed ray against `directions` before it
/// began, and `inverse` and `blocked` are as long (`Kernel`'s contract).
#[inline(always)]
fn at<T: Copy>(values: &[T], i: u32) -> T {
    debug_assert!((i as usize) < values.len());
    // SAFETY: see above.
    unsafe { *values.get_unchecked(i as usize) }
}

/// Sets `blocked[i]` when `hit`, unchecked as in [`at`].
#[inline(always)]
fn mark(blocked: &mut [bool], i: u32, hit: bool) {
    debug_assert!((i as usize) < blocked.len());
    // SAFETY: as in `at`.
    unsafe { *blocked.get_unchecked_mut(i as usize) |= hit };
}

// The methods are compiled for AVX2, which `Kernel`'s contract has the caller promise.
impl Kernel for Pairs {
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn split(
        boxes: &Boxes,
        inverse: &[Vec3A],
        rays: &mut [u32],
        clean: bool,
        children: &mut [u32],
        slot: [usize; 4],
        blocked: &[bool],
    ) -> [usize; 4] {
        let lo = [both(boxes.lo[0]), both(boxes.lo[1]), both(boxes.lo[2])];
        let hi = [both(boxes.hi[0]), both(boxes.hi[1]), both(boxes.hi[2])];
        let far_limit = _mm256_set1_ps(boxes.tmax);
        let zero = _mm256_setzero_ps();
        let used = boxes.used | boxes.used << 4;
        // Each list's end as a pointer: the lengths stay in registers and the writes unchecked
        // (the checks and the spilled lengths were most of this loop).
        assert!(slot.iter().all(|&s| s + rays.len() <= children.len()), "a child list could overflow its room");
        let base = children.as_mut_ptr();
        // SAFETY: each `slot[l] + rays.len()` is within `children` (asserted above).
        let start = slot.map(|s| unsafe { base.add(s) });
        let mut end = start;
        // The unblocked rays first, moved to the front without a branch on each flag (whether a ray
        // is blocked is data, and mispredicts); then two at a time.
        let mut unblocked = rays.len();
        if !clean {
            unblocked = 0;
            for k in 0..rays.len() {
                let i = rays[k];
                rays[unblocked] = i;
                unblocked += usize::from(!at(blocked, i));
            }
        }
        for pair in rays[..unblocked].chunks(2) {
            let (i, j) = (pair[0], pair[pair.len() - 1]);
            let second = pair.len() == 2;
            let (a, b) = (at(inverse, i), at(inverse, j));
            let (ix, iy, iz) = (halves(a.x, b.x), halves(a.y, b.y), halves(a.z, b.z));
            let (px, qx) = (_mm256_mul_ps(lo[0], ix), _mm256_mul_ps(hi[0], ix));
            let (py, qy) = (_mm256_mul_ps(lo[1], iy), _mm256_mul_ps(hi[1], iy));
            let (pz, qz) = (_mm256_mul_ps(lo[2], iz), _mm256_mul_ps(hi[2], iz));
            let near = _mm256_max_ps(
                _mm256_max_ps(_mm256_max_ps(_mm256_min_ps(px, qx), _mm256_min_ps(py, qy)), _mm256_min_ps(pz, qz)),
                zero,
            );
            let far = _mm256_min_ps(
                _mm256_min_ps(_mm256_min_ps(_mm256_max_ps(px, qx), _mm256_max_ps(py, qy)), _mm256_max_ps(pz, qz)),
                far_limit,
            );
            let hits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32 & used;
            // SAFETY: a list holds at most one entry per ray of `rays`, and each ray is written
            // once (at the list's end, which advances only past the rays it keeps), so every write
            // lands below `start[l] + rays.len()`.
            unsafe {
                for lane in 0..4 {
                    *end[lane] = i;
                    end[lane] = end[lane].add((hits >> lane & 1) as usize);
                }
                if second {
                    for lane in 0..4 {
                        *end[lane] = j;
                        end[lane] = end[lane].add((hits >> (lane + 4) & 1) as usize);
                    }
                }
            }
        }
        // SAFETY: `end[l]` lies in the same allocation as `start[l]`, at or after it.
        std::array::from_fn(|lane| unsafe { end[lane].offset_from(start[lane]) } as usize)
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn occlude_pack(
        pack: &TrianglePack,
        origin: Vec3A,
        directions: &[Vec3A],
        rays: &[u32],
        tmax: f32,
        blocked: &mut [bool],
    ) -> u32 {
        let Some(edges) = pack.edges(origin) else { return 0 };
        let plane = |k: usize| [both(edges.planes[k][0]), both(edges.planes[k][1]), both(edges.planes[k][2])];
        let (ab, bc, ca) = (plane(0), plane(1), plane(2));
        let depth = both(edges.depth);
        let far_limit = _mm256_set1_ps(tmax);
        let zero = _mm256_setzero_ps();
        let mut hits = 0;
        // Every listed ray is tested, blocked or not (marking one again changes nothing): whether a
        // ray is blocked is data, and a branch on it mispredicts.
        for pair in rays.chunks(2) {
            let (i, j) = (pair[0], pair[pair.len() - 1]);
            let (a, b) = (at(directions, i), at(directions, j));
            let (x, y, z) = (halves(a.x, b.x), halves(a.y, b.y), halves(a.z, b.z));
            // d·plane, summed x, y, z in that order as `OneRay` does.
            let dot = |p: &[__m256; 3]| {
                _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(x, p[0]), _mm256_mul_ps(y, p[1])), _mm256_mul_ps(z, p[2]))
            };
            let (e0, e1, e2) = (dot(&ab), dot(&bc), dot(&ca));
            let inside = _mm256_and_ps(
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(e0, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(e1, zero)),
                _mm256_cmp_ps::<_CMP_GE_OQ>(e2, zero),
            );
            // The hit is at t = depth / (e0 + e1 + e2), as in `OneRay`.
            let sum = _mm256_add_ps(_mm256_add_ps(e0, e1), e2);
            let near = _mm256_cmp_ps::<_CMP_LT_OQ>(depth, _mm256_mul_ps(far_limit, sum));
            let mask = _mm256_movemask_ps(_mm256_and_ps(inside, near)) as u32;
            let (first, second) = (mask & edges.live != 0, (mask >> 4) & edges.live != 0);
            mark(blocked, i, first);
            mark(blocked, j, second);
            hits += u32::from(first) + u32::from(second);
        }
        hits
    }
}
