//! The pre-test of Wong & Tsang (1993), section 2: a receiving point is
//! visible when its own pixel holds its surface, hidden when none of the
//! 3 x 3 pixels around it does, uncertain otherwise (with the safeguards
//! described in the parent module).

use super::*;

/// The outcome of the pre-test for one point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pretest {
    /// The point's pixel holds its surface: visible, no ray needed.
    Visible,
    /// None of the 3 x 3 pixels around the point holds its surface and each
    /// holds something in front of it: hidden, no ray needed.
    Hidden,
    /// Marginal: the caller casts a shadow ray.
    Uncertain,
}

/// Tally of pre-test outcomes, for statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PretestCounts {
    /// Pairs decided visible.
    pub visible: u64,
    /// Pairs decided hidden.
    pub hidden: u64,
    /// Pairs left to a ray.
    pub uncertain: u64,
}

impl PretestCounts {
    /// Counts one outcome.
    pub fn record(&mut self, outcome: Pretest) {
        match outcome {
            Pretest::Visible => self.visible += 1,
            Pretest::Hidden => self.hidden += 1,
            Pretest::Uncertain => self.uncertain += 1,
        }
    }

    /// All pairs counted.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.visible + self.hidden + self.uncertain
    }

    /// Pairs decided without a ray.
    #[must_use]
    pub fn decided(&self) -> u64 {
        self.visible + self.hidden
    }
}

impl std::ops::AddAssign for PretestCounts {
    fn add_assign(&mut self, other: PretestCounts) {
        self.visible += other.visible;
        self.hidden += other.hidden;
        self.uncertain += other.uncertain;
    }
}

impl ItemBuffer {
    /// The pre-test of paper section 2 for a point lying on surface
    /// `surface` (see the module documentation for the rule and its
    /// safeguards). Points behind the base plane or (nearly) on it, closer
    /// than the near plane, on the skipped surface, or on a surface seen
    /// edge-on are uncertain.
    #[must_use]
    pub fn classify(&self, point: DVec3, surface: u32) -> Pretest {
        if !self.rendered || surface == self.skip {
            return Pretest::Uncertain;
        }
        let Some(plane) = self.planes.get(surface as usize) else {
            return Pretest::Uncertain;
        };
        if plane.offset.abs() <= 1e-2 * self.near {
            return Pretest::Uncertain;
        }
        let local = self.to_local_vector(point - self.origin);
        let Some(centre) = self.locate_local(local) else {
            return Pretest::Uncertain;
        };
        let face_w = centre.face.face_coordinates(local).z;
        if face_w < self.near {
            return Pretest::Uncertain;
        }
        let group = self.groups[surface as usize];
        let same = |item: u32| item != EMPTY && self.groups[item as usize] == group;
        if same(self.items[self.index(centre)]) {
            return Pretest::Visible;
        }
        // First the cheap integer tests on all nine pixels, then the depth
        // safeguard, which costs a division a pixel, only if they all pass.
        let mut neighbours = [(centre, 0usize); 9];
        for (slot, (dr, dc)) in neighbours
            .iter_mut()
            .zip((-1..=1).flat_map(|dr| (-1..=1).map(move |dc| (dr, dc))))
        {
            let Some(p) = self.neighbour(centre, dc, dr) else {
                return Pretest::Uncertain;
            };
            let k = self.index(p);
            let item = self.items[k];
            if item == EMPTY || same(item) {
                return Pretest::Uncertain;
            }
            *slot = (p, k);
        }
        let hidden = neighbours
            .iter()
            .all(|&(p, k)| self.depth[k] > self.plane_depth(plane, p));
        if hidden {
            Pretest::Hidden
        } else {
            Pretest::Uncertain
        }
    }

    /// `1/w` of a surface's plane along the centre ray of pixel `p`
    /// (negative or zero if the ray does not meet the plane in front).
    pub(super) fn plane_depth(&self, plane: &LocalPlane, p: Pixel) -> f32 {
        let f = self.pixel_centre_face(p.face, f64::from(p.col), f64::from(p.row));
        let m = p.face.face_coordinates(plane.normal);
        let inverse_w = m.dot(f) / plane.offset;
        (inverse_w * (1.0 + f64::from(HIDDEN_DEPTH_MARGIN))) as f32
    }
}
