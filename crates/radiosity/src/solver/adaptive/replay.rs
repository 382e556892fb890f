//! Adaptive shooting's shots kept and replayed, beyond the paper: when a
//! solve refines its mesh as it goes (receiver refinement, Cohen,
//! Greenberg, Immel & Brock 1986, done inside one solve rather than by a
//! second solve from scratch), the vertices the split adds have missed the
//! shots made so far. Each round is kept as what it sent (each shooting
//! node, each of its elements' sending radiosity, in a pass per sign) and
//! the scene's negligible irradiance then; replayed, it is the same
//! transfer to other receivers, each refining the source against the
//! threshold it would have had then (what it had gathered from the shots
//! before), so a new vertex gets what it would have got had it been there
//! from the start, and no shot is made twice.

use super::round::Member;
use super::{AdaptiveShooting, receiver_negligible};
use crate::solver::hierarchy;
use crate::solver::method::{Replayed, ShotInputs};

/// One round as it was sent.
#[derive(Clone)]
pub(in crate::solver) struct Recorded {
    /// Its shooters, as they sent, in the order their light was summed.
    members: Vec<Member>,
    /// The negligible irradiance at the scene's mean radiosity, then.
    negligible: f64,
    /// The scene's mean radiosity, then.
    mean_radiosity: f64,
}

impl AdaptiveShooting {
    /// Keeps `members`, just sent, when shots are recorded.
    pub(super) fn keep_record(&mut self, members: &[Member]) {
        if let Some(record) = self.record.as_mut() {
            record.push(Recorded {
                members: members.to_vec(),
                negligible: self.negligible,
                mean_radiosity: self.mean_radiosity,
            });
        }
    }

    /// Round `shot` (counting this method's rounds from 0) sent again to
    /// `inputs.receivers`, which have gathered `inputs.irradiance` from
    /// the rounds before it: its transfers as they were, each receiver
    /// refining each source against the threshold it would have had then.
    /// `None` when abandoned, or when no such round was kept.
    pub(super) fn replay_shot(&mut self, inputs: &ShotInputs<'_>, shot: usize) -> Option<Replayed> {
        let kept = self.record.as_ref()?.get(shot)?.clone();
        let tree = hierarchy::receiver_tree(inputs.receivers, inputs.settings.mesh.patch_size);
        let negligible = receiver_negligible(
            &tree,
            kept.negligible,
            kept.mean_radiosity,
            inputs.irradiance,
        );
        let (irradiance, direct, _) =
            self.send_round(inputs, &kept.members, Some(&tree), &negligible)?;
        Some(Replayed { irradiance, direct })
    }
}
