//! Random scenes and segments for the accelerator tests (drawn with the
//! shared fixed-seed [`Rng`]): polygon soups whose polygons share planes and edges, and
//! query points that land exactly on corners, edges and grid planes.

use glam::DVec3;
use radiosity::accel::bsp::BspSettings;
use radiosity::accel::bvh::BvhSettings;
use radiosity::scene::{Scene, Surface};

pub use super::rng::Rng;

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

/// A random triangle or planar convex quad somewhere in the box `[0, 4]^3`,
/// of size 0.2 to 2 (the BSP tests' first soups).
pub fn random_polygon(rng: &mut Rng) -> Option<Surface> {
    let a = rng.point_in(DVec3::ZERO, DVec3::splat(4.0));
    let size = rng.range(0.2, 2.0);
    let (u, v) = (rng.direction() * size, rng.direction() * size);
    if rng.chance(0.5) {
        surface(vec![a, a + u, a + v])
    } else {
        // A parallelogram, or a kite made convex by construction.
        let (u, v) = if u.cross(v).length() > 0.0 {
            (u, v)
        } else {
            (v, u)
        };
        let far = if rng.chance(0.5) {
            a + u + v
        } else {
            a + (u + v) * rng.range(0.6, 1.5)
        };
        surface(vec![a, a + u, far, a + v])
    }
}

/// A random triangle or planar convex quad of size about `size` somewhere
/// in the box `[0, 4]^3`.
pub fn random_polygon_of_size(rng: &mut Rng, size: f64) -> Option<Surface> {
    let a = rng.point_in(DVec3::ZERO, DVec3::splat(4.0));
    let (u, v) = (rng.direction() * size, rng.direction() * size);
    if rng.chance(0.5) {
        surface(vec![a, a + u, a + v])
    } else {
        // A parallelogram, or a kite made convex by construction.
        let far = if rng.chance(0.5) {
            a + u + v
        } else {
            a + (u + v) * rng.range(0.6, 1.5)
        };
        surface(vec![a, a + u, far, a + v])
    }
}

/// A needle: a long edge and a tip angle down to 1e-6 radians.
pub fn needle(rng: &mut Rng, sharpness: i32) -> Option<Surface> {
    let a = rng.point_in(DVec3::ZERO, DVec3::splat(4.0));
    let u = rng.direction();
    let w = u.any_orthonormal_vector() * u.length() * 10f64.powi(-sharpness);
    surface(vec![a, a + u * 3.0, a + u * 3.0 + w])
}

/// Polygon sizes from tiny (1e-6) to large (2).
pub fn random_size(rng: &mut Rng) -> f64 {
    if rng.chance(0.2) {
        10f64.powi(-(2 + rng.below(5) as i32))
    } else {
        rng.range(0.2, 2.0)
    }
}

/// A soup of random polygons, grid rectangles and edge-sharing groups.
pub fn soup(seed: u64, count: usize) -> Vec<Surface> {
    let mut rng = Rng(seed);
    let mut surfaces = Vec::new();
    while surfaces.len() < count {
        match rng.below(4) {
            0 | 1 => surfaces.extend(random_polygon(&mut rng)),
            2 => surfaces.extend(grid_rectangle(&mut rng)),
            _ => shared_edge_group(&mut rng, &mut surfaces),
        }
    }
    surfaces
}

/// A soup of polygons from tiny to large, grid rectangles, needles and
/// edge-sharing groups.
pub fn varied_soup(seed: u64, count: usize) -> Vec<Surface> {
    let mut rng = Rng(seed);
    let mut surfaces = Vec::new();
    while surfaces.len() < count {
        match rng.below(7) {
            0 | 1 => {
                let size = random_size(&mut rng);
                surfaces.extend(random_polygon_of_size(&mut rng, size));
            }
            2 | 3 => surfaces.extend(grid_rectangle(&mut rng)),
            4 => {
                let sharpness = 1 + rng.below(6) as i32;
                surfaces.extend(needle(&mut rng, sharpness));
            }
            _ => shared_edge_group(&mut rng, &mut surfaces),
        }
    }
    surfaces
}

/// The surfaces moved by `offset` (those still with an area).
pub fn offset(surfaces: Vec<Surface>, offset: DVec3) -> Vec<Surface> {
    surfaces
        .into_iter()
        .filter_map(|s| surface(s.polygon.iter().map(|p| *p + offset).collect()))
        .collect()
}

/// One triangle in the plane z = 0.
pub fn one_triangle() -> Vec<Surface> {
    vec![surface(vec![DVec3::ZERO, DVec3::X, DVec3::Y]).unwrap()]
}

/// A 6 x 6 grid of unit squares sharing edges (the first 36 surfaces),
/// plus 20 random triangles, all in the plane z = 1, facing both ways.
pub fn coplanar_grid(rng: &mut Rng) -> Vec<Surface> {
    let mut surfaces = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            let (x, y) = (f64::from(i), f64::from(j));
            let mut p = vec![
                DVec3::new(x, y, 1.0),
                DVec3::new(x + 1.0, y, 1.0),
                DVec3::new(x + 1.0, y + 1.0, 1.0),
                DVec3::new(x, y + 1.0, 1.0),
            ];
            if (i + j) % 2 == 1 {
                p.reverse();
            }
            surfaces.push(surface(p).unwrap());
        }
    }
    for _ in 0..20 {
        let mut corner = || DVec3::new(rng.range(0.0, 6.0), rng.range(0.0, 6.0), 1.0);
        surfaces.extend(surface(vec![corner(), corner(), corner()]));
    }
    surfaces
}

/// 300 unit squares at z = 0, 0.01, ..., 2.99, randomly shifted and
/// facing both ways (seed 13).
pub fn parallel_squares() -> Vec<Surface> {
    let mut rng = Rng(13);
    let mut surfaces = Vec::new();
    for k in 0..300 {
        let z = 0.01 * f64::from(k);
        let (x, y) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        let mut p = vec![
            DVec3::new(x, y, z),
            DVec3::new(x + 1.0, y, z),
            DVec3::new(x + 1.0, y + 1.0, z),
            DVec3::new(x, y + 1.0, z),
        ];
        if rng.chance(0.5) {
            p.reverse();
        }
        surfaces.push(surface(p).unwrap());
    }
    surfaces
}

/// A geometric series of 400 unit squares, `z = 1 - 0.97^k`, which a
/// surface-area split cuts into a lopsided tree.
pub fn geometric_stack() -> Vec<Surface> {
    (0..400)
        .map(|k| {
            let z = 1.0 - 0.97f64.powi(k);
            surface(vec![
                DVec3::new(0.0, 0.0, z),
                DVec3::new(1.0, 0.0, z),
                DVec3::new(1.0, 1.0, z),
                DVec3::new(0.0, 1.0, z),
            ])
            .unwrap()
        })
        .collect()
}

/// The BSP's presets, plus a shallow tree that has to use leaf buckets and
/// one whose fragment budget refuses splits.
pub fn bsp_settings() -> Vec<(&'static str, BspSettings)> {
    let mut all = BspSettings::presets().to_vec();
    all.push((
        "depth-4",
        BspSettings {
            max_depth: 4,
            ..BspSettings::sah()
        },
    ));
    // A tight fragment budget: splits refused, large leaves.
    all.push((
        "growth-1.1",
        BspSettings {
            max_growth: 1.1,
            ..BspSettings::sah()
        },
    ));
    all
}

/// The BVH's presets, plus variants that exercise leaf-size and bin limits.
pub fn bvh_settings() -> Vec<(&'static str, BvhSettings)> {
    let mut all = BvhSettings::presets().to_vec();
    all.push((
        "sah-2-bins-leaf-1",
        BvhSettings {
            bins: 2,
            leaf_size: 1,
            max_leaf_size: 1,
            ..BvhSettings::sah()
        },
    ));
    all.push((
        "sah-big-leaves",
        BvhSettings {
            leaf_size: 4,
            max_leaf_size: 32,
            primitive_cost: 0.1,
            ..BvhSettings::sah()
        },
    ));
    all
}
