//! The binary tree collapsed into the eight-wide tree the queries walk, by
//! the surface area heuristic's cost of the wide tree itself (Ylitie,
//! Karras & Laine 2017, "Efficient incoherent ray traversal on GPUs through
//! compressed wide BVHs", section 3.1): a dynamic programme over the binary
//! nodes decides, bottom up, which become wide nodes, which become leaves
//! (a whole subtree's surfaces, adjacent in leaf order, in one leaf of up to
//! `max_leaf_size`) and which are dissolved so that their descendants fill
//! the slots of a wide node above. Opening the largest child until there
//! are eight (Wald et al. 2008), the usual collapse, fills the nodes from
//! the top and leaves the bottom ones sparse (on the Sponza atrium 54% of
//! the slots are used); the programme fills them where the cost model says
//! it pays.
//!
//! Only the grouping changes: every wide child's box is a binary node's
//! box, which contains everything below it, so the walks' answers stay the
//! brute-force oracle's.

use super::*;

/// Cost of visiting a wide node (its eight box tests and the stack work),
/// in exact surface tests. A wide node visit and an exact test take about
/// the same time (11 and 8 ns on the Sponza atrium on the 2-core
/// development machine); node counts and times moved little between 0.5
/// and 2.
const WIDE_NODE_COST: f64 = 1.0;

/// Cost of one exact surface test.
const SURFACE_COST: f64 = 1.0;

/// A node's box's half area, finite: an unbounded box (a degenerate
/// surface's, see `crossing_box`) counts as 1e30, and so does any larger
/// one (coordinates beyond about 1e15), so the costs stay finite and
/// comparable; among such boxes the grouping follows the surface counts.
fn area(node: &Node) -> f64 {
    let d = [0, 1, 2].map(|i| f64::from(node.max[i]) - f64::from(node.min[i]));
    let a = d[0] * d[1] + d[1] * d[2] + d[2] * d[0];
    if a.is_finite() {
        a.clamp(0.0, 1e30)
    } else {
        1e30
    }
}

/// How a binary node's subtree fills `i + 1` slots of a wide node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Choice {
    /// One leaf holding all its surfaces.
    Leaf,
    /// One wide node of its own.
    Wide,
    /// Its left subtree in this many slots, its right in the rest.
    Split(u8),
    /// One slot fewer does as well.
    Fewer,
}

/// The programme's table for one binary node: the least cost of its subtree
/// in `i + 1` slots, and how.
#[derive(Clone, Copy)]
struct Plan {
    cost: [f64; WIDTH],
    choice: [Choice; WIDTH],
    /// As a wide node of its own: the slots its left subtree takes (the
    /// right one takes the rest).
    wide_split: u8,
    /// Surfaces in the subtree.
    surfaces: u32,
    /// Its first surface's position in leaf order.
    first: u32,
}

/// The wide tree of `tree`, leaves of at most `max_leaf` surfaces (binary
/// leaves larger than that stay as they are). Node 0 is the root.
pub(super) fn collapse(tree: &Tree, max_leaf: usize) -> Vec<WideNode> {
    debug_assert!(max_leaf <= MAX_LEAF_SIZE, "a leaf's count is a u8");
    if tree.nodes.is_empty() {
        return Vec::new();
    }
    let plans = plan(tree, max_leaf);
    let mut wide = Vec::with_capacity(tree.nodes.len() / WIDTH + 1);
    emit(tree, &plans, 0, &mut wide);
    wide.shrink_to_fit();
    wide
}

/// The programme, bottom up: children come after their parent in the
/// depth-first order, so a reverse sweep meets them first.
fn plan(tree: &Tree, max_leaf: usize) -> Vec<Plan> {
    let nodes = &tree.nodes;
    let mut plans = vec![
        Plan {
            cost: [0.0; WIDTH],
            choice: [Choice::Leaf; WIDTH],
            wide_split: 0,
            surfaces: 0,
            first: 0,
        };
        nodes.len()
    ];
    for at in (0..nodes.len()).rev() {
        let node = &nodes[at];
        let a = area(node);
        if node.is_leaf() {
            let leaf = a * SURFACE_COST * f64::from(node.kind);
            plans[at] = Plan {
                cost: [leaf; WIDTH],
                choice: [Choice::Leaf; WIDTH],
                wide_split: 0,
                surfaces: node.kind,
                first: node.link,
            };
            continue;
        }
        let (left, right) = (&plans[at + 1], &plans[node.link as usize]);
        let surfaces = left.surfaces + right.surfaces;
        // The cheapest way to give the two subtrees `slots` slots between
        // them (at least one each).
        let distribute = |slots: usize| -> (f64, u8) {
            (1..slots)
                .map(|k| (left.cost[k - 1] + right.cost[slots - k - 1], k as u8))
                .min_by(|x, y| x.0.total_cmp(&y.0))
                .expect("two slots or more")
        };
        let (below, wide_split) = distribute(WIDTH);
        let mut plan = Plan {
            cost: [0.0; WIDTH],
            choice: [Choice::Wide; WIDTH],
            wide_split,
            surfaces,
            first: left.first,
        };
        let wide_cost = a * WIDE_NODE_COST + below;
        let leaf_cost = if surfaces as usize <= max_leaf {
            a * SURFACE_COST * f64::from(surfaces)
        } else {
            f64::INFINITY
        };
        (plan.cost[0], plan.choice[0]) = if leaf_cost <= wide_cost {
            (leaf_cost, Choice::Leaf)
        } else {
            (wide_cost, Choice::Wide)
        };
        for i in 1..WIDTH {
            let (split, k) = distribute(i + 1);
            (plan.cost[i], plan.choice[i]) = if split < plan.cost[i - 1] {
                (split, Choice::Split(k))
            } else {
                (plan.cost[i - 1], Choice::Fewer)
            };
        }
        plans[at] = plan;
    }
    plans
}

/// Emits binary node `at` as a wide node (its subtree spread over all
/// [`WIDTH`] slots) and the wide nodes below it; returns its index.
fn emit(tree: &Tree, plans: &[Plan], at: u32, wide: &mut Vec<WideNode>) -> u32 {
    let index = wide.len() as u32;
    wide.push(WideNode::UNUSED);
    let node = &tree.nodes[at as usize];
    let mut slots = Vec::with_capacity(WIDTH);
    if node.is_leaf() {
        slots.push((at, Choice::Leaf));
    } else {
        let k = usize::from(plans[at as usize].wide_split);
        fill(plans, tree, at + 1, k, &mut slots);
        fill(plans, tree, node.link, WIDTH - k, &mut slots);
    }
    let mut out = WideNode::UNUSED;
    for (slot, &(c, choice)) in slots.iter().enumerate() {
        let child = &tree.nodes[c as usize];
        for axis in 0..3 {
            out.bounds[axis][0][slot] = child.min[axis];
            out.bounds[axis][1][slot] = child.max[axis];
        }
        if choice == Choice::Leaf {
            let plan = &plans[c as usize];
            out.link[slot] = plan.first;
            // At most `max_leaf_size` or a binary leaf's size, both at
            // most `MAX_LEAF_SIZE` (64).
            out.count[slot] = plan.surfaces as u8;
            out.leaves |= 1 << slot;
        } else {
            out.link[slot] = emit(tree, plans, c, wide);
        }
    }
    wide[index as usize] = out;
    index
}

/// The slots binary node `at` fills given `slots` of them: each a binary
/// node with [`Choice::Leaf`] or [`Choice::Wide`].
fn fill(plans: &[Plan], tree: &Tree, at: u32, slots: usize, out: &mut Vec<(u32, Choice)>) {
    match plans[at as usize].choice[slots - 1] {
        Choice::Fewer => fill(plans, tree, at, slots - 1, out),
        Choice::Split(k) => {
            let node = &tree.nodes[at as usize];
            let k = usize::from(k);
            fill(plans, tree, at + 1, k, out);
            fill(plans, tree, node.link, slots - k, out);
        }
        choice => out.push((at, choice)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::test_scenes::uniform;

    /// The greedy collapse the programme replaced: open the interior child
    /// of largest area until there are [`WIDTH`] children; binary leaves
    /// stay leaves.
    fn greedy(tree: &Tree, at: u32, wide: &mut Vec<WideNode>) -> u32 {
        let index = wide.len() as u32;
        wide.push(WideNode::UNUSED);
        let node = &tree.nodes[at as usize];
        let mut children = if node.is_leaf() {
            vec![at]
        } else {
            vec![at + 1, node.link]
        };
        while children.len() < WIDTH {
            let open = (0..children.len())
                .filter(|&i| !tree.nodes[children[i] as usize].is_leaf())
                .max_by(|&i, &j| {
                    area(&tree.nodes[children[i] as usize])
                        .total_cmp(&area(&tree.nodes[children[j] as usize]))
                });
            let Some(i) = open else { break };
            let c = children[i];
            children[i] = c + 1;
            children.insert(i + 1, tree.nodes[c as usize].link);
        }
        let mut out = WideNode::UNUSED;
        for (slot, &c) in children.iter().enumerate() {
            let child = tree.nodes[c as usize];
            for axis in 0..3 {
                out.bounds[axis][0][slot] = child.min[axis];
                out.bounds[axis][1][slot] = child.max[axis];
            }
            if child.is_leaf() {
                out.link[slot] = child.link;
                out.count[slot] = child.kind as u8;
                out.leaves |= 1 << slot;
            } else {
                out.link[slot] = greedy(tree, c, wide);
            }
        }
        wide[index as usize] = out;
        index
    }

    /// The cost model's value for wide node `i`, whose own box has half
    /// area `a`, and everything below it.
    fn cost(wide: &[WideNode], i: usize, a: f64) -> f64 {
        let node = &wide[i];
        let mut total = a * WIDE_NODE_COST;
        for k in 0..WIDTH {
            if node.link[k] == EMPTY_SLOT {
                continue;
            }
            let (min, max) = node.child_box(k);
            let box_area = area(&Node {
                min,
                link: 0,
                max,
                kind: 0,
            });
            total += if node.count[k] > 0 {
                box_area * SURFACE_COST * f64::from(node.count[k])
            } else {
                cost(wide, node.link[k] as usize, box_area)
            };
        }
        total
    }

    /// Random scenes of clustered boxes of every shape: the programme's
    /// wide tree costs what its table says, never more than the greedy
    /// collapse of the same binary tree, has no leaf over the limit and
    /// no empty node, and fills more slots.
    #[test]
    fn the_programme_never_costs_more_than_the_greedy_collapse() {
        let mut rng = uniform(7);
        let (mut used_dp, mut used_greedy) = (0usize, 0usize);
        for case in 0..40 {
            let n = 1 + case * 37;
            let clusters: Vec<DVec3> = (0..1 + case % 5)
                .map(|_| DVec3::new(rng(), rng(), rng()) * 100.0)
                .collect();
            let boxes: Vec<Aabb> = (0..n)
                .map(|i| {
                    let c = clusters[i % clusters.len()] + DVec3::new(rng(), rng(), rng()) * 10.0;
                    let size =
                        DVec3::new(rng(), rng(), rng()) * if i % 7 == 0 { 20.0 } else { 0.5 };
                    // Some flat boxes, as walls and floors make.
                    let size = if i % 3 == 0 {
                        size * DVec3::new(1.0, 0.0, 1.0)
                    } else {
                        size
                    };
                    Aabb::of_points([c, c + size])
                })
                .collect();
            let settings = BvhSettings::sah();
            let (tree, _) = Tree::build(&boxes, settings);
            let root_area = area(&tree.nodes[0]);
            let dp = collapse(&tree, settings.max_leaf_size);
            let mut old = Vec::new();
            greedy(&tree, 0, &mut old);
            let (dp_cost, old_cost) = (cost(&dp, 0, root_area), cost(&old, 0, root_area));
            assert!(
                dp_cost <= old_cost * (1.0 + 1e-12),
                "case {case}: {dp_cost} against the greedy {old_cost}"
            );
            let plans = plan(&tree, settings.max_leaf_size);
            if !tree.nodes[0].is_leaf() {
                let root = &tree.nodes[0];
                let best = (1..WIDTH)
                    .map(|k| plans[1].cost[k - 1] + plans[root.link as usize].cost[WIDTH - k - 1])
                    .fold(f64::INFINITY, f64::min);
                let planned = root_area * WIDE_NODE_COST + best;
                assert!((dp_cost - planned).abs() <= 1e-9 * planned, "case {case}");
            }
            for node in &dp {
                assert!(
                    node.link.iter().any(|&l| l != EMPTY_SLOT),
                    "case {case}: empty node"
                );
                for k in 0..WIDTH {
                    assert!(node.count[k] as usize <= settings.max_leaf_size);
                }
            }
            let used = |w: &[WideNode]| {
                w.iter()
                    .flat_map(|n| n.link)
                    .filter(|&l| l != EMPTY_SLOT)
                    .count()
            };
            used_dp += used(&dp) * 1000 / (dp.len() * WIDTH);
            used_greedy += used(&old) * 1000 / (old.len() * WIDTH);
        }
        assert!(
            used_dp > used_greedy,
            "slots used: {used_dp} against {used_greedy}"
        );
    }
}
