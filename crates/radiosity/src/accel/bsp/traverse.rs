//! The BSP's traversal: the front-to-back walk of a shadow segment down
//! the tree with the tolerance bands of the parent module, testing each
//! node's fragments when its plane's band is reached.

use super::*;

impl Bsp<'_> {
    /// Tests the node's fragments; true at the first blocker.
    #[inline]
    pub(super) fn test_entries(
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
