//! Photometry at the bottom of the library: luminance, the weight that
//! ranks patches by unshot power (Wallace, Elmquist & Haines 1989 shoot
//! the brightest first; a colour's brightness is its luminance), and
//! Radiance's conversion of irradiance to illuminance, so that lights
//! given in lumens or candelas, sensors and grids in lux all agree with
//! the reference harness (beyond the paper).

use glam::DVec3;

/// Rec. 709's weights of R, G and B in luminance ([`luminance`]).
pub const LUMINANCE_WEIGHTS: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Luminance of a linear Rec. 709 / sRGB colour: the weight that ranks
/// patches by unshot power and measures convergence.
#[must_use]
pub fn luminance(rgb: DVec3) -> f64 {
    let [r, g, b] = LUMINANCE_WEIGHTS;
    r * rgb.x + g * rgb.y + b * rgb.z
}

/// Radiance's luminous efficacy of white light, lm/W.
pub const LUMINOUS_EFFICACY: f64 = 179.0;

/// Radiance's weights of R, G and B in luminance.
pub const RADIANCE_RGB_WEIGHTS: [f64; 3] = [0.265, 0.670, 0.065];

/// Illuminance in lux from irradiance in W/m^2, as Radiance computes it
/// (`rcalc -e '$1=179*(.265*$1+.67*$2+.065*$3)'` on `rtrace -I` output).
#[must_use]
pub fn lux(irradiance: DVec3) -> f64 {
    let [r, g, b] = RADIANCE_RGB_WEIGHTS;
    LUMINOUS_EFFICACY * (r * irradiance.x + g * irradiance.y + b * irradiance.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// White light of 1 W/m^2 is 179 lux; luminance weighs a colour's
    /// channels to 1 for white.
    #[test]
    fn white_light() {
        assert!((lux(DVec3::ONE) - LUMINOUS_EFFICACY).abs() < 1e-12);
        assert!((luminance(DVec3::ONE) - 1.0).abs() < 1e-12);
        assert!(luminance(DVec3::Y) > luminance(DVec3::X));
    }
}
