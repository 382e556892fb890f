//! Triangulation of simple polygons in `O(n log n)`: the monotone
//! partition sweep of de Berg et al., *Computational Geometry* (3rd ed.,
//! ch. 3), followed by the linear-time triangulation of each monotone
//! piece. Every comparison is decided with Shewchuk's exact orientation
//! predicate (the `robust` crate), so a fuzzed outline cannot confuse the
//! sweep; collinear corners (zero turns) are handled as the sweep's
//! degenerate cases. The loader ([`crate::scene::polygon`]) uses it for
//! planar concave faces (design.md section 1: a surface is planar and
//! convex after loading).

use std::cmp::Ordering;
use std::collections::{BTreeMap, HashMap};

use glam::DVec2;

/// Exact orientation: positive when `a b c` turn counter-clockwise.
pub(crate) fn orient(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    let coord = |p: DVec2| robust::Coord { x: p.x, y: p.y };
    robust::orient2d(coord(a), coord(b), coord(c))
}

/// De Berg's sweep order: higher y first, then smaller x.
fn above(a: DVec2, b: DVec2) -> Ordering {
    b.y.total_cmp(&a.y).then(a.x.total_cmp(&b.x))
}

/// A key of the monotone-partition status: a left-boundary edge (running
/// down from `upper` to `lower`), or a probe point looking for the edge
/// directly left of it.
#[derive(Clone, Copy, Debug)]
enum StatusKey {
    Edge {
        upper: DVec2,
        lower: DVec2,
        edge: usize,
    },
    Probe(DVec2),
}

impl PartialEq for StatusKey {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for StatusKey {}

impl PartialOrd for StatusKey {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for StatusKey {
    /// Left to right along the sweep line, compared where the later edge
    /// starts (edges of a simple polygon never cross, so the order holds
    /// while both are in the status).
    fn cmp(&self, other: &Self) -> Ordering {
        use StatusKey::{Edge, Probe};
        match (*self, *other) {
            (Probe(_), Probe(_)) => Ordering::Equal,
            (Edge { upper, lower, .. }, Probe(q)) => {
                // A point left of the downward edge has the larger x.
                if orient(upper, lower, q) > 0.0 {
                    Ordering::Less
                } else {
                    Ordering::Greater
                }
            }
            (Probe(_), Edge { .. }) => other.cmp(self).reverse(),
            (
                Edge {
                    upper: au,
                    lower: al,
                    edge: ae,
                },
                Edge {
                    upper: bu,
                    lower: bl,
                    edge: be,
                },
            ) => {
                if ae == be {
                    return Ordering::Equal;
                }
                let (u, l, q, r, flip) = if above(au, bu) != Ordering::Greater {
                    (au, al, bu, bl, false)
                } else {
                    (bu, bl, au, al, true)
                };
                let mut side = orient(u, l, q);
                if side == 0.0 {
                    side = orient(u, l, r);
                }
                let order = if side > 0.0 {
                    Ordering::Less
                } else if side < 0.0 {
                    Ordering::Greater
                } else {
                    ae.cmp(&be)
                };
                if flip { order.reverse() } else { order }
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum VertexKind {
    Start,
    Split,
    End,
    Merge,
    Regular,
}

/// Triangulates a simple counter-clockwise polygon in `O(n log n)`:
/// triangles as corner indices, counter-clockwise. `None` if the sweep
/// meets an inconsistency (a non-simple outline; callers test simplicity
/// first).
pub(crate) fn triangulate(p: &[DVec2]) -> Option<Vec<[usize; 3]>> {
    let n = p.len();
    if n < 3 {
        return None;
    }
    let diagonals = monotone_diagonals(p)?;
    let mut triangles = Vec::with_capacity(n - 2);
    for face in split_faces(p, &diagonals)? {
        triangulate_monotone(p, &face, &mut triangles)?;
    }
    // A guard against a wrong split: the pieces must tile the polygon, up to
    // the round-off of the sums, whose scale is the sum of the magnitudes
    // of their terms (a thin polygon's area is far below that).
    let edge_terms = (0..n).map(|i| p[i].perp_dot(p[(i + 1) % n]));
    let piece_terms = triangles
        .iter()
        .map(|t| (p[t[1]] - p[t[0]]).perp_dot(p[t[2]] - p[t[0]]));
    let polygon_area: f64 = edge_terms.clone().sum();
    let pieces_area: f64 = piece_terms.clone().sum();
    let scale: f64 = edge_terms.map(f64::abs).sum::<f64>() + piece_terms.map(f64::abs).sum::<f64>();
    if (pieces_area - polygon_area).abs() > 1e-9 * scale {
        return None;
    }
    Some(triangles)
}

/// The diagonals that split a simple polygon into y-monotone pieces
/// (de Berg et al., section 3.2).
fn monotone_diagonals(p: &[DVec2]) -> Option<Vec<(usize, usize)>> {
    let n = p.len();
    let kind: Vec<VertexKind> = (0..n)
        .map(|i| {
            let (prev, next) = (p[(i + n - 1) % n], p[(i + 1) % n]);
            let prev_below = above(p[i], prev) == Ordering::Less;
            let next_below = above(p[i], next) == Ordering::Less;
            let convex = orient(prev, p[i], next) > 0.0;
            match (prev_below, next_below, convex) {
                (true, true, true) => VertexKind::Start,
                (true, true, false) => VertexKind::Split,
                (false, false, true) => VertexKind::End,
                (false, false, false) => VertexKind::Merge,
                _ => VertexKind::Regular,
            }
        })
        .collect();
    let key = |e: usize| StatusKey::Edge {
        upper: p[e],
        lower: p[(e + 1) % n],
        edge: e,
    };
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| above(p[a], p[b]));
    let mut status: BTreeMap<StatusKey, usize> = BTreeMap::new();
    let mut diagonals = Vec::new();
    let left_of = |status: &BTreeMap<StatusKey, usize>, v: usize| {
        status
            .range(..StatusKey::Probe(p[v]))
            .next_back()
            .map(|(k, h)| (*k, *h))
    };
    for &v in &order {
        let prev = (v + n - 1) % n;
        match kind[v] {
            VertexKind::Start => {
                status.insert(key(v), v);
            }
            VertexKind::End => {
                let helper = status.remove(&key(prev))?;
                if kind[helper] == VertexKind::Merge {
                    diagonals.push((v, helper));
                }
            }
            VertexKind::Split => {
                let (left, helper) = left_of(&status, v)?;
                diagonals.push((v, helper));
                status.insert(left, v);
                status.insert(key(v), v);
            }
            VertexKind::Merge => {
                let helper = status.remove(&key(prev))?;
                if kind[helper] == VertexKind::Merge {
                    diagonals.push((v, helper));
                }
                let (left, helper) = left_of(&status, v)?;
                if kind[helper] == VertexKind::Merge {
                    diagonals.push((v, helper));
                }
                status.insert(left, v);
            }
            VertexKind::Regular => {
                if above(p[prev], p[v]) == Ordering::Less {
                    // Going down the left chain: the interior is right of v.
                    let helper = status.remove(&key(prev))?;
                    if kind[helper] == VertexKind::Merge {
                        diagonals.push((v, helper));
                    }
                    status.insert(key(v), v);
                } else {
                    let (left, helper) = left_of(&status, v)?;
                    if kind[helper] == VertexKind::Merge {
                        diagonals.push((v, helper));
                    }
                    status.insert(left, v);
                }
            }
        }
    }
    Some(diagonals)
}

/// The faces a polygon's diagonals cut it into, each counter-clockwise.
fn split_faces(p: &[DVec2], diagonals: &[(usize, usize)]) -> Option<Vec<Vec<usize>>> {
    let n = p.len();
    if diagonals.is_empty() {
        return Some(vec![(0..n).collect()]);
    }
    let mut extra: HashMap<usize, Vec<usize>> = HashMap::new();
    for &(a, b) in diagonals {
        extra.entry(a).or_default().push(b);
        extra.entry(b).or_default().push(a);
    }
    // At b, coming from a, the face on the left continues along the
    // outgoing edge met first turning clockwise from the way back to a.
    let next = |a: usize, b: usize| -> usize {
        let forward = (b + 1) % n;
        let Some(others) = extra.get(&b) else {
            return forward;
        };
        let back = p[a] - p[b];
        let back_angle = back.y.atan2(back.x);
        let turn = |c: usize| {
            let d = p[c] - p[b];
            let mut cw = back_angle - d.y.atan2(d.x);
            while cw <= 0.0 {
                cw += std::f64::consts::TAU;
            }
            cw
        };
        std::iter::once(forward)
            .chain(others.iter().copied())
            .min_by(|&x, &y| turn(x).total_cmp(&turn(y)))
            .unwrap_or(forward)
    };
    let mut starts: Vec<(usize, usize)> = (0..n).map(|i| (i, (i + 1) % n)).collect();
    for &(a, b) in diagonals {
        starts.push((a, b));
        starts.push((b, a));
    }
    let mut used: std::collections::HashSet<(usize, usize)> = std::collections::HashSet::new();
    let mut faces = Vec::with_capacity(diagonals.len() + 1);
    for start in starts {
        if used.contains(&start) {
            continue;
        }
        let mut face = Vec::new();
        let (mut a, mut b) = start;
        loop {
            if !used.insert((a, b)) || face.len() > n {
                return None;
            }
            face.push(a);
            let c = next(a, b);
            (a, b) = (b, c);
            if (a, b) == start {
                break;
            }
        }
        faces.push(face);
    }
    Some(faces)
}

/// Triangulates a y-monotone counter-clockwise polygon in linear time after
/// sorting (de Berg et al., section 3.3).
fn triangulate_monotone(p: &[DVec2], face: &[usize], out: &mut Vec<[usize; 3]>) -> Option<()> {
    let m = face.len();
    if m < 3 {
        return None;
    }
    let mut emit = |a: usize, b: usize, c: usize| {
        let turn = orient(p[a], p[b], p[c]);
        if turn > 0.0 {
            out.push([a, b, c]);
        } else if turn < 0.0 {
            out.push([a, c, b]);
        }
    };
    if m == 3 {
        emit(face[0], face[1], face[2]);
        return Some(());
    }
    let top = (0..m).min_by(|&a, &b| above(p[face[a]], p[face[b]]))?;
    let bottom = (0..m).max_by(|&a, &b| above(p[face[a]], p[face[b]]))?;
    // Counter-clockwise from the top runs down the left chain.
    let mut on_left = vec![false; m];
    let mut i = top;
    while i != bottom {
        on_left[i] = true;
        i = (i + 1) % m;
    }
    let mut sorted: Vec<(usize, bool)> = (0..m).map(|i| (face[i], on_left[i])).collect();
    sorted.sort_by(|a, b| above(p[a.0], p[b.0]));
    let mut stack: Vec<(usize, bool)> = vec![sorted[0], sorted[1]];
    for j in 2..m - 1 {
        let u = sorted[j];
        let top_of_stack = *stack.last()?;
        if u.1 != top_of_stack.1 {
            for pair in stack.windows(2) {
                emit(u.0, pair[0].0, pair[1].0);
            }
            stack.clear();
            stack.push(sorted[j - 1]);
            stack.push(u);
        } else {
            let mut last = stack.pop()?;
            while let Some(&s) = stack.last() {
                let inside = if u.1 {
                    orient(p[s.0], p[last.0], p[u.0]) > 0.0
                } else {
                    orient(p[u.0], p[last.0], p[s.0]) > 0.0
                };
                if !inside {
                    break;
                }
                emit(u.0, last.0, s.0);
                last = stack.pop()?;
            }
            stack.push(last);
            stack.push(u);
        }
    }
    let lowest = sorted[m - 1].0;
    for pair in stack.windows(2) {
        emit(lowest, pair[0].0, pair[1].0);
    }
    Some(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn area2(p: &[DVec2]) -> f64 {
        (0..p.len())
            .map(|i| p[i].perp_dot(p[(i + 1) % p.len()]))
            .sum()
    }

    pub(crate) fn check_triangulation(p: &[DVec2]) {
        let triangles = triangulate(p).expect("a simple polygon triangulates");
        assert_eq!(triangles.len(), p.len() - 2, "{p:?}");
        let mut sum = 0.0;
        for t in &triangles {
            let a = orient(p[t[0]], p[t[1]], p[t[2]]);
            assert!(a > 0.0, "{t:?} of {p:?}");
            sum += a;
        }
        assert!((sum - area2(p)).abs() <= 1e-9 * area2(p), "{p:?}");
    }

    pub(crate) fn star(n: usize, seed: u64) -> Vec<DVec2> {
        let mut state = seed;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|i| {
                let angle = std::f64::consts::TAU * i as f64 / n as f64;
                let r = 0.2 + random();
                DVec2::new(r * angle.cos(), r * angle.sin())
            })
            .collect()
    }

    #[test]
    fn star_shaped_polygons_triangulate_into_n_minus_2_triangles() {
        for n in [4, 5, 7, 12, 50, 333, 2000] {
            for seed in 0..5 {
                check_triangulation(&star(n, seed));
            }
        }
    }
}
