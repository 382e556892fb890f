//! The BSP's build: fragments classified against candidate planes and split
//! exactly, the plane chosen by the configured cost (surface area heuristic
//! over each node's cell, or the paper's fewest-splits rule), leaves, and
//! each surface's reach (how far an accepted crossing can lie from it).

use super::*;

impl Bsp<'_> {
    /// Builds the subtree over `pieces` in `cell` at `depth` (root = 1),
    /// allowed to create `allowance` new fragments by splitting, and returns
    /// its index, or [`NONE`] for no pieces.
    pub(super) fn build(
        &mut self,
        pieces: Vec<Piece>,
        cell: Cell,
        depth: usize,
        allowance: usize,
        scratch: &mut Scratch,
    ) -> u32 {
        if pieces.is_empty() {
            return NONE;
        }
        self.stats.depth = self.stats.depth.max(depth);
        let max_reach = pieces
            .iter()
            .map(|p| self.reach[p.surface as usize])
            .fold(0.0, f64::max);
        // A fragment on the plane lies within the coplanar tolerance or its
        // surface's non-planarity of it, and a crossing point within its
        // reach of the fragment; both are below the reach.
        let tolerance = self.coplanar + 2.0 * max_reach + self.round_off;
        let index = self.nodes.len() as u32;
        let chosen = if pieces.len() <= self.settings.leaf_size || depth >= self.settings.max_depth
        {
            None
        } else {
            let common = self.common_plane(&pieces);
            self.choose_plane(&pieces, &cell, common, allowance, scratch)
        };
        let Some(plane) = chosen else {
            return self.leaf(&pieces, tolerance);
        };

        let n = pieces.len();
        let sides: Vec<Side> = pieces.iter().map(|p| self.side(p, &plane)).collect();
        let splits = sides.iter().filter(|&&s| s == Side::Both).count();
        if splits > allowance {
            // The sampled estimate was too low for this subtree's budget.
            self.stats.refused += 1;
            return self.leaf(&pieces, tolerance);
        }
        if splits == n {
            // Every fragment straddles (fragments meeting at a point, or
            // smaller than the coplanar tolerance): cutting divides
            // nothing.
            return self.leaf(&pieces, tolerance);
        }
        let mut front = Vec::new();
        let mut back = Vec::new();
        let mut on = Vec::new();
        for (piece, side) in pieces.into_iter().zip(sides) {
            match side {
                Side::On => on.push(piece),
                Side::Front => front.push(piece),
                Side::Back => back.push(piece),
                Side::Both => {
                    let (f, b) = split(&piece.polygon, plane.normal, plane.offset);
                    front.push(Piece {
                        surface: piece.surface,
                        polygon: f,
                    });
                    back.push(Piece {
                        surface: piece.surface,
                        polygon: b,
                    });
                }
            }
        }
        // Many fragments on the plane would all be tested by every segment
        // crossing it anywhere in the region: with the surface area
        // heuristic they go to the child of smaller area instead, to be
        // divided there (as kd-trees place planar primitives; Wald & Havran
        // 2006), unless that child would then hold everything.
        if self.settings.cost == PlaneCost::SurfaceArea && on.len() > self.settings.leaf_size {
            let (f, b, _) = cell.split_areas(plane.normal, plane.offset, scratch);
            let (smaller, larger) = if f <= b {
                (&mut front, &mut back)
            } else {
                (&mut back, &mut front)
            };
            if smaller.len() + on.len() < n {
                smaller.append(&mut on);
            } else if larger.len() + on.len() < n {
                larger.append(&mut on);
            }
        }
        let first = self.entries.len() as u32;
        for piece in &on {
            self.store(piece);
        }
        self.stats.splits += splits;
        self.nodes.push(Node {
            normal: plane.normal,
            offset: plane.offset,
            tolerance,
            children: [NONE; 2],
            first,
            end: self.entries.len() as u32,
        });
        let left = allowance - splits;
        let total = (front.len() + back.len()).max(1);
        let front_allowance = (left as u128 * front.len() as u128 / total as u128) as usize;
        let back_allowance = left - front_allowance;
        let (front_cell, back_cell) = cell.split(plane.normal, plane.offset, scratch);
        let f = self.build(front, front_cell, depth + 1, front_allowance, scratch);
        let b = self.build(back, back_cell, depth + 1, back_allowance, scratch);
        self.nodes[index as usize].children = [f, b];
        index
    }

    /// A node for pieces that are not divided further: a plane node when
    /// they all lie on the first one's plane (tested only by segments that
    /// reach it), else a leaf bucket (tested by every segment that visits
    /// it).
    pub(super) fn leaf(&mut self, pieces: &[Piece], tolerance: f64) -> u32 {
        let index = self.nodes.len() as u32;
        let common = self.common_plane(pieces);
        let first = self.entries.len() as u32;
        for piece in pieces {
            self.store(piece);
        }
        let (normal, offset) = if let Some(plane) = common {
            (plane.normal, plane.offset)
        } else {
            self.stats.leaves += 1;
            self.stats.largest_leaf = self.stats.largest_leaf.max(pieces.len());
            (DVec3::ZERO, 0.0)
        };
        self.nodes.push(Node {
            normal,
            offset,
            tolerance,
            children: [NONE; 2],
            first,
            end: self.entries.len() as u32,
        });
        index
    }

    /// The first piece's plane, if every piece lies on it.
    pub(super) fn common_plane(&self, pieces: &[Piece]) -> Option<Plane> {
        let own = pieces.first()?.surface;
        let surface = &self.surfaces[own as usize];
        let plane = Plane {
            normal: surface.normal,
            offset: surface.offset,
            own: Some(own),
        };
        pieces
            .iter()
            .all(|p| self.side(p, &plane) == Side::On)
            .then_some(plane)
    }

    pub(super) fn side(&self, piece: &Piece, plane: &Plane) -> Side {
        if plane.own == Some(piece.surface) {
            Side::On
        } else {
            classify(&piece.polygon, plane.normal, plane.offset, self.coplanar)
        }
    }

    pub(super) fn store(&mut self, piece: &Piece) {
        self.entries.push(piece.surface);
    }

    /// The surface planes a node tries: those of an evenly spaced sample of
    /// its fragments.
    pub(super) fn surface_candidates(&self, pieces: &[Piece], out: &mut Vec<Plane>) {
        out.clear();
        let n = pieces.len();
        let k = match self.settings.candidates {
            0 => n,
            c => c.min(n),
        };
        let mut last = u32::MAX;
        for c in 0..k {
            let id = pieces[c * n / k].surface;
            // Consecutive fragments of one surface share its plane.
            if id == last {
                continue;
            }
            last = id;
            let s = &self.surfaces[id as usize];
            out.push(Plane {
                normal: s.normal,
                offset: s.offset,
                own: Some(id),
            });
        }
    }

    /// The cheapest candidate plane, or `None` when the node should be a
    /// leaf: no candidate fits the fragment budget or divides anything, or
    /// (surface area heuristic) none costs less than testing every
    /// fragment.
    ///
    /// Surface planes are scored by classifying a sample of the fragments
    /// against each. Axis-aligned planes are the `bins + 1` boundaries of
    /// `bins` equal slabs across the fragments' bounding box on each axis,
    /// scored together by binning (Wald & Havran 2006): each sampled
    /// fragment's lowest and highest coordinate is put in a slab, and
    /// running sums give, for every boundary, the fragments wholly above it
    /// and wholly below it; the rest straddle it. The box's own faces are
    /// boundaries too: cutting off empty space.
    pub(super) fn choose_plane(
        &self,
        pieces: &[Piece],
        cell: &Cell,
        common: Option<Plane>,
        allowance: usize,
        scratch: &mut Scratch,
    ) -> Option<Plane> {
        // Fragments all in one plane: a segment meets that plane at one
        // point, so the chance of testing a part of them is the share of
        // their extent in the plane (their bounding rectangle there) that
        // part covers: a two-dimensional surface area heuristic. Their own
        // plane divides nothing.
        let section = match (self.settings.cost, common) {
            (PlaneCost::SurfaceArea, Some(p)) => in_plane_bounds(pieces, p.normal),
            _ => None,
        };
        let section_area = section.as_ref().map_or(0.0, |s| geometry::area(s));
        let n = pieces.len();
        let sample = match self.settings.cost_sample {
            0 => n,
            s => s.min(n),
        };
        let scale = n as f64 / sample as f64;
        let sampled = |i: usize| &pieces[i * n / sample];
        let area = cell.area();
        let mut best: Option<(f64, Plane)> = None;
        // Counts are `[on, front, back, both]` in the sample.
        let mut consider = |plane: Plane, counts: [usize; 4], scratch: &mut Scratch| {
            let [on, front, back, both] = counts.map(|c| c as f64 * scale);
            if both > allowance as f64 {
                return;
            }
            let cost = match self.settings.cost {
                PlaneCost::SurfaceArea if section.is_some() => {
                    // Cutting off empty space does not shrink the
                    // fragments' extent: only planes dividing them count.
                    if !(section_area > 0.0 && section_area.is_finite())
                        || front + both == 0.0
                        || back + both == 0.0
                    {
                        return;
                    }
                    let section = section.as_deref().unwrap_or_default();
                    let (f, b) = polygon_split_areas(section, plane.normal, plane.offset, scratch);
                    self.settings.traversal_cost
                        + (f * (front + both) + b * (back + both)) / section_area
                }
                PlaneCost::SurfaceArea => {
                    if !(area > 0.0 && area.is_finite()) {
                        return;
                    }
                    let (f, b, cap) = cell.split_areas(plane.normal, plane.offset, scratch);
                    // Fragments on the plane: stored at the node, or in the
                    // smaller child when many (see `build`).
                    let planar = if on > self.settings.leaf_size as f64 {
                        f.min(b) * on
                    } else {
                        2.0 * cap * on
                    };
                    self.settings.traversal_cost
                        + (f * (front + both) + b * (back + both) + planar) / area
                }
                PlaneCost::SplitsAndBalance { split_weight } => {
                    // A plane holding nothing and leaving everything on one
                    // side would divide nothing.
                    if on == 0.0 && (front == 0.0 || back == 0.0) {
                        return;
                    }
                    split_weight * both + (front - back).abs()
                }
            };
            if cost.is_finite() && best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, plane));
            }
        };

        let mut candidates = std::mem::take(&mut scratch.candidates);
        self.surface_candidates(pieces, &mut candidates);
        if section.is_some() {
            candidates.clear();
        }
        for plane in &candidates {
            let mut counts = [0usize; 4];
            for i in 0..sample {
                let k = match self.side(sampled(i), plane) {
                    Side::On => 0,
                    Side::Front => 1,
                    Side::Back => 2,
                    Side::Both => 3,
                };
                counts[k] += 1;
            }
            consider(*plane, counts, scratch);
        }
        scratch.candidates = candidates;

        let bins = self.settings.axis_candidates;
        if bins > 0 {
            let mut lo = DVec3::INFINITY;
            let mut hi = DVec3::NEG_INFINITY;
            for p in pieces.iter().flat_map(|p| &p.polygon) {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            let (cell_lo, cell_hi) = cell.bounds();
            let mut best_axis: Option<(f64, Plane, [usize; 4])> = None;
            let mut low_count = std::mem::take(&mut scratch.low_count);
            let mut high_count = std::mem::take(&mut scratch.high_count);
            for axis in 0..3 {
                let extent = hi[axis] - lo[axis];
                if !(extent > 0.0 && extent.is_finite()) {
                    continue;
                }
                let width = extent / bins as f64;
                // Boundary `j` is at `lo + j width`. A fragment is wholly
                // above boundary `j` when its lowest coordinate is at or
                // above it: `j <= floor((low - lo) / width)`; wholly below
                // when its highest is at or below: `j >= ceil((high - lo) /
                // width)`. Flooring and ceiling are taken at the coplanar
                // tolerance, as the exact classification does.
                low_count.clear();
                low_count.resize(bins + 1, 0usize);
                high_count.clear();
                high_count.resize(bins + 1, 0usize);
                for i in 0..sample {
                    let polygon = &sampled(i).polygon;
                    let (low, high) = polygon
                        .iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                            (a.min(p[axis]), b.max(p[axis]))
                        });
                    let low_bin = ((low + self.coplanar - lo[axis]) / width).floor();
                    let high_bin = ((high - self.coplanar - lo[axis]) / width).ceil();
                    low_count[low_bin.clamp(0.0, bins as f64) as usize] += 1;
                    high_count[high_bin.clamp(0.0, bins as f64) as usize] += 1;
                }
                // above[j] = sum of low_count[j..], below[j] = sum of
                // high_count[..=j].
                let mut above: usize = low_count.iter().sum();
                let mut below = 0usize;
                let mut normal = DVec3::ZERO;
                normal[axis] = 1.0;
                for j in 0..=bins {
                    below += high_count[j];
                    // Fragments both wholly above and wholly below lie on
                    // the plane.
                    let on = (above + below).saturating_sub(sample);
                    let (front, back) = (above - on, below - on);
                    let both = sample - on - front - back;
                    let offset = if j == bins {
                        hi[axis]
                    } else {
                        lo[axis] + width * j as f64
                    };
                    // Scored on the region's bounding box, cheaply; the
                    // best axis-aligned plane is then scored exactly
                    // beside the surface planes.
                    let (f, b) = match &section {
                        Some(section) => polygon_split_areas(section, normal, offset, scratch),
                        None => box_split_areas(cell_lo, cell_hi, axis, offset),
                    };
                    let counts = [on, front, back, both];
                    let estimate = f * (front + both) as f64 + b * (back + both) as f64;
                    if (both as f64) * scale <= allowance as f64
                        && best_axis.as_ref().is_none_or(|(e, _, _)| estimate < *e)
                    {
                        let plane = Plane {
                            normal,
                            offset,
                            own: None,
                        };
                        best_axis = Some((estimate, plane, counts));
                    }
                    above -= low_count[j];
                }
            }
            scratch.low_count = low_count;
            scratch.high_count = high_count;
            if let Some((_, plane, counts)) = best_axis {
                consider(plane, counts, scratch);
            }
        }

        let (cost, plane) = best?;
        if self.settings.cost == PlaneCost::SurfaceArea && cost >= n as f64 {
            return None;
        }
        Some(plane)
    }

    /// Marks the entries of surfaces that were split.
    pub(super) fn flag_split_surfaces(&mut self) {
        let mut count = vec![0u32; self.surfaces.len()];
        for &e in &self.entries {
            count[e as usize] += 1;
        }
        for e in &mut self.entries {
            if count[*e as usize] > 1 {
                *e |= SPLIT_FLAG;
            }
        }
    }
}

/// The bounding rectangle, in their common plane, of pieces lying in the
/// plane with this normal; `None` if it has no area.
pub(super) fn in_plane_bounds(pieces: &[Piece], normal: DVec3) -> Option<Vec<DVec3>> {
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let first = pieces.first()?.polygon[0];
    let along = normal.dot(first);
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for p in pieces.iter().flat_map(|p| &p.polygon) {
        let q = DVec2::new(u.dot(*p), v.dot(*p));
        lo = lo.min(q);
        hi = hi.max(q);
    }
    let extent = hi - lo;
    if !(extent.x > 0.0 && extent.y > 0.0 && extent.is_finite()) {
        return None;
    }
    let at = |x: f64, y: f64| normal * along + u * x + v * y;
    Some(vec![
        at(lo.x, lo.y),
        at(hi.x, lo.y),
        at(hi.x, hi.y),
        at(lo.x, hi.y),
    ])
}

/// The larger of the bounding-box diagonal and the largest coordinate: the
/// scale of both the geometry and its round-off; 1 for no surfaces.
pub(super) fn scene_scale((lo, hi): (DVec3, DVec3)) -> f64 {
    let scale = (hi - lo)
        .length()
        .max(lo.abs().max_element())
        .max(hi.abs().max_element());
    if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    }
}

/// A polygon's area computed about its first corner, so it keeps its
/// digits far from the origin (Newell's sum about the origin loses them).
pub(super) fn local_area(polygon: &[DVec3]) -> f64 {
    let origin = polygon[0];
    let local: Vec<DVec3> = polygon.iter().map(|p| *p - origin).collect();
    geometry::area(&local)
}

/// Smallest and largest signed distance of the corners from a plane.
pub(super) fn distance_range(polygon: &[DVec3], normal: DVec3, offset: f64) -> (f64, f64) {
    polygon
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            let d = normal.dot(*p) - offset;
            (lo.min(d), hi.max(d))
        })
}

pub(super) fn classify(polygon: &[DVec3], normal: DVec3, offset: f64, coplanar: f64) -> Side {
    let (lo, hi) = distance_range(polygon, normal, offset);
    match (lo >= -coplanar, hi <= coplanar) {
        (true, true) => Side::On,
        (true, false) => Side::Front,
        (false, true) => Side::Back,
        (false, false) => Side::Both,
    }
}

/// Cuts a convex polygon exactly at the plane: `(front, back)`; corners on
/// the plane go to both.
pub(super) fn split(polygon: &[DVec3], normal: DVec3, offset: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut front = Vec::with_capacity(polygon.len() + 1);
    let mut back = Vec::with_capacity(polygon.len() + 1);
    clip::split_into(
        polygon,
        |p| normal.dot(p) - offset,
        &mut front,
        &mut back,
        |_| {},
    );
    (front, back)
}

/// How far from the convex hull of a surface's corners a point accepted by
/// [`segment_crosses`](super::segment_crosses) can lie: the crossing point is on the surface's plane
/// (which a non-planar input polygon leaves by up to its non-planarity) and
/// within the edge tolerance of every edge line, a region that near a sharp
/// corner reaches `tolerance / sin(angle / 2)` beyond it. The region is
/// computed exactly (in the plane) with four times the tolerance, and its
/// farthest corner's distance from the polygon is the reach.
pub(super) fn crossing_reach(surface: &Surface) -> f64 {
    let (lo, hi) = distance_range(&surface.polygon, surface.normal, surface.offset);
    let non_planarity = (-lo).max(hi).max(0.0);
    let tolerance = 4.0 * CROSSING_TOLERANCE * surface.area.sqrt();
    match AcceptanceRegion::of(surface, 4.0) {
        AcceptanceRegion::Bounded {
            polygon, region, ..
        } => {
            let excess = region
                .iter()
                .map(|q| distance_to_polygon_2d(&polygon, *q))
                .fold(0.0, f64::max);
            excess + non_planarity + tolerance
        }
        AcceptanceRegion::Empty => non_planarity + tolerance,
        // The edges do not bound a region: a degenerate polygon. Every
        // segment then reaches every plane, which is slow but still exact.
        AcceptanceRegion::Unbounded => f64::INFINITY,
    }
}

/// Distance from `q` to a convex 2-D polygon, counter-clockwise (0 inside).
pub(super) fn distance_to_polygon_2d(polygon: &[DVec2], q: DVec2) -> f64 {
    let n = polygon.len();
    let mut inside = true;
    let mut nearest = f64::INFINITY;
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + 1) % n];
        let e = b - a;
        if e.perp_dot(q - a) < 0.0 {
            inside = false;
        }
        let t = if e.length_squared() > 0.0 {
            ((q - a).dot(e) / e.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        nearest = nearest.min(q.distance(a + e * t));
    }
    if inside { 0.0 } else { nearest }
}
