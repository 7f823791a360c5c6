//! Lights as every technique sees them: plain data, whatever node made them.

use serde::{Deserialize, Serialize};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(Vec<PointLight>, "lights", |v| v.len() * 48);

/// A point light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointLight {
    pub position: [f64; 3],
    /// Radiant intensity per channel, W/sr.
    pub intensity: [f64; 3],
}
