use glam::Vec3A;
use quiver_rt::geometry::{unit_or_zero, Aabb, Ray};
use std::fmt;

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
    /// Up direction (need not be perpendicular to the view, but must not be parallel to it).
    pub up: Vec3A,
    /// Full field of view in degrees.
    pub angle: f32,
}

/// Why a camera cannot make eye rays. [`CameraError::field`] names the NFF field at fault.
///
/// ```
/// use quiver_scenes::scene::{Camera, CameraError};
/// use glam::Vec3A;
/// let e = Camera::try_new(Vec3A::Z * 5.0, Vec3A::ZERO, Vec3A::Z, 45.0).unwrap_err();
/// assert_eq!(e, CameraError::UpAlongView);
/// assert_eq!(e.field(), "up");
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CameraError {
    /// A field (`from`, `at`, `up` or `angle`) holds a NaN or an infinity.
    NonFinite(&'static str),
    /// `from` and `at` are the same point, or so close together or far apart that their
    /// difference has no direction in f32.
    NoViewDirection,
    /// `up` is zero or parallel to the view direction, so the image has no up.
    UpAlongView,
    /// The field of view is not strictly between 0 and 180 degrees.
    Angle(f32),
    /// [`Camera::framing`] was given bounds no f32 camera can frame: not finite, or so large
    /// that the eye point outside them would pass the largest f32 (coordinates within about
    /// a factor 4 of `f32::MAX`).
    CannotFrame,
}

impl CameraError {
    /// The field the fault is reported against: `from`, `at`, `up` or `angle`.
    pub fn field(&self) -> &'static str {
        match self {
            CameraError::NonFinite(f) => f,
            CameraError::NoViewDirection => "at",
            CameraError::UpAlongView => "up",
            CameraError::Angle(_) => "angle",
            CameraError::CannotFrame => "from",
        }
    }
}

impl fmt::Display for CameraError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CameraError::NonFinite(field) => write!(f, "camera '{field}' is not finite"),
            CameraError::NoViewDirection => write!(
                f,
                "camera 'at' gives no view direction: it is the same point as 'from' \
                 (or so far from it that the difference overflows f32)"
            ),
            CameraError::UpAlongView => write!(
                f,
                "camera 'up' is zero or parallel to the view direction from 'from' to 'at'"
            ),
            CameraError::Angle(a) => write!(
                f,
                "camera 'angle' {a} must lie strictly between 0 and 180 degrees"
            ),
            CameraError::CannotFrame => write!(
                f,
                "no camera can frame these bounds in f32: they are not finite, or so large that \
                 a viewpoint outside them lies beyond the largest f32 (give the scene a view)"
            ),
        }
    }
}

impl std::error::Error for CameraError {}

impl Camera {
    /// A camera from eye, look-at point, up vector and field of view, unchecked: a degenerate
    /// one (see [`CameraError`]) makes NaN eye rays, so input from outside the program goes
    /// through [`Camera::try_new`] instead.
    pub fn new(from: Vec3A, at: Vec3A, up: Vec3A, angle: f32) -> Self {
        Camera {
            from,
            at,
            up,
            angle,
        }
    }

    /// [`Camera::new`], or why its eye rays would not be finite.
    ///
    /// ```
    /// use quiver_scenes::scene::{Camera, CameraError};
    /// use glam::Vec3A;
    /// assert!(Camera::try_new(Vec3A::Z, Vec3A::ZERO, Vec3A::Y, 45.0).is_ok());
    /// let same = Camera::try_new(Vec3A::ONE, Vec3A::ONE, Vec3A::Y, 45.0);
    /// assert_eq!(same.unwrap_err(), CameraError::NoViewDirection);
    /// let wide = Camera::try_new(Vec3A::Z, Vec3A::ZERO, Vec3A::Y, 180.0);
    /// assert_eq!(wide.unwrap_err(), CameraError::Angle(180.0));
    /// ```
    pub fn try_new(from: Vec3A, at: Vec3A, up: Vec3A, angle: f32) -> Result<Self, CameraError> {
        let cam = Camera::new(from, at, up, angle);
        cam.validate()?;
        Ok(cam)
    }

    /// Checks that every eye ray [`Camera::ray`] makes is finite.
    pub fn validate(&self) -> Result<(), CameraError> {
        for (field, v) in [("from", self.from), ("at", self.at), ("up", self.up)] {
            if !v.is_finite() {
                return Err(CameraError::NonFinite(field));
            }
        }
        if !self.angle.is_finite() {
            return Err(CameraError::NonFinite("angle"));
        }
        if !(self.angle > 0.0 && self.angle < 180.0) {
            return Err(CameraError::Angle(self.angle));
        }
        // At any scale (`unit_or_zero`): zero only when the points match or their difference
        // overflows.
        let w = unit_or_zero(self.at - self.from);
        if w == Vec3A::ZERO {
            return Err(CameraError::NoViewDirection);
        }
        // Within about 1e-6 radians of the view the image's roll is f32 noise, and at 0 `ray`
        // has no right-hand direction.
        let right = w.cross(unit_or_zero(self.up));
        if right.length() <= 1e-6 {
            return Err(CameraError::UpAlongView);
        }
        Ok(())
    }

    /// A camera that frames `bounds` from a diagonal viewpoint (for files without one): the
    /// bounding sphere fills a 45° view. Computed in f64, so it works at any scale f32 can
    /// hold, and alike at every scale (bounds scaled by a power of two give the camera scaled
    /// by the same power, bit for bit); empty bounds get a view of the unit sphere at the
    /// origin. Fails ([`CameraError::CannotFrame`]) rather than return a view that does not
    /// show the bounds: for bounds that are not finite, and for bounds so large that the
    /// viewpoint, about 4.5 half-diagonals from the centre, would lie beyond `f32::MAX`.
    ///
    /// ```
    /// use quiver_scenes::scene::{Camera, CameraError};
    /// use quiver_rt::geometry::Aabb;
    /// use glam::Vec3A;
    /// let unit = Camera::framing(&Aabb::new(Vec3A::ZERO, Vec3A::ONE)).unwrap();
    /// assert_eq!(unit.at, Vec3A::splat(0.5));
    /// // 2e19 overflowed the f32 length of the extent, once.
    /// let big = Camera::framing(&Aabb::new(Vec3A::splat(-2e19), Vec3A::splat(2e19))).unwrap();
    /// assert!(big.from.length() > 2e19 && big.validate().is_ok());
    /// let huge = Aabb::new(Vec3A::splat(-3e38), Vec3A::splat(3e38));
    /// assert_eq!(Camera::framing(&huge), Err(CameraError::CannotFrame));
    /// ```
    pub fn framing(bounds: &Aabb) -> Result<Self, CameraError> {
        use glam::DVec3;
        let d = |v: Vec3A| DVec3::new(v.x as f64, v.y as f64, v.z as f64);
        let (c, r) = if bounds.is_empty() {
            (DVec3::ZERO, 1.0)
        } else {
            let (lo, hi) = (d(bounds.min), d(bounds.max));
            if !(lo.is_finite() && hi.is_finite()) {
                return Err(CameraError::CannotFrame);
            }
            // f64 holds the extent and its length for any f32 bounds. A point (no extent)
            // gets a sphere a few ulps across, so the view still has a direction.
            let c = (lo + hi) * 0.5;
            let r = ((hi - lo).length() * 0.5)
                .max(c.abs().max_element() * f64::from(f32::EPSILON) * 8.0);
            (c, r.max(f64::from(f32::MIN_POSITIVE)))
        };
        let dir = DVec3::new(0.6, 0.45, 1.0).normalize();
        // 45° full angle: the bounding sphere fits when the distance is r / sin(22.5°).
        let dist = r / 22.5f64.to_radians().sin();
        let f = |v: DVec3| Vec3A::new(v.x as f32, v.y as f32, v.z as f32);
        Camera::try_new(f(c + dir * dist), f(c), Vec3A::Y, 45.0)
            .map_err(|_| CameraError::CannotFrame)
    }

    /// The eye ray through image-plane point `(sx, sy)`, both in `[-1, 1]`: `(-1, 1)` is the
    /// top-left edge of the field of view. The direction is normalised (at any scale); it is
    /// meaningless (zero) for a camera
    /// [`Camera::validate`] rejects.
    pub fn ray(&self, sx: f32, sy: f32) -> Ray {
        self.view().ray(sx, sy)
    }

    /// The camera's frame, computed once for many rays: [`View::ray`] gives exactly
    /// [`Camera::ray`]'s rays.
    ///
    /// ```
    /// use quiver_scenes::Scene;
    /// let cam = Scene::load("tetra2").unwrap().camera;
    /// let view = cam.view();
    /// assert_eq!(view.ray(0.25, -0.5), cam.ray(0.25, -0.5));
    /// ```
    pub fn view(&self) -> View {
        // `unit_or_zero`: a scene and its camera scaled to 1e30 or 1e-30 see the same rays.
        let w = unit_or_zero(self.at - self.from);
        let right = unit_or_zero(w.cross(self.up));
        View {
            from: self.from,
            w,
            right,
            up: right.cross(w),
            h: (self.angle.to_radians() * 0.5).tan(),
        }
    }
}

/// A camera's eye point and frame: where [`Camera::ray`]'s rays come from, without
/// recomputing the frame per ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    from: Vec3A,
    /// Unit view direction, right and up vectors.
    w: Vec3A,
    right: Vec3A,
    up: Vec3A,
    /// Tangent of half the field of view.
    h: f32,
}

impl View {
    /// The eye ray through screen point `(sx, sy)` (see [`Camera::ray`]).
    #[inline]
    pub fn ray(&self, sx: f32, sy: f32) -> Ray {
        self.ray_through(self.across(sx), self.down(sy))
    }

    /// The horizontal part of the direction toward screen x `sx`: with [`View::down`] and
    /// [`View::ray_through`], [`View::ray`]'s arithmetic with each column's and each row's
    /// part computed once.
    ///
    /// ```
    /// use quiver_scenes::Scene;
    /// let view = Scene::load("tetra2").unwrap().camera.view();
    /// let ray = view.ray_through(view.across(0.25), view.down(-0.5));
    /// assert_eq!(ray, view.ray(0.25, -0.5));
    /// ```
    #[inline]
    pub fn across(&self, sx: f32) -> Vec3A {
        self.right * (sx * self.h)
    }

    /// The vertical part of the direction toward screen y `sy` (see [`View::across`]).
    #[inline]
    pub fn down(&self, sy: f32) -> Vec3A {
        self.up * (sy * self.h)
    }

    /// The eye ray whose direction has the parts `across` and `down` (see [`View::across`]).
    #[inline]
    pub fn ray_through(&self, across: Vec3A, down: Vec3A) -> Ray {
        Ray::new(self.from, unit_or_zero(self.w + across + down))
    }
}
