//! A light's own frame: the world turned so that a tilted light lies level and faces down.
//!
//! The top face, the Haar products and the part beyond the face all assume a horizontal light
//! facing down (Sun 2008 §4.5.4 parameterises a receiver's visibility on the cube face parallel
//! to the light). A tilted light keeps that form in its own frame: receivers, normals and ray
//! origins are turned into it, and each ray's direction is turned back into the world to be
//! traced. Lights with one frame share their receivers' top-face visibility.

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

/// How a light is oriented: tilted by `tilt` degrees about its width axis (right-handed; 0
/// faces straight down, 90 faces along its depth axis's negative side), then turned by `turn`
/// degrees about the vertical (right-handed about +y).
///
/// Its frame is the world turned by `R = R_y(turn) R_x(tilt) R_y(−turn)`, so that within it the
/// light is the untilted light turned by `turn` (the texture resampled into its bounding
/// rectangle as before). An untilted light's frame is the world itself, whatever its turn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LightFrame {
    pub turn: f64,
    pub tilt: f64,
}

impl LightFrame {
    /// The frame of a light turned by `turn` and tilted by `tilt` degrees; the world's own
    /// (`turn` forgotten) when the light is not tilted, so that every untilted light shares it.
    pub fn new(turn: f64, tilt: f64) -> Self {
        if tilt.rem_euclid(360.0) == 0.0 { Self::default() } else { Self { turn, tilt } }
    }

    /// Whether the frame is the world's.
    pub fn is_world(&self) -> bool {
        *self == Self::default()
    }

    /// `R`: light frame to world.
    pub fn to_world(&self) -> DMat3 {
        if self.is_world() {
            return DMat3::IDENTITY;
        }
        light_orientation(self.turn, self.tilt) * DMat3::from_rotation_y(-self.turn.to_radians())
    }

    /// `Rᵀ`: world to light frame.
    pub fn to_light(&self) -> DMat3 {
        self.to_world().transpose()
    }

    /// The world direction the light faces (its emitting side's normal).
    pub fn facing(&self) -> DVec3 {
        self.to_world() * DVec3::NEG_Y
    }
}

/// A light's own coordinates (width along `x`, depth along `z`, facing `−y`) to world offsets
/// from its centre: the tilt about the width axis, then the turn about `+y` (degrees).
pub fn light_orientation(turn: f64, tilt: f64) -> DMat3 {
    DMat3::from_rotation_y(turn.to_radians()) * DMat3::from_rotation_x(tilt.to_radians())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The frame turns the light's width axis (x turned by `turn`) onto itself, its facing
    /// onto the tilted normal, and is a rotation.
    #[test]
    fn a_tilt_turns_about_the_width_axis() {
        let frame = LightFrame::new(30.0, 40.0);
        let r = frame.to_world();
        let width_axis = DMat3::from_rotation_y(30f64.to_radians()) * DVec3::X;
        assert!((r * width_axis - width_axis).length() < 1e-12);
        assert!(
            (r.determinant() - 1.0).abs() < 1e-12
                && (r * r.transpose() - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12)
        );
        // Tilted by 40° from straight down, toward the depth axis's negative side.
        let facing = frame.facing();
        assert!((facing.dot(DVec3::NEG_Y) - 40f64.to_radians().cos()).abs() < 1e-12);
        let depth_axis = DMat3::from_rotation_y(30f64.to_radians()) * DVec3::Z;
        assert!((facing.dot(-depth_axis) - 40f64.to_radians().sin()).abs() < 1e-12);
        assert!(LightFrame::new(75.0, 0.0).is_world() && LightFrame::new(75.0, 360.0).is_world());
    }
}
