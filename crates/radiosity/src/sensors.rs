//! Values at sensor points (beyond the paper): the irradiance `E`, the
//! radiosity `B = Ke + Kd E` of the surface and the illuminance at points a
//! user lists, as a lighting designer asks Radiance's `rtrace -I` for them.
//!
//! The points file is `rtrace -I` input: `x y z nx ny nz` on each line. Its
//! grammar here, stricter than rtrace's (which reads a stream of numbers
//! and ignores line ends):
//!
//! * one point per line, exactly six numbers separated by spaces or tabs;
//!   a line with more or fewer is an error (rtrace would silently pair the
//!   numbers of one line with the next), so labels or ids must go after a
//!   `#`;
//! * `#` starts a comment running to the end of the line; blank lines and
//!   comment lines are skipped; lines end in LF, CR LF or CR; a UTF-8
//!   byte-order mark is skipped;
//! * numbers are decimal (`1`, `-0.5`, `2.5e-3`); NaN and infinities are
//!   errors, and so is a normal of zero length. Normals need not be unit
//!   length: they are normalised.
//!
//! Every point must lie on a surface of the scene: radiosity is a solution
//! on the surfaces, and `B` needs the surface's material. A point belongs
//! to the surface nearest to it among those whose front faces along the
//! point's normal (unit normals' dot product above [`NORMAL_AGREEMENT`], as
//! the reference harness of `../shared/reference` decides), if that surface
//! is within [`RELATIVE_TOLERANCE`] of the scene's bounding-box diagonal; a
//! tie goes to the surface that comes first in the input. The search runs
//! on a bounding-volume hierarchy of the surfaces ([`SurfaceIndex`]), so
//! placing `n` points among `m` surfaces costs about `n log m`.
//!
//! A placed point gathers light as a mesh vertex does (the solver's
//! [`Receiver`]): on its surface (moved onto it when it is off by more than
//! round-off), a hair towards the surface's centroid
//! ([`crate::solver::GATHER_NUDGE`]), with the surface's normal; so a sensor
//! at a vertex gets the vertex's value exactly.
//!
//! Illuminance is Radiance's: `179 lm/W x (0.265 R + 0.670 G + 0.065 B)`
//! of the irradiance ([`lux`]).

use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry;
use crate::scene::text::{length, quoted};
use crate::scene::{Limits, Location, Scene, SceneError, Surface};
use crate::solver::{GATHER_NUDGE, Receiver};

pub use crate::mesh::locator::{NORMAL_AGREEMENT, RELATIVE_TOLERANCE};

/// Default `--max-sensors`.
pub const DEFAULT_MAX_SENSORS: usize = 1_000_000;

pub use crate::photometry::{LUMINOUS_EFFICACY, RADIANCE_RGB_WEIGHTS, lux};

/// One line of a points file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorPoint {
    /// Where, as given.
    pub position: DVec3,
    /// Unit normal: the given one, normalised.
    pub normal: DVec3,
    /// The 1-based line it was read from.
    pub line: usize,
}

/// Reads a points file: checked to be a regular file no larger than
/// `limits.max_file_bytes` ([`crate::scene::read_input`]), then
/// [`parse`]d.
pub fn read(
    path: &Path,
    limits: &Limits,
    max_points: usize,
) -> Result<Vec<SensorPoint>, SceneError> {
    let bytes = crate::scene::read_input(path, limits)?;
    parse(path, &bytes, limits, max_points)
}

/// Parses the bytes of a points file (see the module's grammar). `path`
/// only names the file in messages. At most `max_points` points and lines
/// of `limits.max_line_bytes`.
pub fn parse(
    path: &Path,
    bytes: &[u8],
    limits: &Limits,
    max_points: usize,
) -> Result<Vec<SensorPoint>, SceneError> {
    let at = |line: usize, message: String| SceneError::Invalid {
        location: Location::line(path, line),
        message,
    };
    if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
        return Err(SceneError::Invalid {
            location: Location::file(path),
            message: "the file is UTF-16 text: save it as UTF-8 or ASCII".into(),
        });
    }
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut points = Vec::new();
    for (index, line) in lines(bytes).enumerate() {
        let number = index + 1;
        if line.len() > limits.max_line_bytes {
            return Err(at(
                number,
                format!(
                    "the line is {} bytes long, more than the limit of {} bytes (raise it with \
                     --max-line-length)",
                    line.len(),
                    limits.max_line_bytes
                ),
            ));
        }
        let data = match line.iter().position(|&b| b == b'#') {
            Some(hash) => &line[..hash],
            None => line,
        };
        if data.contains(&0) {
            return Err(at(
                number,
                "a NUL byte: this looks like a binary file, not a text file of points".into(),
            ));
        }
        let mut numbers = [0.0; 6];
        let mut count = 0;
        for token in data
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty())
        {
            let value = number_of(token).map_err(|m| at(number, m))?;
            if count < 6 {
                numbers[count] = value;
            }
            count += 1;
        }
        if count == 0 {
            continue;
        }
        if count != 6 {
            let hint = if count > 6 {
                " (put anything else after a '#')"
            } else {
                ""
            };
            return Err(at(
                number,
                format!("a point needs 6 numbers, x y z nx ny nz; this line has {count}{hint}"),
            ));
        }
        let position = DVec3::new(numbers[0], numbers[1], numbers[2]);
        let given = DVec3::new(numbers[3], numbers[4], numbers[5]);
        // Scaled by its largest component first, so that neither tiny nor
        // huge normals under- or overflow on the way to unit length.
        let largest = given.abs().max_element();
        let Some(normal) = (largest > 0.0)
            .then(|| (given / largest).try_normalize())
            .flatten()
        else {
            return Err(at(
                number,
                "the normal (0 0 0) has no direction: give the direction the surface at the \
                 point faces"
                    .into(),
            ));
        };
        if points.len() == max_points {
            return Err(at(
                number,
                format!("more than {max_points} points (raise the limit with --max-sensors)"),
            ));
        }
        points.push(SensorPoint {
            position,
            normal,
            line: number,
        });
    }
    if points.is_empty() {
        return Err(SceneError::Invalid {
            location: Location::file(path),
            message: "no points in the file: each line holds x y z nx ny nz".into(),
        });
    }
    Ok(points)
}

/// Lines ending in LF, CR LF or a lone CR, without their ends.
fn lines(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = bytes;
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let end = rest
            .iter()
            .position(|&b| b == b'\n' || b == b'\r')
            .unwrap_or(rest.len());
        let line = &rest[..end];
        let after = match rest.get(end) {
            Some(b'\r') if rest.get(end + 1) == Some(&b'\n') => end + 2,
            Some(_) => end + 1,
            None => end,
        };
        rest = &rest[after..];
        Some(line)
    })
}

/// A finite decimal number, or what is wrong with the token.
fn number_of(token: &[u8]) -> Result<f64, String> {
    let text = String::from_utf8_lossy(token);
    let value: f64 = std::str::from_utf8(token)
        .ok()
        .and_then(|t| t.parse().ok())
        .ok_or_else(|| {
            let hint = if text.contains(',') {
                " (separate numbers with spaces or tabs, not commas)"
            } else {
                ""
            };
            format!("{} is not a number{hint}", quoted(&text))
        })?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(format!("{} is not a finite number", quoted(&text)))
    }
}

/// The point of a convex surface nearest to `p`.
#[must_use]
pub fn closest_point(surface: &Surface, p: DVec3) -> DVec3 {
    let above = surface.normal.dot(p) - surface.offset;
    let in_plane = p - above * surface.normal;
    if geometry::convex_contains(&surface.polygon, surface.normal, in_plane, 0.0) {
        return in_plane;
    }
    let n = surface.polygon.len();
    let mut best = surface.polygon[0];
    let mut best_squared = f64::INFINITY;
    for i in 0..n {
        let a = surface.polygon[i];
        let edge = surface.polygon[(i + 1) % n] - a;
        let t = ((p - a).dot(edge) / edge.length_squared()).clamp(0.0, 1.0);
        let c = if t.is_finite() { a + edge * t } else { a };
        let squared = c.distance_squared(p);
        if squared < best_squared {
            best_squared = squared;
            best = c;
        }
    }
    best
}

/// Surfaces per leaf of a [`SurfaceIndex`].
const LEAF_SIZE: usize = 4;

/// A node of a [`SurfaceIndex`]: a box and either two children or a range
/// of the sorted surface list.
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first entry of `order`; inner: the left child.
    first: u32,
    /// Leaf: number of entries; inner: 0 (the right child is `right`).
    count: u32,
    right: u32,
}

/// A bounding-volume hierarchy over a scene's surfaces for nearest-surface
/// queries (the shadow-ray accelerators answer only whether a segment is
/// blocked). Built by median splits of the surfaces' centres along the
/// longest axis, so its depth is at most `log2(m) + 1` whatever the scene.
pub struct SurfaceIndex<'a> {
    surfaces: &'a [Surface],
    nodes: Vec<Node>,
    order: Vec<u32>,
    tolerance: f64,
}

/// Why a point could not be placed on a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Miss {
    /// The nearest surface facing along the point's normal and its distance.
    pub nearest_facing: Option<(u32, f64)>,
    /// The nearest surface of any orientation and its distance.
    pub nearest_any: Option<(u32, f64)>,
}

impl<'a> SurfaceIndex<'a> {
    /// Indexes `surfaces`; a point may lie [`RELATIVE_TOLERANCE`] of their
    /// bounding box's diagonal from its surface.
    #[must_use]
    pub fn new(surfaces: &'a [Surface]) -> SurfaceIndex<'a> {
        let mut items: Vec<(u32, DVec3, DVec3, DVec3)> = surfaces
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let lo = s.polygon.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
                let hi = s.polygon.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(*p));
                (i as u32, lo, hi, 0.5 * (lo + hi))
            })
            .collect();
        let (lo, hi) = items
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), item| {
                (lo.min(item.1), hi.max(item.2))
            });
        let diagonal = if items.is_empty() {
            0.0
        } else {
            (hi - lo).length()
        };
        let mut nodes = Vec::with_capacity(2 * items.len() / LEAF_SIZE + 1);
        if !items.is_empty() {
            build(&mut items, 0, &mut nodes);
        }
        SurfaceIndex {
            surfaces,
            nodes,
            order: items.iter().map(|item| item.0).collect(),
            tolerance: RELATIVE_TOLERANCE * diagonal,
        }
    }

    /// How far a point may lie from its surface, metres.
    #[must_use]
    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// The surface nearest to `p` among those `accept` takes, and its
    /// distance; on a tie, the one first in the input.
    pub fn nearest(&self, p: DVec3, accept: impl Fn(&Surface) -> bool) -> Option<(u32, f64)> {
        let mut best: Option<(u32, f64)> = None;
        if self.nodes.is_empty() {
            return None;
        }
        let mut stack = vec![0u32];
        while let Some(n) = stack.pop() {
            let node = self.nodes[n as usize];
            let reach = box_distance(p, node.lo, node.hi);
            if best.is_some_and(|(_, d)| reach > d) {
                continue;
            }
            if node.count > 0 {
                let range = node.first as usize..(node.first + node.count) as usize;
                for &i in &self.order[range] {
                    let surface = &self.surfaces[i as usize];
                    if !accept(surface) {
                        continue;
                    }
                    let d = closest_point(surface, p).distance(p);
                    let better = match best {
                        None => true,
                        Some((j, e)) => d < e || (d == e && i < j),
                    };
                    if better {
                        best = Some((i, d));
                    }
                }
            } else {
                let (left, right) = (node.first, node.right);
                let l = self.nodes[left as usize];
                let r = self.nodes[right as usize];
                // Nearer child on top of the stack: visited first, it
                // tightens the bound that prunes the other.
                if box_distance(p, l.lo, l.hi) <= box_distance(p, r.lo, r.hi) {
                    stack.push(right);
                    stack.push(left);
                } else {
                    stack.push(left);
                    stack.push(right);
                }
            }
        }
        best
    }

    /// The surface a point with unit normal `normal` lies on: the nearest
    /// one facing along the normal, if within the tolerance.
    pub fn place(&self, p: DVec3, normal: DVec3) -> Result<(u32, f64), Miss> {
        let facing = |s: &Surface| s.normal.dot(normal) > NORMAL_AGREEMENT;
        match self.nearest(p, facing) {
            Some((i, d)) if d <= self.tolerance => Ok((i, d)),
            nearest_facing => Err(Miss {
                nearest_facing,
                nearest_any: self.nearest(p, |_| true),
            }),
        }
    }
}

/// Builds the subtree of `items` (reordered in place; `offset` is their
/// position in the whole list) and returns its root.
fn build(items: &mut [(u32, DVec3, DVec3, DVec3)], offset: usize, nodes: &mut Vec<Node>) -> u32 {
    let (lo, hi) = items
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), item| {
            (lo.min(item.1), hi.max(item.2))
        });
    let id = nodes.len() as u32;
    nodes.push(Node {
        lo,
        hi,
        first: offset as u32,
        count: items.len() as u32,
        right: 0,
    });
    if items.len() <= LEAF_SIZE {
        return id;
    }
    let (c_lo, c_hi) = items
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), item| {
            (lo.min(item.3), hi.max(item.3))
        });
    let extent = c_hi - c_lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| a.3[axis].total_cmp(&b.3[axis]));
    let (left_items, right_items) = items.split_at_mut(mid);
    let left = build(left_items, offset, nodes);
    let right = build(right_items, offset + mid, nodes);
    let node = &mut nodes[id as usize];
    node.first = left;
    node.count = 0;
    node.right = right;
    id
}

/// Distance from `p` to the box `[lo, hi]` (0 inside).
fn box_distance(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    (lo - p).max(p - hi).max(DVec3::ZERO).length()
}

/// Places every point on its surface and returns the receivers the solver
/// gathers at, in input order; a point on no surface is an error naming
/// its line in `path`, how far the nearest surface facing its way is, and
/// whether it lies on a surface facing the other way.
pub fn receivers(
    scene: &Scene,
    points: &[SensorPoint],
    path: &Path,
) -> Result<Vec<Receiver>, SceneError> {
    let index = SurfaceIndex::new(&scene.surfaces);
    let placed: Vec<Result<(u32, f64), Miss>> = points
        .par_iter()
        .map(|p| index.place(p.position, p.normal))
        .collect();
    let tolerance = index.tolerance();
    points
        .iter()
        .zip(placed)
        .map(|(point, placement)| match placement {
            Ok((surface, distance)) => Ok(receiver(scene, point, surface, distance, tolerance)),
            Err(miss) => Err(SceneError::Invalid {
                location: Location::line(path, point.line),
                message: miss_message(scene, point, &miss, tolerance),
            }),
        })
        .collect()
}

/// The receiver of a point placed on `surface` at `distance`.
fn receiver(
    scene: &Scene,
    point: &SensorPoint,
    surface: u32,
    distance: f64,
    tolerance: f64,
) -> Receiver {
    let s = &scene.surfaces[surface as usize];
    // A point given on the surface is used as it is (a sensor at a vertex
    // then gathers exactly where the vertex does); one off it by more than
    // round-off, but within the tolerance, moves onto it.
    let on = if distance <= 1e-9 * tolerance {
        point.position
    } else {
        closest_point(s, point.position)
    };
    let centroid = geometry::centroid(&s.polygon);
    Receiver {
        point: on + (centroid - on) * GATHER_NUDGE,
        normal: s.normal,
        surface,
        group: s.group,
    }
}

/// What to tell a user whose point lies on no surface.
fn miss_message(scene: &Scene, point: &SensorPoint, miss: &Miss, tolerance: f64) -> String {
    // `+ 0.0` turns a negative zero into a zero, so a normal reads
    // (0.000, -1.000, 0.000) rather than (-0.000, -1.000, -0.000).
    let (p, n) = (point.position, point.normal + DVec3::ZERO);
    let mut message = format!(
        "the point ({}, {}, {}) lies on no surface facing along its normal ({:.3}, {:.3}, {:.3})",
        p.x, p.y, p.z, n.x, n.y, n.z
    );
    match miss.nearest_facing {
        Some((_, d)) => message.push_str(&format!(
            ": the nearest surface facing that way is {} away, and a point must lie within {} \
             of its surface",
            length(d),
            length(tolerance)
        )),
        None => message.push_str(": no surface of the scene faces that way"),
    }
    if let Some((i, d)) = miss.nearest_any
        && d <= tolerance
    {
        let other = scene.surfaces[i as usize].normal + DVec3::ZERO;
        message.push_str(&format!(
            "; it lies on a surface facing ({:.3}, {:.3}, {:.3}): give the normal of the side \
             to measure",
            other.x, other.y, other.z
        ));
    }
    message
}

/// Radiosity `B = Ke + Kd E` of the surface a receiver lies on.
#[must_use]
pub fn radiosity(scene: &Scene, receiver: &Receiver, irradiance: DVec3) -> DVec3 {
    scene.surfaces[receiver.surface as usize].radiosity(irradiance)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn parse_text(text: &str) -> Result<Vec<SensorPoint>, String> {
        parse(
            &PathBuf::from("p.txt"),
            text.as_bytes(),
            &Limits::default(),
            DEFAULT_MAX_SENSORS,
        )
        .map_err(|e| e.to_string())
    }

    #[test]
    fn the_grammar_of_points_files() {
        let points = parse_text(
            "# a grid\n\n1 2 3 0 0 2\r\n\t-0.5  2.5e-1 +3 0 1 0 # desk\r4 5 6 1e-300 0 0\n",
        )
        .unwrap();
        assert_eq!(points.len(), 3);
        assert_eq!(points[0].position, DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(points[0].normal, DVec3::Z);
        assert_eq!(points[0].line, 3);
        assert_eq!(points[1].position, DVec3::new(-0.5, 0.25, 3.0));
        assert_eq!(points[1].line, 4);
        assert_eq!(points[2].normal, DVec3::X);
        assert_eq!(points[2].line, 5);
        // A byte-order mark and no final line end.
        let points = parse_text("\u{feff}0 0 0 0 3 4").unwrap();
        assert!(points[0].normal.distance(DVec3::new(0.0, 0.6, 0.8)) < 1e-15);
    }

    #[test]
    fn bad_points_files_name_the_line_and_the_problem() {
        let cases = [
            (
                "0 0 0 0 0 1\n0 0 0 0 1\n",
                "p.txt:2: a point needs 6 numbers, x y z nx ny nz; this line has 5",
            ),
            (
                "0 0 0 0 0 1 7\n",
                "p.txt:1: a point needs 6 numbers, x y z nx ny nz; this line has 7 (put \
                 anything else after a '#')",
            ),
            ("0 0 x 0 0 1\n", "p.txt:1: 'x' is not a number"),
            (
                "0,0,0,0,0,1\n",
                "p.txt:1: '0,0,0,0,0,1' is not a number (separate numbers with spaces or tabs, \
                 not commas)",
            ),
            (
                "\n\n0 0 NaN 0 0 1\n",
                "p.txt:3: 'NaN' is not a finite number",
            ),
            ("0 0 0 0 0 inf\n", "p.txt:1: 'inf' is not a finite number"),
            (
                "0 0 1e999 0 0 1\n",
                "p.txt:1: '1e999' is not a finite number",
            ),
            (
                "0 0 0 0 -0 0\n",
                "p.txt:1: the normal (0 0 0) has no direction: give the direction the surface \
                 at the point faces",
            ),
            (
                "0 0 0 0 0 1\n0\x00 0 0 0 0 1\n",
                "p.txt:2: a NUL byte: this looks like a binary file, not a text file of points",
            ),
            (
                "# nothing\n\n",
                "p.txt: no points in the file: each line holds x y z nx ny nz",
            ),
            (
                "",
                "p.txt: no points in the file: each line holds x y z nx ny nz",
            ),
            ("\u{ff}\u{fe}0", "p.txt:1: '\u{ff}\u{fe}0' is not a number"),
        ];
        for (text, message) in cases {
            assert_eq!(parse_text(text).unwrap_err(), message, "{text:?}");
        }
        let utf16 = parse(Path::new("p.txt"), b"\xff\xfe0\x00", &Limits::default(), 10)
            .unwrap_err()
            .to_string();
        assert_eq!(
            utf16,
            "p.txt: the file is UTF-16 text: save it as UTF-8 or ASCII"
        );
        let not_utf8 = parse(
            Path::new("p.txt"),
            b"0 0 \xff 0 0 1",
            &Limits::default(),
            10,
        )
        .unwrap_err()
        .to_string();
        assert_eq!(not_utf8, "p.txt:1: '\u{fffd}' is not a number");
    }

    #[test]
    fn limits_bound_lines_and_points() {
        let limits = Limits {
            max_line_bytes: 12,
            ..Limits::default()
        };
        let long = parse(
            Path::new("p.txt"),
            b"0 0 0 0 0 1\n0 0 0 0 0 1.0\n",
            &limits,
            10,
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            long,
            "p.txt:2: the line is 13 bytes long, more than the limit of 12 bytes (raise it with \
             --max-line-length)"
        );
        let many = parse(
            Path::new("p.txt"),
            b"0 0 0 0 0 1\n# x\n1 0 0 0 0 1\n2 0 0 0 0 1\n",
            &Limits::default(),
            2,
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            many,
            "p.txt:4: more than 2 points (raise the limit with --max-sensors)"
        );
    }

    #[test]
    fn lux_is_radiance_s() {
        // rcalc -e '$1=179*(.265*$1+.67*$2+.065*$3)' on 1 2 3.
        assert!((lux(DVec3::new(1.0, 2.0, 3.0)) - 179.0 * 1.8).abs() < 1e-12);
        assert!((lux(DVec3::ONE) - 179.0).abs() < 1e-12);
    }

    fn square(z: f64, size: f64, flip: bool, face: u32) -> Surface {
        let mut polygon = vec![
            DVec3::new(0.0, 0.0, z),
            DVec3::new(size, 0.0, z),
            DVec3::new(size, size, z),
            DVec3::new(0.0, size, z),
        ];
        if flip {
            polygon.reverse();
        }
        Surface::new(polygon, DVec3::splat(0.5), DVec3::ZERO, face).unwrap()
    }

    #[test]
    fn closest_points_of_a_square() {
        let s = square(0.0, 1.0, false, 0);
        let cases = [
            (DVec3::new(0.5, 0.5, 2.0), DVec3::new(0.5, 0.5, 0.0)),
            (DVec3::new(2.0, 0.5, -1.0), DVec3::new(1.0, 0.5, 0.0)),
            (DVec3::new(-1.0, -3.0, 0.0), DVec3::new(0.0, 0.0, 0.0)),
            (DVec3::new(1.0, 1.0, 0.0), DVec3::new(1.0, 1.0, 0.0)),
        ];
        for (p, q) in cases {
            assert!(closest_point(&s, p).distance(q) < 1e-15, "{p}");
        }
    }

    /// The index finds what a loop over every surface finds, on a stack of
    /// squares of both orientations with random points.
    #[test]
    fn the_index_agrees_with_brute_force() {
        let surfaces: Vec<Surface> = (0..300)
            .map(|i| {
                let mut s = square(
                    f64::from(i % 50) * 0.1,
                    1.0 + f64::from(i % 7) * 0.1,
                    i % 3 == 0,
                    i,
                );
                for p in &mut s.polygon {
                    *p += DVec3::new(f64::from(i / 50) * 0.7, f64::from(i % 5) * 0.3, 0.0);
                }
                Surface::new(s.polygon, s.rho, s.emission, i).unwrap()
            })
            .collect();
        let index = SurfaceIndex::new(&surfaces);
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..2000 {
            let p = DVec3::new(next() * 6.0 - 1.0, next() * 3.0 - 1.0, next() * 6.0 - 0.5);
            let up = next() < 0.5;
            let accept = |s: &Surface| (s.normal.z > 0.0) == up;
            let brute = surfaces
                .iter()
                .enumerate()
                .filter(|(_, s)| accept(s))
                .map(|(i, s)| (i as u32, closest_point(s, p).distance(p)))
                .fold(None, |best: Option<(u32, f64)>, (i, d)| match best {
                    Some((_, e)) if e <= d => best,
                    _ => Some((i, d)),
                });
            assert_eq!(index.nearest(p, accept), brute, "{p}");
        }
    }

    #[test]
    fn points_are_placed_by_distance_and_side() {
        let surfaces = vec![
            square(0.0, 1.0, false, 0),
            square(0.0, 1.0, true, 1),
            square(0.5, 1.0, false, 2),
        ];
        let index = SurfaceIndex::new(&surfaces);
        let tolerance = index.tolerance();
        // The box is 1 x 1 x 0.5: its diagonal is 1.5.
        assert!((tolerance - 1.5e-4).abs() < 1e-15);
        assert_eq!(
            index.place(DVec3::new(0.5, 0.5, 0.0), DVec3::Z),
            Ok((0, 0.0))
        );
        assert_eq!(
            index.place(DVec3::new(0.5, 0.5, 0.0), -DVec3::Z),
            Ok((1, 0.0))
        );
        // A tilted normal within the agreement still picks the side.
        let tilted = DVec3::new(0.4, 0.0, 1.0).normalize();
        assert_eq!(index.place(DVec3::new(0.2, 0.2, 0.5), tilted), Ok((2, 0.0)));
        let off = index
            .place(DVec3::new(0.5, 0.5, 0.25), DVec3::Z)
            .unwrap_err();
        assert_eq!(off.nearest_facing, Some((0, 0.25)));
        let sideways = index
            .place(DVec3::new(0.5, 0.5, 0.0), DVec3::X)
            .unwrap_err();
        assert_eq!(sideways.nearest_facing, None);
        assert_eq!(sideways.nearest_any, Some((0, 0.0)));
    }
}
