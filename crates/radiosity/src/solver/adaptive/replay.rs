//! Adaptive shooting's shots kept and replayed, beyond the paper: when a
//! solve refines its mesh as it goes (receiver refinement, Cohen,
//! Greenberg, Immel & Brock 1986, done inside one solve rather than by a
//! second solve from scratch), the vertices the split adds have missed the
//! shots made so far. Each shot is kept as what it sent (the shooting
//! node, each of its elements' sending radiosity, in a pass per sign) and
//! the scene's negligible irradiance then; replayed, it is the same
//! transfer to other receivers, each refining the source against the
//! threshold it would have had then (what it had gathered from the shots
//! before), so a new vertex gets what it would have got had it been there
//! from the start, and no shot is made twice.

use glam::DVec3;

use super::overshoot::Plan;
use super::{AdaptiveShooting, receiver_negligible};
use crate::solver::hierarchy;
use crate::solver::method::ShotInputs;

/// One shot as it was sent.
#[derive(Clone)]
pub(in crate::solver) struct Recorded {
    /// The shooting node.
    root: u32,
    /// What its elements sent.
    plan: Plan,
    /// The negligible irradiance at the scene's mean radiosity, then.
    negligible: f64,
    /// The scene's mean radiosity, then.
    mean_radiosity: f64,
}

impl AdaptiveShooting {
    /// Keeps `plan`, just sent from `root`, when shots are recorded.
    pub(super) fn keep_record(&mut self, root: u32, plan: &Plan) {
        if let Some(record) = self.record.as_mut() {
            record.push(Recorded {
                root,
                plan: plan.clone(),
                negligible: self.negligible,
                mean_radiosity: self.mean_radiosity,
            });
        }
    }

    /// Shot `shot` (counting this method's shots from 0) sent again to
    /// `inputs.receivers`, which have gathered `inputs.irradiance` from
    /// the shots before it: its transfers as they were, each receiver
    /// refining the source against the threshold it would have had then.
    /// `None` when abandoned, or when no such shot was kept.
    pub(super) fn replay_shot(
        &mut self,
        inputs: &ShotInputs<'_>,
        shot: usize,
    ) -> Option<Vec<DVec3>> {
        let kept = self.record.as_ref()?.get(shot)?.clone();
        let tree = hierarchy::receiver_tree(inputs.receivers, inputs.settings.mesh.patch_size);
        let negligible = receiver_negligible(
            &tree,
            kept.negligible,
            kept.mean_radiosity,
            inputs.irradiance,
        );
        let mut total = vec![DVec3::ZERO; inputs.receivers.len()];
        for (pass, sign) in [(0, 1.0), (1, -1.0)] {
            if !kept.plan.sends_sign(pass) {
                continue;
            }
            let sending = self.begin_pass(inputs.scene, inputs.mesh, kept.root, &kept.plan, sign);
            let gathered = self.gather_to(inputs, kept.root, &sending, &tree, &negligible);
            self.end_pass(kept.root, sending);
            let (irradiance, _) = gathered?;
            for (t, e) in total.iter_mut().zip(irradiance) {
                *t += sign * e;
            }
        }
        Some(total)
    }
}
