//! Surfaces from triangle soup: adjacent coplanar faces of one material get
//! one surface id ([`Surface::group`]).
//!
//! The paper's pre-test (section 2) and its BSP (section 3) assume real
//! surfaces: a vertex is visible when its hemicube pixel holds *its own
//! surface's* id, and "newly created surfaces can still share the same
//! surface id". A modelling tool exports a wall as a dozen triangles; left
//! apart, a vertex's neighbouring pixels hold the ids of the adjacent
//! triangles and the pre-test can decide little (Sponza: 41% of pairs).
//! Merging restores the surfaces the paper assumes.
//!
//! Two faces are merged when they share an edge (both corners equal to the
//! bit), have bitwise equal materials, face the same way, and both lie
//! within [`MERGE_ANGLE_DEGREES`] of one plane. The plane is the group's
//! *seed* (its largest face, groups grown from the largest faces first), not
//! the neighbour's, so a finely tessellated curved surface cannot drift into
//! one group facet by facet. The work is a sort of the edges and a
//! breadth-first walk: `O(n log n)` for `n` corners.

use glam::DVec3;

use super::Surface;
use crate::geometry;

/// Largest angle between a face's plane and its group's plane, and between
/// their normals. Cornell's measured box has a wall 0.33 degrees out of
/// plane; exporters' rounding is far smaller; facets of curved surfaces
/// modelled with fewer than 360 segments a turn are larger.
pub const MERGE_ANGLE_DEGREES: f64 = 1.0;

/// What merging did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MergeSummary {
    /// Surfaces (convex polygons) considered.
    pub surfaces: usize,
    /// Surface ids after merging.
    pub groups: usize,
}

/// Gives each input face its own surface id, the pieces of one face (a
/// concave face triangulated) sharing it, but not the two sides of a
/// double-sided face (back-to-back twins with one face index): a surface id
/// is planar and single-sided. Ids are numbered from 0 in input order. What
/// loaders leave; [`merge_coplanar`] may then join faces.
pub fn group_by_face(surfaces: &mut [Surface]) {
    // (face, normal of its first piece, id) of recent faces: pieces of a
    // face are consecutive.
    let mut last: Option<(u32, DVec3, u32)> = None;
    let mut twin: Option<(u32, u32)> = None;
    let mut next = 0;
    for s in surfaces.iter_mut() {
        let id = match (last, twin) {
            (Some((face, normal, id)), _) if face == s.face && s.normal.dot(normal) > 0.0 => id,
            (_, Some((face, id))) if face == s.face => id,
            _ => {
                let id = next;
                next += 1;
                if last.is_some_and(|(face, _, _)| face == s.face) {
                    twin = Some((s.face, id));
                } else {
                    last = Some((s.face, s.normal, id));
                    twin = None;
                }
                id
            }
        };
        s.group = id;
    }
}

/// Gives adjacent coplanar faces of one material a common [`Surface::group`],
/// numbering groups from 0 in the order of their first surface.
pub fn merge_coplanar(surfaces: &mut [Surface]) -> MergeSummary {
    let n = surfaces.len();
    let neighbours = Adjacency::build(surfaces);
    let (cos_limit, sin_limit) = {
        let angle = MERGE_ANGLE_DEGREES.to_radians();
        (angle.cos(), angle.sin())
    };
    let scale = surfaces
        .iter()
        .flat_map(|s| &s.polygon)
        .fold(0.0_f64, |m, p| m.max(p.abs().max_element()));
    let absolute = 1e-9 * scale.max(f64::MIN_POSITIVE);

    let mut seeds: Vec<u32> = (0..n as u32).collect();
    seeds.sort_by(|&a, &b| {
        surfaces[b as usize]
            .area
            .total_cmp(&surfaces[a as usize].area)
            .then(a.cmp(&b))
    });
    const UNASSIGNED: u32 = u32::MAX;
    let mut group = vec![UNASSIGNED; n];
    let mut queue = Vec::new();
    let mut next = 0;
    for seed in seeds {
        if group[seed as usize] != UNASSIGNED {
            continue;
        }
        let s = &surfaces[seed as usize];
        let (normal, anchor) = (s.normal, geometry::centroid(&s.polygon));
        let joins = |t: &Surface| {
            t.rho.to_array().map(f64::to_bits) == s.rho.to_array().map(f64::to_bits)
                && t.emission.to_array().map(f64::to_bits)
                    == s.emission.to_array().map(f64::to_bits)
                && t.normal.dot(normal) >= cos_limit
                && t.polygon.iter().all(|c| {
                    let offset = *c - anchor;
                    normal.dot(offset).abs() <= sin_limit * offset.length() + absolute
                })
        };
        group[seed as usize] = next;
        queue.clear();
        queue.push(seed);
        while let Some(u) = queue.pop() {
            for &t in neighbours.of(u) {
                if group[t as usize] == UNASSIGNED && joins(&surfaces[t as usize]) {
                    group[t as usize] = next;
                    queue.push(t);
                }
            }
        }
        next += 1;
    }
    // Number groups by their first surface, so ids follow the input order.
    let mut renumber = vec![UNASSIGNED; next as usize];
    let mut count = 0;
    for (surface, g) in surfaces.iter_mut().zip(group) {
        let id = &mut renumber[g as usize];
        if *id == UNASSIGNED {
            *id = count;
            count += 1;
        }
        surface.group = *id;
    }
    MergeSummary {
        surfaces: n,
        groups: count as usize,
    }
}

/// Surfaces sharing an edge, in compressed rows.
struct Adjacency {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Adjacency {
    fn build(surfaces: &[Surface]) -> Adjacency {
        // `+ 0.0` folds -0.0 into 0.0 so the sign of a zero cannot split an edge.
        let key = |p: DVec3| {
            [
                (p.x + 0.0).to_bits(),
                (p.y + 0.0).to_bits(),
                (p.z + 0.0).to_bits(),
            ]
        };
        let mut edges: Vec<([[u64; 3]; 2], u32)> = Vec::new();
        for (i, s) in surfaces.iter().enumerate() {
            let m = s.polygon.len();
            for k in 0..m {
                let (a, b) = (key(s.polygon[k]), key(s.polygon[(k + 1) % m]));
                edges.push(([a.min(b), a.max(b)], i as u32));
            }
        }
        edges.sort_unstable();
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        for run in edges.chunk_by(|x, y| x.0 == y.0) {
            for (i, x) in run.iter().enumerate() {
                for y in &run[i + 1..] {
                    if x.1 != y.1 {
                        pairs.push((x.1, y.1));
                        pairs.push((y.1, x.1));
                    }
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut start = vec![0u32; surfaces.len() + 1];
        for &(a, _) in &pairs {
            start[a as usize + 1] += 1;
        }
        for i in 0..surfaces.len() {
            start[i + 1] += start[i];
        }
        Adjacency {
            start,
            list: pairs.into_iter().map(|(_, b)| b).collect(),
        }
    }

    /// The surfaces sharing an edge with surface `i`.
    fn of(&self, i: u32) -> &[u32] {
        &self.list[self.start[i as usize] as usize..self.start[i as usize + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3], face: u32) -> Surface {
        Surface::new(
            vec![DVec3::from(a), DVec3::from(b), DVec3::from(c)],
            DVec3::splat(0.5),
            DVec3::ZERO,
            face,
        )
        .unwrap()
    }

    /// A unit square floor as two triangles, a wall on one of its edges,
    /// and a floor triangle of another material.
    #[test]
    fn coplanar_neighbours_of_one_material_merge() {
        let mut s = vec![
            tri([0., 0., 0.], [0., 0., 1.], [1., 0., 1.], 0),
            tri([0., 0., 0.], [1., 0., 1.], [1., 0., 0.], 1),
            tri([0., 0., 0.], [1., 0., 0.], [1., 1., 0.], 2),
            tri([1., 0., 0.], [1., 0., 1.], [2., 0., 0.5], 3),
        ];
        s[3].rho = DVec3::splat(0.25);
        // The two floor triangles face up; the wall faces +z.
        let summary = merge_coplanar(&mut s);
        assert_eq!(summary.groups, 3);
        assert_eq!(s.iter().map(|x| x.group).collect::<Vec<_>>(), [0, 0, 1, 2]);
    }

    #[test]
    fn faces_and_their_pieces_get_ids_twins_their_own() {
        let up = |face| tri([0., 0., 0.], [0., 0., 1.], [1., 0., 1.], face);
        let down = |face| tri([0., 0., 0.], [1., 0., 1.], [0., 0., 1.], face);
        // Face 0 in two pieces, face 1 double-sided (interleaved sides, as
        // a loader emitting each triangle's twin after it does), face 2.
        let mut s = vec![up(0), up(0), up(1), down(1), up(1), down(1), up(2)];
        group_by_face(&mut s);
        assert_eq!(
            s.iter().map(|x| x.group).collect::<Vec<_>>(),
            [0, 0, 1, 2, 1, 2, 3]
        );
    }

    #[test]
    fn back_to_back_and_folded_faces_stay_apart() {
        let mut s = vec![
            tri([0., 0., 0.], [0., 0., 1.], [1., 0., 1.], 0),
            // The same triangle facing down.
            tri([0., 0., 0.], [1., 0., 1.], [0., 0., 1.], 1),
            // Folded 2 degrees along the edge (0,0,0)-(1,0,1).
            tri(
                [0., 0., 0.],
                [1., 0., 1.],
                [1.0, -(2.0f64.to_radians().tan()) * 0.5f64.sqrt(), 0.0],
                2,
            ),
            // Folded 0.5 degrees: merged.
            tri(
                [0., 0., 1.],
                [0.5, 0.5f64.to_radians().tan(), 2.0],
                [1., 0., 1.],
                3,
            ),
        ];
        merge_coplanar(&mut s);
        assert_ne!(s[0].group, s[1].group);
        assert_ne!(s[0].group, s[2].group);
        assert_eq!(s[0].group, s[3].group);
    }

    /// A cylinder-like strip whose facets turn 0.9 degrees each: neighbours
    /// are within the limit, but the group stops once facets leave the
    /// seed's plane.
    #[test]
    fn gentle_curves_do_not_drift_into_one_group() {
        let step = 0.9f64.to_radians();
        let mut s = Vec::new();
        let point = |k: usize, z: f64| {
            let a = k as f64 * step;
            DVec3::new(10.0 * a.sin(), 10.0 * (1.0 - a.cos()), z)
        };
        for k in 0..40 {
            let (a, b, c, d) = (
                point(k, 0.0),
                point(k + 1, 0.0),
                point(k + 1, 1.0),
                point(k, 1.0),
            );
            s.push(
                Surface::new(vec![a, d, c, b], DVec3::splat(0.5), DVec3::ZERO, k as u32).unwrap(),
            );
        }
        let summary = merge_coplanar(&mut s);
        // A group holds its seed and at most the facet on each side of it
        // (0.9 degrees away; the next ones are 1.8): at least 40 / 3 groups.
        assert!(summary.groups >= 14, "{summary:?}");
        // Every member is within the limit of its seed, so any two members
        // within twice the limit of each other.
        let limit = (2.0 * MERGE_ANGLE_DEGREES).to_radians().cos() - 1e-12;
        for a in &s {
            for b in s.iter().filter(|b| b.group == a.group) {
                assert!(a.normal.dot(b.normal) >= limit);
            }
        }
    }
}
