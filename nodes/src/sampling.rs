//! Random sampling helpers shared by Monte Carlo estimators and tests.

use glam::{DMat3, DQuat, DVec3};
use rand::{Rng, SeedableRng, rngs::SmallRng};
use std::f64::consts::PI;

/// A deterministic generator for reproducible estimates.
pub fn test_rng(seed: u64) -> SmallRng {
    SmallRng::seed_from_u64(seed)
}

/// Uniform direction on the unit sphere.
pub fn random_unit_vector(rng: &mut impl Rng) -> DVec3 {
    uniform_sphere(rng.random(), rng.random())
}

/// Maps `(u1, u2) ∈ [0,1)²` to a uniform direction on the sphere (pdf `1/4π`).
pub fn uniform_sphere(u1: f64, u2: f64) -> DVec3 {
    let z = 1.0 - 2.0 * u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Uniformly distributed rotation (Shoemake's quaternion method).
pub fn random_rotation(rng: &mut impl Rng) -> DMat3 {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let q = DQuat::from_xyzw(
        a * (2.0 * PI * u2).sin(),
        a * (2.0 * PI * u2).cos(),
        b * (2.0 * PI * u3).sin(),
        b * (2.0 * PI * u3).cos(),
    );
    DMat3::from_quat(q.normalize())
}
