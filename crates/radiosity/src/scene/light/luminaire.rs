//! A luminaire: a point whose intensity is a measured distribution
//! ([`crate::scene::ies`], IESNA LM-63), placed by its nadir and C0
//! direction (`#@light ies FILE.ies X Y Z [DX DY DZ] [MULTIPLIER]`, an
//! `.ies` on a glTF light); the light's intensity multiplies its candela.
//! Beyond the paper, whose sources are surfaces: shot as Wallace, Elmquist
//! & Haines (1989) send a point source's light, with the measured intensity
//! in each receiver's direction.

use std::sync::Arc;

use glam::DVec3;

use super::{
    AtPoints, Light, LightError, LightKind, LightModel, Orientation, Punctual, PunctualKind,
    is_unit, unit_direction,
};
use crate::scene::ies::Profile;

/// A measured luminaire at `position`.
#[derive(Clone, Debug, PartialEq)]
pub struct Luminaire {
    /// Where.
    pub position: DVec3,
    /// Its nadir (vertical angle 0), unit length.
    pub nadir: DVec3,
    /// Its C0 direction (horizontal angle 0), unit, across the nadir.
    pub c0: DVec3,
    /// The distribution, in candela.
    pub profile: Arc<Profile>,
}

impl LightModel for Luminaire {
    fn name(&self) -> &'static str {
        "ies"
    }

    fn validate(&self) -> Result<(), LightError> {
        if !self.position.is_finite() {
            return Err(LightError::Position);
        }
        if !is_unit(self.nadir) || !is_unit(self.c0) || self.nadir.dot(self.c0).abs() > 1e-9 {
            return Err(LightError::Direction);
        }
        Ok(())
    }

    fn position(&self) -> Option<DVec3> {
        Some(self.position)
    }

    /// The candela the profile gives along `towards`.
    fn falloff(&self, towards: DVec3) -> f64 {
        // Counter-clockwise seen from above: C90 = up x C0.
        let c90 = (-self.nadir).cross(self.c0);
        let gamma = towards.dot(self.nadir).clamp(-1.0, 1.0).acos().to_degrees();
        let c = towards.dot(c90).atan2(towards.dot(self.c0)).to_degrees();
        self.profile.candela(gamma, c)
    }

    fn solid_angle(&self) -> Option<f64> {
        Some(self.profile.flux())
    }

    /// Its mean intensity over the sphere, in every direction.
    fn at_points(&self, unit: DVec3) -> AtPoints {
        AtPoints::Located(Orientation::everywhere(
            crate::luminance(unit * self.profile.flux()) / (4.0 * std::f64::consts::PI),
        ))
    }

    /// A point light of the same flux: glTF has no intensity tables.
    fn punctual(&self, intensity: f64) -> Option<Punctual> {
        Some(Punctual {
            kind: PunctualKind::Point,
            position: self.position,
            direction: None,
            intensity: intensity * self.profile.flux() / (4.0 * std::f64::consts::PI),
        })
    }
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
        kind: LightKind::Luminaire(Luminaire {
            position,
            nadir,
            c0,
            profile,
        }),
        colour: DVec3::ONE,
        intensity: multiplier,
    };
    light.validate()?;
    Ok(light)
}

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
