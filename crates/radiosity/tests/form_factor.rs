//! Point-to-polygon form factors (paper section 4) against exact answers:
//! equation (2) against the closed forms of the heat-transfer literature, a
//! many-sided polygon against the disk and the furnace (closed box) sum.
//! The paper's error study of equations (1) and (3) is tested with the
//! experiments (`crates/experiments/tests/disk_study.rs`).

mod common;

use std::f64::consts::PI;

use approx::abs_diff_eq;
use common::rng::Rng;
use glam::DVec3;
use proptest::prelude::*;
use radiosity::form_factor::{FormFactor, analytic, closed_form};

/// Log-spaced values from `lo` to `hi`.
fn log_range(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    (0..count)
        .map(|i| lo * (hi / lo).powf(i as f64 / (count - 1) as f64))
        .collect()
}

fn relative_error(value: f64, exact: f64) -> f64 {
    (value - exact).abs() / exact.abs()
}

/// `sum_g |n . Gamma_g| / (2 pi)`: the size of the terms that equation (2)
/// adds up. A small source far away (or seen at grazing incidence) makes
/// them much larger than their sum, and rounding (about `eps` of each term)
/// then limits the result's absolute accuracy to a few `eps` times this.
fn term_magnitude(receiver: DVec3, normal: DVec3, polygon: &[DVec3]) -> f64 {
    let n = polygon.len();
    (0..n)
        .map(|i| {
            let (a, b) = (polygon[i] - receiver, polygon[(i + 1) % n] - receiver);
            let c = a.cross(b);
            let s = c.length();
            normal.dot(c).abs() / s * s.atan2(a.dot(b))
        })
        .sum::<f64>()
        / (2.0 * PI)
}

/// Agreement to 1e-9 relative, or to the rounding limit of equation (2)'s
/// sum where that is coarser (ill-conditioned far or grazing sources).
/// Returns whether the rounding limit was the binding one.
fn assert_close(value: f64, exact: f64, terms: f64, what: &str) -> bool {
    let rounding = 32.0 * f64::EPSILON * terms;
    let relative = 1e-9 * exact.abs();
    assert!(
        abs_diff_eq!(value, exact, epsilon = relative.max(rounding)),
        "{what}: {value} vs {exact} (error {:e}, rounding bound {rounding:e})",
        (value - exact).abs()
    );
    rounding > relative
}

/// The rectangle `[x0, x1] x [y0, y1]` in the plane `z = height`, facing
/// down (counter-clockwise seen from below).
fn ceiling_rectangle(x0: f64, x1: f64, y0: f64, y1: f64, height: f64) -> [DVec3; 4] {
    [
        DVec3::new(x0, y0, height),
        DVec3::new(x0, y1, height),
        DVec3::new(x1, y1, height),
        DVec3::new(x1, y0, height),
    ]
}

#[test]
fn analytic_matches_the_parallel_rectangle_at_a_corner() {
    let mut count = 0;
    for &a in &log_range(1e-2, 1e2, 13) {
        for &b in &log_range(1e-2, 1e2, 11) {
            for &c in &log_range(1e-2, 1e2, 9) {
                let exact = closed_form::parallel_rectangle_corner(a, b, c);
                let rect = ceiling_rectangle(0.0, a, 0.0, b, c);
                let f = analytic(DVec3::ZERO, DVec3::Z, &rect);
                // Well conditioned throughout: 1e-9 relative, strictly.
                assert!(
                    relative_error(f, exact) < 1e-9,
                    "a {a} b {b} c {c}: {f} vs {exact}"
                );
                count += 1;
            }
        }
    }
    assert_eq!(count, 13 * 11 * 9);
}

#[test]
fn analytic_matches_the_parallel_rectangle_anywhere_below() {
    // The foot of the receiver's normal inside, on the edge line of, and
    // outside the rectangle, in all directions; the closed form is a signed
    // sum of four corner rectangles.
    let mut sampler = Rng(11);
    for _ in 0..2000 {
        let (x0, y0) = (sampler.range(-2.0, 2.0), sampler.range(-2.0, 2.0));
        let (x1, y1) = (x0 + sampler.range(0.05, 3.0), y0 + sampler.range(0.05, 3.0));
        let h = sampler.range(0.05, 3.0);
        let exact = closed_form::parallel_rectangle(x0, x1, y0, y1, h);
        let rect = ceiling_rectangle(x0, x1, y0, y1, h);
        let f = analytic(DVec3::ZERO, DVec3::Z, &rect);
        assert!(
            relative_error(f, exact) < 1e-9,
            "[{x0}, {x1}] x [{y0}, {y1}] at {h}: {f} vs {exact}"
        );
    }
    // Foot exactly inside: the four corner factors add up.
    let inside = closed_form::parallel_rectangle(-1.0, 2.0, -0.5, 1.5, 0.7);
    let sum = closed_form::parallel_rectangle_corner(1.0, 0.5, 0.7)
        + closed_form::parallel_rectangle_corner(2.0, 0.5, 0.7)
        + closed_form::parallel_rectangle_corner(1.0, 1.5, 0.7)
        + closed_form::parallel_rectangle_corner(2.0, 1.5, 0.7);
    assert!(relative_error(inside, sum) < 1e-15);
}

#[test]
fn analytic_matches_the_perpendicular_rectangle() {
    // A small wall far away is seen at grazing incidence (its cosine is
    // about a/c): equation (2) adds terms of size b/c to a sum of size
    // a^2 b / c^3, and for the most extreme corners of the grid (a, b = 0.01,
    // c = 100) rounding of those terms, not the 1e-9, bounds the error.
    let mut rounding_bound = 0;
    // Receiver at the origin, normal +z; the rectangle stands in the plane
    // y = c facing -y, spanning s (along x) and t (height along z).
    let wall = |s0: f64, s1: f64, t0: f64, t1: f64, c: f64| {
        [
            DVec3::new(s0, c, t0),
            DVec3::new(s1, c, t0),
            DVec3::new(s1, c, t1),
            DVec3::new(s0, c, t1),
        ]
    };
    for &a in &log_range(1e-2, 1e2, 13) {
        for &b in &log_range(1e-2, 1e2, 11) {
            for &c in &log_range(1e-2, 1e2, 9) {
                let exact = closed_form::perpendicular_rectangle_corner(a, b, c);
                let rect = wall(0.0, b, 0.0, a, c);
                let f = analytic(DVec3::ZERO, DVec3::Z, &rect);
                let terms = term_magnitude(DVec3::ZERO, DVec3::Z, &rect);
                if assert_close(f, exact, terms, &format!("a {a} b {b} c {c}")) {
                    rounding_bound += 1;
                }
            }
        }
    }
    let mut sampler = Rng(12);
    for _ in 0..2000 {
        let s0 = sampler.range(-2.0, 2.0);
        let s1 = s0 + sampler.range(0.05, 3.0);
        let t0 = sampler.range(0.0, 2.0);
        let t1 = t0 + sampler.range(0.05, 3.0);
        let c = sampler.range(0.05, 3.0);
        let exact = closed_form::perpendicular_rectangle(s0, s1, t0, t1, c);
        let f = analytic(DVec3::ZERO, DVec3::Z, &wall(s0, s1, t0, t1, c));
        assert!(
            relative_error(f, exact) < 1e-9,
            "s [{s0}, {s1}] t [{t0}, {t1}] c {c}: {f} vs {exact}"
        );
    }
    // Only the far, grazing tenth of the grid needs the rounding bound.
    assert!(rounding_bound < 13 * 11 * 9 / 8, "{rounding_bound}");
    // A wall reaching below the receiver's plane: only the part above counts.
    let f = analytic(DVec3::ZERO, DVec3::Z, &wall(-0.5, 1.0, -2.0, 1.5, 0.8));
    let exact = closed_form::perpendicular_rectangle(-0.5, 1.0, 0.0, 1.5, 0.8);
    assert!(relative_error(f, exact) < 1e-9, "{f} vs {exact}");
}

#[test]
fn a_2048_gon_of_equal_area_matches_the_coaxial_disk() {
    // Tolerance. With q(psi) = (rho(psi)^2 - R^2) / 2 the polygon's
    // boundary in polar form and H(rho) = int_0^rho K(s) s ds for the
    // radial kernel K(s) = h^2 / (pi (h^2 + s^2)^2), the error is
    // sum over psi of H(rho) - H(R) = K(R) int q + 1/2 int (K'(xi) / xi) q^2.
    // The first term vanishes (equal areas); |K'(s) / s| =
    // 4 h^2 / (pi (h^2 + s^2)^3) <= 4 h^2 / (pi (h^2 + r_in^2)^3) near the
    // rim, and |q| <= R^2 delta, delta = max(R_N^2 / R^2 - 1, 1 - r_in^2 / R^2)
    // (R_N, r_in the polygon's circum- and inradius). So
    // |error| <= 4 h^2 R^4 delta^2 / (h^2 + r_in^2)^3, plus rounding of the
    // N same-sign edge terms, at most N * 8 eps relative.
    const SIDES: usize = 2048;
    let radius = 0.7;
    let polygon = closed_form::disk_polygon(DVec3::ZERO, DVec3::Z, radius, SIDES);
    let circumradius = polygon[0].length();
    let inradius = circumradius * (PI / SIDES as f64).cos();
    let r2 = radius * radius;
    let delta = (circumradius * circumradius / r2 - 1.0).max(1.0 - inradius * inradius / r2);
    for &h in &log_range(1e-2, 1e2, 25) {
        let exact = closed_form::coaxial_disk(radius, h);
        let f = analytic(DVec3::new(0.0, 0.0, h), -DVec3::Z, &polygon);
        let h2 = h * h;
        let bound = 4.0 * h2 * r2 * r2 * delta * delta / (h2 + inradius * inradius).powi(3);
        let tolerance = bound / exact + SIDES as f64 * 8.0 * f64::EPSILON;
        assert!(tolerance < 1e-6);
        assert!(
            relative_error(f, exact) < tolerance,
            "h {h}: {f} vs {exact}, tolerance {tolerance:e}"
        );
    }
}

#[test]
fn exact_disk_matches_a_many_sided_polygon_in_any_orientation() {
    // disk_exact (closed form, including disks cut by the receiver's tangent
    // plane) against analytic on a 2048-gon of equal area. The polygon's
    // error is of order F (pi/N)^4 except within about R/N of the rim.
    let mut sampler = Rng(13);
    let mut cut = 0;
    for _ in 0..1000 {
        let centre = DVec3::new(
            sampler.range(-1.0, 1.0),
            sampler.range(-1.0, 1.0),
            sampler.range(-1.0, 1.0),
        );
        let disk_normal = sampler.unit_vector();
        let radius = sampler.range(0.1, 1.0);
        let receiver = centre
            + disk_normal * sampler.range(0.05, 2.0)
            + sampler.unit_vector() * sampler.range(0.0, 2.0);
        let normal = sampler.unit_vector();
        if (normal.dot(centre - receiver)).abs() < radius {
            cut += 1;
        }
        let exact = closed_form::disk_exact(receiver, normal, centre, disk_normal, radius);
        let numeric =
            closed_form::disk_numeric(receiver, normal, centre, disk_normal, radius, 2048);
        assert!(
            abs_diff_eq!(exact, numeric, epsilon = 1e-9),
            "{receiver} {normal}: {exact} vs {numeric}"
        );
    }
    assert!(cut > 200, "{cut} disks cut by the tangent plane");
}

#[test]
fn exact_disk_matches_the_offset_parallel_disk() {
    let mut sampler = Rng(14);
    for _ in 0..1000 {
        let (radius, h, a) = (
            sampler.range(0.1, 2.0),
            sampler.range(0.01, 3.0),
            sampler.range(0.0, 3.0),
        );
        let exact = closed_form::parallel_disk(radius, h, a);
        let f = closed_form::disk_exact(
            DVec3::new(a, 0.0, h),
            -DVec3::Z,
            DVec3::ZERO,
            DVec3::Z,
            radius,
        );
        // disk_exact adds terms of size R^2 / |w| that cancel to a factor
        // of size R^2 h^2 / |w|^4 for a receiver near the disk's plane far
        // from it, losing up to about five digits here.
        assert!(
            relative_error(f, exact) < 1e-10,
            "R {radius} h {h} a {a}: {f} vs {exact}"
        );
    }
}

/// The six faces of the box `[0, size.x] x [0, size.y] x [0, size.z]`,
/// each counter-clockwise seen from inside, with its inward normal.
fn box_faces(size: DVec3) -> Vec<([DVec3; 4], DVec3)> {
    let (x, y, z) = (DVec3::X * size.x, DVec3::Y * size.y, DVec3::Z * size.z);
    let face =
        |origin: DVec3, e1: DVec3, e2: DVec3| [origin, origin + e1, origin + e1 + e2, origin + e2];
    vec![
        (face(DVec3::ZERO, z, x), DVec3::Y),
        (face(y, x, z), -DVec3::Y),
        (face(DVec3::ZERO, y, z), DVec3::X),
        (face(x, z, y), -DVec3::X),
        (face(DVec3::ZERO, x, y), DVec3::Z),
        (face(z, y, x), -DVec3::Z),
    ]
}

fn box_sum(faces: &[([DVec3; 4], DVec3)], receiver: DVec3, normal: DVec3) -> f64 {
    faces
        .iter()
        .map(|(face, _)| analytic(receiver, normal, face))
        .sum()
}

#[test]
fn factors_to_the_inside_of_a_closed_box_sum_to_one() {
    let size = DVec3::new(3.0, 2.0, 1.5);
    let faces = box_faces(size);
    for (face, inward) in &faces {
        let normal = radiosity::geometry::normal(face).unwrap();
        assert!((normal - *inward).length() < 1e-15);
    }
    let mut sampler = Rng(15);
    for _ in 0..2000 {
        let receiver = DVec3::new(
            sampler.range(0.0, size.x),
            sampler.range(0.0, size.y),
            sampler.range(0.0, size.z),
        );
        let normal = sampler.unit_vector();
        let sum = box_sum(&faces, receiver, normal);
        assert!(
            abs_diff_eq!(sum, 1.0, epsilon = 1e-9),
            "{receiver} {normal}: {sum}"
        );
    }
    // Receivers on a face, facing in.
    for _ in 0..500 {
        let (face, inward) = &faces[(sampler.unit() * 6.0) as usize];
        let (u, v) = (sampler.unit(), sampler.unit());
        let receiver = face[0] + (face[1] - face[0]) * u + (face[3] - face[0]) * v;
        let sum = box_sum(&faces, receiver, *inward);
        assert!(
            abs_diff_eq!(sum, 1.0, epsilon = 1e-9),
            "{receiver} {inward}: {sum}"
        );
    }
    // Receivers on an edge where two faces meet (a vertex of one of them):
    // the adjacent face's factor is the limit along the receiving face, so
    // the sum stays 1.
    for _ in 0..500 {
        let t = sampler.range(0.01, 0.99);
        let receiver = DVec3::new(t * size.x, 0.0, 0.0);
        for normal in [DVec3::Y, DVec3::Z] {
            let sum = box_sum(&faces, receiver, normal);
            assert!(
                abs_diff_eq!(sum, 1.0, epsilon = 1e-9),
                "{receiver} {normal}: {sum}"
            );
        }
        let receiver = DVec3::new(size.x, size.y, t * size.z);
        for normal in [-DVec3::X, -DVec3::Y] {
            let sum = box_sum(&faces, receiver, normal);
            assert!(
                abs_diff_eq!(sum, 1.0, epsilon = 1e-9),
                "{receiver} {normal}: {sum}"
            );
        }
    }
}

#[test]
fn a_receiver_on_a_source_edge_is_finite_and_continuous() {
    // A floor receiver (normal +y) on the base edge of a wall (z = 0, facing
    // +z), and one tilted about the edge. Approaching along the floor the
    // factor tends to a limit, which is also the value on the edge.
    let wall = [
        DVec3::new(-1.0, 0.0, 0.0),
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(2.0, 1.5, 0.0),
        DVec3::new(-1.0, 1.5, 0.0),
    ];
    let base = DVec3::new(0.3, 0.0, 0.0);
    for tilt in [0.0_f64, 0.3, -0.6, 1.2] {
        // Receiver normal turned about the edge (x axis) from +y towards +z.
        let normal = DVec3::new(0.0, tilt.cos(), tilt.sin());
        // Along the receiver's tangent plane, in front of the wall.
        let along = DVec3::new(0.0, -tilt.sin(), tilt.cos());
        let on_edge = analytic(base, normal, &wall);
        let near = analytic(base + along * 1e-9, normal, &wall);
        let farther = analytic(base + along * 1e-6, normal, &wall);
        for f in [on_edge, near, farther] {
            assert!(f.is_finite() && (0.0..=1.0).contains(&f), "{f}");
        }
        assert!(
            abs_diff_eq!(on_edge, near, epsilon = 1e-8),
            "tilt {tilt}: {on_edge} vs {near}"
        );
        assert!(
            abs_diff_eq!(near, farther, epsilon = 1e-5),
            "tilt {tilt}: {near} vs {farther}"
        );
    }
    // The floor receiver's limit is the perpendicular-rectangle factor with
    // the receiver on the common line: two corner rectangles of 1/4 each.
    let f = analytic(base, DVec3::Y, &wall);
    let exact = closed_form::perpendicular_rectangle(-1.3, 1.7, 0.0, 1.5, 0.0);
    assert!(
        abs_diff_eq!(f, 0.5, epsilon = 1e-12) && abs_diff_eq!(exact, 0.5, epsilon = 1e-12),
        "{f} {exact}"
    );
    // Approaching from other directions (off the tangent plane) the values
    // still settle, and stay finite and non-negative.
    for direction in [
        DVec3::new(0.0, 1.0, 1.0),
        DVec3::new(0.5, 0.2, 1.0),
        DVec3::new(0.0, 1.0, 1e-3),
    ] {
        let d = direction.normalize();
        let near = analytic(base + d * 1e-9, DVec3::Y, &wall);
        let farther = analytic(base + d * 1e-6, DVec3::Y, &wall);
        assert!(near.is_finite() && near >= 0.0);
        assert!(
            abs_diff_eq!(near, farther, epsilon = 1e-5),
            "{d}: {near} vs {farther}"
        );
    }
}

#[test]
fn a_receiver_in_a_corner_is_finite_and_continuous() {
    // Floor receiver (normal +y) in the corner of a box: the corner is a
    // vertex of both adjacent walls and of the floor.
    let size = DVec3::new(2.0, 1.5, 1.0);
    let faces = box_faces(size);
    let corner = DVec3::ZERO;
    for (face, _) in &faces {
        let f = analytic(corner, DVec3::Y, face);
        assert!(f.is_finite() && (0.0..=1.0).contains(&f), "{f}");
    }
    // The wall z = 0 (facing +z), from the corner: the value there is the
    // limit along +z (the wall's normal projected on the floor), which is
    // the perpendicular-rectangle corner factor as c -> 0, 1/4.
    let (wall, _) = &faces[4];
    let at_corner = analytic(corner, DVec3::Y, wall);
    assert!(
        abs_diff_eq!(at_corner, 0.25, epsilon = 1e-12),
        "{at_corner}"
    );
    for delta in [1e-9, 1e-6] {
        let f = analytic(corner + DVec3::Z * delta, DVec3::Y, wall);
        let exact = closed_form::perpendicular_rectangle_corner(size.y, size.x, delta);
        assert!(
            abs_diff_eq!(f, exact, epsilon = 1e-9),
            "{delta}: {f} vs {exact}"
        );
        assert!(
            abs_diff_eq!(f, at_corner, epsilon = 2.0 * delta),
            "{delta}: {f} vs {at_corner}"
        );
    }
    // Along the floor's diagonal the limit is different (3/8 from each
    // wall: the factor is discontinuous at a corner), but the approach is
    // continuous.
    let diagonal = DVec3::new(1.0, 0.0, 1.0).normalize();
    let near = analytic(corner + diagonal * 1e-9, DVec3::Y, wall);
    let farther = analytic(corner + diagonal * 1e-6, DVec3::Y, wall);
    assert!(abs_diff_eq!(near, 0.375, epsilon = 1e-8), "{near}");
    assert!(
        abs_diff_eq!(near, farther, epsilon = 1e-5),
        "{near} vs {farther}"
    );
    // And the box still sums to one just inside the corner.
    let sum = box_sum(&faces, corner + diagonal * 1e-9, DVec3::Y);
    assert!(abs_diff_eq!(sum, 1.0, epsilon = 1e-9), "{sum}");
}

/// A convex quadrilateral: four points at increasing angles on a circle,
/// mapped by an affine map of the plane (which keeps convexity), placed in
/// 3D on a plane through `origin` with normal `(theta, phi)`.
fn convex_quad(
    angles: [f64; 4],
    affine: [f64; 4],
    origin: DVec3,
    theta: f64,
    phi: f64,
) -> Option<[DVec3; 4]> {
    let mut sorted = angles;
    sorted.sort_by(f64::total_cmp);
    let det = affine[0] * affine[3] - affine[1] * affine[2];
    if det.abs() < 0.05 {
        return None;
    }
    let normal = DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    );
    let (u, v) = normal.any_orthonormal_pair();
    let mut quad = sorted.map(|a| {
        let (x, y) = (a.cos(), a.sin());
        let (px, py) = (affine[0] * x + affine[1] * y, affine[2] * x + affine[3] * y);
        origin + u * px + v * py
    });
    if det < 0.0 {
        quad.reverse();
    }
    // Skip slivers: every corner must turn by a visible angle.
    let area = radiosity::geometry::area(&quad);
    for i in 0..4 {
        let (a, b, c) = (quad[i], quad[(i + 1) % 4], quad[(i + 2) % 4]);
        if (b - a).cross(c - b).length() < 1e-3 * area.max(1e-300) {
            return None;
        }
    }
    Some(quad)
}

proptest! {
    #[test]
    fn analytic_is_bounded_and_additive_over_convex_quads(
        angles in prop::array::uniform4(0.0..(2.0 * PI)),
        affine in prop::array::uniform4(-2.0..2.0_f64),
        origin in prop::array::uniform3(-1.0..1.0_f64),
        (theta, phi) in (0.0..PI, 0.0..(2.0 * PI)),
        receiver in prop::array::uniform3(-3.0..3.0_f64),
        (r_theta, r_phi) in (0.0..PI, 0.0..(2.0 * PI)),
    ) {
        let Some(quad) = convex_quad(angles, affine, DVec3::from_array(origin), theta, phi) else {
            return Ok(());
        };
        let x = DVec3::from_array(receiver);
        let n = DVec3::new(r_theta.sin() * r_phi.cos(), r_theta.sin() * r_phi.sin(), r_theta.cos());
        let whole = analytic(x, n, &quad);
        prop_assert!(whole.is_finite() && (0.0..=1.0).contains(&whole), "{}", whole);
        let first = analytic(x, n, &[quad[0], quad[1], quad[2]]);
        let second = analytic(x, n, &[quad[0], quad[2], quad[3]]);
        prop_assert!((whole - first - second).abs() < 1e-12, "{} vs {} + {}", whole, first, second);
        // Equation (3) and (1) stay in [0, 1] for the same receiver.
        let area = radiosity::geometry::area(&quad);
        let source = radiosity::form_factor::Source {
            polygon: &quad,
            centroid: radiosity::geometry::centroid(&quad),
            normal: radiosity::geometry::normal(&quad).unwrap(),
            area,
        };
        for formula in FormFactor::ALL {
            let f = formula.evaluate(x, n, &source);
            prop_assert!(f.is_finite() && (0.0..=1.0).contains(&f), "{:?} {}", formula, f);
        }
    }
}
