//! The geometry of the surface-area cost: a node's cell (the scene's box
//! cut by the planes above it) as a convex polyhedron, its split by a
//! candidate plane, and the areas of the parts (MacDonald & Booth 1990).

use super::*;

/// Reusable buffers of the build.
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) candidates: Vec<Plane>,
    pub(super) low_count: Vec<usize>,
    pub(super) high_count: Vec<usize>,
    pub(super) points: Vec<DVec3>,
    pub(super) polygon: Vec<DVec3>,
    pub(super) back: Vec<DVec3>,
    pub(super) flat: Vec<(f64, DVec2)>,
}

/// A convex polyhedron, as its faces: a node's region of space (the
/// scene's box cut by the planes above it), for the surface-area cost.
#[derive(Clone, Debug)]
pub(super) struct Cell {
    pub(super) faces: Vec<Vec<DVec3>>,
}

impl Cell {
    /// The surfaces' bounding box `(lo, hi)`, grown by a tenth of its
    /// diagonal so no face is flat.
    pub(super) fn around((lo, hi): (DVec3, DVec3)) -> Cell {
        if !(lo.is_finite() && hi.is_finite()) {
            return Cell { faces: Vec::new() };
        }
        let margin = 0.1 * (hi - lo).length().max(f64::MIN_POSITIVE.sqrt());
        let (lo, hi) = (lo - margin, hi + margin);
        let c = |x: bool, y: bool, z: bool| {
            DVec3::new(
                if x { hi.x } else { lo.x },
                if y { hi.y } else { lo.y },
                if z { hi.z } else { lo.z },
            )
        };
        let (f, t) = (false, true);
        Cell {
            faces: vec![
                vec![c(f, f, f), c(f, t, f), c(f, t, t), c(f, f, t)],
                vec![c(t, f, f), c(t, f, t), c(t, t, t), c(t, t, f)],
                vec![c(f, f, f), c(f, f, t), c(t, f, t), c(t, f, f)],
                vec![c(f, t, f), c(t, t, f), c(t, t, t), c(f, t, t)],
                vec![c(f, f, f), c(t, f, f), c(t, t, f), c(f, t, f)],
                vec![c(f, f, t), c(f, t, t), c(t, t, t), c(t, f, t)],
            ],
        }
    }

    pub(super) fn area(&self) -> f64 {
        self.faces.iter().map(|f| geometry::area(f)).sum()
    }

    pub(super) fn bounds(&self) -> (DVec3, DVec3) {
        self.faces
            .iter()
            .flatten()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            })
    }

    /// Areas of the parts in front of and behind the plane, caps included,
    /// and of the cap (the plane's section of the cell).
    pub(super) fn split_areas(
        &self,
        normal: DVec3,
        offset: f64,
        scratch: &mut Scratch,
    ) -> (f64, f64, f64) {
        let (mut front, mut back) = (0.0, 0.0);
        scratch.points.clear();
        for face in &self.faces {
            let (lo, hi) = distance_range(face, normal, offset);
            if lo <= 0.0 && hi >= 0.0 {
                scratch
                    .points
                    .extend(face.iter().filter(|p| normal.dot(**p) == offset));
            }
            if lo >= 0.0 {
                front += geometry::area(face);
                continue;
            }
            if hi <= 0.0 {
                back += geometry::area(face);
                continue;
            }
            let (f, b) = polygon_split_areas(face, normal, offset, scratch);
            front += f;
            back += b;
        }
        let cap = convex_area(&scratch.points, normal, &mut scratch.flat);
        (front + cap, back + cap, cap)
    }

    /// The parts in front of and behind the plane.
    pub(super) fn split(&self, normal: DVec3, offset: f64, scratch: &mut Scratch) -> (Cell, Cell) {
        let mut front = Vec::with_capacity(self.faces.len() + 1);
        let mut back = Vec::with_capacity(self.faces.len() + 1);
        scratch.points.clear();
        for face in &self.faces {
            let (lo, hi) = distance_range(face, normal, offset);
            if lo >= 0.0 && hi > 0.0 {
                front.push(face.clone());
            } else if hi <= 0.0 && lo < 0.0 {
                back.push(face.clone());
            } else if lo < 0.0 && hi > 0.0 {
                split_in_scratch(face, normal, offset, scratch);
                front.push(scratch.polygon.clone());
                back.push(scratch.back.clone());
            }
            // A face lying in the plane is replaced by the cap.
            scratch
                .points
                .extend(face.iter().filter(|p| normal.dot(**p) == offset));
        }
        let cap = convex_polygon(&scratch.points, normal, &mut scratch.flat);
        if cap.len() >= 3 {
            front.push(cap.clone());
            back.push(cap);
        }
        (Cell { faces: front }, Cell { faces: back })
    }
}

/// Areas of the parts of a convex polygon in front of and behind a plane
/// (see [`split_in_scratch`]).
pub(super) fn polygon_split_areas(
    polygon: &[DVec3],
    normal: DVec3,
    offset: f64,
    scratch: &mut Scratch,
) -> (f64, f64) {
    split_in_scratch(polygon, normal, offset, scratch);
    (
        geometry::area(&scratch.polygon),
        geometry::area(&scratch.back),
    )
}

/// Splits a convex polygon at the plane into `scratch.polygon` (front) and
/// `scratch.back`, adding the points where it crosses the plane to
/// `scratch.points`.
pub(super) fn split_in_scratch(
    polygon: &[DVec3],
    normal: DVec3,
    offset: f64,
    scratch: &mut Scratch,
) {
    let points = &mut scratch.points;
    clip::split_into(
        polygon,
        |p| normal.dot(p) - offset,
        &mut scratch.polygon,
        &mut scratch.back,
        |c| points.push(c),
    );
}

/// Surface areas of the parts of the box `lo..hi` above and below the
/// plane `p[axis] = offset` (the plane clamped into the box).
pub(super) fn box_split_areas(lo: DVec3, hi: DVec3, axis: usize, offset: f64) -> (f64, f64) {
    let d = (hi - lo).max(DVec3::ZERO);
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let face = d[u] * d[v];
    let rim = 2.0 * (d[u] + d[v]);
    let below = (offset - lo[axis]).clamp(0.0, d[axis]);
    let above = d[axis] - below;
    (2.0 * face + rim * above, 2.0 * face + rim * below)
}

/// The convex hull of points lying in a plane, as a polygon ordered around
/// their centre (`flat` is scratch space).
pub(super) fn convex_polygon(
    points: &[DVec3],
    normal: DVec3,
    flat: &mut Vec<(f64, DVec2)>,
) -> Vec<DVec3> {
    if points.len() < 3 {
        return Vec::new();
    }
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let centre = points.iter().copied().sum::<DVec3>() / points.len() as f64;
    order_around(points, centre, u, v, flat);
    flat.iter()
        .map(|(_, q)| centre + u * q.x + v * q.y)
        .collect()
}

/// Area of the convex hull of points lying in a plane.
pub(super) fn convex_area(points: &[DVec3], normal: DVec3, flat: &mut Vec<(f64, DVec2)>) -> f64 {
    if points.len() < 3 {
        return 0.0;
    }
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let centre = points.iter().copied().sum::<DVec3>() / points.len() as f64;
    order_around(points, centre, u, v, flat);
    let n = flat.len();
    let twice: f64 = (0..n)
        .map(|i| flat[i].1.perp_dot(flat[(i + 1) % n].1))
        .sum();
    0.5 * twice.abs()
}

/// The points in plane coordinates about `centre`, sorted by angle. Points
/// crossing the plane from several faces repeat; repeats add no area.
pub(super) fn order_around(
    points: &[DVec3],
    centre: DVec3,
    u: DVec3,
    v: DVec3,
    flat: &mut Vec<(f64, DVec2)>,
) {
    flat.clear();
    flat.extend(points.iter().map(|p| {
        let q = DVec2::new(u.dot(*p - centre), v.dot(*p - centre));
        (q.y.atan2(q.x), q)
    }));
    flat.sort_by(|a, b| a.0.total_cmp(&b.0));
}
