//! A spot light: a point whose light is limited to a cone (glTF's `spot`,
//! `#@light spot X Y Z DX DY DZ CANDELA INNER_DEG OUTER_DEG [R G B]`). Its
//! intensity falls from full inside the inner cone to nothing at the outer
//! one as the `KHR_lights_punctual` specification recommends
//! ([`spot_falloff`]). Beyond the paper, whose sources are surfaces: shot
//! as Wallace, Elmquist & Haines (1989) send a point source's light to each
//! receiver, with the cone's intensity in that direction.

use glam::DVec3;

use super::{
    AtPoints, Directive, LightError, LightKind, LightModel, Orientation, Punctual, PunctualKind,
    is_unit, unit_direction, vector,
};

/// A spot at `position` shining along `direction`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spot {
    /// Where.
    pub position: DVec3,
    /// The cone's axis, unit length, pointing where the light goes.
    pub direction: DVec3,
    /// Half-angle of full intensity, radians, in `[0, outer]`.
    pub inner: f64,
    /// Half-angle beyond which there is no light, radians, in `(0, pi/2]`.
    pub outer: f64,
}

/// `#@light spot X Y Z DX DY DZ CANDELA INNER_DEG OUTER_DEG [R G B]`.
pub const DIRECTIVE: Directive = Directive {
    word: "spot",
    form: "X Y Z DX DY DZ CANDELA INNER_DEG OUTER_DEG [R G B]",
    numbers: 9,
    parse: |n| {
        let direction = unit_direction(vector(n, 3)).map_err(|e| e.to_string())?;
        let (inner, outer) = cone(n[7], n[8]).map_err(|e| e.to_string())?;
        Ok((
            LightKind::Spot(Spot {
                position: vector(n, 0),
                direction,
                inner,
                outer,
            }),
            n[6],
        ))
    },
};

impl LightModel for Spot {
    fn name(&self) -> &'static str {
        "spot"
    }

    fn validate(&self) -> Result<(), LightError> {
        if !self.position.is_finite() {
            return Err(LightError::Position);
        }
        if !is_unit(self.direction) {
            return Err(LightError::Direction);
        }
        cone(self.inner.to_degrees(), self.outer.to_degrees())?;
        Ok(())
    }

    fn position(&self) -> Option<DVec3> {
        Some(self.position)
    }

    fn falloff(&self, towards: DVec3) -> f64 {
        spot_falloff(
            self.direction.dot(towards),
            self.inner.cos(),
            self.outer.cos(),
        )
    }

    fn solid_angle(&self) -> Option<f64> {
        Some(spot_solid_angle(self.inner.cos(), self.outer.cos()))
    }

    fn at_points(&self, unit: DVec3) -> AtPoints {
        AtPoints::Located(Orientation {
            power: crate::luminance(unit),
            axis: self.direction,
            theta_o: self.outer,
            theta_e: 0.0,
        })
    }

    fn punctual(&self, intensity: f64) -> Option<Punctual> {
        Some(Punctual {
            kind: PunctualKind::Spot {
                inner: self.inner,
                outer: self.outer,
            },
            position: self.position,
            direction: Some(self.direction),
            intensity,
        })
    }
}

/// The spot cone from half-angles in degrees, checked.
pub fn cone(inner_degrees: f64, outer_degrees: f64) -> Result<(f64, f64), LightError> {
    // A right angle that came through radians and back.
    let snap = |a: f64| {
        if a > 90.0 && a <= 90.0 + 1e-9 {
            90.0
        } else {
            a
        }
    };
    let (inner_degrees, outer_degrees) = (snap(inner_degrees), snap(outer_degrees));
    let ok = inner_degrees.is_finite()
        && outer_degrees.is_finite()
        && inner_degrees >= 0.0
        && outer_degrees > 0.0
        && inner_degrees <= outer_degrees
        && outer_degrees <= 90.0;
    if ok {
        Ok((inner_degrees.to_radians(), outer_degrees.to_radians()))
    } else {
        Err(LightError::Cone {
            inner: inner_degrees,
            outer: outer_degrees,
        })
    }
}

/// The spot's falloff at `cos_angle` from its axis: `s^2` with `s` the
/// position of `cos_angle` between the outer and inner cones' cosines,
/// clamped to `[0, 1]`.
#[must_use]
pub fn spot_falloff(cos_angle: f64, cos_inner: f64, cos_outer: f64) -> f64 {
    if cos_angle <= cos_outer {
        return 0.0;
    }
    if cos_angle >= cos_inner {
        return 1.0;
    }
    let s = (cos_angle - cos_outer) / (cos_inner - cos_outer);
    s * s
}

/// The falloff integrated over the sphere, steradians:
/// `2 pi ((1 - cos_inner) + (cos_inner - cos_outer) / 3)`.
#[must_use]
pub fn spot_solid_angle(cos_inner: f64, cos_outer: f64) -> f64 {
    2.0 * std::f64::consts::PI * ((1.0 - cos_inner) + (cos_inner - cos_outer) / 3.0)
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;

    #[test]
    fn spot_falloff_is_the_specifications() {
        let (inner, outer) = cone(20.0, 40.0).unwrap();
        let (ci, co) = (inner.cos(), outer.cos());
        assert_eq!(spot_falloff(1.0, ci, co), 1.0);
        assert_eq!(spot_falloff(19f64.to_radians().cos(), ci, co), 1.0);
        assert_eq!(spot_falloff(41f64.to_radians().cos(), ci, co), 0.0);
        let mid = 30f64.to_radians().cos();
        let s = (mid - co) / (ci - co);
        assert_relative_eq!(spot_falloff(mid, ci, co), s * s);
        // The solid angle integrates the falloff (midpoint rule in cos).
        let n = 200_000;
        let numeric: f64 = (0..n)
            .map(|i| {
                let c = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
                spot_falloff(c, ci, co) * 2.0 / n as f64
            })
            .sum::<f64>()
            * 2.0
            * std::f64::consts::PI;
        assert_relative_eq!(spot_solid_angle(ci, co), numeric, max_relative = 1e-6);
    }
}
