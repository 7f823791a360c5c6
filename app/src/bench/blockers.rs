//! `lightloom bench --only blockers`: blocker sphere sets (Sun 2008 §5.2) on the CPU and the GPU.
//!
//! * Fig. 5.5: per receiver, 60 spheres, SH order 3–6: the visibility as a chain of truncated
//!   products against log-space accumulation and one PS*-2 exponential (thesis: 1.9× / 3.4× /
//!   6.5× / 11.0×).
//! * The thesis's scenes at order 4: 65k receivers under 244 moving spheres and 120k under 500
//!   (thesis: 22.4 Hz and 12.6 Hz average on a GeForce 7800 GTX): the blocked transport from
//!   scratch, after one sphere moves (only the receiver parts within its reach; the engine's
//!   stage adds gathering and hashing every part), and after every sphere moves; then the same
//!   update split between the CPU (clusters and sphere lists) and the GPU (log sum,
//!   exponential and product per receiver).

use lightloom_nodes::kinds::blockers::{BlockerSet, ShadowTables};
use lightloom_nodes::sh::ShBasis;
use lightloom_nodes::sh_exponential::{
    BlockedProduct, Blocker, ExpMethod, LOG_CLIP_RELATIVE, LogCapTable, LogScratch, ShExp, add_rotated_zonal,
    blockers_in_reach, cap_zonal, receiver_parts,
};
use lightloom_nodes::sh_exponential::{OlTable, training_logs};
use lightloom_render::GpuContext;
use lightloom_render::shexp::{GpuBlockedProduct, GpuTimings, cull};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use std::time::Instant;

pub fn blocker_figures(gpu: &GpuContext) {
    speed_up_table();
    for (receivers, spheres) in [(65_000, 244), (120_000, 500)] {
        update_rate(gpu, receivers, spheres);
    }
}

/// 60 random spheres around the origin (angular radii up to about 40°).
fn spheres_around(rng: &mut SmallRng, count: usize) -> Vec<Blocker> {
    (0..count)
        .map(|_| Blocker {
            centre: [rng.random_range(-3.0..3.0), rng.random_range(0.5..4.0), rng.random_range(-3.0..3.0)],
            radius: rng.random_range(0.2..0.6),
        })
        .collect()
}

fn speed_up_table() {
    println!(
        "Blocker spheres, Fig. 5.5 (60 spheres, per receiver; thesis speed-up 1.9 / 3.4 / 6.5 / 11.0x at n = 3..6):"
    );
    let mut rng = SmallRng::seed_from_u64(55);
    let spheres = spheres_around(&mut rng, 60);
    let receivers: Vec<glam::DVec3> =
        (0..400).map(|_| glam::DVec3::new(rng.random_range(-2.0..2.0), 0.0, rng.random_range(-2.0..2.0))).collect();
    for bands in 3..=6 {
        let shexp = ShExp::new(bands);
        let table = LogCapTable::new(&shexp, 512, LOG_CLIP_RELATIVE);
        let basis = ShBasis::new(bands);
        let mut y = vec![0.0; bands * bands];
        let start = Instant::now();
        let mut sink = 0.0;
        for x in &receivers {
            let mut g = shexp.one();
            for s in &spheres {
                let to = glam::DVec3::from(s.centre) - *x;
                let mut cap = vec![0.0; bands * bands];
                let theta = (s.radius / to.length()).min(1.0).asin();
                add_rotated_zonal(&basis, &cap_zonal(bands, theta.cos()), to.normalize(), 1.0, &mut y, &mut cap);
                g = shexp.product(&g, &cap);
            }
            sink += g[0];
        }
        let chain = start.elapsed().as_secs_f64() / receivers.len() as f64;
        let start = Instant::now();
        let mut scratch = LogScratch::new(bands);
        for x in &receivers {
            let mut f = vec![0.0; bands * bands];
            for s in &spheres {
                s.add_log(*x, &table, &basis, 1.0, &mut scratch, &mut f);
            }
            sink += shexp.exp_ps_star(&f, 2)[0];
        }
        let log = start.elapsed().as_secs_f64() / receivers.len() as f64;
        std::hint::black_box(sink);
        println!(
            "  n = {bands}: product chain {:.1} us, log space + PS*-2 {:.1} us per receiver: {:.1}x",
            chain * 1e6,
            log * 1e6,
            chain / log
        );
    }
}

/// A floor of `count` receivers (a square grid, 30 m wide) under `spheres` spheres in clumps
/// (characters), order 4, PS*-2.
fn update_rate(gpu: &GpuContext, count: usize, spheres: usize) {
    let side = (count as f64).sqrt().ceil() as usize;
    let receivers: Vec<glam::DVec3> = (0..side * side)
        .map(|i| {
            glam::DVec3::new(
                -15.0 + 30.0 * (i % side) as f64 / side as f64,
                0.0,
                -15.0 + 30.0 * (i / side) as f64 / side as f64,
            )
        })
        .collect();
    let mut rng = SmallRng::seed_from_u64(7);
    let clumps: Vec<[f64; 2]> =
        (0..8).map(|_| [rng.random_range(-12.0..12.0), rng.random_range(-12.0..12.0)]).collect();
    let mut blockers: Vec<Blocker> = (0..spheres)
        .map(|i| {
            let c = clumps[i % clumps.len()];
            Blocker {
                centre: [
                    c[0] + rng.random_range(-0.6..0.6),
                    rng.random_range(0.2..1.8),
                    c[1] + rng.random_range(-0.6..0.6),
                ],
                radius: rng.random_range(0.08..0.25),
            }
        })
        .collect();
    let bands = 4;
    let shexp = ShExp::new(bands);
    let table = LogCapTable::new(&shexp, 512, LOG_CLIP_RELATIVE);
    let product = BlockedProduct::new(ShExp::new(bands), bands);
    let transfer: Vec<f32> = (0..receivers.len() * 16).map(|i| if i % 16 == 0 { 1.0 } else { 0.1 }).collect();
    let parts = receiver_parts(&receivers, 256);
    let run = |blockers: &[Blocker], which: &[usize]| -> f64 {
        let start = Instant::now();
        which.par_iter().for_each(|&p| {
            let points: Vec<glam::DVec3> = parts[p].iter().map(|&i| receivers[i]).collect();
            let near = blockers_in_reach(&points, blockers);
            if near.is_empty() {
                return;
            }
            let mut t: Vec<f32> =
                parts[p].iter().flat_map(|&i| transfer[i * 16..(i + 1) * 16].iter().copied()).collect();
            let mut v = t.clone();
            product.apply(&points, &near, &table, ExpMethod::PsStar(2), 1.0, &mut [&mut v, &mut t]);
        });
        start.elapsed().as_secs_f64()
    };
    let all: Vec<usize> = (0..parts.len()).collect();
    let full = run(&blockers, &all);
    // One sphere moves 10 cm: the parts it reaches, before or after.
    let old = blockers[0];
    blockers[0].centre[0] += 0.1;
    let touched: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&p| {
            let points: Vec<glam::DVec3> = parts[p].iter().map(|&i| receivers[i]).collect();
            !blockers_in_reach(&points, &[old, blockers[0]]).is_empty()
        })
        .collect();
    let moved = run(&blockers, &touched);
    // Every sphere moves 10 cm (animated characters): all parts in reach.
    for b in &mut blockers {
        b.centre[2] += 0.1;
    }
    let every = run(&blockers, &all);
    let gpu_line = gpu_update(gpu, &receivers, &blockers, &transfer, &table);
    println!(
        "  {} receivers, {spheres} spheres, order 4 (thesis: {} Hz on a 7800 GTX): from scratch {:.0} ms; one sphere moved \
         {:.1} ms ({} of {} parts); all spheres moved {:.0} ms = {:.1} Hz on this CPU",
        receivers.len(),
        if spheres == 244 { "22.4" } else { "12.6" },
        full * 1e3,
        moved * 1e3,
        touched.len(),
        parts.len(),
        every * 1e3,
        1.0 / every
    );
    println!("    {gpu_line}");
}

/// Every sphere moved, the thesis's way: clusters and sphere lists on the CPU, the log sum,
/// exponential and product on the GPU (`lightloom_render::shexp`), on the same two vectors
/// per receiver as the CPU rows.
fn gpu_update(
    gpu: &GpuContext,
    receivers: &[glam::DVec3],
    blockers: &[Blocker],
    transfer: &[f32],
    table: &LogCapTable,
) -> String {
    let shexp = ShExp::new(table.bands);
    let ol = OlTable::fit(&shexp, &training_logs(table, 300, 3), 64, 8.0, 0.5);
    let set = BlockerSet {
        blockers: blockers.to_vec(),
        method: ExpMethod::PsStar(2),
        strength: 1.0,
        tables: ShadowTables { log: table.clone(), ol },
    };
    let product = match GpuBlockedProduct::new(gpu, &set, table.bands) {
        Ok(p) => p,
        Err(e) => return format!("GPU: {e}"),
    };
    // The fastest of three updates.
    let mut best: Option<(f64, f64, GpuTimings)> = None;
    for _ in 0..3 {
        let start = Instant::now();
        let culled = cull(receivers, blockers, 256);
        let cpu = start.elapsed().as_secs_f64();
        let (mut v, mut t) = (transfer.to_vec(), transfer.to_vec());
        let timings = match product.apply(gpu, receivers, blockers, &culled, &mut [&mut v, &mut t]) {
            Ok(timings) => timings,
            Err(e) => return format!("GPU: {e}"),
        };
        let total = cpu + (timings.upload + timings.kernel + timings.readback).as_secs_f64();
        if best.as_ref().is_none_or(|b| total < b.0) {
            best = Some((total, cpu, timings));
        }
    }
    let (total, cpu, t) = best.expect("three runs");
    format!(
        "split, all spheres moved: CPU clusters and lists {:.1} ms; GPU upload {:.1} ms, kernel {:.1} ms, readback {:.1} ms \
         ({}); {:.1} Hz in all, {:.1} Hz kernel only",
        cpu * 1e3,
        t.upload.as_secs_f64() * 1e3,
        t.kernel.as_secs_f64() * 1e3,
        t.readback.as_secs_f64() * 1e3,
        gpu.describe(),
        1.0 / total,
        1.0 / t.kernel.as_secs_f64()
    )
}
