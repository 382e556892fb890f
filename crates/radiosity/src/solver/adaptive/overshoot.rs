//! Overshooting (Feda & Purgathofer 1992, "Accelerating radiosity by
//! overshooting"; Gortler, Cohen & Slusallek 1993, "Radiosity and
//! relaxation methods", who show it is over-relaxation of the shooting
//! iteration): a shooter sends, besides the light that has arrived at its
//! elements, the part of the light still unshot elsewhere that they are
//! bound to receive and reflect, so the bounces between two surfaces take
//! fewer shots back and forth.
//!
//! The light still to arrive at element `e` is estimated as the paper's
//! ambient term does it (Cohen, Chen, Wallace & Greenberg 1988): the power
//! unshot elsewhere spread over the scene's area, `U = sum dB_j A_j /
//! sum A_j` over the elements `j` outside the shooter (per channel,
//! never below zero). Element `e` then sends `dB_e + w rho_e U` (`w` is
//! `--overshoot`) and is left with `-w rho_e U`: negative unshot
//! radiosity, which the light it later receives cancels, or a later shot
//! of it sends back as negative light where the estimate was too high.
//!
//! Negative light in the shot's sources: a source node's point sources
//! and visibility samples ([`crate::solver::hierarchy::sources`]) are
//! weighted by their elements' power, which must have one sign. So a
//! shooter whose elements' sending radiosities differ in sign (by their
//! luminance) shoots twice: once its positive elements, once its negative
//! ones negated, whose irradiance is then subtracted. Each pass is an
//! ordinary transfer. Without overshooting nothing is ever negative and
//! a shot is one pass, as before, to the last bit. On a device
//! (`resident.rs`) each pass is a device shot booked with its sign, the
//! first setting the shooter's elements to minus their overshoot; the
//! second is never abandoned, since the first is booked already.
//!
//! The energy ledger stays exact: the power shot is what the elements
//! send, and what they are left with is what they had less that. The
//! stopping rule and the choice of shooter take unshot power element by
//! element in magnitude ([`super::Shooter::unshot_magnitude`]), so
//! negative power never hides positive power still to be shot.

use glam::DVec3;

use super::{AdaptiveShooting, Counters};
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::hierarchy::Tree;
use crate::solver::method::ShotInputs;

/// What one shot's elements send.
#[derive(Clone)]
pub(super) struct Plan {
    /// Per element of the shooter, in its items' order: what it sends,
    /// its unshot radiosity and its overshoot.
    sends: Vec<DVec3>,
    /// Per element likewise: its overshoot, which it keeps as negative
    /// unshot radiosity.
    overs: Vec<DVec3>,
    /// The power sent, per channel (W): the shot's power.
    pub(super) power: DVec3,
    /// Whether some element sends positive light, and some negative (by
    /// luminance).
    signs: [bool; 2],
}

impl Plan {
    /// The plan for shooting node `root`. An element overshoots by its
    /// reflectance times the ambient irradiance where its unshot radiosity
    /// is positive; one with none, or with negative radiosity to send
    /// back, sends no more than it has: an element of no power is left out
    /// of its node's point sources and visibility samples, and must stay
    /// so.
    pub(super) fn new(shooting: &AdaptiveShooting, scene: &Scene, mesh: &Mesh, root: u32) -> Plan {
        let items = shooting.hierarchy.tree.items_of(root);
        let ambient = if shooting.overshoot > 0.0 {
            let mut elsewhere = shooting.unshot_sum(mesh, false);
            for &e in items {
                elsewhere -= shooting.unshot[e as usize] * mesh.elements[e as usize].area;
            }
            let area = mesh.total_area();
            if area > 0.0 {
                (elsewhere / area).max(DVec3::ZERO) * shooting.overshoot
            } else {
                DVec3::ZERO
            }
        } else {
            DVec3::ZERO
        };
        let mut plan = Plan {
            sends: Vec::with_capacity(items.len()),
            overs: Vec::with_capacity(items.len()),
            power: DVec3::ZERO,
            signs: [false; 2],
        };
        for &e in items {
            let element = &mesh.elements[e as usize];
            let unshot = shooting.unshot[e as usize];
            let over = if ambient == DVec3::ZERO || luminance(unshot) <= 0.0 {
                DVec3::ZERO
            } else {
                scene.surfaces[element.surface as usize].rho * ambient
            };
            let send = unshot + over;
            plan.power += send * element.area;
            let l = luminance(send);
            plan.signs[0] |= l > 0.0;
            plan.signs[1] |= l < 0.0;
            plan.sends.push(send);
            plan.overs.push(over);
        }
        plan
    }

    /// What the shooter's elements are left with: minus their overshoot
    /// (zero without).
    pub(super) fn leave(&self, shooting: &mut AdaptiveShooting, root: u32) {
        for (&e, over) in shooting
            .hierarchy
            .tree
            .items_of(root)
            .iter()
            .zip(&self.overs)
        {
            shooting.unshot[e as usize] = -*over;
        }
    }
}

impl Plan {
    /// Which passes the shot takes: `[positive, negative]` (the positive
    /// one alone when nothing is sent, a shot gathering nothing).
    pub(super) fn passes(&self) -> [bool; 2] {
        if self.signs == [false, false] {
            [true, false]
        } else {
            self.signs
        }
    }

    /// Sets `sending` for the shooter's elements `items` to what they send
    /// in the pass of `sign`: their light of that sign, times `sign`;
    /// zero for the others.
    pub(super) fn fill(&self, items: &[u32], sign: f64, sending: &mut [DVec3]) {
        for (&e, &send) in items.iter().zip(&self.sends) {
            sending[e as usize] = if sign * luminance(send) > 0.0 {
                send * sign
            } else {
                DVec3::ZERO
            };
        }
    }

    /// What the shooter's elements are left with, in its items' order.
    pub(super) fn left(&self) -> Vec<DVec3> {
        self.overs.iter().map(|o| -*o).collect()
    }
}

impl AdaptiveShooting {
    /// Starts the pass of `sign` of shooting `root` (on the CPU or a
    /// device): what its elements send in it, in the send buffer (taken
    /// out of `self` until [`AdaptiveShooting::end_pass`]), and its
    /// sources prepared from that.
    pub(super) fn begin_pass(
        &mut self,
        scene: &Scene,
        mesh: &Mesh,
        root: u32,
        plan: &Plan,
        sign: f64,
    ) -> Vec<DVec3> {
        let mut sending = std::mem::take(&mut self.sending);
        plan.fill(self.hierarchy.tree.items_of(root), sign, &mut sending);
        self.sources
            .prepare(scene, mesh, &self.hierarchy, &sending, root);
        sending
    }

    /// Gives the send buffer back, zero again.
    pub(super) fn end_pass(&mut self, root: u32, mut sending: Vec<DVec3>) {
        for &e in self.hierarchy.tree.items_of(root) {
            sending[e as usize] = DVec3::ZERO;
        }
        self.sending = sending;
    }

    /// The shot's transfers to `inputs.receivers` (over their tree
    /// `tree`, the solve's receivers' when `None`, whose nodes' negligible
    /// irradiance is `negligible`): one pass per sign the plan's elements
    /// send, each an ordinary transfer of light of one sign, the negative
    /// pass's irradiance subtracted; `None` when abandoned.
    pub(super) fn send(
        &mut self,
        inputs: &ShotInputs<'_>,
        root: u32,
        plan: &Plan,
        tree: Option<&Tree>,
        negligible: &[f64],
    ) -> Option<(Vec<DVec3>, Counters)> {
        let (scene, mesh) = (inputs.scene, inputs.mesh);
        let mut total: Option<(Vec<DVec3>, Counters)> = None;
        for (pass, sign) in [(0, 1.0), (1, -1.0)] {
            if !plan.signs[pass] {
                continue;
            }
            let sending = self.begin_pass(scene, mesh, root, plan, sign);
            let tree = tree.unwrap_or(&self.receiver_tree);
            let gathered = self.gather_to(inputs, root, &sending, tree, negligible);
            self.end_pass(root, sending);
            let (irradiance, counters) = gathered?;
            total = Some(match total {
                None if sign > 0.0 => (irradiance, counters),
                None => (irradiance.into_iter().map(|e| -e).collect(), counters),
                Some((mut sum, mut all)) => {
                    for (s, e) in sum.iter_mut().zip(irradiance) {
                        *s += sign * e;
                    }
                    all += counters;
                    (sum, all)
                }
            });
        }
        // Nothing to send (every element's radiosity zero): a shot that
        // gathers nothing, as a pass over empty sources would.
        Some(total.unwrap_or_else(|| {
            (
                vec![DVec3::ZERO; inputs.receivers.len()],
                Counters::default(),
            )
        }))
    }
}
