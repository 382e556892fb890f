//! Brute-force visibility: every surface is tested against every shadow
//! segment, as in Wallace, Elmquist & Haines (1989). Kept as the oracle for
//! the BSP and BVH (design.md section 3).

use glam::DVec3;

use super::{InvalidTree, Occluder, PreparedSurfaces};
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
}
