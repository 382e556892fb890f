//! A Lambertian point light: a point whose intensity falls as the cosine
//! from its axis, `I(theta) = I0 cos(theta)` in front and nothing behind,
//! the far field of a small diffuse panel (a recessed downlight's opal
//! diffuser, a lit sign seen from across a hall). Its flux is `pi I0`.
//! `#@light lambert X Y Z DX DY DZ CANDELA [R G B]` places one at `X Y Z`
//! facing `DX DY DZ`, `CANDELA` on its axis.
//!
//! This module is the worked example of adding a kind of light (see
//! [`super`]): its type, its capability methods ([`LightModel`]), its
//! directive and its tests are all here; the registration is one line of
//! `light_kinds!` in `mod.rs`. Everything else reads it through those
//! methods: the solver's shot (the point-source transfer of Wallace,
//! Elmquist & Haines 1989, evaluated at each receiver), the final pass's
//! light tree and shadow rays, the statistics file, the shooting order by
//! flux.

use glam::DVec3;

use super::{
    AtPoints, Directive, LightError, LightKind, LightModel, Orientation, Punctual, is_unit,
    unit_direction, vector,
};

/// A Lambertian point light at `position` facing `axis`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Where.
    pub position: DVec3,
    /// The direction of its peak intensity, unit length.
    pub axis: DVec3,
}

/// `#@light lambert X Y Z DX DY DZ CANDELA [R G B]`.
pub const DIRECTIVE: Directive = Directive {
    word: "lambert",
    form: "X Y Z DX DY DZ CANDELA [R G B]",
    numbers: 7,
    parse: |n| {
        let axis = unit_direction(vector(n, 3)).map_err(|e| e.to_string())?;
        Ok((
            LightKind::Lambert(Lambert {
                position: vector(n, 0),
                axis,
            }),
            n[6],
        ))
    },
};

impl LightModel for Lambert {
    fn name(&self) -> &'static str {
        "lambert"
    }

    fn validate(&self) -> Result<(), LightError> {
        if !self.position.is_finite() {
            return Err(LightError::Position);
        }
        if !is_unit(self.axis) {
            return Err(LightError::Direction);
        }
        Ok(())
    }

    fn position(&self) -> Option<DVec3> {
        Some(self.position)
    }

    /// `cos(theta)` from the axis in front, 0 behind.
    fn falloff(&self, towards: DVec3) -> f64 {
        self.axis.dot(towards).max(0.0)
    }

    /// The cosine integrated over the hemisphere in front: `pi`.
    fn solid_angle(&self) -> Option<f64> {
        Some(std::f64::consts::PI)
    }

    /// Its peak intensity, sent over the hemisphere about its axis (the
    /// bounds of an emitting surface facing the same way).
    fn at_points(&self, unit: DVec3) -> AtPoints {
        AtPoints::Located(Orientation {
            power: crate::luminance(unit),
            axis: self.axis,
            theta_o: 0.0,
            theta_e: std::f64::consts::FRAC_PI_2,
        })
    }

    /// glTF's punctual lights have no cosine distribution: left out.
    fn punctual(&self, _intensity: f64) -> Option<Punctual> {
        None
    }
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;
    use crate::photometry::lux;
    use crate::scene::light::{Light, parse_directive};

    fn downlight(candela: f64) -> Light {
        parse_directive(&format!("lambert 0 2 0 0 -3 0 {candela}"), "l".into()).unwrap()
    }

    /// On a floor `h` below, `x` across: `I0 cos^2 / d^2 = I0 h^2 / d^4`
    /// (the light's cosine and the floor's are the same angle).
    #[test]
    fn its_irradiance_is_the_closed_form() {
        let light = downlight(300.0);
        assert_eq!(light.kind.name(), "lambert");
        for x in [0.0, 0.5, 1.0, 3.0, 10.0] {
            let point = DVec3::new(x, 0.0, 0.0);
            let (e, far) = light.irradiance(point, DVec3::Y, 100.0);
            let d2 = 4.0 + x * x;
            assert_relative_eq!(lux(e), 300.0 * 4.0 / (d2 * d2), max_relative = 1e-12);
            assert_eq!(far, DVec3::new(0.0, 2.0, 0.0));
        }
        // Above it (behind the light): nothing.
        let (e, _) = light.irradiance(DVec3::new(0.0, 3.0, 0.0), -DVec3::Y, 100.0);
        assert_eq!(e, DVec3::ZERO);
    }

    /// The flux is `pi I0`, and is the falloff integrated over the sphere
    /// (midpoint rule in the cosine).
    #[test]
    fn its_flux_is_pi_times_its_peak() {
        let light = downlight(LUMINOUS_EFFICACY_CANDELA);
        let flux = light.flux().unwrap();
        assert_relative_eq!(flux.x, std::f64::consts::PI, max_relative = 1e-12);
        let model = light.model();
        let n = 100_000;
        let numeric: f64 = (0..n)
            .map(|i| {
                let c = -1.0 + (f64::from(i) + 0.5) * 2.0 / f64::from(n);
                let towards = DVec3::new((1.0 - c * c).sqrt(), c, 0.0);
                model.falloff(-towards) * 2.0 / f64::from(n)
            })
            .sum::<f64>()
            * 2.0
            * std::f64::consts::PI;
        assert_relative_eq!(model.solid_angle().unwrap(), numeric, max_relative = 1e-6);
    }

    /// One candela-per-radiometric-unit: 179 cd is 1 W/sr.
    const LUMINOUS_EFFICACY_CANDELA: f64 = crate::photometry::LUMINOUS_EFFICACY;

    #[test]
    fn bad_directives_say_why() {
        for (text, says) in [
            ("lambert 0 2 0 0 -1 0", "6 numbers after 'lambert'"),
            ("lambert 0 2 0 0 0 0 100", "direction has no length"),
            ("lambert 0 2 0 0 -1 0 -5", "intensity -5"),
        ] {
            let e = parse_directive(text, "l".into()).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
        let light = parse_directive("lambert 0 2 0 0 -1 0 100 1 0.5 0", "l".into()).unwrap();
        assert_eq!(light.colour, DVec3::new(1.0, 0.5, 0.0));
    }
}
