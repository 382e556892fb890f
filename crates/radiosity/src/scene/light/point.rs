//! A point light: the same intensity in every direction (glTF's `point`,
//! `#@light point X Y Z CANDELA [R G B]`), shot as the point-source
//! transfer of Wallace, Elmquist & Haines (1989).

use glam::DVec3;

use super::{
    AtPoints, Directive, LightError, LightKind, LightModel, Orientation, Punctual, PunctualKind,
    vector,
};

/// A point light at `position`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Where.
    pub position: DVec3,
}

/// `#@light point X Y Z CANDELA [R G B]`.
pub const DIRECTIVE: Directive = Directive {
    word: "point",
    form: "X Y Z CANDELA [R G B]",
    numbers: 4,
    parse: |n| {
        Ok((
            LightKind::Point(Point {
                position: vector(n, 0),
            }),
            n[3],
        ))
    },
};

impl LightModel for Point {
    fn name(&self) -> &'static str {
        "point"
    }

    fn validate(&self) -> Result<(), LightError> {
        if self.position.is_finite() {
            Ok(())
        } else {
            Err(LightError::Position)
        }
    }

    fn position(&self) -> Option<DVec3> {
        Some(self.position)
    }

    fn falloff(&self, _towards: DVec3) -> f64 {
        1.0
    }

    fn solid_angle(&self) -> Option<f64> {
        Some(4.0 * std::f64::consts::PI)
    }

    fn at_points(&self, unit: DVec3) -> AtPoints {
        AtPoints::Located(Orientation::everywhere(crate::luminance(unit)))
    }

    fn punctual(&self, intensity: f64) -> Option<Punctual> {
        Some(Punctual {
            kind: PunctualKind::Point,
            position: self.position,
            direction: None,
            intensity,
        })
    }
}
