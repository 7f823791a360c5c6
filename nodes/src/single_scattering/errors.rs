//! The airlight tables' error against the reference over random queries (the experiments).

use super::*;

/// Errors of the table model against the reference over random parameters (the thesis's
/// Fig. 3.6 experiment): per sample, `|model − reference|` divided by the total airlight over
/// the hemisphere of view directions around the source (the thesis's normalisation), and
/// divided by the reference itself (pointwise relative error, the stricter measure).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ErrorStats {
    pub samples: usize,
    pub mean_normalised: f64,
    pub max_normalised: f64,
    pub mean_relative: f64,
    pub max_relative: f64,
}

/// Random `(β, D_sv, D_vp, γ)`: β log-uniform in [0.005, 0.5] /m, D_sv in [0.5, 50] m,
/// D_vp in [0.5, 100] m (log-uniform), γ uniform in (0, π); optical thicknesses span
/// 0.0025–25 (source) and 0.0025–50 (view), the range of the thesis's Fig. 3.7.
pub fn random_queries(count: usize, seed: u64) -> Vec<AirlightQuery> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(seed);
    let log_uniform =
        |lo: f64, hi: f64, rng: &mut rand::rngs::SmallRng| (lo.ln() + rng.random::<f64>() * (hi / lo).ln()).exp();
    (0..count)
        .map(|_| AirlightQuery {
            beta: log_uniform(0.005, 0.5, &mut rng),
            d_sv: log_uniform(0.5, 50.0, &mut rng),
            d_vp: log_uniform(0.5, 100.0, &mut rng),
            gamma: rng.random_range(1e-3..PI),
            i0: 1.0,
        })
        .collect()
}

/// The mean of the reference airlight over view directions in the hemisphere around the
/// source (`γ ∈ [0, π/2]`, weight `sin γ`), for the same medium and distances.
pub fn hemisphere_mean_airlight(q: &AirlightQuery, phase: &Phase) -> f64 {
    let (nodes, weights) = gauss_legendre(16);
    nodes
        .iter()
        .zip(&weights)
        .map(|(x, w)| {
            let g = (x + 1.0) * FRAC_PI_2 / 2.0;
            w * FRAC_PI_2 / 2.0 * g.sin() * airlight_reference(&AirlightQuery { gamma: g, ..*q }, phase)
        })
        .sum()
}

pub fn airlight_errors(
    queries: &[AirlightQuery],
    phase: &Phase,
    tables: &[FTable],
    interpolation: Interpolation,
) -> ErrorStats {
    use rayon::prelude::*;
    let errors: Vec<(f64, f64)> = queries
        .par_iter()
        .map(|q| {
            let reference = airlight_reference(q, phase);
            let model = airlight(q, phase, tables, interpolation);
            let norm = (2.0 * PI * hemisphere_mean_airlight(q, phase)).max(1e-300);
            ((model - reference).abs() / norm, (model - reference).abs() / reference.abs().max(1e-300))
        })
        .collect();
    let n = errors.len().max(1) as f64;
    ErrorStats {
        samples: errors.len(),
        mean_normalised: errors.iter().map(|e| e.0).sum::<f64>() / n,
        max_normalised: errors.iter().map(|e| e.0).fold(0.0, f64::max),
        mean_relative: errors.iter().map(|e| e.1).sum::<f64>() / n,
        max_relative: errors.iter().map(|e| e.1).fold(0.0, f64::max),
    }
}
