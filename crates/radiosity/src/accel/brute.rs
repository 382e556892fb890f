//! Brute-force visibility: every surface is tested against every shadow
//! segment, as in Wallace, Elmquist & Haines (1989), and against every ray
//! of a closest-hit query. Kept as the oracle for the BSP and BVH
//! (design.md section 3).

use glam::DVec3;

use super::{Hit, InvalidTree, Nearest, Occluder, PreparedSurfaces, ray_end};
use crate::scene::Surface;

/// Tests every surface.
pub struct BruteForce {
    prepared: PreparedSurfaces,
}

impl BruteForce {
    /// Prepares the scene's surfaces.
    #[must_use]
    pub fn new(surfaces: &[Surface]) -> Self {
        BruteForce {
            prepared: PreparedSurfaces::new(surfaces),
        }
    }
}

impl Occluder for BruteForce {
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool {
        (0..self.prepared.len() as u32)
            .any(|i| !self.prepared.skips(i, skip) && self.prepared.crosses(i, from, to))
    }

    /// Every surface not skipped is tested; the nearest crossing wins.
    fn closest_hit(
        &self,
        origin: DVec3,
        direction: DVec3,
        max_t: f64,
        skip: [u32; 2],
    ) -> Option<Hit> {
        let end = ray_end(origin, direction, max_t)?;
        let mut nearest = Nearest::default();
        for i in 0..self.prepared.len() as u32 {
            if self.prepared.skips(i, skip) {
                continue;
            }
            if let Some(s) = self.prepared.crossing(i, origin, end) {
                nearest.offer(i, s);
            }
        }
        nearest.hit(max_t)
    }

    /// Surfaces are tested in input order up to the first blocker; there
    /// are no nodes.
    fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        let mut tested = 0u32;
        let blocked = (0..self.prepared.len() as u32).any(|i| {
            if self.prepared.skips(i, skip) {
                return false;
            }
            tested += 1;
            self.prepared.crosses(i, from, to)
        });
        (blocked, tested, 0)
    }

    /// A flat list has no invariants beyond its construction.
    fn validate(&self) -> Result<(), InvalidTree> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_at(z: f64) -> Surface {
        let p = vec![
            DVec3::new(-1.0, -1.0, z),
            DVec3::new(1.0, -1.0, z),
            DVec3::new(1.0, 1.0, z),
            DVec3::new(-1.0, 1.0, z),
        ];
        Surface::new(p, DVec3::splat(0.5), DVec3::ZERO, 0).unwrap()
    }

    #[test]
    fn blocks_only_segments_through_the_polygon() {
        let surfaces = vec![square_at(1.0)];
        let occ = BruteForce::new(&surfaces);
        let none = [u32::MAX; 2];
        assert!(occ.occluded(DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0), none));
        assert!(!occ.occluded(DVec3::ZERO, DVec3::new(0.0, 0.0, 0.9), none));
        assert!(!occ.occluded(DVec3::new(3.0, 0.0, 0.0), DVec3::new(3.0, 0.0, 2.0), none));
        // Edges count as blocking.
        assert!(occ.occluded(DVec3::new(1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 2.0), none));
        // Skipped surfaces never block.
        assert!(!occ.occluded(DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0), [0, u32::MAX]));
        // A segment ending on the plane does not cross it.
        assert!(!occ.occluded(DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0), none));
    }

    #[test]
    fn closest_hit_is_the_nearest_crossing() {
        // Surface ids 0, 1, 2 at heights 3, 1, 2.
        let mut surfaces = vec![square_at(3.0), square_at(1.0), square_at(2.0)];
        for (id, s) in surfaces.iter_mut().enumerate() {
            s.group = id as u32;
        }
        let occ = BruteForce::new(&surfaces);
        let none = [u32::MAX; 2];
        let up = DVec3::Z;
        let hit = occ.closest_hit(DVec3::ZERO, up, 10.0, none).unwrap();
        assert_eq!((hit.surface, hit.t), (1, 1.0));
        // Skipping the nearest gives the next; from above, the top one.
        assert_eq!(
            occ.closest_hit(DVec3::ZERO, up, 10.0, [1, 9])
                .unwrap()
                .surface,
            2
        );
        let down = occ.closest_hit(DVec3::new(0.5, 0.0, 5.0), -up, 10.0, none);
        assert_eq!(down.map(|h| (h.surface, h.t)), Some((0, 2.0)));
        // The maximum distance is exclusive; the origin's plane is not hit.
        assert!(occ.closest_hit(DVec3::ZERO, up, 1.0, none).is_none());
        assert_eq!(
            occ.closest_hit(DVec3::Z, up, 10.0, none).unwrap().surface,
            2
        );
        // No distance, or backwards, or to infinity: nothing.
        for max_t in [0.0, -5.0, f64::NAN, f64::INFINITY] {
            assert!(occ.closest_hit(DVec3::ZERO, up, max_t, none).is_none());
        }
        assert!(
            occ.closest_hit(DVec3::ZERO, DVec3::ZERO, 10.0, none)
                .is_none()
        );
    }
}
