//! Input faces to planar convex pieces (design.md section 1: a surface is
//! planar and convex after loading).
//!
//! A face keeps its outline when it is planar and convex. A planar concave
//! face is triangulated; a slightly non-planar face is split into triangles
//! of its own corners (a quad along the diagonal that folds it least, as
//! modelling tools do), and the loader warns. A face folded so much that the
//! choice of split changes its shape visibly, or whose outline crosses or
//! touches itself (a bow-tie, a pentagram), is refused: what the user meant
//! is unclear.
//!
//! Everything here is `O(n log n)` in the corner count `n`: the simplicity
//! test is the Shamos-Hoey sweep (Shamos & Hoey 1976, "Geometric
//! intersection problems") and the triangulation is the monotone partition
//! sweep of [`crate::geometry::triangulate`]. Both sweeps decide every
//! comparison with Shewchuk's exact orientation predicate (the `robust`
//! crate), so a fuzzed outline cannot confuse them.

use std::cmp::Ordering;
use std::collections::{BTreeSet, HashMap};
use std::ops::Bound;

use glam::{DVec2, DVec3};

use crate::geometry::triangulate::{orient, triangulate};

/// Largest distance of a corner from the face's plane, relative to the
/// face's size, that still counts as planar. Exporters writing six decimals
/// stay well inside it.
pub const PLANARITY_TOLERANCE: f64 = 1e-3;

/// Largest fold, in degrees, between the triangles a non-planar face is
/// split into: beyond it the two ways of splitting a quad give visibly
/// different shapes, so the face is refused rather than guessed at. A unit
/// square with one corner raised by 0.1 folds by 8 degrees.
pub const MAX_FOLD_DEGREES: f64 = 10.0;

/// Corners closer than this fraction of the face's size are one corner, and
/// a corner this close to the line through its neighbours is not a corner.
const MERGE_TOLERANCE: f64 = 1e-9;

/// How far a non-planar face is from its plane, and how it was split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Warp {
    /// Largest distance of a corner from the best-fit (Newell) plane, metres.
    pub deviation: f64,
    /// The face's size (bounding-box diagonal), metres.
    pub size: f64,
    /// Largest angle between the normals of two adjacent triangles of the
    /// split, degrees.
    pub fold_degrees: f64,
    /// Triangles the face became.
    pub triangles: usize,
}

/// A face as planar convex pieces.
#[derive(Clone, Debug)]
pub struct Pieces {
    /// Planar convex polygons, counter-clockwise about the face's normal.
    pub polygons: Vec<Vec<DVec3>>,
    /// Set when the face was not planar and was split into triangles.
    pub warp: Option<Warp>,
}

/// Why a face cannot become surfaces.
#[derive(Clone, Debug, PartialEq)]
pub enum FaceProblem {
    /// No area: all corners on a line or at a point.
    Degenerate,
    /// Too far from planar to split without guessing.
    TooWarped(Warp),
    /// Two edges cross or touch; edges are numbered by their first corner
    /// (0-based positions in the face), edge `i` running to corner `i + 1`.
    Crossing {
        /// One edge.
        first: usize,
        /// The other edge.
        second: usize,
        /// Number of corners in the face, to name the closing edge.
        corners: usize,
    },
    /// Two corners that are not neighbours are at the same point (0-based
    /// positions in the face).
    Coincident(usize, usize),
    /// The sweeps met an outline they could not handle (a guard: not seen
    /// in fuzzing).
    Untriangulable,
}

/// Splits a face (its corners in input order) into planar convex pieces.
pub fn convex_pieces(corners: &[DVec3]) -> Result<Pieces, FaceProblem> {
    let size = bounding_diagonal(corners);
    if !(size > 0.0 && size.is_finite()) {
        return Err(FaceProblem::Degenerate);
    }
    let tolerance = MERGE_TOLERANCE * size;
    if let [a, b, c] = *corners {
        // Most faces of real scenes: the tests of `simplify` and the area
        // test below, without their allocations.
        let twice_area = (b - a).cross(c - a).length();
        let longest = a.distance(b).max(b.distance(c)).max(c.distance(a));
        let shortest = a.distance(b).min(b.distance(c)).min(c.distance(a));
        if shortest <= tolerance
            || twice_area <= tolerance * longest
            || 0.5 * twice_area <= 1e-12 * size * size
        {
            return Err(FaceProblem::Degenerate);
        }
        return Ok(Pieces {
            polygons: vec![corners.to_vec()],
            warp: None,
        });
    }
    let points = simplify(corners, tolerance);
    if points.len() < 3 {
        return Err(FaceProblem::Degenerate);
    }
    let positions: Vec<DVec3> = points.iter().map(|(p, _)| *p).collect();
    let crossing_error = |crossing: Crossing| {
        let original = |i: usize| points[i].1;
        match crossing {
            Crossing::Edges(a, b) => FaceProblem::Crossing {
                first: original(a).min(original(b)),
                second: original(a).max(original(b)),
                corners: corners.len(),
            },
            Crossing::Corners(a, b) => {
                FaceProblem::Coincident(original(a).min(original(b)), original(a).max(original(b)))
            }
        }
    };
    let area_vector = crate::geometry::newell_area_vector(&positions);
    // An area below (1e-6 size)^2 is round-off of a line or a point.
    let tiny = 0.5 * area_vector.length() <= 1e-12 * size * size;
    // The lobes of a figure eight such as a bow-tie cancel in Newell's
    // normal: what is left is small, and, when the face is not exactly
    // planar, it can point along the face rather than across it, so the
    // face seen along it looks simple. Such a face is tested for crossings
    // in the plane of its spread.
    let spread = spread_normal(&positions);
    let suspicious = tiny || spread.is_some_and(|s| area_vector.normalize().dot(s).abs() < 0.5);
    if suspicious
        && let Some(s) = spread
        && let Some(crossing) = find_crossing(&flatten(&positions, s))
    {
        return Err(crossing_error(crossing));
    }
    if tiny {
        return Err(FaceProblem::Degenerate);
    }
    let normal = area_vector.normalize();
    if positions.len() == 3 {
        return Ok(Pieces {
            polygons: vec![positions],
            warp: None,
        });
    }
    let offset = crate::geometry::plane_offset(&positions, normal);
    let deviation = positions
        .iter()
        .map(|p| (normal.dot(*p) - offset).abs())
        .fold(0.0, f64::max);
    let flat = flatten(&positions, normal);
    if let Some(crossing) = find_crossing(&flat) {
        return Err(crossing_error(crossing));
    }
    if deviation <= PLANARITY_TOLERANCE * size {
        let projected: Vec<DVec3> = positions
            .iter()
            .map(|p| *p - normal * (normal.dot(*p) - offset))
            .collect();
        if is_convex(&flat) {
            return Ok(Pieces {
                polygons: vec![projected],
                warp: None,
            });
        }
        let triangles = triangulate(&flat).ok_or(FaceProblem::Untriangulable)?;
        return Ok(Pieces {
            polygons: triangles
                .iter()
                .map(|t| t.iter().map(|&i| projected[i]).collect())
                .collect(),
            warp: None,
        });
    }
    let triangles = if positions.len() == 4 {
        flattest_quad_split(&positions, &flat).ok_or(FaceProblem::Untriangulable)?
    } else {
        triangulate(&flat).ok_or(FaceProblem::Untriangulable)?
    };
    let warp = Warp {
        deviation,
        size,
        fold_degrees: largest_fold(&positions, &triangles),
        triangles: triangles.len(),
    };
    if warp.fold_degrees > MAX_FOLD_DEGREES {
        return Err(FaceProblem::TooWarped(warp));
    }
    Ok(Pieces {
        polygons: triangles
            .iter()
            .map(|t| t.iter().map(|&i| positions[i]).collect())
            .collect(),
        warp: Some(warp),
    })
}

/// Diagonal of the axis-aligned bounding box: the scale tolerances are
/// measured against (within a factor of 1.8 of the diameter, in linear
/// time).
fn bounding_diagonal(points: &[DVec3]) -> f64 {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in points {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    (hi - lo).length()
}

/// Coordinates in the plane through the first corner with the given unit
/// normal, counter-clockwise about it.
fn flatten(positions: &[DVec3], normal: DVec3) -> Vec<DVec2> {
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let origin = positions[0];
    positions
        .iter()
        .map(|p| DVec2::new((*p - origin).dot(u), (*p - origin).dot(v)))
        .collect()
}

/// A normal for corners whose signed area cancels out: the plane through
/// the first corner, the corner farthest from it and the corner farthest
/// from the line through both. `None` when all lie on a line.
fn spread_normal(positions: &[DVec3]) -> Option<DVec3> {
    let origin = positions[0];
    let far = *positions.iter().max_by(|a, b| {
        a.distance_squared(origin)
            .total_cmp(&b.distance_squared(origin))
    })?;
    let axis = far - origin;
    let side = positions
        .iter()
        .map(|p| axis.cross(*p - origin))
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))?;
    (side.length() > 1e-9 * axis.length_squared()).then(|| side.normalize())
}

/// Drops repeated corners, corners on the line through their neighbours and
/// zero-width spikes, in linear time. Keeps each corner's position in the
/// input, for messages.
fn simplify(corners: &[DVec3], tolerance: f64) -> Vec<(DVec3, usize)> {
    let collinear = |a: DVec3, b: DVec3, c: DVec3| {
        let ac = c - a;
        let length = ac.length();
        length <= tolerance || ac.cross(b - a).length() <= tolerance * length
    };
    let close = |a: DVec3, b: DVec3| a.distance(b) <= tolerance;
    let mut out: std::collections::VecDeque<(DVec3, usize)> =
        std::collections::VecDeque::with_capacity(corners.len());
    for (i, p) in corners.iter().enumerate() {
        if out.back().is_some_and(|q| close(q.0, *p)) {
            continue;
        }
        out.push_back((*p, i));
        while out.len() >= 3 {
            let n = out.len();
            if !collinear(out[n - 3].0, out[n - 2].0, out[n - 1].0) {
                break;
            }
            let last = out.pop_back().expect("three corners");
            out.pop_back();
            if !out.back().is_some_and(|q| close(q.0, last.0)) {
                out.push_back(last);
            }
        }
    }
    // The outline is closed: the same tests across the seam.
    loop {
        let n = out.len();
        if n < 3 {
            break;
        }
        if close(out[n - 1].0, out[0].0) || collinear(out[n - 2].0, out[n - 1].0, out[0].0) {
            out.pop_back();
        } else if collinear(out[n - 1].0, out[0].0, out[1].0) {
            out.pop_front();
        } else {
            break;
        }
    }
    out.into()
}

/// True when every turn of a simple outline is counter-clockwise or
/// straight.
fn is_convex(p: &[DVec2]) -> bool {
    let n = p.len();
    (0..n).all(|i| orient(p[i], p[(i + 1) % n], p[(i + 2) % n]) >= 0.0)
}

/// Of a non-planar quad's two diagonals, the one whose triangles fold least
/// (and lie inside the quad seen along its normal).
fn flattest_quad_split(positions: &[DVec3], flat: &[DVec2]) -> Option<Vec<[usize; 3]>> {
    let splits = [[[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]]];
    splits
        .into_iter()
        .filter(|split| {
            split
                .iter()
                .all(|t| orient(flat[t[0]], flat[t[1]], flat[t[2]]) > 0.0)
        })
        .map(|split| (largest_fold(positions, &split), split))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, split)| split.to_vec())
}

/// Largest angle in degrees between the normals of two triangles that share
/// an edge.
fn largest_fold(positions: &[DVec3], triangles: &[[usize; 3]]) -> f64 {
    let normal = |t: &[usize; 3]| {
        (positions[t[1]] - positions[t[0]])
            .cross(positions[t[2]] - positions[t[0]])
            .normalize_or_zero()
    };
    let mut by_edge: HashMap<(usize, usize), usize> = HashMap::new();
    let mut fold: f64 = 0.0;
    for (k, t) in triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            if let Some(&other) = by_edge.get(&(b, a)) {
                let (n1, n2) = (normal(t), normal(&triangles[other]));
                fold = fold.max(n1.cross(n2).length().atan2(n1.dot(n2)).to_degrees());
            } else {
                by_edge.insert((a, b), k);
            }
        }
    }
    fold
}

/// Where a closed outline meets itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Crossing {
    /// Edges `i` (from corner `i` to `i + 1`) and `j` cross or touch.
    Edges(usize, usize),
    /// Corners `i` and `j` are at the same point.
    Corners(usize, usize),
}

/// Lexicographic order by x, then y: the Shamos-Hoey sweep's event order.
fn by_x(a: DVec2, b: DVec2) -> Ordering {
    a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y))
}

/// An edge in the Shamos-Hoey status: left and right endpoints (by
/// [`by_x`]) and its number.
#[derive(Clone, Copy, Debug)]
struct SweepEdge {
    left: DVec2,
    right: DVec2,
    edge: usize,
}

impl PartialEq for SweepEdge {
    fn eq(&self, other: &Self) -> bool {
        self.edge == other.edge
    }
}

impl Eq for SweepEdge {}

impl PartialOrd for SweepEdge {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for SweepEdge {
    /// Bottom to top along the sweep line. Two edges in the status are
    /// compared where the later one starts: no crossing lies left of the
    /// sweep line (the sweep stops at the first), so that is their order at
    /// the sweep line too.
    fn cmp(&self, other: &Self) -> Ordering {
        if self.edge == other.edge {
            return Ordering::Equal;
        }
        let (a, b, flip) = if by_x(self.left, other.left) != Ordering::Greater {
            (self, other, false)
        } else {
            (other, self, true)
        };
        let mut side = orient(a.left, a.right, b.left);
        if side == 0.0 {
            side = orient(a.left, a.right, b.right);
        }
        let order = if side > 0.0 {
            Ordering::Less
        } else if side < 0.0 {
            Ordering::Greater
        } else {
            a.edge.cmp(&b.edge)
        };
        if flip { order.reverse() } else { order }
    }
}

/// True when two edges of the outline `p` share a point they should not:
/// any point for edges that are not neighbours, more than their common
/// corner for neighbours.
fn edges_meet(p: &[DVec2], i: usize, j: usize) -> bool {
    let n = p.len();
    let (a0, a1) = (p[i], p[(i + 1) % n]);
    let (b0, b1) = (p[j], p[(j + 1) % n]);
    if (i + 1) % n == j || (j + 1) % n == i {
        // Neighbours: they overlap only when they fold back on each other.
        let (shared, a, b) = if (i + 1) % n == j {
            (a1, a0, b1)
        } else {
            (a0, a1, b0)
        };
        return orient(a, shared, b) == 0.0 && (a - shared).dot(b - shared) > 0.0;
    }
    let d1 = orient(b0, b1, a0);
    let d2 = orient(b0, b1, a1);
    let d3 = orient(a0, a1, b0);
    let d4 = orient(a0, a1, b1);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |s0: DVec2, s1: DVec2, q: DVec2| {
        q.x >= s0.x.min(s1.x)
            && q.x <= s0.x.max(s1.x)
            && q.y >= s0.y.min(s1.y)
            && q.y <= s0.y.max(s1.y)
    };
    (d1 == 0.0 && on(b0, b1, a0))
        || (d2 == 0.0 && on(b0, b1, a1))
        || (d3 == 0.0 && on(a0, a1, b0))
        || (d4 == 0.0 && on(a0, a1, b1))
}

/// The first place where a closed outline crosses or touches itself, or
/// `None` for a simple polygon: the Shamos-Hoey sweep, `O(n log n)`.
pub(crate) fn find_crossing(p: &[DVec2]) -> Option<Crossing> {
    let n = p.len();
    if n < 3 {
        return None;
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| by_x(p[a], p[b]));
    for w in order.windows(2) {
        if p[w[0]] == p[w[1]] {
            return Some(Crossing::Corners(w[0].min(w[1]), w[0].max(w[1])));
        }
    }
    let edge = |e: usize| {
        let (a, b) = (p[e], p[(e + 1) % n]);
        if by_x(a, b) == Ordering::Less {
            SweepEdge {
                left: a,
                right: b,
                edge: e,
            }
        } else {
            SweepEdge {
                left: b,
                right: a,
                edge: e,
            }
        }
    };
    let mut status: BTreeSet<SweepEdge> = BTreeSet::new();
    let check = |a: &SweepEdge, b: &SweepEdge| {
        edges_meet(p, a.edge, b.edge)
            .then_some(Crossing::Edges(a.edge.min(b.edge), a.edge.max(b.edge)))
    };
    for &v in &order {
        let incident = [(v + n - 1) % n, v];
        for &e in &incident {
            let s = edge(e);
            if s.right == p[v] {
                let below = status.range(..s).next_back().copied();
                let above = status
                    .range((Bound::Excluded(s), Bound::Unbounded))
                    .next()
                    .copied();
                status.remove(&s);
                if let (Some(a), Some(b)) = (below, above)
                    && let Some(c) = check(&a, &b)
                {
                    return Some(c);
                }
            }
        }
        for &e in &incident {
            let s = edge(e);
            if s.left == p[v] {
                let below = status.range(..s).next_back().copied();
                let above = status
                    .range((Bound::Excluded(s), Bound::Unbounded))
                    .next()
                    .copied();
                for neighbour in [below, above].into_iter().flatten() {
                    if let Some(c) = check(&s, &neighbour) {
                        return Some(c);
                    }
                }
                status.insert(s);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangulate::tests::{area2, check_triangulation, star};

    fn brute_force_simple(p: &[DVec2]) -> bool {
        let n = p.len();
        for i in 0..n {
            for j in i + 1..n {
                if p[i] == p[j] || edges_meet(p, i, j) {
                    return false;
                }
            }
        }
        true
    }

    #[test]
    fn combs_and_spirals_with_horizontal_edges() {
        // A comb: teeth along x with horizontal tops and bottoms.
        let mut comb = vec![DVec2::new(0.0, 0.0), DVec2::new(20.0, 0.0)];
        for k in (0..10).rev() {
            let x = 2.0 * k as f64;
            comb.push(DVec2::new(x + 2.0, 5.0));
            comb.push(DVec2::new(x + 1.0, 5.0));
            comb.push(DVec2::new(x + 1.0, 1.0));
            comb.push(DVec2::new(x, 1.0));
        }
        comb.pop();
        comb.push(DVec2::new(0.0, 5.0));
        assert!(brute_force_simple(&comb));
        check_triangulation(&comb);
        // The same comb turned a quarter: the teeth point along -x.
        let turned: Vec<DVec2> = comb.iter().map(|q| DVec2::new(-q.y, q.x)).collect();
        check_triangulation(&turned);
    }

    #[test]
    fn crossing_matches_brute_force_on_random_grid_polygons() {
        // Small integer grids make many collinear, touching and repeated
        // corners: the degenerate cases of the sweep.
        let mut state = 7u64;
        let mut random = |m: u64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) % m
        };
        let mut simple = 0;
        for _ in 0..20000 {
            let n = 3 + random(6) as usize;
            let p: Vec<DVec2> = (0..n)
                .map(|_| DVec2::new(random(5) as f64, random(5) as f64))
                .collect();
            let expected = brute_force_simple(&p);
            assert_eq!(find_crossing(&p).is_none(), expected, "{p:?}");
            if expected && area2(&p) > 0.0 {
                simple += 1;
                check_triangulation(&p);
            }
        }
        assert!(simple > 500, "{simple}");
    }

    #[test]
    fn pentagram_and_bow_tie_cross() {
        let pentagram: Vec<DVec2> = (0..5)
            .map(|i| {
                let a = std::f64::consts::TAU * (2 * i) as f64 / 5.0;
                DVec2::new(a.cos(), a.sin())
            })
            .collect();
        assert!(matches!(
            find_crossing(&pentagram),
            Some(Crossing::Edges(..))
        ));
        let bow_tie = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.0, 1.0),
        ];
        assert_eq!(find_crossing(&bow_tie), Some(Crossing::Edges(0, 2)));
    }

    fn quad(z: f64) -> Vec<DVec3> {
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, z),
            DVec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn slightly_warped_quad_splits_along_the_flatter_diagonal() {
        // A long quad with one corner raised: its two splits fold
        // differently.
        let quad = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(4.0, 1.0, 0.02),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let pieces = convex_pieces(&quad).unwrap();
        let warp = pieces.warp.expect("non-planar");
        assert_eq!(pieces.polygons.len(), 2);
        let folds =
            [[[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]]].map(|s| largest_fold(&quad, &s));
        assert!((warp.fold_degrees - folds[0].min(folds[1])).abs() < 1e-12);
        assert!(folds[0] != folds[1]);
        // Every triangle keeps the input corners (no gap to the neighbours).
        for t in &pieces.polygons {
            assert!(t.iter().all(|c| quad.contains(c)));
        }
        let total: f64 = pieces
            .polygons
            .iter()
            .map(|t| crate::geometry::area(t))
            .sum();
        assert!((total - 4.0).abs() < 1e-3);
    }

    #[test]
    fn planar_quad_stays_whole_and_strongly_warped_quad_is_refused() {
        assert_eq!(convex_pieces(&quad(0.0)).unwrap().polygons.len(), 1);
        assert!(convex_pieces(&quad(0.0005)).unwrap().warp.is_none());
        let warp = convex_pieces(&quad(0.05)).unwrap().warp.unwrap();
        assert!(warp.fold_degrees > 1.0 && warp.fold_degrees < MAX_FOLD_DEGREES);
        assert!(matches!(
            convex_pieces(&quad(0.5)),
            Err(FaceProblem::TooWarped(w)) if w.fold_degrees > 20.0
        ));
    }

    #[test]
    fn slightly_non_planar_bow_tie_is_a_crossing() {
        // Found by the load_mesh fuzzer: a bow-tie 0.08 mm out of plane,
        // whose Newell normal lies along the face; seen along it the face
        // looked simple, and no diagonal split it.
        let bow_tie = [
            DVec3::new(0.556, 0.5488, 0.5592),
            DVec3::new(0.0, 0.5488, 0.0),
            DVec3::new(0.0, 0.5488, 0.5592),
            DVec3::new(0.556, 0.54888, 0.0),
        ];
        assert_eq!(
            convex_pieces(&bow_tie).unwrap_err(),
            FaceProblem::Crossing {
                first: 0,
                second: 2,
                corners: 4
            }
        );
    }

    #[test]
    fn triangulation_of_a_40000_corner_face_is_exact() {
        let p = star(40_000, 3);
        check_triangulation(&p);
        assert!(find_crossing(&p).is_none());
    }
}
