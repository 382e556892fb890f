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
//! # Kinds, and adding one
//!
//! Each kind of light is a type of its own module implementing
//! [`LightModel`], the capability methods the rest of the program asks of
//! a light: where it is, its intensity in a direction, the irradiance it
//! sends a point, its flux, how the final pass bounds it, its glTF form.
//! Nothing outside the module matches on kinds. `light_kinds!` (in this file) registers
//! them: one line gives the kind its [`LightKind`] variant and, where it
//! has one, its `#@light` directive. [`lambert`] is the worked example of
//! adding a kind: a point whose intensity falls as the cosine from its
//! axis, `#@light lambert X Y Z DX DY DZ CANDELA [R G B]`. Its module holds
//! its type, its capability methods, its directive's parser and its tests
//! (the closed forms of its irradiance and flux); the registration is the
//! line `Lambert(lambert::Lambert)` below. The solver shoots it, the final
//! pass draws its shadows sharp, the statistics file names it and
//! `tests/lights.rs` checks a room lit by one against the closed form,
//! with no other change.
//!
//! # Spot cones
//!
//! A spot's intensity falls from full inside the inner cone to nothing at
//! the outer one as the `KHR_lights_punctual` specification recommends:
//! with `s = (cos(a) - cos(outer)) / (cos(inner) - cos(outer))` clamped to
//! `[0, 1]` at angle `a` from the axis, the intensity is `I s^2`.

use std::fmt;

use glam::DVec3;

use crate::photometry::LUMINOUS_EFFICACY;

pub mod lambert;
pub mod luminaire;
pub mod point;
pub mod spot;
pub mod sun;

pub use self::lambert::Lambert;
pub use self::luminaire::{Luminaire, luminaire, luminaire_numbers};
pub use self::point::Point;
pub use self::spot::{Spot, cone, spot_falloff, spot_solid_angle};
pub use self::sun::Sun;
pub use super::sky::SkyLight;

/// What a kind of light can do: the capability methods every part of the
/// program asks of a light (the solver's shot, the final pass, the
/// statistics, the glTF writer). Each is per unit of the light's
/// radiometric quantity ([`Light::radiometric`]): the light's colour and
/// intensity are applied by [`Light`].
pub trait LightModel: fmt::Debug + Send + Sync {
    /// Its type as the statistics file and messages give it (`point`).
    fn name(&self) -> &'static str;

    /// Checks what a file can get wrong: positions finite, directions
    /// unit, angles in range.
    ///
    /// # Errors
    ///
    /// The first thing wrong.
    fn validate(&self) -> Result<(), LightError>;

    /// Where it is; `None` for light from far away (the sun, a sky).
    fn position(&self) -> Option<DVec3>;

    /// What multiplies the light's radiometric intensity along the unit
    /// direction `towards`, leaving the light: 1 for a point light.
    fn falloff(&self, towards: DVec3) -> f64;

    /// Irradiance per radiometric unit at `point` (unit normal `normal`)
    /// if nothing is in the way, and the point the shadow segment must
    /// reach to check that (the light's position, or a point `reach`
    /// metres towards a distant light). A light with a position sends
    /// `falloff cos / d^2` ([`from_position`]).
    fn transfer(&self, point: DVec3, normal: DVec3, reach: f64) -> (f64, DVec3) {
        let _ = reach;
        match self.position() {
            Some(position) => from_position(self, position, point, normal),
            None => (0.0, point),
        }
    }

    /// The falloff integrated over the sphere, steradians (4 pi for a point
    /// light): the flux per unit of radiometric intensity; `None` where the
    /// power depends on what it falls on (the sun, a sky).
    fn solid_angle(&self) -> Option<f64>;

    /// How the final pass evaluates it at the points shown.
    fn at_points(&self, unit: DVec3) -> AtPoints;

    /// Its `KHR_lights_punctual` form, for `intensity` of its own quantity
    /// (`None`: glTF has no such light, and the writer leaves it out).
    fn punctual(&self, intensity: f64) -> Option<Punctual>;

    /// The sky it comes from, for light drawn over the sky's directions
    /// ([`crate::scene::sky`]); `None` for every other kind.
    fn sky(&self) -> Option<&SkyLight> {
        None
    }
}

/// The irradiance per radiometric unit a light at `position` sends to
/// `point` (unit normal `normal`): `falloff cos / d^2`, and its position
/// as the shadow segment's far end; nothing at the light itself or facing
/// away.
pub fn from_position<L: LightModel + ?Sized>(
    light: &L,
    position: DVec3,
    point: DVec3,
    normal: DVec3,
) -> (f64, DVec3) {
    let to_light = position - point;
    let d2 = to_light.length_squared();
    // At the light itself (or NaN): no defined direction.
    if d2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return (0.0, position);
    }
    let d = d2.sqrt();
    let cos = normal.dot(to_light) / d;
    if cos <= 0.0 {
        return (0.0, position);
    }
    let falloff = light.falloff(-to_light / d);
    (falloff * cos / d2, position)
}

/// How the final pass takes a light at the points it shows
/// ([`crate::final_gather`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AtPoints {
    /// A light at a point, in the final pass's light tree with these
    /// bounds.
    Located(Orientation),
    /// Light from one direction far away, at every point (the sun).
    Distant,
    /// Light from everywhere at once, left with the mesh's values (a sky).
    FromMesh,
}

/// A located light's bounds in the final pass's light tree: the power it
/// stands for and the cone of directions it sends light in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orientation {
    /// Luminance of its intensity (peak, or mean for a measured one).
    pub power: f64,
    /// The cone's axis, unit length.
    pub axis: DVec3,
    /// The cone's half-angle about the axis, radians.
    pub theta_o: f64,
    /// How far beyond it light is sent, radians.
    pub theta_e: f64,
}

impl Orientation {
    /// A light of `power` sending light every way (a point light, a
    /// luminaire by its mean intensity).
    #[must_use]
    pub fn everywhere(power: f64) -> Orientation {
        Orientation {
            power,
            axis: DVec3::Y,
            theta_o: std::f64::consts::PI,
            theta_e: std::f64::consts::FRAC_PI_2,
        }
    }
}

/// A light as `KHR_lights_punctual` gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Punctual {
    /// Point, spot or directional.
    pub kind: PunctualKind,
    /// Where (the origin for a directional light).
    pub position: DVec3,
    /// Where its light goes, unit length (spot and directional).
    pub direction: Option<DVec3>,
    /// Candela, or lux for a directional light.
    pub intensity: f64,
}

/// `KHR_lights_punctual`'s types.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PunctualKind {
    /// The same intensity every way.
    Point,
    /// Limited to a cone with these half-angles, radians.
    Spot {
        /// Full intensity inside.
        inner: f64,
        /// Nothing beyond.
        outer: f64,
    },
    /// Parallel light.
    Directional,
}

/// What a directive's parser makes: the kind and the light's intensity.
pub type Parsed = (LightKind, f64);

/// A kind's `#@light` directive: its word, its form (for messages), the
/// numbers it takes before an optional colour, and its parser, which makes
/// the kind and its intensity from those numbers (all finite).
#[derive(Clone, Copy)]
pub struct Directive {
    /// The word after `#@light`.
    pub word: &'static str,
    /// What follows the word, for messages: `X Y Z CANDELA [R G B]`.
    pub form: &'static str,
    /// How many numbers it takes before the optional colour.
    pub numbers: usize,
    /// The kind and its intensity from those numbers; the message says
    /// what is wrong.
    pub parse: fn(&[f64]) -> Result<Parsed, String>,
}

/// Registers the kinds of light: `Variant(module::Type)` gives the kind its
/// [`LightKind`] variant, and `Variant(module::Type) = DIRECTIVE` its
/// `#@light` directive too.
macro_rules! light_kinds {
    ($( $(#[$doc:meta])* $variant:ident($($path:ident)::+) $(= $directive:expr)? ),* $(,)?) => {
        /// A light's kind: where it is and how its intensity is spread. Each
        /// variant is a kind's own type ([`LightModel`]).
        #[derive(Clone, Debug, PartialEq)]
        pub enum LightKind {
            $( $(#[$doc])* $variant($($path)::+), )*
        }

        impl LightKind {
            /// Its capability methods.
            #[must_use]
            pub fn model(&self) -> &dyn LightModel {
                match self {
                    $( LightKind::$variant(kind) => kind, )*
                }
            }
        }

        /// The `#@light` directives of the kinds that have one, in the
        /// order of their registration.
        pub const DIRECTIVES: &[Directive] = &[ $( $($directive,)? )* ];
    };
}

light_kinds! {
    /// The same intensity in every direction, from a point.
    Point(point::Point) = point::DIRECTIVE,
    /// A point whose light is limited to a cone.
    Spot(spot::Spot) = spot::DIRECTIVE,
    /// Parallel light from far away.
    Sun(sun::Sun) = sun::DIRECTIVE,
    /// A point whose intensity falls as the cosine from its axis.
    Lambert(lambert::Lambert) = lambert::DIRECTIVE,
    /// A point whose intensity is a luminaire's measured distribution
    /// ([`super::ies`]; its directive names a file: [`luminaire_numbers`]).
    Luminaire(luminaire::Luminaire),
    /// Daylight from the sky above the horizon ([`super::sky`]).
    Sky(SkyLight),
}

impl LightKind {
    /// Its type as the statistics file and messages give it: `point`,
    /// `spot`, `sun`, `lambert`, `sky` or `ies`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        self.model().name()
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
    /// for the sun and a sky, a multiplier of a luminaire's candela;
    /// finite and at least 0.
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

/// Whether `d` is finite and of unit length.
#[must_use]
pub fn is_unit(d: DVec3) -> bool {
    d.is_finite() && (d.length() - 1.0).abs() < 1e-9
}

impl Light {
    /// Its kind's capability methods.
    #[must_use]
    pub fn model(&self) -> &dyn LightModel {
        self.kind.model()
    }

    /// Checks what a file can get wrong: intensity and colour finite and
    /// not negative, then the kind's own ([`LightModel::validate`]).
    pub fn validate(&self) -> Result<(), LightError> {
        if !(self.intensity.is_finite() && self.intensity >= 0.0) {
            return Err(LightError::Intensity(self.intensity));
        }
        if !(self.colour.is_finite() && self.colour.min_element() >= 0.0) {
            return Err(LightError::Colour(self.colour));
        }
        self.model().validate()
    }

    /// The radiant intensity or irradiance per unit of the light's own
    /// quantity: `colour / 179` (W per candela-steradian, or W/m^2 per
    /// lux).
    #[must_use]
    pub fn radiometric(&self) -> DVec3 {
        self.colour * (self.intensity / LUMINOUS_EFFICACY)
    }

    /// Where it is ([`LightModel::position`]); `None` for the sun and a sky.
    #[must_use]
    pub fn position(&self) -> Option<DVec3> {
        self.model().position()
    }

    /// What multiplies [`Light::radiometric`] along the unit direction
    /// `towards` ([`LightModel::falloff`]).
    #[must_use]
    pub fn falloff(&self, towards: DVec3) -> f64 {
        self.model().falloff(towards)
    }

    /// Irradiance (W/m^2 per channel) it sends to a point with unit normal
    /// `normal` if nothing is in the way, and the point the shadow segment
    /// must reach to check that ([`LightModel::transfer`]). A sky's comes
    /// from many directions: see [`Light::sky_sample`].
    #[must_use]
    pub fn irradiance(&self, point: DVec3, normal: DVec3, reach: f64) -> (DVec3, DVec3) {
        let (weight, far) = self.model().transfer(point, normal, reach);
        if weight == 0.0 {
            return (DVec3::ZERO, far);
        }
        (self.radiometric() * weight, far)
    }

    /// The sky it comes from ([`LightModel::sky`]).
    #[must_use]
    pub fn sky(&self) -> Option<&SkyLight> {
        self.model().sky()
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
        let Some(sky) = self.sky() else {
            return (DVec3::ZERO, point);
        };
        let towards = patch.direction(u, v);
        let far = point + towards * reach;
        let cos = normal.dot(towards);
        if cos <= 0.0 {
            return (DVec3::ZERO, far);
        }
        let weight = sky.sky.relative_luminance(towards) * cos * patch.solid_angle();
        (self.radiometric() * weight, far)
    }

    /// Radiant flux (W per channel): the intensity integrated over the
    /// sphere ([`LightModel::solid_angle`]); `None` for the sun and a sky,
    /// whose power depends on what they fall on.
    #[must_use]
    pub fn flux(&self) -> Option<DVec3> {
        let per_axis = self.model().solid_angle()?;
        Some(self.radiometric() * per_axis)
    }
}

/// The forms of the `#@light` directive, for messages: each registered
/// kind's ([`DIRECTIVES`]), and `ies`'s, which names a file.
#[must_use]
pub fn directive_forms() -> String {
    let mut forms: Vec<String> = DIRECTIVES
        .iter()
        .map(|d| format!("#@light {} {}", d.word, d.form))
        .collect();
    forms.push("#@light ies FILE.ies X Y Z [DX DY DZ] [MULTIPLIER]".into());
    forms.join(", ")
}

/// The words `#@light` knows: the registered kinds' and `ies`.
fn known_words() -> String {
    let mut words: Vec<&str> = DIRECTIVES.iter().map(|d| d.word).collect();
    words.push("ies");
    words.join(", ")
}

/// Parses what follows `#@light` in an OBJ file ([`directive_forms`]), but
/// `ies` (read with its file by the OBJ reader): a light named `name`,
/// checked; the message says what is wrong.
pub fn parse_directive(text: &str, name: String) -> Result<Light, String> {
    let mut words = text.split_whitespace();
    let word = words
        .next()
        .ok_or_else(|| format!("no light type ({})", known_words()))?;
    let numbers: Vec<f64> = words
        .map(|w| {
            w.parse::<f64>()
                .map_err(|_| format!("'{w}' is not a number"))
        })
        .collect::<Result<_, _>>()?;
    let Some(directive) = DIRECTIVES.iter().find(|d| d.word == word) else {
        return Err(format!(
            "unknown light type '{word}' (known: {})",
            known_words()
        ));
    };
    let needed = directive.numbers;
    if numbers.len() != needed && numbers.len() != needed + 3 {
        return Err(format!(
            "{} numbers after '{word}'; the form is #@light {word} {}",
            numbers.len(),
            directive.form
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
    let (kind, intensity) = (directive.parse)(&numbers[..needed])?;
    let light = Light {
        name,
        kind,
        colour,
        intensity,
    };
    light.validate().map_err(|e| e.to_string())?;
    Ok(light)
}

/// Three numbers from `numbers` at `i` as a vector.
#[must_use]
pub fn vector(numbers: &[f64], i: usize) -> DVec3 {
    DVec3::new(numbers[i], numbers[i + 1], numbers[i + 2])
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
            LightKind::Point(Point {
                position: DVec3::new(1.0, 2.0, 3.0)
            })
        );
        assert_eq!((l.intensity, l.colour), (100.0, DVec3::ONE));
        let l = parse_directive("spot 0 3 0 0 -2 0 500 20 30 1 0.5 0.25", "s".into()).unwrap();
        let LightKind::Spot(Spot {
            direction, outer, ..
        }) = l.kind
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
                "unknown light type 'lamp' (known: point, spot, sun, lambert, ies)",
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
            kind: LightKind::Point(Point {
                position: DVec3::new(0.0, 2.0, 0.0),
            }),
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
