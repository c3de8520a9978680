use glam::Vec3A;
use quiver::geometry::{Aabb, Ray};

/// A pinhole camera in the SPD/NFF convention.
///
/// `angle` is the full field of view in degrees, from the top image edge to the bottom one
/// (the image is square, as in every SPD scene).
///
/// ```
/// use quiver_scenes::scene::Camera;
/// use glam::Vec3A;
/// let cam = Camera::new(Vec3A::ZERO, Vec3A::Z, Vec3A::Y, 90.0);
/// let centre = cam.ray(0.0, 0.0);
/// assert!((centre.dir - Vec3A::Z).length() < 1e-6);
/// assert!((cam.ray(0.0, 1.0).dir.normalize().y - 0.5f32.sqrt()).abs() < 1e-6);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub from: Vec3A,
    /// Point at the image centre.
    pub at: Vec3A,
    /// Up direction (need not be perpendicular to the view).
    pub up: Vec3A,
    /// Full field of view in degrees.
    pub angle: f32,
}

impl Camera {
    /// A camera from eye, look-at point, up vector and field of view.
    pub fn new(from: Vec3A, at: Vec3A, up: Vec3A, angle: f32) -> Self {
        Camera {
            from,
            at,
            up,
            angle,
        }
    }

    /// A camera that frames `bounds` from a diagonal viewpoint (for files without one).
    pub fn framing(bounds: &Aabb) -> Self {
        let (c, r) = if bounds.is_empty() {
            (Vec3A::ZERO, 1.0)
        } else {
            (bounds.center(), (bounds.extent().length() * 0.5).max(1e-6))
        };
        let dir = Vec3A::new(0.6, 0.45, 1.0).normalize();
        // 45° full angle: the bounding sphere fits when the distance is r / sin(22.5°).
        let dist = r / (22.5f32).to_radians().sin();
        let cam = Camera::new(c + dir * dist, c, Vec3A::Y, 45.0);
        if cam.from.is_finite() && cam.at.is_finite() && cam.from != cam.at {
            cam
        } else {
            // Bounds too large (or too small) to frame in f32: a fixed view of the origin.
            Camera::new(Vec3A::new(0.0, 0.0, 10.0), Vec3A::ZERO, Vec3A::Y, 45.0)
        }
    }

    /// The eye ray through image-plane point `(sx, sy)`, both in `[-1, 1]`: `(-1, 1)` is the
    /// top-left edge of the field of view. The direction is normalised.
    pub fn ray(&self, sx: f32, sy: f32) -> Ray {
        let w = (self.at - self.from).normalize();
        let right = w.cross(self.up).normalize();
        let up = right.cross(w);
        let h = (self.angle.to_radians() * 0.5).tan();
        let dir = (w + right * (sx * h) + up * (sy * h)).normalize();
        Ray::new(self.from, dir)
    }
}
