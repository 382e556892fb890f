//! Random scenes and segments for the accelerator tests: a fixed-seed
//! generator, polygon soups whose polygons share planes and edges, and
//! query points that land exactly on corners, edges and grid planes.

use glam::DVec3;
use radiosity::scene::{Scene, Surface};

/// SplitMix64: a small, fixed-seed generator, so failures reproduce.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    pub fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }

    pub fn point_in(&mut self, lo: DVec3, hi: DVec3) -> DVec3 {
        DVec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }

    pub fn direction(&mut self) -> DVec3 {
        DVec3::new(
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
        )
    }

    /// Often a grid value (lo, lo + step, ...), so points land exactly on
    /// axis-aligned planes and edges.
    pub fn snapped(&mut self, lo: f64, hi: f64, step: f64) -> f64 {
        if self.chance(0.3) && step > 0.0 {
            let steps = ((hi - lo) / step).floor().max(1.0) as usize;
            lo + step * self.below(steps + 1) as f64
        } else {
            self.range(lo, hi)
        }
    }
}

pub fn surface(polygon: Vec<DVec3>) -> Option<Surface> {
    Surface::new(polygon, DVec3::splat(0.5), DVec3::ZERO, 0)
}

/// The surfaces, each its own surface id (`group` = its index), as a soup
/// loaded without merging; skip lists in the tests name surfaces by index.
pub fn numbered(surfaces: &[Surface]) -> Vec<Surface> {
    let mut out = surfaces.to_vec();
    for (i, s) in out.iter_mut().enumerate() {
        s.group = i as u32;
    }
    out
}

pub fn builtin(name: &str) -> Scene {
    radiosity::scene::builtin::load(name)
        .expect("the scene is built in")
        .expect("the scene loads")
}

pub fn bounds(surfaces: &[Surface]) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in surfaces.iter().flat_map(|s| &s.polygon) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    (lo, hi)
}

/// Interesting points of a scene: corners, edge points, interior points of
/// surfaces, and points anywhere in (a little beyond) the bounding box,
/// often on a grid so they fall exactly on axis-aligned planes.
pub fn random_point(rng: &mut Rng, surfaces: &[Surface], lo: DVec3, hi: DVec3) -> DVec3 {
    let s = &surfaces[rng.below(surfaces.len())].polygon;
    match rng.below(5) {
        0 => s[rng.below(s.len())],
        1 => {
            let i = rng.below(s.len());
            let t = if rng.chance(0.2) { 0.5 } else { rng.unit() };
            s[i].lerp(s[(i + 1) % s.len()], t)
        }
        2 => {
            // A random point of a fan triangle.
            let i = 1 + rng.below(s.len() - 2);
            let (mut a, mut b) = (rng.unit(), rng.unit());
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            s[0] + (s[i] - s[0]) * a + (s[i + 1] - s[0]) * b
        }
        3 => {
            let margin = (hi - lo) * 0.1;
            let (lo, hi) = (lo - margin, hi + margin);
            let step = (hi - lo).max_element() / 16.0;
            DVec3::new(
                rng.snapped(lo.x, hi.x, step),
                rng.snapped(lo.y, hi.y, step),
                rng.snapped(lo.z, hi.z, step),
            )
        }
        _ => rng.point_in(lo, hi),
    }
}

pub fn random_skip(rng: &mut Rng, n: usize) -> [u32; 2] {
    let mut one = || {
        if rng.chance(0.3) {
            u32::MAX
        } else {
            rng.below(n) as u32
        }
    };
    [one(), one()]
}

/// An axis-aligned rectangle on a plane of a coarse grid, so several lie in
/// the same plane, touch, overlap or share edges.
pub fn grid_rectangle(rng: &mut Rng) -> Option<Surface> {
    let axis = rng.below(3);
    let level = 0.5 * rng.below(9) as f64;
    let corner = |rng: &mut Rng| 0.5 * rng.below(9) as f64;
    let (a0, a1) = (corner(rng), corner(rng));
    let (b0, b1) = (corner(rng), corner(rng));
    if a0 == a1 || b0 == b1 {
        return None;
    }
    let at = |a: f64, b: f64| match axis {
        0 => DVec3::new(level, a, b),
        1 => DVec3::new(b, level, a),
        _ => DVec3::new(a, b, level),
    };
    let mut polygon = vec![at(a0, b0), at(a1, b0), at(a1, b1), at(a0, b1)];
    if rng.chance(0.5) {
        polygon.reverse();
    }
    surface(polygon)
}

/// A closed tetrahedron or a strip of triangles sharing edges.
pub fn shared_edge_group(rng: &mut Rng, out: &mut Vec<Surface>) {
    let base = rng.point_in(DVec3::ZERO, DVec3::splat(3.5));
    if rng.chance(0.5) {
        let p = [
            base,
            base + DVec3::new(rng.range(0.3, 1.0), 0.0, 0.0),
            base + DVec3::new(0.0, rng.range(0.3, 1.0), 0.0),
            base + DVec3::new(0.0, 0.0, rng.range(0.3, 1.0)),
        ];
        for [i, j, k] in [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
            out.extend(surface(vec![p[i], p[j], p[k]]));
        }
    } else {
        let mut prev = [base, base + DVec3::new(0.0, rng.range(0.3, 1.0), 0.0)];
        for _ in 0..rng.below(5) + 2 {
            let next = prev[0]
                + DVec3::new(
                    rng.range(0.2, 0.8),
                    rng.range(-0.3, 0.3),
                    rng.range(-0.5, 0.5),
                );
            out.extend(surface(vec![prev[0], next, prev[1]]));
            prev = [next, prev[1]];
            prev.swap(0, 1);
        }
    }
}

/// A soup shaped like the real files (the conference room, Sponza): a
/// floor tessellated into triangles, a finely tessellated closed cylinder
/// (a column or chair leg: hundreds of small facets whose planes each have
/// the whole shell behind them), clusters of triangles under 1 mm^2,
/// needles, and pairs of faces back to back (the same triangle twice with
/// opposite windings, as modelling tools leave them), all offset by
/// `offset`.
pub fn real_file_soup(rng: &mut Rng, offset: DVec3) -> Vec<Surface> {
    let mut out = Vec::new();
    let mut push = |polygon: Vec<DVec3>| {
        out.extend(surface(polygon.into_iter().map(|p| p + offset).collect()));
    };
    // The floor: a 12 x 12 grid of squares, each cut into two triangles.
    for i in 0..12 {
        for j in 0..12 {
            let (x, y) = (0.25 * f64::from(i), 0.25 * f64::from(j));
            let a = DVec3::new(x, y, 0.0);
            let b = a + DVec3::X * 0.25;
            let c = b + DVec3::Y * 0.25;
            let d = a + DVec3::Y * 0.25;
            push(vec![a, b, c]);
            push(vec![a, c, d]);
        }
    }
    // A cylinder of radius 0.2 and height 1.5 standing on the floor, 48
    // sides by 12 rings, with caps.
    let (centre, radius, sides, rings) = (DVec3::new(1.5, 1.5, 0.0), 0.2, 48, 12);
    let ring = |k: usize, h: usize| {
        let angle = std::f64::consts::TAU * k as f64 / sides as f64;
        centre + DVec3::new(radius * angle.cos(), radius * angle.sin(), 0.125 * h as f64)
    };
    for h in 0..rings {
        for k in 0..sides {
            let (a, b) = (ring(k, h), ring((k + 1) % sides, h));
            let (c, d) = (ring((k + 1) % sides, h + 1), ring(k, h + 1));
            push(vec![a, b, c]);
            push(vec![a, c, d]);
        }
    }
    for k in 0..sides {
        let top = centre + DVec3::Z * 0.125 * rings as f64;
        push(vec![top, ring(k, rings), ring((k + 1) % sides, rings)]);
    }
    // Clusters of tiny triangles (edges of 0.1 to 1 mm) scattered above
    // the floor, some sharing corners.
    for _ in 0..12 {
        let base = rng.point_in(DVec3::new(0.2, 0.2, 0.05), DVec3::new(2.8, 2.8, 1.8));
        let mut last = base;
        for _ in 0..25 {
            let size = rng.range(1e-4, 1e-3);
            let a = if rng.chance(0.5) { last } else { base };
            let b = a + rng.direction() * size;
            let c = a + rng.direction() * size;
            last = b;
            push(vec![a, b, c]);
        }
    }
    // Needles: a long edge and a tiny third side.
    for _ in 0..20 {
        let a = rng.point_in(DVec3::new(0.0, 0.0, 0.1), DVec3::new(3.0, 3.0, 1.5));
        let u = rng.direction();
        let w = u.any_orthonormal_vector() * rng.range(1e-6, 1e-3);
        push(vec![a, a + u * 0.5, a + u * 0.5 + w]);
    }
    // Faces back to back: a box of thin panels modelled twice, once per
    // side, and a few floating back-to-back triangles.
    for _ in 0..10 {
        let a = rng.point_in(DVec3::new(0.0, 0.0, 0.2), DVec3::new(2.5, 2.5, 1.5));
        let (u, v) = (rng.direction() * 0.3, rng.direction() * 0.3);
        push(vec![a, a + u, a + v]);
        push(vec![a, a + v, a + u]);
    }
    let table = DVec3::new(0.3, 2.0, 0.7);
    let (u, v) = (DVec3::X * 0.8, DVec3::Y * 0.6);
    push(vec![table, table + u, table + u + v, table + v]);
    push(vec![table, table + v, table + u + v, table + u]);
    out
}
