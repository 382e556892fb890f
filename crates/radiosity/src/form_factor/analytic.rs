//! The exact point-to-polygon form factor: Lambert's contour formula as
//! Baum, Rushmeier & Winget (SIGGRAPH 1989) use it, the paper's equation (2)
//! and the form factor of the `wong-tsang93` preset (paper section 4).
//!
//! For a receiver at `x` with unit normal `n` and a planar polygon with
//! corners `p_g`, counter-clockwise seen from its front,
//!
//! `F = -1/(2 pi) * sum_g n . Gamma_g`, `Gamma_g = unit(R_g x R_g+1) * angle(R_g, R_g+1)`,
//!
//! with `R_g = p_g - x`. The minus sign is the paper's appendix sign: with a
//! counter-clockwise polygon in front of a receiver that faces it,
//! `sum n . Gamma_g` is negative. The formula only holds for the part of the
//! polygon in front of the receiver's tangent plane, so the polygon is clipped
//! to `n . (p - x) >= 0` first (design.md section 4); the clip
//! ([`crate::geometry::clip::clip_each`]) streams its corners into the sum,
//! so a call never allocates and accepts any number of corners.

use std::f64::consts::{PI, TAU};

use glam::DVec3;

use crate::geometry::{self, clip};

/// Relative distance (to the farthest corner) under which the receiver
/// counts as sitting on a corner, or on an edge seen at about 180 degrees;
/// also the size under which the receiver's normal counts as parallel to
/// the polygon's. Positions are rounded to about `1e-16` of the polygon's
/// size, so beyond `1e-11` an offset's direction is known to about `1e-5`.
pub const DEGENERATE: f64 = 1e-11;

/// Relative distance (to the farthest corner) within which a corner counts
/// as lying on the receiver's tangent plane, and is kept by the clip.
pub const ON_PLANE: f64 = 1e-12;

/// Form factor from the differential area at `receiver` (unit normal
/// `receiver_normal`) to the planar `polygon` (corners counter-clockwise seen
/// from its front), the paper's equation (2).
///
/// The polygon is first clipped to the receiver's front half-space, so a
/// source crossing the receiver's tangent plane is handled. The result is 0
/// when the receiver is behind the polygon's plane, for fewer than three
/// corners or a polygon without area, and is clamped to `[0, 1]`. Each edge's
/// angle is `atan2(|a x b|, a . b)`, accurate at every angle.
///
/// Degenerate edges (the factor stays finite and non-negative, never NaN):
///
/// * receiver on an edge's line outside the edge: the edge contributes its
///   limit, 0;
/// * receiver on an edge, or at a corner, of the polygon (a vertex where
///   two surfaces meet): the factor is discontinuous there, since from the
///   polygon's own plane the polygon subtends no solid angle while from
///   just in front of it it fills up to half the hemisphere. The value
///   returned is the limit as the receiver approaches along its own tangent
///   plane from the polygon's front, in the direction `d` of the polygon's
///   normal projected on the tangent plane (the polygon's normal itself when
///   the receiver's normal is opposite to the polygon's). On an edge that limit does not
///   depend on the approach direction within the receiver's tangent plane
///   (a floor vertex on the base of a wall gets 1/2 from a large wall); at a
///   polygon corner it does, and `d` is a choice (a floor vertex in a
///   right-angled room corner gets 1/4 from each large adjacent wall, where
///   a point of the floor approaching along the corner's diagonal gets 3/8).
#[must_use]
pub fn analytic(receiver: DVec3, receiver_normal: DVec3, polygon: &[DVec3]) -> f64 {
    if polygon.len() < 3 {
        return 0.0;
    }
    let Some(source_normal) = geometry::normal(polygon) else {
        return 0.0;
    };
    analytic_facing(receiver, receiver_normal, polygon, source_normal)
}

/// [`analytic`] for a polygon whose unit normal is known already (a mesh
/// element's surface's): the same formula without the polygon's normal
/// computed again, which is a tenth of its cost. The normal only decides
/// the degenerate cases [`analytic`] describes (a receiver on the
/// polygon's edge or corner, or facing the way it does); a polygon with
/// fewer than three corners gives 0.
#[must_use]
pub fn analytic_facing(
    receiver: DVec3,
    receiver_normal: DVec3,
    polygon: &[DVec3],
    source_normal: DVec3,
) -> f64 {
    facing::<false>(receiver, receiver_normal, polygon, source_normal)
}

/// [`analytic_facing`] with each edge's angle from
/// [`super::angle::atan2_positive`] (within 2 units in the last place of
/// the platform's `atan2`, at about half its cost): the default method's
/// factor. The paper's presets keep [`analytic`], so their results stay
/// bit for bit.
#[must_use]
pub fn analytic_facing_fast(
    receiver: DVec3,
    receiver_normal: DVec3,
    polygon: &[DVec3],
    source_normal: DVec3,
) -> f64 {
    facing::<true>(receiver, receiver_normal, polygon, source_normal)
}

/// [`analytic_facing`], its angles from the platform's `atan2` or, with
/// `FAST`, from [`super::angle::atan2_positive`].
#[inline(always)]
fn facing<const FAST: bool>(
    receiver: DVec3,
    receiver_normal: DVec3,
    polygon: &[DVec3],
    source_normal: DVec3,
) -> f64 {
    if polygon.len() < 3 {
        return 0.0;
    }
    let scale = polygon
        .iter()
        .map(|p| p.distance_squared(receiver))
        .fold(0.0, f64::max)
        .sqrt();
    if !(scale > 0.0 && scale.is_finite()) {
        return 0.0;
    }
    // No separate test for a receiver behind the polygon's plane: the sum
    // is then the projected solid angle seen from the back, negative, and
    // the clamp gives 0. A test against the plane would misjudge receivers
    // on the polygon's edges when its normal is known only roughly (a
    // sliver), where the sign of the sum is still right.
    let tolerance = ON_PLANE * scale;
    let facing = receiver_normal.dot(source_normal);
    let tangential = source_normal - facing * receiver_normal;
    // Normalised only where a degenerate edge needs it ([`Contour::approach`]).
    let approach = if tangential.length() > DEGENERATE {
        Approach::Tangential(tangential)
    } else if facing > 0.0 {
        // The receiver faces the way the polygon does: the polygon is behind
        // or inside its tangent plane.
        return 0.0;
    } else {
        Approach::Normal(source_normal)
    };

    let mut contour = Contour::<FAST> {
        receiver,
        normal: receiver_normal,
        approach,
        at_receiver: DEGENERATE * scale,
        first: None,
        previous: DVec3::ZERO,
        sum: 0.0,
    };
    // Cuts lie where an edge crosses the tangent plane itself (not the
    // tolerance band), so they are on the plane.
    clip::clip_each(
        polygon,
        |p| receiver_normal.dot(p - receiver),
        tolerance,
        |p| contour.push(p),
    );
    let sum = contour.close();
    super::clamp_factor(-sum / TAU)
}

/// The direction from which the receiver approaches a degenerate edge:
/// the polygon's normal projected on the receiver's tangent plane (to be
/// normalised), or the polygon's normal itself.
#[derive(Clone, Copy)]
enum Approach {
    Tangential(DVec3),
    Normal(DVec3),
}

/// The clipped polygon's corners as the clip emits them, accumulating
/// `sum n . Gamma_g` one edge at a time (`FAST`: the angles from
/// [`super::angle::atan2_positive`]).
struct Contour<const FAST: bool> {
    receiver: DVec3,
    normal: DVec3,
    approach: Approach,
    /// Distance under which a corner counts as the receiver itself. It is
    /// measured against the polygon's size, not the edge's: a clip can emit
    /// a copy of a corner at the receiver one rounding error away, and the
    /// edge between the two copies must contribute nothing.
    at_receiver: f64,
    first: Option<DVec3>,
    previous: DVec3,
    sum: f64,
}

impl<const FAST: bool> Contour<FAST> {
    /// `atan2(s, cos)` for `s > 0`.
    #[inline(always)]
    fn angle(s: f64, cos: f64) -> f64 {
        if FAST {
            super::angle::atan2_positive(s, cos)
        } else {
            s.atan2(cos)
        }
    }

    fn push(&mut self, corner: DVec3) {
        if self.first.is_none() {
            self.first = Some(corner);
        } else {
            self.sum += self.edge(self.previous, corner);
        }
        self.previous = corner;
    }

    fn close(mut self) -> f64 {
        if let Some(first) = self.first {
            self.sum += self.edge(self.previous, first);
        }
        self.sum
    }

    /// The unit approach direction.
    fn approach(&self) -> DVec3 {
        match self.approach {
            Approach::Tangential(t) => t.normalize(),
            Approach::Normal(n) => n,
        }
    }

    /// `n . Gamma` for the edge from `p` to `q`.
    fn edge(&self, p: DVec3, q: DVec3) -> f64 {
        let mut a = p - self.receiver;
        let mut b = q - self.receiver;
        let here = self.at_receiver * self.at_receiver;
        let (la2, lb2) = (a.length_squared(), b.length_squared());
        // A corner at the receiver: seen from the receiver moved a little
        // along `approach`, that corner lies in the direction `-approach`.
        match (la2 <= here, lb2 <= here) {
            (true, true) => return 0.0,
            (true, false) => a = -self.approach() * lb2.sqrt(),
            (false, true) => b = -self.approach() * la2.sqrt(),
            (false, false) => {}
        }
        let c = a.cross(b);
        let s = c.length();
        let cos = a.dot(b);
        if cos > 0.0 {
            // atan2(s, cos) / s tends to 1 / cos as s -> 0: smooth, so an
            // edge whose line passes through the receiver contributes 0.
            let angle_over_sine = if s > 0.0 {
                Self::angle(s, cos) / s
            } else {
                1.0 / cos
            };
            return self.normal.dot(c) * angle_over_sine;
        }
        // `s / |b - a|` is the receiver's distance from the edge's line;
        // against the angle instead, a corner close to the receiver would
        // make rounding look like a real offset.
        let edge = b - a;
        if s > self.at_receiver * edge.length() {
            return self.normal.dot(c) * Self::angle(s, cos) / s;
        }
        // The receiver is on the edge: the angle is pi, and from the receiver
        // moved to `x + delta * approach` the cross product is
        // `(a - delta d) x (b - delta d) = delta (b - a) x d` (as a x b = 0).
        let axis = edge.cross(self.approach()).normalize_or_zero();
        PI * self.normal.dot(axis)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(half: f64, z: f64) -> [DVec3; 4] {
        [
            DVec3::new(-half, -half, z),
            DVec3::new(half, -half, z),
            DVec3::new(half, half, z),
            DVec3::new(-half, half, z),
        ]
    }

    #[test]
    fn positive_in_front_and_zero_behind() {
        let sq = square(0.5, 0.0);
        let front = analytic(DVec3::new(0.1, 0.2, 1.0), -DVec3::Z, &sq);
        assert!(front > 0.0 && front < 1.0, "{front}");
        assert_eq!(analytic(DVec3::new(0.1, 0.2, -1.0), DVec3::Z, &sq), 0.0);
        // Facing away from a polygon in front of it.
        assert_eq!(analytic(DVec3::new(0.1, 0.2, 1.0), DVec3::Z, &sq), 0.0);
    }

    #[test]
    fn reversed_winding_is_seen_from_the_other_side() {
        let mut sq = square(0.5, 0.0);
        let f = analytic(DVec3::new(0.0, 0.0, 1.0), -DVec3::Z, &sq);
        sq.reverse();
        let g = analytic(DVec3::new(0.0, 0.0, -1.0), DVec3::Z, &sq);
        assert!((f - g).abs() < 1e-15);
        assert_eq!(analytic(DVec3::new(0.0, 0.0, 1.0), -DVec3::Z, &sq), 0.0);
    }

    #[test]
    fn huge_polygon_close_up_fills_the_hemisphere() {
        let f = analytic(DVec3::new(0.0, 0.0, 1e-6), -DVec3::Z, &square(1e3, 0.0));
        assert!((f - 1.0).abs() < 1e-8, "{f}");
    }

    #[test]
    fn clipping_keeps_the_front_part_only() {
        // Receiver on the floor (normal +y) facing a wall (z = 0) that extends
        // below the floor: only the part above the floor counts.
        let wall_above = [
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ];
        let wall_through = [
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ];
        let x = DVec3::new(0.2, 0.0, 0.5);
        let f = analytic(x, DVec3::Y, &wall_above);
        let g = analytic(x, DVec3::Y, &wall_through);
        assert!(f > 0.0);
        assert!((f - g).abs() < 1e-15, "{f} {g}");
    }

    #[test]
    fn degenerate_input_gives_zero() {
        assert_eq!(analytic(DVec3::Z, -DVec3::Z, &[]), 0.0);
        assert_eq!(analytic(DVec3::Z, -DVec3::Z, &[DVec3::X, DVec3::Y]), 0.0);
        assert_eq!(
            analytic(
                DVec3::Z,
                -DVec3::Z,
                &[DVec3::X, 2.0 * DVec3::X, 3.0 * DVec3::X]
            ),
            0.0
        );
        let nan = DVec3::splat(f64::NAN);
        assert_eq!(analytic(nan, -DVec3::Z, &square(1.0, 0.0)), 0.0);
    }

    #[test]
    fn receiver_on_the_base_of_a_wall_gets_half() {
        // Floor point on the base edge of a large wall: the limit from the
        // floor is 1/2, the wall filling half the hemisphere.
        let wall = [
            DVec3::new(-1e4, 0.0, 0.0),
            DVec3::new(1e4, 0.0, 0.0),
            DVec3::new(1e4, 1e4, 0.0),
            DVec3::new(-1e4, 1e4, 0.0),
        ];
        let f = analytic(DVec3::ZERO, DVec3::Y, &wall);
        assert!((f - 0.5).abs() < 1e-4, "{f}");
    }
}
