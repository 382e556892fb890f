//! Exact point-to-surface form factors from the heat-transfer literature
//! (Howell's catalogue of configuration factors, Siegel & Howell), the
//! references against which the paper's formulas of section 4 are measured:
//! equation (2) must reproduce them, and equations (1) and (3) approximate
//! the disk factors (the paper's Figures 4.2 and 4.6).
//!
//! Every factor is from a differential area to a finite surface, like
//! [`super::FormFactor`]. Rectangles and disks are described in a frame
//! attached to the receiver, as in the catalogue; the general disk
//! ([`disk_exact`]) takes world-space vectors.

use std::f64::consts::TAU;

use glam::DVec3;

use super::analytic::analytic;

/// Differential area on the normal through one corner of a parallel
/// rectangle with sides `a` and `b` at distance `c`:
///
/// `F = 1/(2 pi) [ A/sqrt(1+A^2) atan(B/sqrt(1+A^2)) + B/sqrt(1+B^2) atan(A/sqrt(1+B^2)) ]`,
/// `A = a/c`, `B = b/c`,
///
/// evaluated with the ratios multiplied out so that `c = 0` gives the limit
/// from the front, 1/4. Zero if `a` or `b` is not positive.
#[must_use]
pub fn parallel_rectangle_corner(a: f64, b: f64, c: f64) -> f64 {
    if !(a > 0.0 && b > 0.0) {
        return 0.0;
    }
    let ha = a.hypot(c);
    let hb = b.hypot(c);
    (a / ha * (b / ha).atan() + b / hb * (a / hb).atan()) / TAU
}

/// Differential area at distance `height` below a parallel rectangle and
/// facing it, anywhere: the rectangle spans `[x_min, x_max] x [y_min, y_max]`
/// in its own plane, measured from the foot of the receiver's normal. The
/// foot may lie inside or outside the rectangle; the factor is a signed sum
/// of four [`parallel_rectangle_corner`] factors (the corner rectangles
/// spanned by the foot and each corner).
#[must_use]
pub fn parallel_rectangle(x_min: f64, x_max: f64, y_min: f64, y_max: f64, height: f64) -> f64 {
    let corner = |x: f64, y: f64| {
        x.signum() * y.signum() * parallel_rectangle_corner(x.abs(), y.abs(), height)
    };
    corner(x_max, y_max) - corner(x_min, y_max) - corner(x_max, y_min) + corner(x_min, y_min)
}

/// Differential area in a plane perpendicular to a rectangle, with its
/// normal parallel to the rectangle, opposite one corner. The
/// rectangle rises to height `a` along the receiver's normal from the line
/// where the two planes meet, has width `b` along that line, and the receiver
/// lies at distance `c` from the line on the perpendicular through a corner:
///
/// `F = 1/(2 pi) [ atan(1/Y) - Y/sqrt(X^2+Y^2) atan(1/sqrt(X^2+Y^2)) ]`,
/// `X = a/b`, `Y = c/b`,
///
/// which is `[atan(b/c) - (c/h) atan(b/h)] / (2 pi)` with `h = sqrt(a^2+c^2)`.
/// The two terms nearly cancel when `a << c`, so it is evaluated as the sum
/// of two positive terms, `atan(b/c) - atan(b/h) = atan(a^2 b / ((h+c)(c h + b^2)))`
/// and `(1 - c/h) atan(b/h) = a^2 / (h (h+c)) atan(b/h)`. Checks: `a -> infinity` gives `atan(b/c)/(2 pi)` (an infinitely tall wall
/// projects onto the wedge of azimuths it spans); `b -> infinity` gives
/// `(1 - c/sqrt(a^2+c^2))/4`, half the two-dimensional strip factor;
/// `c -> 0` gives 1/4. Zero if `a` or `b` is not positive.
#[must_use]
pub fn perpendicular_rectangle_corner(a: f64, b: f64, c: f64) -> f64 {
    if !(a > 0.0 && b > 0.0) {
        return 0.0;
    }
    let h = a.hypot(c);
    let a2 = a * a;
    let azimuth = (a2 * b / ((h + c) * (c * h + b * b))).atan();
    let elevation = a2 / (h * (h + c)) * (b / h).atan();
    (azimuth + elevation) / TAU
}

/// Differential area at distance `distance` from the line where its plane
/// meets a perpendicular rectangle, its normal parallel to the rectangle.
/// The rectangle spans `[s_min, s_max]` along the line, measured from the
/// foot of the receiver's perpendicular to the line, and `[t_min, t_max]`
/// in height above the receiver's plane; any part below that plane is behind
/// the receiver and ignored. A signed sum of
/// [`perpendicular_rectangle_corner`] factors.
#[must_use]
pub fn perpendicular_rectangle(
    s_min: f64,
    s_max: f64,
    t_min: f64,
    t_max: f64,
    distance: f64,
) -> f64 {
    let (t_min, t_max) = (t_min.max(0.0), t_max.max(0.0));
    let strip = |s: f64| {
        s.signum()
            * (perpendicular_rectangle_corner(t_max, s.abs(), distance)
                - perpendicular_rectangle_corner(t_min, s.abs(), distance))
    };
    strip(s_max) - strip(s_min)
}

/// Differential area on the axis of a parallel disk of radius `radius` at
/// distance `height`, facing it: `R^2 / (h^2 + R^2)`.
#[must_use]
pub fn coaxial_disk(radius: f64, height: f64) -> f64 {
    let r2 = radius * radius;
    r2 / (height * height + r2)
}

/// Differential area facing a parallel disk of radius `radius`, at distance
/// `height` from the disk's plane and `offset` from its axis:
///
/// `F = 1/2 [1 - (h^2 + a^2 - R^2) / sqrt((h^2 + a^2 + R^2)^2 - 4 a^2 R^2)]`,
///
/// evaluated without cancellation: the square root as
/// `sqrt((h^2 + (a-R)^2)(h^2 + (a+R)^2))`, and far away (`h^2 + a^2 > R^2`)
/// as `2 R^2 h^2 / (Q (Q + P))` with `P, Q` the numerator and root.
#[must_use]
pub fn parallel_disk(radius: f64, height: f64, offset: f64) -> f64 {
    let (r2, h2, a) = (radius * radius, height * height, offset.abs());
    let p = h2 + a * a - r2;
    let q = ((h2 + (a - radius).powi(2)) * (h2 + (a + radius).powi(2))).sqrt();
    if q == 0.0 {
        return 0.0;
    }
    if p >= 0.0 {
        2.0 * r2 * h2 / (q * (q + p))
    } else {
        0.5 * (1.0 - p / q)
    }
}

/// Exact factor from the differential area at `receiver` (unit normal
/// `receiver_normal`) to a disk of any orientation: centre `centre`, unit
/// normal `disk_normal` (its emitting side), radius `radius`.
///
/// Lambert's contour integral `F = -1/(2 pi) \oint n . (r x dr) / |r|^2`
/// around the rim `r(psi) = w + R (u cos psi + v sin psi)`, `w = c - x`,
/// has an integrand `(alpha + beta cos psi + gamma sin psi) / (A + B cos psi
/// + C sin psi)` with `alpha = R^2 n.k`, `beta = R n.(w x v)`,
/// `gamma = -R n.(w x u)`, `A = |w|^2 + R^2`, `B = 2R w.u`, `C = 2R w.v`.
/// Over the whole rim, with `S = sqrt(A^2 - B^2 - C^2)`, it integrates to
///
/// `F = -alpha / S + (beta B + gamma C) / (S (S + A))`.
///
/// When the disk crosses the receiver's tangent plane only the part in
/// front counts: its contour is an arc of the rim, integrated in closed form
/// (continuous antiderivatives, no division by a vanishing `sqrt(B^2+C^2)`),
/// closed by a chord that is an ordinary polygon edge. Zero when the
/// receiver is on or behind the disk's plane, or the disk is behind the
/// receiver; clamped to `[0, 1]`.
#[must_use]
pub fn disk_exact(
    receiver: DVec3,
    receiver_normal: DVec3,
    centre: DVec3,
    disk_normal: DVec3,
    radius: f64,
) -> f64 {
    let Some(k) = disk_normal.try_normalize() else {
        return 0.0;
    };
    let n = receiver_normal;
    let w = centre - receiver;
    let height = -k.dot(w);
    if !(height > 0.0 && radius > 0.0) {
        return 0.0;
    }
    let (u, _) = k.any_orthonormal_pair();
    let v = k.cross(u);
    let rim = |psi: f64| centre + radius * (u * psi.cos() + v * psi.sin());

    // Where the rim is in front of the tangent plane:
    // n . (r(psi)) = n.w + R mu cos(psi - chi).
    let (nw, nu, nv) = (n.dot(w), n.dot(u), n.dot(v));
    let mu = nu.hypot(nv);
    if nw + radius * mu <= 0.0 {
        return 0.0;
    }

    let alpha = radius * radius * n.dot(k);
    let beta = radius * n.dot(w.cross(v));
    let gamma = -radius * n.dot(w.cross(u));
    let big_a = w.length_squared() + radius * radius;
    let big_b = 2.0 * radius * w.dot(u);
    let big_c = 2.0 * radius * w.dot(v);
    let rho = big_b.hypot(big_c);
    let s = ((big_a - rho) * (big_a + rho)).sqrt();

    let f = if nw - radius * mu >= 0.0 {
        -alpha / s + (beta * big_b + gamma * big_c) / (s * (s + big_a))
    } else {
        let chi = nv.atan2(nu);
        let lambda = (-nw / (radius * mu)).clamp(-1.0, 1.0).acos();
        let (psi1, psi2) = (chi - lambda, chi + lambda);
        // Rotate so that the denominator is A + rho cos t, t = psi - phi.
        let phi = big_c.atan2(big_b);
        let (sin_phi, cos_phi) = phi.sin_cos();
        let beta_t = beta * cos_phi + gamma * sin_phi;
        let gamma_t = gamma * cos_phi - beta * sin_phi;
        let (t1, t2) = (psi1 - phi, psi2 - phi);
        let arc = Arc { a: big_a, rho, s };
        let integral = alpha * (arc.inverse(t2) - arc.inverse(t1))
            + beta_t * (arc.cosine(t2) - arc.cosine(t1))
            + gamma_t * arc.sine(t1, t2);
        // The chord closes the contour from the arc's end back to its start.
        let (a, b) = (rim(psi2) - receiver, rim(psi1) - receiver);
        let c = a.cross(b);
        let sc = c.length();
        let chord = if sc > 0.0 {
            n.dot(c) * sc.atan2(a.dot(b)) / sc
        } else {
            0.0
        };
        -(integral + chord) / TAU
    };
    super::clamp_factor(f)
}

/// Antiderivatives of `1/(A + rho cos t)`, `cos t/(A + rho cos t)` and
/// `sin t/(A + rho cos t)` for `A > rho >= 0`, `S = sqrt(A^2 - rho^2)`,
/// continuous in `t` and stable as `rho -> 0`.
struct Arc {
    a: f64,
    rho: f64,
    s: f64,
}

impl Arc {
    /// `t - 2 atan(rho sin t / (A + S + rho cos t))`, over `S`.
    fn inverse(&self, t: f64) -> f64 {
        (t - 2.0 * self.half_angle_atan(t)) / self.s
    }

    /// `(t - A G(t)) / rho` with `G` the [`Arc::inverse`] antiderivative,
    /// rewritten so that no term divides by `rho`.
    fn cosine(&self, t: f64) -> f64 {
        let (sin, cos) = t.sin_cos();
        let denominator = self.a + self.s + self.rho * cos;
        let z = self.rho * sin / denominator;
        let atan_over_z = if z == 0.0 { 1.0 } else { z.atan() / z };
        -t * self.rho / (self.s * (self.s + self.a))
            + 2.0 * self.a / self.s * sin / denominator * atan_over_z
    }

    /// `-(ln(A + rho cos t2) - ln(A + rho cos t1)) / rho`, as a definite
    /// integral so that `rho -> 0` is exact.
    fn sine(&self, t1: f64, t2: f64) -> f64 {
        let q = (t2.cos() - t1.cos()) / (self.a + self.rho * t1.cos());
        let y = self.rho * q;
        let ln_over_y = if y == 0.0 { 1.0 } else { y.ln_1p() / y };
        -q * ln_over_y
    }

    fn half_angle_atan(&self, t: f64) -> f64 {
        let (sin, cos) = t.sin_cos();
        (self.rho * sin / (self.a + self.s + self.rho * cos)).atan()
    }
}

/// Corners of the regular polygon with `sides` corners and the area of the
/// disk (centre `centre`, unit normal `normal`, radius `radius`),
/// counter-clockwise seen from the normal's side. Its circumradius is
/// `R sqrt(2 pi / (N sin(2 pi / N)))`.
#[must_use]
pub fn disk_polygon(centre: DVec3, normal: DVec3, radius: f64, sides: usize) -> Vec<DVec3> {
    let sides = sides.max(3);
    let k = normal.normalize_or(DVec3::Z);
    let (u, _) = k.any_orthonormal_pair();
    let v = k.cross(u);
    let step = TAU / sides as f64;
    let circumradius = radius * (TAU / (sides as f64 * step.sin())).sqrt();
    (0..sides)
        .map(|i| {
            let (sin, cos) = (step * i as f64).sin_cos();
            centre + circumradius * (u * cos + v * sin)
        })
        .collect()
}

/// The disk factor evaluated numerically: [`analytic`] on the
/// [`disk_polygon`] with `sides` corners. The polygon's boundary departs
/// from the rim by about `R (pi/N)^2 / 3` and encloses the same area, so the
/// error falls like `N^-4` (about `1e-12` relative for `N = 2048`); an
/// independent check of [`disk_exact`].
#[must_use]
pub fn disk_numeric(
    receiver: DVec3,
    receiver_normal: DVec3,
    centre: DVec3,
    disk_normal: DVec3,
    radius: f64,
    sides: usize,
) -> f64 {
    analytic(
        receiver,
        receiver_normal,
        &disk_polygon(centre, disk_normal, radius, sides),
    )
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    #[test]
    fn corner_rectangle_limits() {
        // Far away the factor tends to a b / (pi c^2).
        let f = parallel_rectangle_corner(1.0, 2.0, 1e3);
        assert!((f / (2.0 / (PI * 1e6)) - 1.0).abs() < 1e-5);
        // Close up a corner sees a quarter of the hemisphere.
        assert!((parallel_rectangle_corner(1.0, 1.0, 0.0) - 0.25).abs() < 1e-15);
        assert!((parallel_rectangle(-1e9, 1e9, -1e9, 1e9, 1.0) - 1.0).abs() < 1e-8);
        assert_eq!(parallel_rectangle_corner(0.0, 1.0, 0.0), 0.0);
    }

    #[test]
    fn perpendicular_rectangle_limits() {
        let (a, b, c) = (0.7_f64, 1e9_f64, 0.4_f64);
        let strip = (1.0 - c / a.hypot(c)) / 4.0;
        assert!((perpendicular_rectangle_corner(a, b, c) - strip).abs() < 1e-9);
        let wall = perpendicular_rectangle_corner(1e12, 0.3, 0.5);
        assert!((wall - (0.3_f64 / 0.5).atan() / TAU).abs() < 1e-9);
        assert_eq!(perpendicular_rectangle_corner(1.0, 1.0, 0.0), 0.25);
        // An infinite wall seen from the floor fills half the hemisphere as
        // the receiver approaches it.
        let f = perpendicular_rectangle(-1e9, 1e9, 0.0, 1e9, 1e-9);
        assert!((f - 0.5).abs() < 1e-8, "{f}");
    }

    #[test]
    fn parallel_disk_on_axis_and_far_away() {
        assert!((parallel_disk(0.5, 2.0, 0.0) - coaxial_disk(0.5, 2.0)).abs() < 1e-16);
        let (r, h, a) = (0.1_f64, 3e3_f64, 4e3_f64);
        let d2 = h * h + a * a;
        let point = r * r * h * h / (d2 * d2);
        assert!((parallel_disk(r, h, a) / point - 1.0).abs() < 1e-6);
    }

    #[test]
    fn exact_disk_agrees_with_parallel_disk() {
        for &(h, a) in &[(0.3, 0.0), (0.3, 0.4), (1.0, 2.0), (0.05, 0.99), (2.0, 0.5)] {
            let exact = parallel_disk(1.0, h, a);
            let x = DVec3::new(a, 0.0, h);
            let f = disk_exact(x, -DVec3::Z, DVec3::ZERO, DVec3::Z, 1.0);
            assert!(
                (f / exact - 1.0).abs() < 1e-12,
                "h {h} a {a}: {f} vs {exact}"
            );
        }
    }

    #[test]
    fn disk_polygon_has_the_disk_area() {
        let p = disk_polygon(
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(1.0, 1.0, 0.0).normalize(),
            0.5,
            7,
        );
        let area = crate::geometry::area(&p);
        assert!((area - PI * 0.25).abs() < 1e-14);
        let normal = crate::geometry::normal(&p).unwrap();
        assert!((normal - DVec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-14);
    }
}
