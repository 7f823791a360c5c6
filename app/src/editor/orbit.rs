//! The viewport's orbit camera (Blender-style navigation): orbit around a target, pan the
//! target in the view plane, dolly towards it, frame the scene.

use glam::{DVec3, Vec3};
use lightloom_nodes::project::Camera;
use lightloom_nodes::reference::PinholeCamera;
use lightloom_render::CameraView;

/// A camera orbiting `target` at `distance`, `yaw` around +Y (0 looks down -Z) and `pitch`
/// above the horizon, both in radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    pub target: DVec3,
    pub distance: f64,
    pub yaw: f64,
    pub pitch: f64,
    pub fov_y_deg: f64,
}

const PITCH_LIMIT: f64 = 1.55;

impl OrbitCamera {
    pub fn from_camera(camera: &Camera) -> Self {
        let target = DVec3::from(camera.target);
        let offset = DVec3::from(camera.position) - target;
        let distance = offset.length().max(1e-3);
        let pitch = (offset.y / distance).clamp(-1.0, 1.0).asin();
        let yaw = offset.x.atan2(offset.z);
        Self { target, distance, yaw, pitch, fov_y_deg: camera.fov_y_deg }
    }

    pub fn position(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + DVec3::new(sy * cp, sp, cy * cp) * self.distance
    }

    pub fn to_camera(self, name: &str) -> Camera {
        Camera {
            name: name.into(),
            position: self.position().to_array(),
            target: self.target.to_array(),
            fov_y_deg: self.fov_y_deg,
        }
    }

    pub fn view(&self) -> CameraView {
        CameraView {
            position: self.position().as_vec3(),
            target: self.target.as_vec3(),
            fov_y_deg: self.fov_y_deg as f32,
        }
    }

    pub fn pinhole(&self) -> PinholeCamera {
        PinholeCamera { position: self.position(), target: self.target, fov_y_deg: self.fov_y_deg }
    }

    /// The same view with a field of view `factor` times as tall (in tangent): a viewport
    /// `factor` times taller than the render frame shows the frame at the camera's field of view.
    pub fn widened(mut self, factor: f64) -> Self {
        let tan = (self.fov_y_deg.to_radians() / 2.0).tan() * factor;
        self.fov_y_deg = (2.0 * tan.atan()).to_degrees();
        self
    }

    /// Where world point `p` lands in a `width`×`height` image of this camera (pixels, y
    /// down), and its depth along the view; `None` behind the camera.
    pub fn project(&self, p: DVec3, (width, height): (f64, f64)) -> Option<((f64, f64), f64)> {
        let forward = (self.target - self.position()).normalize();
        let (right, up) = lightloom_nodes::reference::camera_basis(forward);
        let d = p - self.position();
        let depth = d.dot(forward);
        if depth <= 1e-6 {
            return None;
        }
        let tan = (self.fov_y_deg.to_radians() / 2.0).tan();
        let x = d.dot(right) / (depth * tan * width / height.max(1e-9));
        let y = d.dot(up) / (depth * tan);
        Some((((x * 0.5 + 0.5) * width, (0.5 - y * 0.5) * height), depth))
    }

    /// Moves world point `p` so that its image follows a drag of `(dx, dy)` pixels in an
    /// image `height` pixels tall, at the same depth (in the view plane through `p`).
    pub fn drag_point(&self, p: DVec3, (dx, dy): (f64, f64), height: f64) -> DVec3 {
        let forward = (self.target - self.position()).normalize();
        let (right, up) = lightloom_nodes::reference::camera_basis(forward);
        let depth = (p - self.position()).dot(forward).max(1e-6);
        let world_per_pixel = 2.0 * depth * (self.fov_y_deg.to_radians() / 2.0).tan() / height.max(1.0);
        p + (right * dx - up * dy) * world_per_pixel
    }

    /// Moves world point `p` within the plane through it of unit `normal` so that its image
    /// follows a drag of `(dx, dy)` pixels: to where the ray through the dragged image meets that
    /// plane. Where the plane is seen nearly edge-on, or the ray meets it behind the camera or
    /// past 100 camera distances, the view-plane move projected onto the plane instead. A level
    /// plane (`normal` ±y) keeps the height exactly: it is the light's plane, which keys its
    /// traced transport.
    pub fn drag_point_in_plane(&self, p: DVec3, normal: DVec3, delta: (f64, f64), height: f64) -> DVec3 {
        let in_plane = |q: DVec3| {
            let moved = q - normal * (q - p).dot(normal);
            if normal.x == 0.0 && normal.z == 0.0 { DVec3::new(moved.x, p.y, moved.z) } else { moved }
        };
        let dragged = self.drag_point(p, delta, height);
        let eye = self.position();
        let ray = (dragged - eye).normalize_or_zero();
        let facing = ray.dot(normal);
        if facing.abs() < 0.05 {
            return in_plane(dragged);
        }
        let t = (p - eye).dot(normal) / facing;
        if t <= 0.0 || t > 100.0 * self.distance.max(1.0) {
            return in_plane(dragged);
        }
        in_plane(eye + ray * t)
    }

    /// Turns by a drag of `(dx, dy)` pixels (a full viewport height ≈ half a turn).
    pub fn orbit(&mut self, (dx, dy): (f64, f64), viewport_height: f64) {
        let speed = std::f64::consts::PI / viewport_height.max(1.0);
        self.yaw -= dx * speed;
        self.pitch = (self.pitch + dy * speed).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// Moves the target so the scene follows a drag of `(dx, dy)` pixels.
    pub fn pan(&mut self, (dx, dy): (f64, f64), viewport_height: f64) {
        let forward = (self.target - self.position()).normalize();
        let (right, up) = lightloom_nodes::reference::camera_basis(forward);
        let world_per_pixel =
            2.0 * self.distance * (self.fov_y_deg.to_radians() / 2.0).tan() / viewport_height.max(1.0);
        self.target += (-right * dx + up * dy) * world_per_pixel;
    }

    /// Dollies towards the target: `factor < 1` moves closer.
    pub fn zoom(&mut self, factor: f64) {
        if factor.is_finite() && factor > 0.0 {
            self.distance = (self.distance * factor).clamp(1e-3, 1e6);
        }
    }

    /// Looks at the centre of `bounds` from the current direction, far enough to see it all.
    pub fn frame(&mut self, (lo, hi): ([f32; 3], [f32; 3])) {
        let (lo, hi) = (Vec3::from(lo).as_dvec3(), Vec3::from(hi).as_dvec3());
        if !(lo.x <= hi.x && lo.is_finite() && hi.is_finite()) {
            return;
        }
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        self.target = (lo + hi) * 0.5;
        self.distance = radius / (self.fov_y_deg.to_radians() / 2.0).sin() * 1.1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera { name: "c".into(), position: [1.0, 2.0, 5.0], target: [0.0, 0.5, 0.0], fov_y_deg: 40.0 }
    }

    #[test]
    fn a_project_camera_round_trips() {
        let orbit = OrbitCamera::from_camera(&camera());
        let back = orbit.to_camera("c");
        for i in 0..3 {
            assert!((back.position[i] - camera().position[i]).abs() < 1e-9);
        }
        assert_eq!(back.target, camera().target);
    }

    #[test]
    fn orbiting_keeps_the_distance_and_panning_keeps_the_view_direction() {
        let mut orbit = OrbitCamera::from_camera(&camera());
        let d = orbit.distance;
        orbit.orbit((120.0, -40.0), 600.0);
        assert!(((orbit.position() - orbit.target).length() - d).abs() < 1e-9);
        orbit.orbit((0.0, 1e6), 600.0);
        assert!(orbit.pitch <= PITCH_LIMIT, "the camera never flips over the pole");
        let forward = (orbit.target - orbit.position()).normalize();
        let target = orbit.target;
        orbit.pan((30.0, 10.0), 600.0);
        let moved = orbit.target - target;
        assert!(moved.length() > 0.0 && moved.dot(forward).abs() < 1e-9, "panning moves in the view plane");
        assert!(((orbit.target - orbit.position()).normalize() - forward).length() < 1e-9);
        orbit.zoom(0.5);
        assert!((orbit.distance - d * 0.5).abs() < 1e-9);
    }

    #[test]
    fn a_dragged_point_follows_the_pointer_at_its_depth() {
        let orbit = OrbitCamera::from_camera(&camera()).widened(1.3);
        let size = (800.0, 500.0);
        // The target projects to the image centre.
        let (centre, _) = orbit.project(orbit.target, size).unwrap();
        assert!((centre.0 - 400.0).abs() < 1e-9 && (centre.1 - 250.0).abs() < 1e-9);
        let p = DVec3::new(0.7, 1.4, -0.3);
        let ((x, y), depth) = orbit.project(p, size).unwrap();
        let moved = orbit.drag_point(p, (35.0, -20.0), size.1);
        let ((x2, y2), depth2) = orbit.project(moved, size).unwrap();
        assert!((x2 - x - 35.0).abs() < 1e-6 && (y2 - y + 20.0).abs() < 1e-6, "({x}, {y}) → ({x2}, {y2})");
        assert!((depth2 - depth).abs() < 1e-9, "the point stays at its depth");
        // Behind the camera there is no image.
        let behind = orbit.position() * 2.0 - orbit.target;
        assert!(orbit.project(behind, size).is_none());
    }

    /// A point dragged in a tilted plane stays in it and lands under the pointer; in a level
    /// plane its height is kept to the bit (the light's plane keys its traced transport).
    #[test]
    fn a_point_dragged_in_its_plane_stays_in_it_under_the_pointer() {
        let orbit = OrbitCamera::from_camera(&camera()).widened(1.3);
        let size = (800.0, 500.0);
        let p = DVec3::new(0.7, 1.4, -0.3);
        let ((x, y), _) = orbit.project(p, size).unwrap();
        let normal = DVec3::new(0.4, 0.8, -0.3).normalize();
        let moved = orbit.drag_point_in_plane(p, normal, (35.0, -20.0), size.1);
        assert!((moved - p).dot(normal).abs() < 1e-12 && (moved - p).length() > 0.05, "{moved}");
        let ((x2, y2), _) = orbit.project(moved, size).unwrap();
        assert!((x2 - x - 35.0).abs() < 1e-6 && (y2 - y + 20.0).abs() < 1e-6, "({x}, {y}) → ({x2}, {y2})");
        let level = orbit.drag_point_in_plane(p, DVec3::Y, (35.0, -20.0), size.1);
        assert_eq!(level.y.to_bits(), p.y.to_bits());
        // A plane seen edge-on takes the view-plane move, kept in the plane.
        let eye = orbit.position();
        let edge_on = (p - eye).cross(DVec3::Y).normalize();
        let moved = orbit.drag_point_in_plane(p, edge_on, (35.0, -20.0), size.1);
        assert!((moved - p).dot(edge_on).abs() < 1e-9 && moved.is_finite());
    }

    #[test]
    fn framing_fits_the_bounds_in_view() {
        let mut orbit = OrbitCamera::from_camera(&camera());
        orbit.frame(([-2.0, 0.0, -2.0], [2.0, 1.0, 2.0]));
        assert_eq!(orbit.target, DVec3::new(0.0, 0.5, 0.0));
        let radius = DVec3::new(4.0, 1.0, 4.0).length() / 2.0;
        // The bounding sphere subtends at most the vertical field of view.
        let half_angle = (radius / orbit.distance).asin().to_degrees();
        assert!(half_angle <= orbit.fov_y_deg / 2.0 && half_angle > orbit.fov_y_deg / 2.0 * 0.8);
    }
}
