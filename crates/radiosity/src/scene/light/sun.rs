//! The sun: parallel light from far away (glTF's `directional`, `--sun`,
//! `#@light sun DX DY DZ LUX [R G B]`), `E cos(theta)` at every point the
//! sky sees along its direction. Beyond the paper, whose sources are
//! surfaces: one shadow ray a receiver, as Wallace, Elmquist & Haines
//! (1989) test a point source's visibility.

use glam::DVec3;

use super::{
    AtPoints, Directive, LightError, LightKind, LightModel, Punctual, PunctualKind, is_unit,
    unit_direction, vector,
};

/// Parallel light travelling along `direction`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// The direction the light travels, unit length.
    pub direction: DVec3,
}

/// `#@light sun DX DY DZ LUX [R G B]`.
pub const DIRECTIVE: Directive = Directive {
    word: "sun",
    form: "DX DY DZ LUX [R G B]",
    numbers: 4,
    parse: |n| {
        let direction = unit_direction(vector(n, 0)).map_err(|e| e.to_string())?;
        Ok((LightKind::Sun(Sun { direction }), n[3]))
    },
};

impl LightModel for Sun {
    fn name(&self) -> &'static str {
        "sun"
    }

    fn validate(&self) -> Result<(), LightError> {
        if is_unit(self.direction) {
            Ok(())
        } else {
            Err(LightError::Direction)
        }
    }

    fn position(&self) -> Option<DVec3> {
        None
    }

    fn falloff(&self, _towards: DVec3) -> f64 {
        1.0
    }

    /// `cos` towards a point `reach` metres up the sun's direction.
    fn transfer(&self, point: DVec3, normal: DVec3, reach: f64) -> (f64, DVec3) {
        let cos = -normal.dot(self.direction);
        let far = point - self.direction * reach;
        if cos <= 0.0 {
            return (0.0, far);
        }
        (cos, far)
    }

    fn solid_angle(&self) -> Option<f64> {
        None
    }

    fn at_points(&self, _unit: DVec3) -> AtPoints {
        AtPoints::Distant
    }

    fn punctual(&self, intensity: f64) -> Option<Punctual> {
        Some(Punctual {
            kind: PunctualKind::Directional,
            position: DVec3::ZERO,
            direction: Some(self.direction),
            intensity,
        })
    }
}
