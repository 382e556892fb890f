//! Lights that are not surfaces (beyond the paper, which lights its room
//! with emitting patches only): point, spot and sun lights as glTF's
//! `KHR_lights_punctual` and the OBJ directive `#@light` describe them.
//!
//! Progressive radiosity takes them as shooters whose one shot is the
//! direct illumination: a point or spot light sends `I(w) cos(theta) / d^2`
//! to every receiver that sees it (the point-to-vertex transfer of Wallace
//! et al. 1989 with the source's intensity in that direction), the sun
//! `E cos(theta)` to every receiver with nothing between it and the sky;
//! what the receivers reflect then bounces like any other unshot light.
//!
//! # Units
//!
//! Lights are photometric, as glTF and lighting practice give them: point
//! and spot lights in candela, the sun in lux on a plane facing it. The
//! solver is radiometric (`Ke` and glTF emission in W/m^2) and reports
//! illuminance as Radiance does, `179 lm/W x (0.265 R + 0.670 G + 0.065 B)`
//! ([`crate::photometry::lux`]). A light's radiant intensity per channel is
//! therefore `colour x candela / 179` W/sr: a white light of `I` candela
//! gives exactly `I cos(theta) / d^2` lux in the sensors' lux column, and a
//! coloured one that times its colour's luminance (as three.js and Blender
//! scale intensity by colour). Blender's light watts are not radiometric:
//! its glTF exporter writes a point light of `P` W as `P x 683 / (4 pi)`
//! candela, which is what is read here.
//!
//! # Spot cones
//!
//! A spot's intensity falls from full inside the inner cone to nothing at
//! the outer one as the `KHR_lights_punctual` specification recommends:
//! with `s = (cos(a) - cos(outer)) / (cos(inner) - cos(outer))` clamped to
//! `[0, 1]` at angle `a` from the axis, the intensity is `I s^2`.

use std::sync::Arc;

use glam::DVec3;

use super::ies::Profile;
use super::sky::Sky;
use crate::photometry::LUMINOUS_EFFICACY;

/// Where a light is and how its intensity is spread.
#[derive(Clone, Debug, PartialEq)]
pub enum LightKind {
    /// The same intensity in every direction, from a point.
    Point {
        /// Where.
        position: DVec3,
    },
    /// A point whose light is limited to a cone.
    Spot {
        /// Where.
        position: DVec3,
        /// The cone's axis, unit length, pointing where the light goes.
        direction: DVec3,
        /// Half-angle of full intensity, radians, in `[0, outer]`.
        inner: f64,
        /// Half-angle beyond which there is no light, radians, in
        /// `(0, pi/2]`.
        outer: f64,
    },
    /// Parallel light from far away.
    Sun {
        /// The direction the light travels, unit length.
        direction: DVec3,
    },
    /// Daylight from the sky above the horizon ([`super::sky`]): the
    /// light's intensity is the sky's unobstructed horizontal illuminance
    /// in lux.
    Sky {
        /// Its luminance distribution.
        sky: Arc<Sky>,
        /// Patch subdivision (see [`super::sky::patches`]), at least 1.
        subdivision: usize,
    },
    /// A point whose intensity is a luminaire's measured distribution
    /// ([`super::ies`]); the light's intensity multiplies its candela.
    Luminaire {
        /// Where.
        position: DVec3,
        /// Its nadir (vertical angle 0), unit length.
        nadir: DVec3,
        /// Its C0 direction (horizontal angle 0), unit, across the nadir.
        c0: DVec3,
        /// The distribution, in candela.
        profile: Arc<Profile>,
    },
}

impl LightKind {
    /// Its type as the statistics file and messages give it: `point`,
    /// `spot`, `sun`, `sky` or `ies`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            LightKind::Point { .. } => "point",
            LightKind::Spot { .. } => "spot",
            LightKind::Sun { .. } => "sun",
            LightKind::Sky { .. } => "sky",
            LightKind::Luminaire { .. } => "ies",
        }
    }
}

/// A light: its kind, colour and intensity.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    /// How a message names it: `#@light at line 12`, `light 'Lamp'`.
    pub name: String,
    /// Where it is and how its light is spread.
    pub kind: LightKind,
    /// Linear RGB, each channel finite and at least 0; multiplies the
    /// intensity.
    pub colour: DVec3,
    /// Candela for point and spot lights (on the axis, for a spot), lux
    /// for the sun, a multiplier of a luminaire's candela; finite and at
    /// least 0.
    pub intensity: f64,
}

/// Why a light cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LightError {
    /// Negative, NaN or infinite intensity.
    #[error("its intensity {0} is not a finite number at least 0")]
    Intensity(f64),
    /// A colour channel negative, NaN or infinite.
    #[error("its colour ({}, {}, {}) is not finite and at least 0 in every channel", .0.x, .0.y, .0.z)]
    Colour(DVec3),
    /// A position that is not finite.
    #[error("its position is not finite")]
    Position,
    /// A direction of zero length or not finite.
    #[error("its direction has no length or is not finite")]
    Direction,
    /// Cone angles out of order or range.
    #[error(
        "its cone angles are wrong: inner {inner} and outer {outer} degrees must satisfy \
         0 <= inner <= outer <= 90 and outer > 0"
    )]
    Cone {
        /// Inner half-angle, degrees.
        inner: f64,
        /// Outer half-angle, degrees.
        outer: f64,
    },
}

/// A unit vector along `v`, or the error for a direction that has none.
pub fn unit_direction(v: DVec3) -> Result<DVec3, LightError> {
    let length = v.length();
    if length.is_finite() && length > 0.0 {
        let unit = v / length;
        if unit.is_finite() {
            return Ok(unit);
        }
    }
    Err(LightError::Direction)
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

impl Light {
    /// Checks what a file can get wrong: intensity and colour finite and
    /// not negative, positions finite, directions unit, cones in order.
    pub fn validate(&self) -> Result<(), LightError> {
        if !(self.intensity.is_finite() && self.intensity >= 0.0) {
            return Err(LightError::Intensity(self.intensity));
        }
        if !(self.colour.is_finite() && self.colour.min_element() >= 0.0) {
            return Err(LightError::Colour(self.colour));
        }
        let unit = |d: DVec3| d.is_finite() && (d.length() - 1.0).abs() < 1e-9;
        match &self.kind {
            LightKind::Point { position } => {
                if !position.is_finite() {
                    return Err(LightError::Position);
                }
            }
            LightKind::Spot {
                position,
                direction,
                inner,
                outer,
            } => {
                if !position.is_finite() {
                    return Err(LightError::Position);
                }
                if !unit(*direction) {
                    return Err(LightError::Direction);
                }
                cone(inner.to_degrees(), outer.to_degrees())?;
            }
            LightKind::Sun { direction } => {
                if !unit(*direction) {
                    return Err(LightError::Direction);
                }
            }
            LightKind::Sky { .. } => {}
            LightKind::Luminaire {
                position,
                nadir,
                c0,
                ..
            } => {
                if !position.is_finite() {
                    return Err(LightError::Position);
                }
                if !unit(*nadir) || !unit(*c0) || nadir.dot(*c0).abs() > 1e-9 {
                    return Err(LightError::Direction);
                }
            }
        }
        Ok(())
    }

    /// The radiant intensity or irradiance per unit of the light's own
    /// quantity: `colour / 179` (W per candela-steradian, or W/m^2 per
    /// lux).
    #[must_use]
    pub fn radiometric(&self) -> DVec3 {
        self.colour * (self.intensity / LUMINOUS_EFFICACY)
    }

    /// The position of a point, spot or luminaire; `None` for the sun.
    #[must_use]
    pub fn position(&self) -> Option<DVec3> {
        match &self.kind {
            LightKind::Point { position }
            | LightKind::Spot { position, .. }
            | LightKind::Luminaire { position, .. } => Some(*position),
            LightKind::Sun { .. } | LightKind::Sky { .. } => None,
        }
    }

    /// What multiplies [`Light::radiometric`] along the unit direction
    /// `towards`: 1 for a point light and the sun, the cone's falloff for a
    /// spot, the candela a luminaire's profile gives there.
    #[must_use]
    pub fn falloff(&self, towards: DVec3) -> f64 {
        match &self.kind {
            LightKind::Point { .. } | LightKind::Sun { .. } => 1.0,
            LightKind::Sky { sky, .. } => sky.relative_luminance(-towards),
            LightKind::Luminaire {
                nadir, c0, profile, ..
            } => {
                // Counter-clockwise seen from above: C90 = up x C0.
                let c90 = (-*nadir).cross(*c0);
                let gamma = towards.dot(*nadir).clamp(-1.0, 1.0).acos().to_degrees();
                let c = towards.dot(c90).atan2(towards.dot(*c0)).to_degrees();
                profile.candela(gamma, c)
            }
            LightKind::Spot {
                direction,
                inner,
                outer,
                ..
            } => spot_falloff(direction.dot(towards), inner.cos(), outer.cos()),
        }
    }

    /// Irradiance (W/m^2 per channel) it sends to a point with unit normal
    /// `normal` if nothing is in the way, and the point the shadow segment
    /// must reach to check that (the light's position, or for the sun a
    /// point `reach` metres towards it).
    #[must_use]
    pub fn irradiance(&self, point: DVec3, normal: DVec3, reach: f64) -> (DVec3, DVec3) {
        match &self.kind {
            // A sky comes from many directions: see [`Light::sky_sample`].
            LightKind::Sky { .. } => (DVec3::ZERO, point),
            LightKind::Sun { direction } => {
                let cos = -normal.dot(*direction);
                let far = point - *direction * reach;
                if cos <= 0.0 {
                    return (DVec3::ZERO, far);
                }
                (self.radiometric() * cos, far)
            }
            LightKind::Point { position }
            | LightKind::Spot { position, .. }
            | LightKind::Luminaire { position, .. } => {
                let to_light = *position - point;
                let d2 = to_light.length_squared();
                // At the light itself (or NaN): no defined direction.
                if d2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                    return (DVec3::ZERO, *position);
                }
                let d = d2.sqrt();
                let cos = normal.dot(to_light) / d;
                if cos <= 0.0 {
                    return (DVec3::ZERO, *position);
                }
                let falloff = self.falloff(-to_light / d);
                (self.radiometric() * (falloff * cos / d2), *position)
            }
        }
    }

    /// One stratified sample of a sky's irradiance at a point with unit
    /// normal `normal`: the direction drawn at `(u, v)` in `patch`, the
    /// irradiance it stands for if unblocked (the patch's solid angle times
    /// the luminance and cosine there) and the far end of its shadow
    /// segment, `reach` metres towards the sky. Zero for any other light.
    #[must_use]
    pub fn sky_sample(
        &self,
        patch: &super::sky::Patch,
        (u, v): (f64, f64),
        point: DVec3,
        normal: DVec3,
        reach: f64,
    ) -> (DVec3, DVec3) {
        let LightKind::Sky { sky, .. } = &self.kind else {
            return (DVec3::ZERO, point);
        };
        let towards = patch.direction(u, v);
        let far = point + towards * reach;
        let cos = normal.dot(towards);
        if cos <= 0.0 {
            return (DVec3::ZERO, far);
        }
        let weight = sky.relative_luminance(towards) * cos * patch.solid_angle();
        (self.radiometric() * weight, far)
    }

    /// Radiant flux (W per channel) of a point, spot or luminaire: the
    /// intensity integrated over the sphere; `None` for the sun, whose
    /// power depends on what it falls on.
    #[must_use]
    pub fn flux(&self) -> Option<DVec3> {
        let per_axis = match &self.kind {
            LightKind::Point { .. } => 4.0 * std::f64::consts::PI,
            LightKind::Spot { inner, outer, .. } => spot_solid_angle(inner.cos(), outer.cos()),
            LightKind::Luminaire { profile, .. } => profile.flux(),
            LightKind::Sun { .. } | LightKind::Sky { .. } => return None,
        };
        Some(self.radiometric() * per_axis)
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

/// A luminaire at `position` with its nadir along `nadir` (not
/// necessarily unit) and the profile's candela times `multiplier`. Its C0
/// direction is `c0_towards` made perpendicular to the nadir (a glTF node's
/// +x axis); without one, the world's +x axis (the -z axis when the nadir
/// is within 25 degrees of x), so C90 (counter-clockwise seen from above)
/// is, for a luminaire hanging straight down, C0 along +x and C90 along -z.
pub fn luminaire(
    name: String,
    position: DVec3,
    nadir: DVec3,
    c0_towards: Option<DVec3>,
    multiplier: f64,
    profile: Arc<Profile>,
) -> Result<Light, LightError> {
    let nadir = unit_direction(nadir)?;
    let towards = c0_towards.unwrap_or(if nadir.x.abs() > 0.9 {
        -DVec3::Z
    } else {
        DVec3::X
    });
    let c0 = unit_direction(towards - nadir * nadir.dot(towards))?;
    let light = Light {
        name,
        kind: LightKind::Luminaire {
            position,
            nadir,
            c0,
            profile,
        },
        colour: DVec3::ONE,
        intensity: multiplier,
    };
    light.validate()?;
    Ok(light)
}

/// The forms of the `#@light` directive, for messages.
pub const DIRECTIVE_FORMS: &str = "#@light point X Y Z CANDELA [R G B], \
     #@light spot X Y Z DX DY DZ CANDELA INNER_DEG OUTER_DEG [R G B], \
     #@light sun DX DY DZ LUX [R G B], \
     #@light ies FILE.ies X Y Z [DX DY DZ] [MULTIPLIER]";

/// The numbers of an `#@light ies` directive after its file name: the
/// position, the nadir (default straight down) and the multiplier
/// (default 1).
pub fn luminaire_numbers(numbers: &[f64]) -> Result<(DVec3, DVec3, f64), String> {
    if let Some(bad) = numbers.iter().find(|v| !v.is_finite()) {
        return Err(format!("{bad} is not a finite number"));
    }
    let v = |i: usize| DVec3::new(numbers[i], numbers[i + 1], numbers[i + 2]);
    match numbers.len() {
        3 => Ok((v(0), -DVec3::Y, 1.0)),
        4 => Ok((v(0), -DVec3::Y, numbers[3])),
        6 => Ok((v(0), v(3), 1.0)),
        7 => Ok((v(0), v(3), numbers[6])),
        n => Err(format!(
            "{n} numbers after the file name; the form is #@light ies FILE.ies X Y Z [DX DY DZ] \
             [MULTIPLIER]"
        )),
    }
}

/// Parses what follows `#@light` in an OBJ file (see [`DIRECTIVE_FORMS`]):
/// a light named `name`, checked; the message says what is wrong.
pub fn parse_directive(text: &str, name: String) -> Result<Light, String> {
    let mut words = text.split_whitespace();
    let kind = words
        .next()
        .ok_or("no light type (point, spot, sun or ies)")?;
    let numbers: Vec<f64> = words
        .map(|w| {
            w.parse::<f64>()
                .map_err(|_| format!("'{w}' is not a number"))
        })
        .collect::<Result<_, _>>()?;
    // The numbers each type takes before its optional colour.
    let (needed, form) = match kind {
        "point" => (4, "point X Y Z CANDELA [R G B]"),
        "spot" => (9, "spot X Y Z DX DY DZ CANDELA INNER_DEG OUTER_DEG [R G B]"),
        "sun" => (4, "sun DX DY DZ LUX [R G B]"),
        other => {
            return Err(format!(
                "unknown light type '{other}' (known: point, spot, sun, ies)"
            ));
        }
    };
    if numbers.len() != needed && numbers.len() != needed + 3 {
        return Err(format!(
            "{} numbers after '{kind}'; the form is #@light {form}",
            numbers.len()
        ));
    }
    if let Some(bad) = numbers.iter().find(|v| !v.is_finite()) {
        return Err(format!("{bad} is not a finite number"));
    }
    let colour = if numbers.len() == needed + 3 {
        DVec3::new(numbers[needed], numbers[needed + 1], numbers[needed + 2])
    } else {
        DVec3::ONE
    };
    let v = |i: usize| DVec3::new(numbers[i], numbers[i + 1], numbers[i + 2]);
    let (kind, intensity) = match kind {
        "point" => (LightKind::Point { position: v(0) }, numbers[3]),
        "spot" => {
            let direction = unit_direction(v(3)).map_err(|e| e.to_string())?;
            let (inner, outer) = cone(numbers[7], numbers[8]).map_err(|e| e.to_string())?;
            (
                LightKind::Spot {
                    position: v(0),
                    direction,
                    inner,
                    outer,
                },
                numbers[6],
            )
        }
        _ => {
            let direction = unit_direction(v(0)).map_err(|e| e.to_string())?;
            (LightKind::Sun { direction }, numbers[3])
        }
    };
    let light = Light {
        name,
        kind,
        colour,
        intensity,
    };
    light.validate().map_err(|e| e.to_string())?;
    Ok(light)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn directives_parse_and_bad_ones_say_why() {
        let l = parse_directive(" point 1 2 3 100", "l".into()).unwrap();
        assert_eq!(
            l.kind,
            LightKind::Point {
                position: DVec3::new(1.0, 2.0, 3.0)
            }
        );
        assert_eq!((l.intensity, l.colour), (100.0, DVec3::ONE));
        let l = parse_directive("spot 0 3 0 0 -2 0 500 20 30 1 0.5 0.25", "s".into()).unwrap();
        let LightKind::Spot {
            direction, outer, ..
        } = l.kind
        else {
            panic!("not a spot")
        };
        assert_eq!(direction, -DVec3::Y);
        assert_relative_eq!(outer, 30f64.to_radians());
        assert_eq!(l.colour, DVec3::new(1.0, 0.5, 0.25));
        let l = parse_directive("sun 1 -1 0 100000", "u".into()).unwrap();
        assert!(matches!(l.kind, LightKind::Sun { .. }));
        for (text, says) in [
            ("", "no light type"),
            (
                "lamp 1 2 3 4",
                "unknown light type 'lamp' (known: point, spot, sun, ies)",
            ),
            ("point 1 2 3", "3 numbers after 'point'"),
            ("point 1 2 3 4 5", "5 numbers after 'point'"),
            ("point 1 2 x 4", "'x' is not a number"),
            ("point 1 2 3 -4", "intensity -4"),
            ("point 1 2 3 nan", "NaN is not a finite number"),
            ("spot 0 0 0 0 -1 0 10 40 30", "inner 40 and outer 30"),
            ("spot 0 0 0 0 0 0 10 20 30", "direction has no length"),
            ("sun 0 0 0 10", "direction has no length"),
            ("point 0 0 0 1 1 -1 1", "colour"),
        ] {
            let e = parse_directive(text, "l".into()).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
    }

    fn point(intensity: f64) -> Light {
        Light {
            name: "p".into(),
            kind: LightKind::Point {
                position: DVec3::new(0.0, 2.0, 0.0),
            },
            colour: DVec3::ONE,
            intensity,
        }
    }

    #[test]
    fn a_white_candela_gives_its_inverse_square_law_in_lux() {
        let light = point(100.0);
        // 2 m below, straight down: 100 / 4 = 25 lux.
        let (e, to) = light.irradiance(DVec3::ZERO, DVec3::Y, 10.0);
        assert_relative_eq!(crate::photometry::lux(e), 25.0, max_relative = 1e-12);
        assert_eq!(to, DVec3::new(0.0, 2.0, 0.0));
        // 2 m across as well: d^2 = 8, cos = 1/sqrt 2.
        let (e, _) = light.irradiance(DVec3::new(2.0, 0.0, 0.0), DVec3::Y, 10.0);
        assert_relative_eq!(
            crate::photometry::lux(e),
            100.0 / 8.0 / 2f64.sqrt(),
            max_relative = 1e-12
        );
        // Facing away: nothing.
        let (e, _) = light.irradiance(DVec3::ZERO, -DVec3::Y, 10.0);
        assert_eq!(e, DVec3::ZERO);
    }

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

    #[test]
    fn flux_of_a_point_light_is_four_pi_intensity() {
        let flux = point(179.0).flux().unwrap();
        assert_relative_eq!(flux.x, 4.0 * std::f64::consts::PI, max_relative = 1e-12);
    }

    #[test]
    fn bad_lights_are_named() {
        let mut light = point(-1.0);
        assert_eq!(light.validate(), Err(LightError::Intensity(-1.0)));
        light.intensity = f64::NAN;
        assert!(light.validate().is_err());
        light.intensity = 1.0;
        light.colour = DVec3::new(1.0, -0.1, 0.0);
        assert!(matches!(light.validate(), Err(LightError::Colour(_))));
        assert!(cone(30.0, 20.0).is_err());
        assert!(cone(0.0, 0.0).is_err());
        assert!(cone(10.0, 91.0).is_err());
        assert!(cone(0.0, 90.0).is_ok());
        assert_eq!(unit_direction(DVec3::ZERO), Err(LightError::Direction));
        assert_eq!(
            unit_direction(DVec3::new(0.0, 0.0, f64::INFINITY)),
            Err(LightError::Direction)
        );
    }
}
