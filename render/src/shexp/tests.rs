use super::*;
use lightloom_nodes::kinds::blockers::ShadowTables;
use lightloom_nodes::sh_exponential::{BlockedProduct, LOG_CLIP_RELATIVE, LogCapTable, OlTable, ShExp, training_logs};

/// A set at `bands` with the node's tables (512 log entries, OL fitted as the node fits it).
fn set(bands: usize, method: ExpMethod, blockers: Vec<Blocker>) -> BlockerSet {
    let shexp = ShExp::new(bands);
    let log = LogCapTable::new(&shexp, 512, LOG_CLIP_RELATIVE);
    let ol = OlTable::fit(&shexp, &training_logs(&log, 600, 7), 64, 8.0, 0.5);
    BlockerSet { blockers, method, strength: 1.0, tables: ShadowTables { log, ol } }
}

/// A deterministic stream in [0, 1).
fn uniform(state: &mut u64) -> f64 {
    *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 53) as f64
}

/// Receivers on a 3 m floor (one inside a sphere) under eight spheres, and two random
/// transport vectors per receiver.
fn scene(bands_t: usize) -> (Vec<DVec3>, Vec<Blocker>, Vec<Vec<f32>>) {
    let mut state = 42;
    let mut positions: Vec<DVec3> =
        (0..900).map(|i| DVec3::new((i % 30) as f64 * 0.1 - 1.5, 0.0, (i / 30) as f64 * 0.1 - 1.5)).collect();
    let blockers: Vec<Blocker> = (0..8)
        .map(|_| Blocker {
            centre: [uniform(&mut state) * 2.0 - 1.0, 0.3 + uniform(&mut state), uniform(&mut state) * 2.0 - 1.0],
            radius: 0.1 + 0.2 * uniform(&mut state),
        })
        .collect();
    positions.push(DVec3::from(blockers[0].centre));
    let n = bands_t * bands_t;
    let vectors = (0..2)
        .map(|_| {
            (0..positions.len() * n).map(|k| if k % n == 0 { 1.5 } else { uniform(&mut state) as f32 - 0.5 }).collect()
        })
        .collect();
    (positions, blockers, vectors)
}

/// The GPU kernel against the CPU twin (`BlockedProduct::apply`, f64) on the same clusters:
/// PS*-2 and HYB at order 4 on 6-band transport, and PS*-4 at order 6 on 14 bands.
#[test]
fn the_gpu_product_matches_the_cpu_twin() {
    let gpu = GpuContext::headless().expect("a wgpu device (lavapipe on machines without a GPU)");
    for (bands_b, bands_t, method) in
        [(4, 6, ExpMethod::PsStar(2)), (4, 6, ExpMethod::Hyb), (6, 14, ExpMethod::PsStar(4))]
    {
        let (positions, blockers, vectors) = scene(bands_t);
        let set = set(bands_b, method, blockers.clone());
        let culled = cull(&positions, &blockers, 64);
        let (mut gpu_v, mut gpu_t) = (vectors[0].clone(), vectors[1].clone());
        let product = GpuBlockedProduct::new(&gpu, &set, bands_t).unwrap();
        product.apply(&gpu, &positions, &blockers, &culled, &mut [&mut gpu_v, &mut gpu_t]).unwrap();

        let (mut cpu_v, mut cpu_t) = (vectors[0].clone(), vectors[1].clone());
        let cpu = BlockedProduct::new(set.shexp(), bands_t);
        let n = bands_t * bands_t;
        for (p, &(first, count)) in culled.ranges.iter().enumerate() {
            let members: Vec<usize> = (0..positions.len()).filter(|&i| culled.part_of[i] as usize == p).collect();
            let near: Vec<Blocker> = culled.spheres[first as usize..(first + count) as usize]
                .iter()
                .map(|&s| blockers[s as usize])
                .collect();
            let points: Vec<DVec3> = members.iter().map(|&i| positions[i]).collect();
            let gather = |data: &[f32]| -> Vec<f32> {
                members.iter().flat_map(|&i| data[i * n..(i + 1) * n].iter().copied()).collect()
            };
            let (mut v, mut t) = (gather(&cpu_v), gather(&cpu_t));
            cpu.apply(&points, &near, &set.tables.log, method, 1.0, &mut [&mut v, &mut t]);
            for (k, &i) in members.iter().enumerate() {
                cpu_v[i * n..(i + 1) * n].copy_from_slice(&v[k * n..(k + 1) * n]);
                cpu_t[i * n..(i + 1) * n].copy_from_slice(&t[k * n..(k + 1) * n]);
            }
        }
        let scale = cpu_v.iter().chain(&cpu_t).fold(0f32, |m, v| m.max(v.abs()));
        for i in 0..positions.len() {
            let worst = [(&gpu_v, &cpu_v), (&gpu_t, &cpu_t)]
                .iter()
                .flat_map(|(g, c)| (i * n..(i + 1) * n).map(|k| (g[k] - c[k]).abs()))
                .fold(0f32, f32::max);
            if worst <= 2e-3 * scale {
                continue;
            }
            // HYB halves f̂ until its norm is under a threshold: where the norm sits on it (or
            // a power of two above), f32 and f64 may halve a different number of times, and
            // OL (an approximation) then lands elsewhere. The f32 log sums differ from the f64
            // ones by about 1e-4 of their norm, so "on it" is within 1e-3 octave. Nowhere else
            // may they differ.
            let near = hyb_halving_edge(&set, &positions[i], &culled, i);
            assert!(
                method == ExpMethod::Hyb && near < 1e-3,
                "order {bands_b}, {bands_t} transport bands, {method:?}: receiver {i} off by {worst} of {scale} \
                 (log2 distance of its norm to a halving edge {near})"
            );
        }
        // Not a trivial pass: the spheres darken the floor, and the receiver inside one is black.
        let shadowed = (0..positions.len()).filter(|&i| (cpu_v[i * n] - vectors[0][i * n]).abs() > 0.05).count();
        assert!(shadowed > 50, "{shadowed} receivers shadowed");
        let inside = positions.len() - 1;
        assert!(
            gpu_v[inside * n..(inside + 1) * n].iter().all(|&v| v == 0.0),
            "a receiver inside a sphere sees nothing"
        );
    }
}

/// How far (in log₂) receiver `i`'s ‖f̂‖ lies from HYB's halving threshold times a power of two.
fn hyb_halving_edge(set: &BlockerSet, x: &DVec3, culled: &Culled, i: usize) -> f64 {
    let bands = set.bands();
    let basis = lightloom_nodes::sh::ShBasis::new(bands);
    let mut scratch = lightloom_nodes::sh_exponential::LogScratch::new(bands);
    let mut f = vec![0.0; bands * bands];
    let (first, count) = culled.ranges[culled.part_of[i] as usize];
    for &s in &culled.spheres[first as usize..(first + count) as usize] {
        set.blockers[s as usize].add_log(*x, &set.tables.log, &basis, 1.0, &mut scratch, &mut f);
    }
    let norm = f[1..].iter().map(|v| v * v).sum::<f64>().sqrt();
    let octaves = (norm / set.tables.ol.halving_threshold).log2();
    (octaves - octaves.round()).abs()
}

/// Every sphere whose influence reaches a receiver is listed for its cluster (brute force).
#[test]
fn clusters_list_every_sphere_that_reaches_their_receivers() {
    let (positions, blockers, _) = scene(2);
    let culled = cull(&positions, &blockers, 32);
    assert!(culled.ranges.len() > 1);
    for (i, x) in positions.iter().enumerate() {
        let (first, count) = culled.ranges[culled.part_of[i] as usize];
        let listed = &culled.spheres[first as usize..(first + count) as usize];
        for (s, b) in blockers.iter().enumerate() {
            if (DVec3::from(b.centre) - *x).length() <= b.influence_radius() {
                assert!(listed.contains(&(s as u32)), "sphere {s} reaches receiver {i} but is not listed");
            }
        }
    }
}

/// Orders beyond the kernel's arrays and vectors of the wrong length are refused with a reason.
#[test]
fn sizes_the_kernel_cannot_hold_are_refused() {
    let gpu = GpuContext::headless().expect("a wgpu device");
    let (positions, blockers, mut vectors) = scene(4);
    let wide = set(7, ExpMethod::PsStar(2), blockers.clone());
    let refused = GpuBlockedProduct::new(&gpu, &wide, 4).err().expect("7 visibility bands are refused");
    assert!(refused.to_string().contains("up to 6 visibility bands"), "{refused}");
    let product = GpuBlockedProduct::new(&gpu, &set(3, ExpMethod::PsStar(2), blockers.clone()), 5).unwrap();
    let culled = cull(&positions, &blockers, 64);
    let error = product.apply(&gpu, &positions, &blockers, &culled, &mut [&mut vectors[0]]).unwrap_err();
    assert!(error.to_string().contains("25 coefficients per vector"), "{error}");
}
