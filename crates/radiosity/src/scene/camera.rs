//! The camera a scene brings (`#@camera`, a glTF camera node) or a user
//! gives (`--camera`): a pinhole with eye, target, up and vertical field of
//! view (design.md section 7), as the paper's figures view their room
//! (Wong & Tsang 1993, section 5).

use glam::DVec3;

use super::text::quoted;

/// A pinhole camera: eye, target, up and vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// Point looked at.
    pub target: DVec3,
    /// Approximate up direction.
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_degrees: f64,
}

impl Camera {
    /// Parses `eye,target,up,fov` as ten numbers separated by commas or
    /// white space, as `--camera` and the `#@camera` directive take it.
    pub fn parse(text: &str) -> Result<Camera, CameraError> {
        let numbers: Vec<f64> = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse::<f64>()
                    .map_err(|_| CameraError::NotANumber(quoted(t)))
                    .and_then(|v| {
                        if v.is_finite() {
                            Ok(v)
                        } else {
                            Err(CameraError::NotFinite(quoted(t)))
                        }
                    })
            })
            .collect::<Result<_, _>>()?;
        if numbers.len() != 10 {
            return Err(CameraError::Count(numbers.len()));
        }
        let v = |i: usize| DVec3::new(numbers[i], numbers[i + 1], numbers[i + 2]);
        let camera = Camera {
            eye: v(0),
            target: v(3),
            up: v(6),
            fov_degrees: numbers[9],
        };
        camera.validate()?;
        Ok(camera)
    }

    /// Checks that the camera defines a view.
    pub fn validate(&self) -> Result<(), CameraError> {
        let forward = self.target - self.eye;
        if forward.length() <= 1e-12 {
            return Err(CameraError::EyeAtTarget);
        }
        if forward.cross(self.up).length() <= 1e-12 * forward.length() * self.up.length() {
            return Err(CameraError::Up);
        }
        if !(self.fov_degrees > 0.0 && self.fov_degrees < 180.0) {
            return Err(CameraError::FieldOfView(self.fov_degrees));
        }
        Ok(())
    }

    /// A camera that frames the whole bounding box `[lo, hi]` from the front
    /// (+z side), a little above, for scenes that bring no camera.
    #[must_use]
    pub fn framing(lo: DVec3, hi: DVec3) -> Camera {
        let centre = 0.5 * (lo + hi);
        let radius = 0.5 * (hi - lo).length().max(1e-6);
        let fov_degrees: f64 = 45.0;
        let distance = radius / (0.5 * fov_degrees.to_radians()).sin();
        let direction = DVec3::new(0.35, 0.3, 1.0).normalize();
        Camera {
            eye: centre + direction * distance,
            target: centre,
            up: DVec3::Y,
            fov_degrees,
        }
    }
}

/// Why a camera ([`Camera::parse`], [`Camera::validate`]) defines no view.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CameraError {
    /// A token that is no number (quoted as given).
    #[error("{0} is not a number")]
    NotANumber(String),
    /// An infinite or NaN number (quoted as given).
    #[error("{0} is not a finite number")]
    NotFinite(String),
    /// Not ten numbers.
    #[error(
        "a camera needs 10 numbers (eye x,y,z, target x,y,z, up x,y,z, fov in degrees), found {0}"
    )]
    Count(usize),
    /// Eye and target coincide.
    #[error("the camera's eye and target coincide")]
    EyeAtTarget,
    /// No usable up direction.
    #[error("the camera's up direction is zero or along the view direction")]
    Up,
    /// A field of view outside (0, 180) degrees.
    #[error("field of view {0} degrees is not between 0 and 180")]
    FieldOfView(f64),
}
