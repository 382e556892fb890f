//! The BVH's `validate`: the invariants of the built tree, and of the
//! eight-wide tree the queries walk, against its primitives' boxes (see
//! [`super::Bvh::validate`]).

use super::*;

impl Tree {
    /// Checks the structure against the primitives' boxes: see
    /// [`Bvh::validate`].
    pub(super) fn validate(
        &self,
        boxes: &[Aabb],
        settings: &BvhSettings,
        stats: &BvhStats,
    ) -> Result<(), InvalidTree> {
        let nodes = &self.nodes;
        if boxes.is_empty() {
            return if nodes.is_empty()
                && self.primitives.is_empty()
                && *stats == BvhStats::default()
            {
                Ok(())
            } else {
                Err(InvalidTree("an empty scene has a non-empty tree".into()))
            };
        }
        if nodes.is_empty() {
            return Err(InvalidTree("no nodes".into()));
        }
        let mut parent = vec![u32::MAX; nodes.len()];
        let mut depth = vec![0usize; nodes.len()];
        depth[0] = 1;
        let mut next_primitive = 0usize;
        let mut leaves = 0;
        let mut largest = 0;
        let mut seen = vec![false; boxes.len()];
        for (i, node) in nodes.iter().enumerate() {
            if i > 0 && parent[i] == u32::MAX {
                return Err(InvalidTree(format!(
                    "node {i} has no parent (or comes before it)"
                )));
            }
            if node.is_leaf() {
                let range = node.primitives();
                if range.is_empty()
                    || range.start != next_primitive
                    || range.end > self.primitives.len()
                {
                    return Err(InvalidTree(format!(
                        "leaf {i}: primitive range {range:?} is out of order"
                    )));
                }
                if range.len() > settings.max_leaf_size {
                    return Err(InvalidTree(format!(
                        "leaf {i} holds {} primitives",
                        range.len()
                    )));
                }
                next_primitive = range.end;
                leaves += 1;
                largest = largest.max(range.len());
                for &p in &self.primitives[range] {
                    let Some(b) = boxes.get(p as usize) else {
                        return Err(InvalidTree(format!("leaf {i}: primitive {p} out of range")));
                    };
                    if std::mem::replace(&mut seen[p as usize], true) {
                        return Err(InvalidTree(format!("primitive {p} is in two leaves")));
                    }
                    if !node.contains(&Node::new(*b, 0, 1)) {
                        return Err(InvalidTree(format!(
                            "leaf {i}'s box does not contain primitive {p}'s"
                        )));
                    }
                }
                continue;
            }
            if node.axis() > 2 {
                return Err(InvalidTree(format!("node {i}: split axis {}", node.axis())));
            }
            let right = node.link as usize;
            if right <= i + 1 || right >= nodes.len() {
                return Err(InvalidTree(format!(
                    "node {i}: right child {right} out of depth-first order"
                )));
            }
            for child in [i + 1, right] {
                if parent[child] != u32::MAX {
                    return Err(InvalidTree(format!("node {child} has two parents")));
                }
                parent[child] = i as u32;
                depth[child] = depth[i] + 1;
                if !node.contains(&nodes[child]) {
                    return Err(InvalidTree(format!(
                        "node {i}'s box does not contain child {child}'s"
                    )));
                }
            }
        }
        if next_primitive != self.primitives.len() || self.primitives.len() != boxes.len() {
            return Err(InvalidTree(
                "leaves do not cover the primitive list exactly".into(),
            ));
        }
        if let Some(p) = seen.iter().position(|s| !s) {
            return Err(InvalidTree(format!("primitive {p} is in no leaf")));
        }
        let max_depth = depth.iter().copied().max().unwrap_or(0);
        if max_depth > MAX_DEPTH {
            return Err(InvalidTree(format!(
                "depth {max_depth} exceeds {MAX_DEPTH}"
            )));
        }
        let actual = BvhStats {
            nodes: nodes.len(),
            leaves,
            depth: max_depth,
            max_leaf_size: largest,
            wide_nodes: stats.wide_nodes,
            wide_max_leaf_size: stats.wide_max_leaf_size,
        };
        if actual != *stats {
            return Err(InvalidTree(format!(
                "statistics {stats:?}, tree {actual:?}"
            )));
        }
        Ok(())
    }
}

impl Bvh<'_> {
    /// The eight-wide tree's part of [`Bvh::validate`]: every wide node
    /// reached once, every surface in one wide leaf, each child box
    /// containing everything below it.
    pub(super) fn validate_wide(&self, boxes: &[Aabb]) -> Result<(), InvalidTree> {
        let wide = &self.wide;
        if wide.len() != self.stats.wide_nodes || wide.is_empty() != boxes.is_empty() {
            return Err(InvalidTree(format!(
                "{} wide nodes for {} surfaces, statistics say {}",
                wide.len(),
                boxes.len(),
                self.stats.wide_nodes
            )));
        }
        let mut reached = vec![false; wide.len()];
        let mut seen = vec![false; boxes.len()];
        let mut todo = if wide.is_empty() {
            vec![]
        } else {
            vec![0usize]
        };
        let within = |outer: &WideNode, k: usize, min: [f32; 3], max: [f32; 3]| {
            let (lower, upper) = outer.child_box(k);
            (0..3).all(|a| lower[a] <= min[a] && upper[a] >= max[a])
        };
        let mut largest = 0;
        while let Some(i) = todo.pop() {
            if std::mem::replace(&mut reached[i], true) {
                return Err(InvalidTree(format!("wide node {i} is reached twice")));
            }
            let node = &wide[i];
            if node.link.iter().all(|&l| l == EMPTY_SLOT) {
                return Err(InvalidTree(format!("wide node {i} has no child")));
            }
            for k in 0..WIDTH {
                let link = node.link[k];
                let leaf = node.leaves >> k & 1 == 1;
                if leaf != (node.count[k] > 0) || (link == EMPTY_SLOT && leaf) {
                    return Err(InvalidTree(format!(
                        "wide node {i}: child {k}'s leaf bit disagrees with its count"
                    )));
                }
                if link == EMPTY_SLOT {
                    continue;
                }
                if node.count[k] == 0 {
                    let c = link as usize;
                    let Some(child) = wide.get(c) else {
                        return Err(InvalidTree(format!(
                            "wide node {i}: child {c} out of range"
                        )));
                    };
                    for j in 0..WIDTH {
                        let (min, max) = child.child_box(j);
                        if child.link[j] != EMPTY_SLOT && !within(node, k, min, max) {
                            return Err(InvalidTree(format!(
                                "wide node {i}: box {k} does not contain {c}'s"
                            )));
                        }
                    }
                    todo.push(c);
                    continue;
                }
                let count = usize::from(node.count[k]);
                largest = largest.max(count);
                if count > self.settings.max_leaf_size.max(self.stats.max_leaf_size) {
                    return Err(InvalidTree(format!(
                        "wide node {i}: leaf {k} holds {count} surfaces, over the settings' {}",
                        self.settings.max_leaf_size
                    )));
                }
                let range = link as usize..link as usize + count;
                let Some(primitives) = self.tree.primitives.get(range) else {
                    return Err(InvalidTree(format!("wide node {i}: leaf {k} out of range")));
                };
                for &p in primitives {
                    if std::mem::replace(&mut seen[p as usize], true) {
                        return Err(InvalidTree(format!("surface {p} is in two wide leaves")));
                    }
                    let n = Node::new(boxes[p as usize], 0, 1);
                    if !within(node, k, n.min, n.max) {
                        return Err(InvalidTree(format!(
                            "wide node {i}: box {k} does not contain surface {p}"
                        )));
                    }
                }
            }
        }
        if largest != self.stats.wide_max_leaf_size {
            return Err(InvalidTree(format!(
                "the largest wide leaf holds {largest} surfaces, statistics say {}",
                self.stats.wide_max_leaf_size
            )));
        }
        if let Some(i) = reached.iter().position(|r| !r) {
            return Err(InvalidTree(format!("wide node {i} is not reached")));
        }
        if let Some(p) = seen.iter().position(|s| !s) {
            return Err(InvalidTree(format!("surface {p} is in no wide leaf")));
        }
        Ok(())
    }
}
