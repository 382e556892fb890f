//! Spherical triangles: the solid angle a planar triangle subtends from a
//! point (Van Oosterom & Strackee 1983) and directions drawn uniformly in
//! it (Arvo 1995, "Stratified sampling of spherical triangles"), for the
//! sky seen through an opening, and directions spread evenly over the
//! sphere for sight lines: beyond the paper, whose sources are all surfaces
//! of the scene.

use glam::DVec3;

/// The solid angle of the spherical triangle of unit vectors `a`, `b`,
/// `c` (steradians, in `[0, 2 pi]`), accurate for tiny triangles: Van
/// Oosterom & Strackee's `tan(omega / 2) = |a . (b x c)| / (1 + a.b + b.c +
/// c.a)`.
#[must_use]
pub fn solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let numerator = a.dot(b.cross(c)).abs();
    let denominator = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    let half = numerator.atan2(denominator);
    (2.0 * half).max(0.0)
}

/// `n` directions spread evenly over the sphere (a Fibonacci lattice), the
/// same every time.
#[must_use]
pub fn sphere_directions(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), y, r * phi.sin())
        })
        .collect()
}

/// The angle at corner `a` of the spherical triangle `a b c` (unit
/// vectors): between the great arcs towards `b` and towards `c`.
fn corner_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let tb = b - a * a.dot(b);
    let tc = c - a * a.dot(c);
    tb.cross(tc).length().atan2(tb.dot(tc))
}

/// The unit vector in the direction of `v`'s component orthogonal to the
/// unit `a`; `None` when `v` is (numerically) along `a`.
fn orthogonal(v: DVec3, a: DVec3) -> Option<DVec3> {
    let w = v - a * a.dot(v);
    let length = w.length();
    (length > 1e-300).then(|| w / length)
}

/// A direction in the spherical triangle `a b c` (unit vectors) at `(u, v)`
/// in `[0, 1]^2`, uniformly distributed in solid angle when `(u, v)` is
/// uniform; a stratified grid of `(u, v)` gives stratified directions.
/// Arvo's construction: `u` chooses the sub-triangle `a b c'` of area
/// `u omega` (`c'` on the arc from `a` to `c`), `v` the point on the arc from
/// `b` to `c'`. `omega` is the triangle's solid angle ([`solid_angle`]),
/// passed in because callers need it anyway. Many directions in one
/// triangle: [`Triangle`].
#[must_use]
pub fn sample_triangle(a: DVec3, b: DVec3, c: DVec3, omega: f64, u: f64, v: f64) -> DVec3 {
    Triangle::new(a, b, c, omega).sample(u, v)
}

/// A spherical triangle with what [`Triangle::sample`] needs of it worked
/// out once: the angle at its first corner and the arc towards its third.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    a: DVec3,
    b: DVec3,
    c: DVec3,
    omega: f64,
    alpha: f64,
    sin_alpha: f64,
    cos_alpha: f64,
    cos_c: f64,
    /// `c`'s direction square to `a` (`None` when along it).
    towards_c: Option<DVec3>,
}

impl Triangle {
    /// The triangle of unit vectors `a`, `b`, `c` and solid angle `omega`.
    #[must_use]
    pub fn new(a: DVec3, b: DVec3, c: DVec3, omega: f64) -> Triangle {
        let alpha = corner_angle(a, b, c);
        Triangle {
            a,
            b,
            c,
            omega,
            alpha,
            sin_alpha: alpha.sin(),
            cos_alpha: alpha.cos(),
            cos_c: a.dot(b),
            towards_c: orthogonal(c, a),
        }
    }

    /// Its corners.
    #[must_use]
    pub fn corners(&self) -> [DVec3; 3] {
        [self.a, self.b, self.c]
    }

    /// The direction at `(u, v)` ([`sample_triangle`]).
    #[must_use]
    pub fn sample(&self, u: f64, v: f64) -> DVec3 {
        let (a, b, c) = (self.a, self.b, self.c);
        let area = u * self.omega;
        let (s, t) = (area - self.alpha).sin_cos();
        let uu = t - self.cos_alpha;
        let vv = s + self.sin_alpha * self.cos_c;
        let denominator = (vv * s + uu * t) * self.sin_alpha;
        let q = if denominator.abs() > 1e-300 {
            (((vv * t - uu * s) * self.cos_alpha - vv) / denominator).clamp(-1.0, 1.0)
        } else {
            a.dot(c)
        };
        let c_hat = match self.towards_c {
            Some(w) => a * q + w * (1.0 - q * q).max(0.0).sqrt(),
            None => c,
        };
        let z = 1.0 - v * (1.0 - c_hat.dot(b));
        match orthogonal(c_hat, b) {
            Some(w) => (b * z + w * (1.0 - z * z).max(0.0).sqrt()).normalize(),
            None => b,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn unit(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z).normalize()
    }

    #[test]
    fn an_octant_is_an_eighth_of_the_sphere() {
        let omega = solid_angle(DVec3::X, DVec3::Y, DVec3::Z);
        assert_relative_eq!(omega, std::f64::consts::PI / 2.0, max_relative = 1e-14);
        // Tiny: a 1 mm triangle 10 m away, planar area / d^2.
        let (a, b, c) = (
            DVec3::new(0.0, 0.0, 10.0),
            DVec3::new(1e-3, 0.0, 10.0),
            DVec3::new(0.0, 1e-3, 10.0),
        );
        let omega = solid_angle(a.normalize(), b.normalize(), c.normalize());
        assert_relative_eq!(omega, 0.5e-6 / 100.0, max_relative = 1e-6);
    }

    #[test]
    fn directions_are_uniform_in_solid_angle_and_inside_the_triangle() {
        // The mean of a linear function of the direction over a triangle,
        // by a stratified grid of samples, against the same mean by
        // splitting the triangle finely (its solid-angle-weighted
        // centroids): both estimate the integral of d . w / omega.
        let (a, b, c) = (
            unit(1.0, 0.2, 0.1),
            unit(0.1, 1.0, 0.3),
            unit(0.2, 0.3, 1.0),
        );
        let omega = solid_angle(a, b, c);
        let w = DVec3::new(0.3, -0.5, 0.8);
        let n = 200;
        let mut mean = 0.0;
        for i in 0..n {
            for j in 0..n {
                let u = (f64::from(i) + 0.5) / f64::from(n);
                let v = (f64::from(j) + 0.5) / f64::from(n);
                let d = sample_triangle(a, b, c, omega, u, v);
                assert_relative_eq!(d.length(), 1.0, max_relative = 1e-12);
                // Inside: on the inner side of each great circle.
                let normal = a.cross(b).dot(c).signum();
                for (p, q) in [(a, b), (b, c), (c, a)] {
                    assert!(p.cross(q).dot(d) * normal >= -1e-9);
                }
                mean += d.dot(w);
            }
        }
        mean /= f64::from(n * n);
        // The exact integral of d over a spherical triangle is half the sum
        // of each edge's arc angle times its great circle's unit normal
        // (the vector form of Stokes' theorem on the sphere).
        let mut integral = DVec3::ZERO;
        for (p, q) in [(a, b), (b, c), (c, a)] {
            let angle = p.cross(q).length().atan2(p.dot(q));
            integral += p.cross(q).normalize() * (0.5 * angle);
        }
        if integral.dot(a + b + c) < 0.0 {
            integral = -integral;
        }
        let exact = integral.dot(w) / omega;
        assert_relative_eq!(mean, exact, max_relative = 1e-4);
    }
}
