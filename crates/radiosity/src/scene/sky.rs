//! Daylight: a sky of given horizontal illuminance whose light arrives
//! from every direction above the horizon that nothing blocks (through
//! windows, skylights, open courtyards), and the sun's position.
//!
//! Three luminance distributions, as Radiance's `gensky` gives them:
//!
//! * `uniform`: the same luminance everywhere, `L = E_h / pi`;
//! * `overcast`: the CIE standard overcast sky (Moon & Spencer 1942),
//!   `L(theta) = L_z (1 + 2 cos theta) / 3` at zenith angle `theta`, three
//!   times brighter at the zenith than at the horizon, `L_z = 9 E_h / (7 pi)`;
//! * `clear`: the CIE clear sky (CIE 110-1994, as `gensky +s`),
//!   `L proportional to (0.91 + 10 e^(-3 gamma) + 0.45 cos^2 gamma)
//!   (1 - e^(-0.32 / cos theta))`, `gamma` the angle to the sun, scaled so
//!   that the sky's horizontal illuminance is `E_h`.
//!
//! `E_h` is the unobstructed horizontal illuminance from the sky alone
//! (lux); the sun, when there is one, is a separate light
//! ([`super::LightKind::Sun`]). Directions: y up, north along -z, east
//! along +x; an azimuth is measured from north towards east.
//!
//! The sky is shot as a set of patches (Tregenza's 145, each divided
//! `subdivision^2` times as Reinhart does, the zenith cap too: 580 at the
//! default 2), one
//! direction drawn in each patch per receiver, uniformly over its solid
//! angle, from a generator seeded by the receiver: a stratified estimate
//! of the sky's irradiance that is unbiased for any sky and any
//! obstruction, the same whatever the number of threads.

use std::f64::consts::PI;

use glam::DVec3;

use super::light::{AtPoints, LightError, LightModel, Punctual};
use super::{Light, LightKind, Scene};

/// The luminance distributions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SkyModel {
    /// Constant luminance.
    Uniform,
    /// CIE standard overcast sky.
    Overcast,
    /// CIE clear sky (needs the sun's position).
    Clear,
}

impl std::str::FromStr for SkyModel {
    type Err = String;

    fn from_str(s: &str) -> Result<SkyModel, String> {
        match s {
            "uniform" => Ok(SkyModel::Uniform),
            "overcast" => Ok(SkyModel::Overcast),
            "clear" => Ok(SkyModel::Clear),
            other => Err(format!(
                "unknown sky '{other}' (known: uniform, overcast, clear)"
            )),
        }
    }
}

/// Tregenza's bands: altitude of each band's lower edge (degrees) and its
/// patch count; the zenith cap above 84 degrees is one patch.
const TREGENZA: [(f64, usize); 7] = [
    (0.0, 30),
    (12.0, 30),
    (24.0, 24),
    (36.0, 24),
    (48.0, 18),
    (60.0, 12),
    (72.0, 6),
];

/// Largest patch subdivision accepted (`--sky-subdivision`).
pub const MAX_SUBDIVISION: usize = 16;

/// One patch of the sky: a cell in altitude and azimuth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    /// Sine of the lower and upper altitudes.
    pub sin_altitude: (f64, f64),
    /// Azimuth range, radians from north towards east.
    pub azimuth: (f64, f64),
}

impl Patch {
    /// Solid angle, steradians.
    #[must_use]
    pub fn solid_angle(&self) -> f64 {
        (self.sin_altitude.1 - self.sin_altitude.0) * (self.azimuth.1 - self.azimuth.0)
    }

    /// The direction towards the sky at `(u, v)` in `[0, 1)^2` of the
    /// patch, uniformly in solid angle.
    #[must_use]
    pub fn direction(&self, u: f64, v: f64) -> DVec3 {
        let s = self.sin_altitude.0 + u * (self.sin_altitude.1 - self.sin_altitude.0);
        let a = self.azimuth.0 + v * (self.azimuth.1 - self.azimuth.0);
        towards(s.clamp(-1.0, 1.0).asin(), a)
    }
}

/// The unit vector towards altitude `altitude` and azimuth `azimuth`
/// (radians; azimuth from north, -z, towards east, +x).
#[must_use]
pub fn towards(altitude: f64, azimuth: f64) -> DVec3 {
    let (sa, ca) = altitude.sin_cos();
    DVec3::new(azimuth.sin() * ca, sa, -azimuth.cos() * ca)
}

/// Tregenza's patches, each band's patches divided `subdivision` times in
/// altitude and azimuth (Reinhart's scheme) and the zenith cap into
/// `subdivision^2` cells of equal solid angle: `subdivision` 1 gives 145
/// patches, 2 gives 580, 4 gives 2320.
#[must_use]
pub fn patches(subdivision: usize) -> Vec<Patch> {
    let m = subdivision.max(1);
    let mut out = Vec::new();
    let sin = |degrees: f64| degrees.to_radians().sin();
    for (lower, count) in TREGENZA {
        for row in 0..m {
            let a0 = lower + 12.0 * row as f64 / m as f64;
            let a1 = lower + 12.0 * (row + 1) as f64 / m as f64;
            let n = count * m;
            for k in 0..n {
                let w = 2.0 * PI / n as f64;
                out.push(Patch {
                    sin_altitude: (sin(a0), sin(a1)),
                    azimuth: (w * k as f64, w * (k + 1) as f64),
                });
            }
        }
    }
    // The zenith cap above 84 degrees: `m^2` cells of equal solid angle
    // (Reinhart keeps it whole, but one direction drawn in a cap forty
    // times larger than its neighbours makes the estimate under a small
    // skylight noisy): ring r from the top spans the cap's (r/m)^2 to
    // ((r+1)/m)^2 of its height in sine, in 2r + 1 sectors.
    let depth = 1.0 - sin(84.0);
    for r in 0..m {
        let top = 1.0 - depth * (r as f64 / m as f64).powi(2);
        let bottom = 1.0 - depth * ((r + 1) as f64 / m as f64).powi(2);
        let n = 2 * r + 1;
        for k in 0..n {
            let w = 2.0 * PI / n as f64;
            out.push(Patch {
                sin_altitude: (bottom, top),
                azimuth: (w * k as f64, w * (k + 1) as f64),
            });
        }
    }
    out
}

/// The ground's patches: the sky's of `subdivision` mirrored below the
/// horizon.
#[must_use]
pub fn ground_patches(subdivision: usize) -> Vec<Patch> {
    patches(subdivision)
        .into_iter()
        .map(|p| Patch {
            sin_altitude: (-p.sin_altitude.1, -p.sin_altitude.0),
            azimuth: p.azimuth,
        })
        .collect()
}

/// A sky: its model, the sun's direction for the clear sky, the constant
/// that makes its horizontal illuminance one lux, and the ground's
/// luminance below the horizon.
#[derive(Clone, Debug, PartialEq)]
pub struct Sky {
    /// The distribution.
    pub model: SkyModel,
    /// Towards the sun (unit, above the horizon), for the clear sky.
    pub sun: Option<DVec3>,
    /// Luminance at each direction per lux of horizontal illuminance is
    /// `scale` times the model's shape.
    scale: f64,
    /// Luminance below the horizon per lux of the sky's horizontal
    /// illuminance (1/sr).
    ground: f64,
}

impl Sky {
    /// A sky of `model`; `sun` (towards the sun) is needed by `clear`.
    pub fn new(model: SkyModel, sun: Option<DVec3>) -> Result<Sky, String> {
        if model == SkyModel::Clear && sun.is_none() {
            return Err("the clear sky needs the sun's position: give --sun".into());
        }
        let mut sky = Sky {
            model,
            sun,
            scale: 1.0,
            ground: 0.0,
        };
        sky.scale = match model {
            SkyModel::Uniform => 1.0 / PI,
            SkyModel::Overcast => 9.0 / (7.0 * PI),
            SkyModel::Clear => 1.0 / sky.horizontal_integral(),
        };
        Ok(sky)
    }

    /// The model's luminance shape towards the unit `direction` (0 below
    /// the horizon).
    fn shape(&self, direction: DVec3) -> f64 {
        let cos_theta = direction.y;
        if cos_theta <= 0.0 {
            return 0.0;
        }
        match self.model {
            SkyModel::Uniform => 1.0,
            SkyModel::Overcast => (1.0 + 2.0 * cos_theta) / 3.0,
            SkyModel::Clear => {
                let sun = self.sun.unwrap_or(DVec3::Y);
                let gamma = direction.dot(sun).clamp(-1.0, 1.0).acos();
                let f = |g: f64| 0.91 + 10.0 * (-3.0 * g).exp() + 0.45 * g.cos().powi(2);
                let phi = |cos: f64| 1.0 - (-0.32 / cos).exp();
                let zs = sun.y.clamp(-1.0, 1.0).acos();
                f(gamma) * phi(cos_theta) / (f(zs) * phi(1.0))
            }
        }
    }

    /// The same sky over a ground whose luminance is `ground` per lux of
    /// the sky's horizontal illuminance (1/sr): a diffuse ground of
    /// reflectance `rho` lit by the sky alone has `rho / pi`, and
    /// `rho (1 + E_sun / E_sky) / pi` with a sun giving `E_sun` on the
    /// horizontal (Radiance's `gensky` ground).
    #[must_use]
    pub fn with_ground(mut self, ground: f64) -> Sky {
        self.ground = ground;
        self
    }

    /// The ground's luminance per lux of the sky's horizontal illuminance.
    #[must_use]
    pub fn ground(&self) -> f64 {
        self.ground
    }

    /// Luminance towards `direction` per lux of horizontal illuminance
    /// (1/sr): integrated with the cosine over the upper hemisphere, 1;
    /// below the horizon, the ground's.
    #[must_use]
    pub fn relative_luminance(&self, direction: DVec3) -> f64 {
        if direction.y <= 0.0 {
            return self.ground;
        }
        self.scale * self.shape(direction)
    }

    /// `int shape cos dw` over the upper hemisphere (midpoint rule, fine
    /// in altitude near the sun's peak).
    fn horizontal_integral(&self) -> f64 {
        let (na, nz) = (1800, 1440);
        let mut sum = 0.0;
        for i in 0..na {
            // Uniform in sin(altitude): equal solid angle per cell.
            let s = (i as f64 + 0.5) / na as f64;
            let altitude = s.asin();
            for j in 0..nz {
                let azimuth = 2.0 * PI * (j as f64 + 0.5) / nz as f64;
                sum += self.shape(towards(altitude, azimuth)) * s;
            }
        }
        sum * 2.0 * PI / (na * nz) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn patches_tile_the_hemisphere() {
        for (m, count) in [(1, 145), (2, 580), (4, 2320)] {
            let p = patches(m);
            assert_eq!(p.len(), count, "subdivision {m}");
            let total: f64 = p.iter().map(Patch::solid_angle).sum();
            assert_relative_eq!(total, 2.0 * PI, max_relative = 1e-12);
        }
    }

    #[test]
    fn every_sky_has_unit_horizontal_illuminance_per_lux() {
        let sun = towards(35f64.to_radians(), 200f64.to_radians());
        for sky in [
            Sky::new(SkyModel::Uniform, None).unwrap(),
            Sky::new(SkyModel::Overcast, None).unwrap(),
            Sky::new(SkyModel::Clear, Some(sun)).unwrap(),
        ] {
            // Stratified over the 2305 patches, 16 points each.
            let mut sum = 0.0;
            for p in patches(4) {
                for i in 0..4 {
                    for j in 0..4 {
                        let d = p.direction((f64::from(i) + 0.5) / 4.0, (f64::from(j) + 0.5) / 4.0);
                        sum += sky.relative_luminance(d) * d.y * p.solid_angle() / 16.0;
                    }
                }
            }
            assert_relative_eq!(sum, 1.0, max_relative = 2e-3);
        }
        // The overcast zenith is three times the horizon.
        let overcast = Sky::new(SkyModel::Overcast, None).unwrap();
        let horizon = overcast.relative_luminance(DVec3::new(1.0, 1e-9, 0.0).normalize());
        assert_relative_eq!(
            overcast.relative_luminance(DVec3::Y) / horizon,
            3.0,
            max_relative = 1e-6
        );
        assert!(Sky::new(SkyModel::Clear, None).is_err());
        assert!("cloudy".parse::<SkyModel>().is_err());
    }

    #[test]
    fn azimuth_runs_from_north_towards_east() {
        let north = towards(0.0, 0.0);
        let east = towards(0.0, 90f64.to_radians());
        assert!((north - DVec3::NEG_Z).length() < 1e-12);
        assert!((east - DVec3::X).length() < 1e-12);
        assert!((towards(90f64.to_radians(), 1.0) - DVec3::Y).length() < 1e-12);
    }
}

/// The sun as the command line gives it (`--sun ALTITUDE AZIMUTH LUX`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunSpec {
    /// Degrees above the horizon, in (0, 90].
    pub altitude: f64,
    /// Degrees from north towards east.
    pub azimuth: f64,
    /// Illuminance on a plane facing the sun, lux.
    pub illuminance: f64,
}

/// The sky as the command line gives it (`--sky MODEL --sky-illuminance
/// LUX --sky-subdivision N`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkySpec {
    /// The distribution.
    pub model: SkyModel,
    /// Unobstructed horizontal illuminance of the sky alone, lux.
    pub illuminance: f64,
    /// Patch subdivision, 1 to [`MAX_SUBDIVISION`].
    pub subdivision: usize,
    /// Reflectance of the ground below the horizon, in `[0, 1)`
    /// (`--ground-reflectance`, default [`DEFAULT_GROUND_REFLECTANCE`]).
    pub ground_reflectance: f64,
}

/// Default `--ground-reflectance`, as daylighting tools take it (Radiance's
/// `gensky`, Daysim).
pub const DEFAULT_GROUND_REFLECTANCE: f64 = 0.2;

/// Default `--sky-subdivision`: 580 patches.
pub const DEFAULT_SUBDIVISION: usize = 2;

/// Daylight added to a scene: a sun, a sky, both or neither.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Daylight {
    /// `--sun`.
    pub sun: Option<SunSpec>,
    /// `--sky`.
    pub sky: Option<SkySpec>,
}

impl Daylight {
    /// The lights it adds: the sun, then the sky; the message names the
    /// flag at fault.
    pub fn lights(&self) -> Result<Vec<Light>, String> {
        let mut lights = Vec::new();
        let mut towards_sun = None;
        if let Some(sun) = self.sun {
            let ok = sun.altitude.is_finite()
                && sun.altitude > 0.0
                && sun.altitude <= 90.0
                && sun.azimuth.is_finite();
            if !ok {
                return Err(format!(
                    "--sun: the altitude must be above 0 and at most 90 degrees and the azimuth \
                     finite, not {} and {}",
                    sun.altitude, sun.azimuth
                ));
            }
            if !(sun.illuminance.is_finite() && sun.illuminance >= 0.0) {
                return Err(format!(
                    "--sun: the illuminance must be a finite number of lux at least 0, not {}",
                    sun.illuminance
                ));
            }
            let towards = towards(sun.altitude.to_radians(), sun.azimuth.to_radians());
            towards_sun = Some(towards);
            lights.push(Light {
                name: "the sun (--sun)".into(),
                kind: LightKind::Sun(super::light::Sun {
                    direction: -towards,
                }),
                colour: DVec3::ONE,
                intensity: sun.illuminance,
            });
        }
        if let Some(spec) = self.sky {
            if !(spec.illuminance.is_finite() && spec.illuminance >= 0.0) {
                return Err(format!(
                    "--sky-illuminance must be a finite number of lux at least 0, not {}",
                    spec.illuminance
                ));
            }
            if !(1..=MAX_SUBDIVISION).contains(&spec.subdivision) {
                return Err(format!(
                    "--sky-subdivision must be from 1 to {MAX_SUBDIVISION}, not {}",
                    spec.subdivision
                ));
            }
            if !(spec.ground_reflectance.is_finite()
                && (0.0..1.0).contains(&spec.ground_reflectance))
            {
                return Err(format!(
                    "--ground-reflectance must be from 0 to below 1, not {}",
                    spec.ground_reflectance
                ));
            }
            // The ground is lit by the sky and the sun, in lux per lux of the
            // sky's horizontal illuminance.
            let sun_share = match (self.sun, spec.illuminance > 0.0) {
                (Some(sun), true) => {
                    sun.illuminance * sun.altitude.to_radians().sin() / spec.illuminance
                }
                _ => 0.0,
            };
            let sky = Sky::new(spec.model, towards_sun)?
                .with_ground(spec.ground_reflectance * (1.0 + sun_share) / PI);
            lights.push(Light {
                name: "the sky (--sky)".into(),
                kind: LightKind::Sky(SkyLight {
                    sky: std::sync::Arc::new(sky),
                    subdivision: spec.subdivision,
                }),
                colour: DVec3::ONE,
                intensity: spec.illuminance,
            });
        }
        Ok(lights)
    }
}

/// A sky as a light ([`super::light`]): its luminance distribution and
/// how finely its directions are drawn; the light's intensity is the sky's
/// unobstructed horizontal illuminance in lux. Its light comes from many
/// directions at once, drawn through the scene's openings and over the
/// rest of the sky by the solver ([`crate::solver::sky`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SkyLight {
    /// Its luminance distribution.
    pub sky: std::sync::Arc<Sky>,
    /// Patch subdivision (see [`patches`]), at least 1.
    pub subdivision: usize,
}

impl LightModel for SkyLight {
    fn name(&self) -> &'static str {
        "sky"
    }

    fn validate(&self) -> Result<(), LightError> {
        Ok(())
    }

    fn position(&self) -> Option<DVec3> {
        None
    }

    /// The sky's relative luminance seen looking back along `towards`.
    fn falloff(&self, towards: DVec3) -> f64 {
        self.sky.relative_luminance(-towards)
    }

    /// None from one direction: its samples are [`Light::sky_sample`]'s.
    fn transfer(&self, point: DVec3, _normal: DVec3, _reach: f64) -> (f64, DVec3) {
        (0.0, point)
    }

    fn solid_angle(&self) -> Option<f64> {
        None
    }

    /// Its light changes slowly across a surface and takes hundreds of
    /// rays at a point: the final pass leaves it with the mesh.
    fn at_points(&self, _unit: DVec3) -> AtPoints {
        AtPoints::FromMesh
    }

    /// glTF has no skies.
    fn punctual(&self, _intensity: f64) -> Option<Punctual> {
        None
    }

    fn sky(&self) -> Option<&SkyLight> {
        Some(self)
    }
}

/// The unobstructed horizontal illuminance (lux) of the scene's overcast
/// sky when that sky is all that lights it, the denominator of the daylight
/// factor (CIE: the interior illuminance over the unobstructed horizontal
/// illuminance of a CIE standard overcast sky); else why not.
///
/// # Errors
///
/// A sentence naming what else lights the scene, or the sky that is not
/// overcast.
pub fn overcast_alone(scene: &Scene) -> Result<f64, String> {
    let mut sky = None;
    for light in &scene.lights {
        match &light.kind {
            LightKind::Sky(s) if s.sky.model == SkyModel::Overcast => {
                sky = Some(light.intensity);
            }
            LightKind::Sky(_) => {
                return Err(
                    "the daylight factor is defined under the overcast sky (--sky overcast), \
                     not this one"
                        .into(),
                );
            }
            LightKind::Sun(_) => {
                return Err(format!(
                    "the daylight factor is defined without the sun, and {} lights the scene",
                    light.name
                ));
            }
            _ => {
                return Err(format!(
                    "the daylight factor is defined under the overcast sky alone, and the light {} \
                     lights the scene",
                    light.name
                ));
            }
        }
    }
    if let Some(surface) = scene.surfaces.iter().find(|s| s.emission != DVec3::ZERO) {
        return Err(format!(
            "the daylight factor is defined under the overcast sky alone, and face {} emits light",
            surface.face + 1
        ));
    }
    match sky {
        Some(lux) if lux > 0.0 => Ok(lux),
        Some(_) => Err("the overcast sky gives no light (--sky-illuminance 0)".into()),
        None => {
            Err("the scene has no overcast sky: give --sky overcast --sky-illuminance LUX".into())
        }
    }
}
