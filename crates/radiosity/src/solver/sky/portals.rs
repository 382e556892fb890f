//! Portals found and checked (beyond the paper, whose sources are all
//! surfaces): the openings through which daylight enters a scene (a
//! window, a skylight, a slit, a courtyard's open top), found from the
//! geometry, so that the sky can be sampled through them as a source
//! instead of being found by directions drawn over the whole sky (see
//! [`super`]): the idea behind Radiance's `mkillum` and the portals of
//! pbrt-v4 and Mitsuba, found here without the user marking them; and the
//! openings a user marks ([`Marked`]), checked to see the sky. Both trace
//! rays, so they live with the solver, not with the scene that only reads
//! what the file marks ([`crate::scene::portal`]).
//!
//! An opening is a hole in the surfaces: a closed loop of *boundary*
//! edges, pieces of surface edges that no other surface's edge runs along
//! (a wall built of four quads around a window leaves the window's outline
//! uncovered; the quads' shared sides cover each other, T-junctions
//! included; a crease, where two surfaces meet at an angle, is covered). A
//! loop that is planar and not filled by a surface (a free-standing board's
//! outline is filled by the board) is an opening. Walls modelled with
//! thickness, whose openings are tunnels without boundary edges, have none;
//! there a user marks the opening with faces of a portal material.

use std::collections::HashMap;

use glam::DVec3;

use crate::accel::Occluder;
use crate::geometry;
use crate::scene::polygon::convex_pieces;
pub use crate::scene::portal::{Marked, Portal};
use crate::scene::{Scene, SceneError, Surface, bounds_of};

/// Most portals kept: the largest by area (a scene of loose pieces can
/// have thousands of small outlines that pass no daylight).
pub const MAX_PORTALS: usize = 256;

/// The openings of `surfaces` ([`Portal`]), largest first, at most
/// [`MAX_PORTALS`]; `occluder` (over the same surfaces) tells a filled
/// outline from an open one.
#[must_use]
pub fn openings(surfaces: &[Surface], occluder: &dyn Occluder) -> Vec<Portal> {
    let (lo, hi) = bounds_of(surfaces);
    let diagonal = (hi - lo).length();
    if !(diagonal.is_finite() && diagonal > 0.0) {
        return Vec::new();
    }
    let tolerance = 1e-6 * diagonal;
    let pieces = boundary_pieces(surfaces, lo, tolerance);
    let mut portals: Vec<Portal> = loops(&pieces, tolerance)
        .into_iter()
        .filter_map(|outline| opening(&outline, occluder, tolerance))
        .collect();
    portals.sort_by(|a, b| b.area.total_cmp(&a.area));
    portals.truncate(MAX_PORTALS);
    portals
}

/// A planar, unfilled loop as a portal; `None` for a warped, degenerate or
/// filled one.
fn opening(outline: &[DVec3], occluder: &dyn Occluder, tolerance: f64) -> Option<Portal> {
    let pieces = convex_pieces(outline).ok()?;
    if pieces.warp.is_some() {
        return None;
    }
    let normal = geometry::normal(outline)?;
    let area: f64 = pieces.polygons.iter().map(|p| geometry::area(p)).sum();
    // A sliver (a crack between two surfaces that nearly meet) passes no
    // light worth sampling.
    let size = geometry::diameter(outline);
    if area <= 1e3 * tolerance * size {
        return None;
    }
    // Filled: a surface lies in the loop's plane at one of a few points
    // spread over it (each piece's centroid and the points half and nine
    // tenths of the way from it to each corner): the outline of a surface
    // with a hole in it has its centroid in the hole.
    let reach = 1e3 * tolerance;
    for piece in &pieces.polygons {
        let centre = geometry::centroid(piece);
        let probes = std::iter::once(centre).chain(
            piece
                .iter()
                .flat_map(|&c| [0.5, 0.9].map(|f| centre + (c - centre) * f)),
        );
        for probe in probes {
            if occluder.occluded(
                probe + normal * reach,
                probe - normal * reach,
                [u32::MAX; 2],
            ) {
                return None;
            }
        }
    }
    Some(Portal {
        pieces: pieces.polygons,
        normal,
        area,
    })
}

/// Directions cast from a marked portal's centre, on each side, to find
/// the sky through it.
const PROBES: usize = 64;

/// Checks that daylight can come through each marked portal: from its
/// centre, some direction on one side or the other reaches past every
/// surface (`reach` metres out). A portal buried in a wall or shut in a
/// closed room samples nothing and is an error naming its face.
///
/// # Errors
///
/// The first misplaced portal, at its face's line.
pub fn check_marked(
    marked: &[Marked],
    occluder: &dyn Occluder,
    reach: f64,
) -> Result<(), SceneError> {
    for m in marked {
        let Some(normal) = geometry::normal(&m.polygon) else {
            continue;
        };
        let centre = geometry::centroid(&m.polygon);
        let size = geometry::diameter(&m.polygon);
        // Directions over the whole sphere: both sides at once.
        let open = geometry::spherical::sphere_directions(PROBES)
            .into_iter()
            .any(|d| {
                let side = if d.dot(normal) >= 0.0 {
                    normal
                } else {
                    -normal
                };
                let from = centre + side * (1e-6 * size);
                !occluder.occluded(from, from + d * reach, [u32::MAX; 2])
            });
        if !open {
            return Err(SceneError::Invalid {
                location: m.location.clone(),
                message: format!(
                    "the portal face (material {}) sees no sky on either side: a portal must fill \
                     an opening to the outside (a window, a skylight), not lie inside a wall or a \
                     closed room",
                    crate::scene::text::quoted(&m.material)
                ),
            });
        }
    }
    Ok(())
}

/// Checks a loaded scene's marked portals ([`check_marked`]) where it has
/// a sky for them to serve, over a BVH of its surfaces, rays reaching past
/// the whole scene.
///
/// # Errors
///
/// The first misplaced portal, at its face's line.
pub fn check_scene(scene: &Scene) -> Result<(), SceneError> {
    let has_sky = scene.lights.iter().any(|l| l.sky().is_some());
    if scene.portals.is_empty() || !has_sky {
        return Ok(());
    }
    let occluder = crate::accel::Accel::Bvh.build(&scene.surfaces);
    let (lo, hi) = bounds_of(&scene.surfaces);
    let reach = 2.0 * (hi - lo).length() + 1.0;
    check_marked(&scene.portals, occluder.as_ref(), reach)
}

/// A straight piece of a boundary.
type Piece = (DVec3, DVec3);

/// The pieces of the surfaces' edges that no other edge runs along.
fn boundary_pieces(surfaces: &[Surface], lo: DVec3, tolerance: f64) -> Vec<Piece> {
    let edges: Vec<Piece> = surfaces
        .iter()
        .flat_map(|s| {
            let n = s.polygon.len();
            (0..n).map(move |i| (s.polygon[i], s.polygon[(i + 1) % n]))
        })
        .collect();
    // Most edges of a mesh are shared corner to corner: matched exactly,
    // each distinct edge kept once with its count.
    let key = |p: DVec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let mut index: HashMap<([u64; 3], [u64; 3]), usize> = HashMap::new();
    let mut unique: Vec<(Piece, u32)> = Vec::new();
    for (a, b) in edges {
        let (ka, kb) = (key(a), key(b));
        let k = if ka < kb { (ka, kb) } else { (kb, ka) };
        let i = *index.entry(k).or_insert_with(|| {
            unique.push(((a, b), 0));
            unique.len() - 1
        });
        unique[i].1 += 1;
    }
    let open: Vec<Piece> = unique.iter().map(|u| u.0).collect();
    // The rest by their lines: a line's key is its direction (sign fixed)
    // and its point nearest `lo`, each quantised; neighbouring keys are
    // looked up too, so that round-off at a cell's border loses nothing.
    let cell = 16.0 * tolerance;
    let line = |(a, b): Piece| -> Option<(DVec3, DVec3)> {
        let d = (b - a).normalize_or_zero();
        if d == DVec3::ZERO {
            return None;
        }
        let d = if d.x < 0.0 || (d.x == 0.0 && (d.y < 0.0 || (d.y == 0.0 && d.z < 0.0))) {
            -d
        } else {
            d
        };
        let r = a - lo;
        Some((d, r - d * d.dot(r)))
    };
    // Directions to 1e-5 radians (collinear edges agree to round-off).
    let quantise = |(d, p): (DVec3, DVec3), shift: f64| -> [i64; 6] {
        let q = |x: f64, c: f64| ((x / c) + shift).floor() as i64;
        [
            q(d.x, 1e-5),
            q(d.y, 1e-5),
            q(d.z, 1e-5),
            q(p.x, cell),
            q(p.y, cell),
            q(p.z, cell),
        ]
    };
    let mut by_line: HashMap<[i64; 6], Vec<usize>> = HashMap::new();
    for (i, &edge) in open.iter().enumerate() {
        if let Some(l) = line(edge) {
            by_line.entry(quantise(l, 0.0)).or_default().push(i);
        }
    }
    let mut pieces = Vec::new();
    for (i, &(a, b)) in open.iter().enumerate() {
        if unique[i].1 > 1 {
            continue;
        }
        let Some(l) = line((a, b)) else { continue };
        let length = (b - a).length();
        let direction = (b - a) / length;
        let on_line = |p: DVec3| {
            let t = (p - a).dot(direction);
            ((p - a) - direction * t).length() <= 4.0 * tolerance
        };
        // The other edges along this one, as intervals of it.
        let mut covered: Vec<(f64, f64)> = Vec::new();
        let mut seen = Vec::new();
        for shift in 0..64u32 {
            // The two cells nearest the key on each axis.
            let mut k = quantise(l, 0.5);
            for (axis, value) in k.iter_mut().enumerate() {
                if shift & (1 << axis) != 0 {
                    *value -= 1;
                }
            }
            let Some(list) = by_line.get(&k) else {
                continue;
            };
            for &j in list {
                if j == i || seen.contains(&j) {
                    continue;
                }
                seen.push(j);
                let (c, e) = open[j];
                if on_line(c) && on_line(e) {
                    let (s, t) = ((c - a).dot(direction), (e - a).dot(direction));
                    covered.push((s.min(t), s.max(t)));
                }
            }
        }
        covered.sort_by(|x, y| x.0.total_cmp(&y.0));
        // What is left of [0, length].
        let mut at = 0.0;
        for (s, t) in covered {
            if s > at + tolerance {
                pieces.push((a + direction * at, a + direction * s.min(length)));
            }
            at = f64::max(at, t);
            if at >= length {
                break;
            }
        }
        if at < length - tolerance {
            pieces.push((a + direction * at, b));
        }
    }
    pieces.retain(|(a, b)| (*b - *a).length() > tolerance);
    pieces
}

/// The closed loops the pieces make, each as its corners in order.
fn loops(pieces: &[Piece], tolerance: f64) -> Vec<Vec<DVec3>> {
    let cell = 8.0 * tolerance;
    let key = |p: DVec3| {
        [
            (p.x / cell).floor() as i64,
            (p.y / cell).floor() as i64,
            (p.z / cell).floor() as i64,
        ]
    };
    // Each piece's two ends, by cell.
    let mut ends: HashMap<[i64; 3], Vec<(usize, bool)>> = HashMap::new();
    for (i, &(a, b)) in pieces.iter().enumerate() {
        ends.entry(key(a)).or_default().push((i, false));
        ends.entry(key(b)).or_default().push((i, true));
    }
    let near = |p: DVec3, used: &[bool]| -> Option<(usize, bool)> {
        let k = key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = ends.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                        continue;
                    };
                    for &(j, end) in list {
                        let q = if end { pieces[j].1 } else { pieces[j].0 };
                        if !used[j] && (q - p).length() <= 2.0 * tolerance {
                            return Some((j, end));
                        }
                    }
                }
            }
        }
        None
    };
    let mut used = vec![false; pieces.len()];
    let mut out = Vec::new();
    for start in 0..pieces.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let (first, mut at) = pieces[start];
        let mut outline = vec![first];
        let closed = loop {
            if (at - first).length() <= 2.0 * tolerance && outline.len() >= 3 {
                break true;
            }
            outline.push(at);
            let Some((j, end)) = near(at, &used) else {
                break false;
            };
            used[j] = true;
            // Walk the piece from the end that meets us to its other end.
            at = if end { pieces[j].0 } else { pieces[j].1 };
        };
        if closed && outline.len() >= 3 {
            out.push(outline);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Accel;

    fn quad(origin: DVec3, u: DVec3, v: DVec3, face: u32) -> Surface {
        Surface::new(
            vec![origin, origin + u, origin + u + v, origin + v],
            DVec3::splat(0.5),
            DVec3::ZERO,
            face,
        )
        .unwrap()
    }

    /// A closed 4 x 3 x 4 room whose ceiling, four quads, leaves a 1 x 1
    /// hole over [1.5, 2.5]^2; with a free board on the floor.
    fn room() -> Vec<Surface> {
        let (w, h) = (4.0, 3.0);
        let mut s = vec![
            quad(DVec3::ZERO, DVec3::Z * w, DVec3::X * w, 0),
            quad(DVec3::ZERO, DVec3::Y * h, DVec3::Z * w, 1),
            quad(DVec3::X * w, DVec3::Z * w, DVec3::Y * h, 2),
            quad(DVec3::ZERO, DVec3::X * w, DVec3::Y * h, 3),
            quad(DVec3::Z * w, DVec3::Y * h, DVec3::X * w, 4),
        ];
        let ceiling = |x0: f64, z0: f64, x1: f64, z1: f64, id: u32| {
            quad(
                DVec3::new(x0, h, z0),
                DVec3::X * (x1 - x0),
                DVec3::Z * (z1 - z0),
                id,
            )
        };
        s.push(ceiling(0.0, 0.0, w, 1.5, 5));
        s.push(ceiling(0.0, 2.5, w, w, 6));
        s.push(ceiling(0.0, 1.5, 1.5, 2.5, 7));
        s.push(ceiling(2.5, 1.5, w, 2.5, 8));
        // A board in the air: its outline is filled.
        s.push(quad(
            DVec3::new(0.5, 1.0, 0.5),
            DVec3::X * 0.5,
            DVec3::Z * 0.5,
            9,
        ));
        s
    }

    #[test]
    fn a_hole_between_four_quads_is_found_and_a_board_is_not() {
        let surfaces = room();
        let occluder = Accel::Bvh.build(&surfaces);
        let portals = openings(&surfaces, occluder.as_ref());
        assert_eq!(portals.len(), 1, "{portals:?}");
        let p = &portals[0];
        assert!((p.area - 1.0).abs() < 1e-9, "{}", p.area);
        assert!(p.normal.y.abs() > 1.0 - 1e-12);
        for piece in &p.pieces {
            for c in piece {
                assert!((c.y - 3.0).abs() < 1e-9);
                assert!((1.5 - 1e-9..=2.5 + 1e-9).contains(&c.x), "{c}");
                assert!((1.5 - 1e-9..=2.5 + 1e-9).contains(&c.z), "{c}");
            }
        }
    }

    #[test]
    fn a_closed_room_has_none_and_an_open_top_is_one() {
        let mut surfaces = room();
        // Fill the hole: no opening left.
        surfaces.push(quad(DVec3::new(1.5, 3.0, 1.5), DVec3::X, DVec3::Z, 10));
        let occluder = Accel::Bvh.build(&surfaces);
        assert!(openings(&surfaces, occluder.as_ref()).is_empty());
        // A courtyard: four walls and a floor, no ceiling.
        let surfaces: Vec<Surface> = room().into_iter().take(5).collect();
        let occluder = Accel::Bvh.build(&surfaces);
        let portals = openings(&surfaces, occluder.as_ref());
        assert_eq!(portals.len(), 1);
        assert!((portals[0].area - 16.0).abs() < 1e-9);
    }
}
