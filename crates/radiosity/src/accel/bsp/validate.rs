//! The BSP's `validate`: the invariants of the built tree (see
//! [`super::Bsp::validate`]).

use super::*;

impl Bsp<'_> {
    /// Checks the tree's invariants: a well-formed depth-first node array;
    /// every fragment on its node's plane and on the correct side of every
    /// ancestor's plane (within the coplanar tolerance); every fragment on
    /// its surface's plane and inside its polygon; each surface's fragments
    /// adding up to its area (1e-9 relative, plus the corners' round-off,
    /// plus the tilt of the fragments of a slightly non-planar polygon; the
    /// areas computed about the polygon's first corner to keep their digits);
    /// node tolerances
    /// covering the surfaces below them; statistics matching the tree.
    pub fn validate(&self) -> Result<(), InvalidTree> {
        let nodes = &self.nodes;
        let mut parent = vec![NONE; nodes.len()];
        let mut depth = vec![0usize; nodes.len()];
        let mut expected_first = 0u32;
        for (i, node) in nodes.iter().enumerate() {
            if node.first != expected_first || node.end < node.first {
                return Err(InvalidTree(format!(
                    "node {i}: fragment range does not follow its predecessor's"
                )));
            }
            expected_first = node.end;
            if i == 0 {
                depth[0] = 1;
            } else if parent[i] == NONE {
                return Err(InvalidTree(format!(
                    "node {i} has no parent (or comes before it)"
                )));
            }
            for &child in &node.children {
                if child == NONE {
                    continue;
                }
                let c = child as usize;
                if c <= i || c >= nodes.len() {
                    return Err(InvalidTree(format!(
                        "node {i}: child {child} out of depth-first order"
                    )));
                }
                if parent[c] != NONE {
                    return Err(InvalidTree(format!("node {c} has two parents")));
                }
                parent[c] = i as u32;
                depth[c] = depth[i] + 1;
            }
            if node.is_leaf() && node.children != [NONE; 2] {
                return Err(InvalidTree(format!("leaf bucket {i} has children")));
            }
            if !node.is_leaf() && (node.normal.length() - 1.0).abs() > 1e-9 {
                return Err(InvalidTree(format!(
                    "node {i}: normal is not a unit vector"
                )));
            }
        }
        if expected_first as usize != self.entries.len() {
            return Err(InvalidTree(
                "node ranges do not cover the fragment list exactly".into(),
            ));
        }
        let max_depth = depth.iter().copied().max().unwrap_or(0);
        if max_depth != self.stats.depth || max_depth > self.settings.max_depth {
            return Err(InvalidTree(format!(
                "depth {max_depth}, statistics say {}, limit {}",
                self.stats.depth, self.settings.max_depth
            )));
        }
        let leaves = nodes.iter().filter(|n| n.is_leaf()).count();
        let largest = nodes
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| (n.end - n.first) as usize)
            .max()
            .unwrap_or(0);
        if self.stats.nodes != nodes.len()
            || self.stats.fragments != self.entries.len()
            || self.stats.fragments != self.surfaces.len() + self.stats.splits
            || self.stats.leaves != leaves
            || self.stats.largest_leaf != largest
        {
            return Err(InvalidTree(format!(
                "statistics {:?} do not match the tree",
                self.stats
            )));
        }

        let slack = self.coplanar + self.round_off;
        let mut area = vec![0.0; self.surfaces.len()];
        let mut count = vec![0usize; self.surfaces.len()];
        let mut max_reach = vec![0.0f64; nodes.len()];
        for (i, node) in nodes.iter().enumerate() {
            for k in node.first..node.end {
                let entry = self.entries[k as usize];
                let id = (entry & !SPLIT_FLAG) as usize;
                let Some(surface) = self.surfaces.get(id) else {
                    return Err(InvalidTree(format!(
                        "node {i}: surface id {id} out of range"
                    )));
                };
                let polygon = &self.replay(id as u32, i, &parent);
                if polygon.len() < 3 {
                    return Err(InvalidTree(format!(
                        "node {i}: fragment of surface {id} has fewer than 3 corners"
                    )));
                }
                area[id] += local_area(polygon);
                count[id] += 1;
                let (lo, hi) = distance_range(polygon, surface.normal, surface.offset);
                let off_plane = self.reach[id] + self.round_off;
                if lo < -off_plane || hi > off_plane {
                    return Err(InvalidTree(format!(
                        "a fragment of surface {id} leaves the surface's plane"
                    )));
                }
                // Containment about the polygon's first corner, with the
                // normal computed there: far from the origin, a tiny
                // polygon's own normal (Newell's sum about the origin) can
                // have lost its digits.
                let origin = surface.polygon[0];
                let local: Vec<DVec3> = surface.polygon.iter().map(|p| *p - origin).collect();
                let local_normal = geometry::normal(&local).unwrap_or(surface.normal);
                let inside = 1e-9 * surface.area.sqrt() + self.round_off;
                if !polygon
                    .iter()
                    .all(|p| geometry::convex_contains(&local, local_normal, *p - origin, inside))
                {
                    return Err(InvalidTree(format!(
                        "a fragment of surface {id} leaves the surface's polygon"
                    )));
                }
                // The fragment lies on its node's plane and on the right side
                // of every ancestor's.
                let mut at = i;
                let mut child = NONE;
                loop {
                    let n = &nodes[at];
                    max_reach[at] = max_reach[at].max(self.reach[id]);
                    if n.normal != DVec3::ZERO {
                        let (lo, hi) = distance_range(polygon, n.normal, n.offset);
                        let ok = if child == NONE {
                            let on = slack + self.reach[id];
                            lo >= -on && hi <= on
                        } else if child == n.children[0] {
                            lo >= -slack
                        } else {
                            hi <= slack
                        };
                        if !ok {
                            return Err(InvalidTree(format!(
                                "a fragment of surface {id} stored at node {i} is on the wrong side of node {at}'s plane"
                            )));
                        }
                    }
                    if parent[at] == NONE {
                        break;
                    }
                    child = at as u32;
                    at = parent[at] as usize;
                }
            }
        }
        for (i, node) in nodes.iter().enumerate() {
            if node.tolerance < self.coplanar + 2.0 * max_reach[i] {
                return Err(InvalidTree(format!(
                    "node {i}: tolerance does not cover the surfaces below it"
                )));
            }
        }
        for (id, surface) in self.surfaces.iter().enumerate() {
            if count[id] == 0 {
                return Err(InvalidTree(format!("surface {id} has no fragment")));
            }
            let expected = local_area(&surface.polygon);
            // Split corners are rounded to the coordinates' precision, which
            // far from the origin is coarse next to a tiny polygon.
            let corner_round_off = 16.0 * f64::EPSILON * self.round_off / ROUND_OFF;
            let diameter = geometry::diameter(&surface.polygon);
            let perimeter = 4.0 * diameter;
            // A slightly non-planar polygon (as the OBJ loader accepts them)
            // splits into fragments tilted from its plane by up to about
            // `4 d / diameter`, `d` its corners' largest distance from the
            // plane; each fragment's area exceeds its projection by half
            // the square of that, so the pieces' areas add up to a little
            // more than the whole's.
            let bend = surface
                .polygon
                .iter()
                .map(|p| (surface.normal.dot(*p) - surface.offset).abs())
                .fold(0.0, f64::max);
            let tilt = if diameter > 0.0 {
                4.0 * bend / diameter
            } else {
                0.0
            };
            let slack = (1e-9 + 0.5 * tilt * tilt) * expected + corner_round_off * perimeter;
            if (area[id] - expected).abs() > slack {
                return Err(InvalidTree(format!(
                    "surface {id}: fragments cover {} m^2 of {expected} m^2",
                    area[id]
                )));
            }
        }
        for k in 0..self.entries.len() {
            let entry = self.entries[k];
            let split = count[(entry & !SPLIT_FLAG) as usize] > 1;
            if (entry & SPLIT_FLAG != 0) != split {
                return Err(InvalidTree(format!("entry {k}: split flag is wrong")));
            }
        }
        Ok(())
    }

    /// The fragment of surface `id` stored at node `at`, rebuilt by
    /// replaying the build's classifications and splits down the path from
    /// the root (the same arithmetic in the same order gives the same
    /// corners), so the tree need not keep fragment geometry.
    pub(super) fn replay(&self, id: u32, at: usize, parent: &[u32]) -> Vec<DVec3> {
        let surface = &self.surfaces[id as usize];
        let mut path = Vec::new();
        let mut node = at;
        while parent[node] != NONE {
            path.push((parent[node] as usize, node as u32));
            node = parent[node] as usize;
        }
        let mut polygon = surface.polygon.clone();
        for &(ancestor, child) in path.iter().rev() {
            let n = &self.nodes[ancestor];
            // A surface always lies on its own plane (see `side`).
            let own = n.normal == surface.normal && n.offset == surface.offset;
            if !own && classify(&polygon, n.normal, n.offset, self.coplanar) == Side::Both {
                let (front, back) = split(&polygon, n.normal, n.offset);
                polygon = if child == n.children[0] { front } else { back };
            }
        }
        polygon
    }
}
