//! The BSP's traversals: the front-to-back walk of a shadow segment down
//! the tree with the tolerance bands of the parent module, testing each
//! node's fragments when its plane's band is reached and stopping at the
//! first blocker; and the same walk for a closest-hit ray, which goes on
//! to the end but skips whatever lies beyond the nearest crossing so far.

use super::*;

/// What the walk still has to do, on its stack.
#[derive(Clone, Copy, Debug, Default)]
struct Pending {
    node: u32,
    /// Test the node's own fragments (else walk its subtree).
    plane: bool,
    /// The segment's parameter interval inside the node's region (for the
    /// closest-hit walk's plane tests, inside the plane's band).
    t0: f64,
    t1: f64,
}

/// A query's memory of split surfaces already tested: the last
/// [`TESTED_MEMORY`], in a ring.
struct Tested {
    ids: [u32; TESTED_MEMORY],
    len: usize,
    next: usize,
}

impl Tested {
    fn new() -> Tested {
        Tested {
            ids: [0; TESTED_MEMORY],
            len: 0,
            next: 0,
        }
    }

    fn contains(&self, id: u32) -> bool {
        self.ids[..self.len].contains(&id)
    }

    fn remember(&mut self, id: u32) {
        self.ids[self.next] = id;
        self.next = (self.next + 1) % TESTED_MEMORY;
        self.len = (self.len + 1).min(TESTED_MEMORY);
    }
}

impl Bsp<'_> {
    /// Tests the node's fragments; true at the first blocker.
    #[inline]
    fn test_entries(
        &self,
        node: &Node,
        from: DVec3,
        to: DVec3,
        skip: [u32; 2],
        tested: &mut Tested,
        tests: &mut u32,
    ) -> bool {
        for &entry in &self.entries[node.first as usize..node.end as usize] {
            let id = entry & !SPLIT_FLAG;
            if self.prepared.skips(id, skip) {
                continue;
            }
            let split = entry & SPLIT_FLAG != 0;
            if split && tested.ids[..tested.len].contains(&id) {
                continue;
            }
            *tests += 1;
            if self.prepared.crosses(id, from, to) {
                return true;
            }
            if split {
                tested.ids[tested.next] = id;
                tested.next = (tested.next + 1) % TESTED_MEMORY;
                tested.len = (tested.len + 1).min(TESTED_MEMORY);
            }
        }
        false
    }

    /// The front-to-back walk of Figure 3.2, carrying the segment's
    /// parameter interval inside the current region: `(blocked, surfaces
    /// tested, nodes visited)`.
    pub(super) fn walk(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        if self.nodes.is_empty() {
            return (false, 0, 0);
        }
        let round_off = QUERY_ROUND_OFF * from.abs().max_element().max(to.abs().max_element());
        // Far children and planes still to do: each node pushes at most two
        // entries above its ancestors', so twice the depth bounds the stack.
        let mut pending = [Pending::default(); 2 * MAX_DEPTH];
        let mut top = 0;
        let mut tested = Tested {
            ids: [0; TESTED_MEMORY],
            len: 0,
            next: 0,
        };
        let (mut tests, mut visited) = (0u32, 0u32);
        let mut current = 0u32;
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        loop {
            while current != NONE {
                visited += 1;
                let node = &self.nodes[current as usize];
                if node.is_leaf() {
                    if self.test_entries(node, from, to, skip, &mut tested, &mut tests) {
                        return (true, tests, visited);
                    }
                    break;
                }
                let d0 = node.normal.dot(from) - node.offset;
                let dd = node.normal.dot(to) - node.offset - d0;
                let tolerance = node.tolerance + round_off;
                // The common cases first, without a division: the part of
                // the segment in this region stays on one side.
                let (da, db) = (d0 + t0 * dd, d0 + t1 * dd);
                if da.min(db) > tolerance {
                    current = node.children[0];
                    continue;
                }
                if da.max(db) < -tolerance {
                    current = node.children[1];
                    continue;
                }
                // Parameters whose point is on (or within the tolerance of)
                // each side: `d0 + t dd >= -tolerance` and `<= tolerance`.
                let (front, back) = if dd > 0.0 {
                    (
                        (t0.max((-tolerance - d0) / dd), t1),
                        (t0, t1.min((tolerance - d0) / dd)),
                    )
                } else if dd < 0.0 {
                    (
                        (t0, t1.min((-tolerance - d0) / dd)),
                        (t0.max((tolerance - d0) / dd), t1),
                    )
                } else {
                    let empty = (1.0, 0.0);
                    (
                        if d0 >= -tolerance { (t0, t1) } else { empty },
                        if d0 <= tolerance { (t0, t1) } else { empty },
                    )
                };
                let reaches = [front.0 <= front.1, back.0 <= back.1];
                let near = usize::from(d0 + t0 * dd < 0.0);
                let far = 1 - near;
                let intervals = [front, back];
                if reaches[far] {
                    let child = node.children[far];
                    if child != NONE {
                        pending[top] = Pending {
                            node: child,
                            plane: false,
                            t0: intervals[far].0,
                            t1: intervals[far].1,
                        };
                        top += 1;
                    }
                    if reaches[near] && node.end > node.first {
                        pending[top] = Pending {
                            node: current,
                            plane: true,
                            t0: 0.0,
                            t1: 0.0,
                        };
                        top += 1;
                    }
                }
                if reaches[near] {
                    current = node.children[near];
                    (t0, t1) = intervals[near];
                } else {
                    current = NONE;
                }
            }
            if top == 0 {
                return (false, tests, visited);
            }
            top -= 1;
            let next = pending[top];
            if next.plane {
                let node = &self.nodes[next.node as usize];
                if self.test_entries(node, from, to, skip, &mut tested, &mut tests) {
                    return (true, tests, visited);
                }
                current = NONE;
            } else {
                current = next.node;
                (t0, t1) = (next.t0, next.t1);
            }
        }
    }
}

impl Bsp<'_> {
    /// Like [`Occluder::closest_hit`], also returning how many surfaces
    /// were tested and how many nodes were visited (for benchmarks and
    /// tests).
    #[must_use]
    pub fn closest_hit_counting(
        &self,
        origin: DVec3,
        direction: DVec3,
        max_t: f64,
        skip: [u32; 2],
    ) -> (Option<Hit>, u32, u32) {
        let Some(end) = ray_end(origin, direction, max_t) else {
            return (None, 0, 0);
        };
        let (nearest, tests, visited) = self.walk_closest(origin, end, skip);
        (nearest.hit(max_t), tests, visited)
    }

    /// Tests every fragment of the node not skipped and not tested before,
    /// keeping the nearest crossing.
    fn offer_entries(
        &self,
        node: &Node,
        (from, to): (DVec3, DVec3),
        skip: [u32; 2],
        tested: &mut Tested,
        nearest: &mut Nearest,
    ) -> u32 {
        let mut tests = 0;
        for &entry in &self.entries[node.first as usize..node.end as usize] {
            let id = entry & !SPLIT_FLAG;
            let split = entry & SPLIT_FLAG != 0;
            if self.prepared.skips(id, skip) || (split && tested.contains(id)) {
                continue;
            }
            tests += 1;
            if let Some(s) = self.prepared.crossing(id, from, to) {
                nearest.offer(id, s);
            }
            if split {
                tested.remember(id);
            }
        }
        tests
    }

    /// The walk of [`Bsp::walk`] for the nearest crossing of `from -> to`:
    /// the same intervals, near child first, then the node's plane, then
    /// the far child; a region or plane band whose interval starts beyond
    /// the nearest crossing so far is skipped (a crossing lies in the
    /// intervals of every node down to its fragment's, so nothing nearer
    /// is lost). Returns `(nearest, surfaces tested, nodes visited)`.
    pub(super) fn walk_closest(
        &self,
        from: DVec3,
        to: DVec3,
        skip: [u32; 2],
    ) -> (Nearest, u32, u32) {
        let mut nearest = Nearest::default();
        if self.nodes.is_empty() {
            return (nearest, 0, 0);
        }
        let round_off = QUERY_ROUND_OFF * from.abs().max_element().max(to.abs().max_element());
        let mut pending = [Pending::default(); 2 * MAX_DEPTH];
        let mut top = 0;
        let mut tested = Tested::new();
        let (mut tests, mut visited) = (0u32, 0u32);
        let mut current = 0u32;
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        loop {
            while current != NONE && t0 <= nearest.limit() {
                visited += 1;
                let node = &self.nodes[current as usize];
                if node.is_leaf() {
                    tests += self.offer_entries(node, (from, to), skip, &mut tested, &mut nearest);
                    break;
                }
                let d0 = node.normal.dot(from) - node.offset;
                let dd = node.normal.dot(to) - node.offset - d0;
                let tolerance = node.tolerance + round_off;
                let (da, db) = (d0 + t0 * dd, d0 + t1 * dd);
                if da.min(db) > tolerance {
                    current = node.children[0];
                    continue;
                }
                if da.max(db) < -tolerance {
                    current = node.children[1];
                    continue;
                }
                let (front, back) = if dd > 0.0 {
                    (
                        (t0.max((-tolerance - d0) / dd), t1),
                        (t0, t1.min((tolerance - d0) / dd)),
                    )
                } else if dd < 0.0 {
                    (
                        (t0, t1.min((-tolerance - d0) / dd)),
                        (t0.max((tolerance - d0) / dd), t1),
                    )
                } else {
                    let empty = (1.0, 0.0);
                    (
                        if d0 >= -tolerance { (t0, t1) } else { empty },
                        if d0 <= tolerance { (t0, t1) } else { empty },
                    )
                };
                let reaches = [front.0 <= front.1, back.0 <= back.1];
                let near = usize::from(d0 + t0 * dd < 0.0);
                let far = 1 - near;
                let intervals = [front, back];
                if reaches[far] {
                    let child = node.children[far];
                    if child != NONE {
                        pending[top] = Pending {
                            node: child,
                            plane: false,
                            t0: intervals[far].0,
                            t1: intervals[far].1,
                        };
                        top += 1;
                    }
                    // Both sides reached: the band within the tolerance of
                    // the plane is where they overlap.
                    if reaches[near] && node.end > node.first {
                        pending[top] = Pending {
                            node: current,
                            plane: true,
                            t0: front.0.max(back.0),
                            t1: front.1.min(back.1),
                        };
                        top += 1;
                    }
                }
                if reaches[near] {
                    current = node.children[near];
                    (t0, t1) = intervals[near];
                } else {
                    current = NONE;
                }
            }
            // The next pending task that can still hold the answer.
            let next = loop {
                if top == 0 {
                    return (nearest, tests, visited);
                }
                top -= 1;
                if pending[top].t0 <= nearest.limit() {
                    break pending[top];
                }
            };
            if next.plane {
                let node = &self.nodes[next.node as usize];
                tests += self.offer_entries(node, (from, to), skip, &mut tested, &mut nearest);
                current = NONE;
            } else {
                current = next.node;
                (t0, t1) = (next.t0, next.t1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::brute::BruteForce;
    use crate::accel::test_scenes::{NONE_SKIPPED, quad, square_at_z};

    #[test]
    fn closest_hit_walks_front_to_back() {
        let surfaces: Vec<Surface> = (0..40).map(|i| square_at_z(f64::from(i), 1.0)).collect();
        let brute = BruteForce::new(&surfaces);
        let bsp = Bsp::new(&surfaces);
        for (z, up) in [(-0.5, 1.0), (20.5, 1.0), (39.5, -1.0), (12.25, -1.0)] {
            let origin = DVec3::new(0.1, -0.2, z);
            let direction = DVec3::new(0.0, 0.0, up);
            let (hit, tests, _) = bsp.closest_hit_counting(origin, direction, 50.0, NONE_SKIPPED);
            assert_eq!(
                hit,
                brute.closest_hit(origin, direction, 50.0, NONE_SKIPPED)
            );
            let expected = if up > 0.0 { z.ceil() } else { z.floor() };
            assert_eq!(hit.unwrap().surface, expected as u32);
            // Regions beyond the first hit are skipped.
            assert!(tests <= 4, "{tests}");
        }
    }

    #[test]
    fn a_split_surface_is_tested_once_and_found_from_either_piece() {
        // The floor z = 0 and a wall in the plane x = 0 crossing it: the
        // wall is split in two by the floor's plane.
        let mut surfaces = vec![
            square_at_z(0.0, 2.0),
            quad([
                [0.0, -1.0, -1.0],
                [0.0, 1.0, -1.0],
                [0.0, 1.0, 1.0],
                [0.0, -1.0, 1.0],
            ]),
        ];
        surfaces[1].group = 1;
        let bsp = Bsp::with_settings(&surfaces, BspSettings::fastest_build());
        assert_eq!(bsp.stats().splits, 1);
        let brute = BruteForce::new(&surfaces);
        for (origin, direction) in [
            (DVec3::new(-1.0, 0.0, 0.5), DVec3::X),
            (DVec3::new(-1.0, 0.0, -0.5), DVec3::X),
            (DVec3::new(-1.0, 0.5, 0.5), DVec3::new(1.0, 0.0, -1.0)),
            (DVec3::new(-1.0, 0.5, 1.5), DVec3::new(1.0, 0.0, -1.0)),
            (DVec3::new(0.5, 0.5, 1.0), DVec3::NEG_Z),
        ] {
            let (hit, tests, _) = bsp.closest_hit_counting(origin, direction, 4.0, NONE_SKIPPED);
            assert_eq!(hit, brute.closest_hit(origin, direction, 4.0, NONE_SKIPPED));
            assert!(hit.is_some() && tests <= 2, "{origin:?}: {tests}");
        }
    }
}
