//! Glass: thin transparent panes (a window's glazing) that let light
//! through, dimmed by their transmittance, instead of blocking it. Beyond
//! the paper, whose surfaces are all opaque: daylight reaches rooms
//! through glass. A pane is not a surface of the solve (it neither
//! receives nor reflects: the few per cent a real pane reflects are left
//! out); it is not in the shadow rays' accelerator, and the shadow
//! segments of lights, the sun and the sky are dimmed by each pane they
//! cross ([`transmittance`]). Panes also serve as the sky's portals.
//!
//! From MTL, a material with dissolve `d` below 1 (or `Tr` above 0) is
//! glass of transmittance `(1 - d) Tf` (`Tf`, the transmission filter,
//! white when absent); from glTF, `KHR_materials_transmission`'s
//! `transmissionFactor` times the base colour.

use glam::DVec3;

use crate::geometry;

/// A planar convex piece of glass.
#[derive(Clone, Debug, PartialEq)]
pub struct Pane {
    /// Corners, in order.
    pub polygon: Vec<DVec3>,
    /// Unit normal.
    pub normal: DVec3,
    /// Fraction of the light passing through, per channel, in `[0, 1]`.
    pub transmittance: DVec3,
    /// The material's name, for messages.
    pub material: String,
}

impl Pane {
    /// A pane of `polygon` (planar, convex); `None` without area.
    #[must_use]
    pub fn new(polygon: Vec<DVec3>, transmittance: DVec3, material: &str) -> Option<Pane> {
        let normal = geometry::normal(&polygon)?;
        Some(Pane {
            polygon,
            normal,
            transmittance: transmittance.clamp(DVec3::ZERO, DVec3::ONE),
            material: material.to_string(),
        })
    }

    /// Whether the segment from `from` to `to` crosses the pane's interior.
    #[must_use]
    pub fn crossed_by(&self, from: DVec3, to: DVec3) -> bool {
        let offset = self.normal.dot(self.polygon[0]);
        let (a, b) = (self.normal.dot(from) - offset, self.normal.dot(to) - offset);
        if a == b || a.signum() == b.signum() || a == 0.0 || b == 0.0 {
            return false;
        }
        let t = a / (a - b);
        let hit = from + (to - from) * t;
        geometry::convex_contains(&self.polygon, self.normal, hit, 0.0)
    }
}

/// The fraction of light, per channel, that passes every pane the segment
/// from `from` to `to` crosses (1 when it crosses none).
#[must_use]
pub fn transmittance(panes: &[Pane], from: DVec3, to: DVec3) -> DVec3 {
    panes
        .iter()
        .filter(|p| p.crossed_by(from, to))
        .fold(DVec3::ONE, |t, p| t * p.transmittance)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_segment_through_two_panes_keeps_the_product() {
        let square = |z: f64| {
            vec![
                DVec3::new(0.0, 0.0, z),
                DVec3::new(1.0, 0.0, z),
                DVec3::new(1.0, 1.0, z),
                DVec3::new(0.0, 1.0, z),
            ]
        };
        let panes = [
            Pane::new(square(1.0), DVec3::new(0.8, 0.9, 0.7), "glass").unwrap(),
            Pane::new(square(2.0), DVec3::splat(0.5), "glass").unwrap(),
        ];
        let through = transmittance(&panes, DVec3::new(0.5, 0.5, 0.0), DVec3::new(0.5, 0.5, 3.0));
        assert_eq!(through, DVec3::new(0.4, 0.45, 0.35));
        let one = transmittance(&panes, DVec3::new(0.5, 0.5, 0.0), DVec3::new(0.5, 0.5, 1.5));
        assert_eq!(one, DVec3::new(0.8, 0.9, 0.7));
        // Beside the panes, and short of them.
        let beside = transmittance(&panes, DVec3::new(1.5, 0.5, 0.0), DVec3::new(1.5, 0.5, 3.0));
        assert_eq!(beside, DVec3::ONE);
        let short = transmittance(&panes, DVec3::new(0.5, 0.5, 0.0), DVec3::new(0.5, 0.5, 0.9));
        assert_eq!(short, DVec3::ONE);
    }
}
