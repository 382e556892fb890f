//! Shots in rounds, beyond the paper: progressive radiosity (Cohen, Chen,
//! Wallace & Greenberg 1988; Wallace, Elmquist & Haines 1989) shoots one
//! patch at a time, the brightest, each shot waiting for the one before.
//! A round shoots at once the brightest shooter and every other whose
//! unshot power is more than [`AdaptiveSettings::round`] times its: a
//! block of the Southwell iteration taken as one Jacobi step (Gortler,
//! Cohen & Slusallek 1993, "Radiosity and relaxation methods", compare
//! the orderings), so a parallel device has many shooters' work to run
//! without the host in between.
//!
//! Within a round every shooter sends what it held when the round began,
//! each receiver refines each shooter's source against the threshold its
//! irradiance then gives, and what the round's shooters receive from one
//! another is booked after the round, as one shot's. The receivers sum the
//! shooters' light in one fixed order (by shooter index), so a rerun gives
//! the same result to the last bit. `--max-shots` and `--max-subsources`
//! cut a round short, keeping its brightest shooters. A fraction of 1 is
//! the brightest shooter alone: the paper's loop.
//!
//! [`AdaptiveSettings::round`]: super::AdaptiveSettings::round

use std::time::Instant;

use glam::DVec3;

use super::overshoot::Plan;
use super::{AdaptiveShooting, Counters};
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::Settings;
use crate::solver::hierarchy::Tree;
use crate::solver::method::{Shot, ShotInputs, Stats, add_direct, emission_share};

/// One shooter of a round, as it sends.
#[derive(Clone)]
pub(in crate::solver) struct Member {
    /// Its node of the element tree.
    pub(super) root: u32,
    /// What its elements send.
    pub(super) plan: Plan,
    /// The share of what it sends that is its emission sent for the first
    /// time, per channel: its light's direct part.
    pub(super) share: DVec3,
}

/// The shooters of a round, by index among the shooters, in the order
/// their light is summed (ascending): the brightest (`powers`' first
/// largest), and every other whose power is more than `fraction` of its
/// (that fraction taken in `f32` when `single`, as a device takes it of
/// the `f32` powers it reports, so that both choose alike).
/// At most `shots` of them, and only while fewer than `subsources`
/// elements are taken (`sizes` are the shooters' elements), the brightest
/// kept; never none.
pub(in crate::solver) fn round_rule(
    powers: &[f64],
    sizes: impl Fn(usize) -> u64,
    fraction: f64,
    single: bool,
    shots: Option<u64>,
    subsources: Option<u64>,
) -> Vec<usize> {
    let best = powers
        .iter()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |best, (i, &p)| {
            if p > best.1 { (i, p) } else { best }
        })
        .0;
    let top = powers.get(best).copied().unwrap_or(0.0);
    let mut round: Vec<usize> = if fraction < 1.0 && top > 0.0 {
        let bar = if single {
            f64::from(fraction as f32 * top as f32)
        } else {
            fraction * top
        };
        (0..powers.len())
            .filter(|&i| i == best || powers[i] > bar)
            .collect()
    } else {
        vec![best]
    };
    if round.len() > 1 && (shots.is_some() || subsources.is_some()) {
        // The brightest first (the first of equals), as the shooters
        // would have gone one at a time.
        round.sort_by(|&a, &b| powers[b].total_cmp(&powers[a]).then(a.cmp(&b)));
        let (mut taken, mut elements) = (0, 0);
        round.retain(|&i| {
            let keep = taken == 0
                || (shots.is_none_or(|s| taken < s) && subsources.is_none_or(|s| elements < s));
            if keep {
                taken += 1;
                elements += sizes(i);
            }
            keep
        });
        round.sort_unstable();
    }
    round
}

impl AdaptiveShooting {
    /// The next round's shooters ([`round_rule`]) under `settings`' limits,
    /// `stats` having been shot so far; `single` where the powers are a
    /// device's.
    pub(super) fn choose_round(
        &self,
        settings: &Settings,
        stats: &Stats,
        single: bool,
    ) -> Vec<usize> {
        let tree = &self.hierarchy.tree;
        round_rule(
            &self.shooter_power,
            |s| tree.items_of(self.hierarchy.shooters[s]).len() as u64,
            self.round,
            single,
            settings.max_shots.map(|m| m.saturating_sub(stats.shots)),
            settings
                .max_subsources
                .map(|m| m.saturating_sub(stats.subsources)),
        )
    }

    /// What each of `round`'s shooters sends, from the state the round
    /// begins with.
    pub(super) fn members(&self, inputs: &ShotInputs<'_>, round: &[usize]) -> Vec<Member> {
        let (scene, mesh) = (inputs.scene, inputs.mesh);
        round
            .iter()
            .map(|&s| {
                let root = self.hierarchy.shooters[s];
                let plan = Plan::new(self, scene, mesh, root);
                let emitted = self.emission.pending_power(
                    scene,
                    self.hierarchy.tree.items_of(root).iter().map(|&e| {
                        let element = &mesh.elements[e as usize];
                        (e as usize, element.surface, element.area)
                    }),
                );
                Member {
                    root,
                    share: emission_share(emitted, plan.power),
                    plan,
                }
            })
            .collect()
    }

    /// The round of `members` has shot (on the CPU or a device): it is
    /// kept when shots are recorded, each shooter is left with what its
    /// plan leaves it and its emission is taken. The power the round sent,
    /// of it the emission's, and the elements shot.
    pub(super) fn end_round(
        &mut self,
        scene: &Scene,
        mesh: &Mesh,
        members: &[Member],
    ) -> (DVec3, DVec3, u64) {
        self.keep_record(members);
        let (mut power, mut emitted, mut elements) = (DVec3::ZERO, DVec3::ZERO, 0);
        for m in members {
            power += m.plan.power;
            emitted += self.take_emission(scene, mesh, m.root);
            elements += self.hierarchy.tree.items_of(m.root).len() as u64;
            m.plan.leave(self, m.root);
        }
        (power, emitted, elements)
    }

    /// A round on the CPU: each shooter's transfers in turn, summed; then
    /// each is left with what its plan leaves it and its emission is
    /// taken. `None` when abandoned, nothing changed.
    pub(super) fn shoot_round(
        &mut self,
        inputs: &ShotInputs<'_>,
        stats: &mut Stats,
    ) -> Option<Shot> {
        if std::mem::take(&mut self.stale_powers) {
            self.total_shooter_power(inputs.mesh);
        }
        let start = Instant::now();
        let (scene, mesh) = (inputs.scene, inputs.mesh);
        let round = self.choose_round(inputs.settings, stats, false);
        let members = self.members(inputs, &round);
        let gather_start = Instant::now();
        let negligible = self.receiver_negligible(inputs.irradiance);
        let (irradiance, direct, counters) =
            self.send_round(inputs, &members, None, &negligible)?;
        let gather_end = Instant::now();
        let (power, emitted, elements) = self.end_round(scene, mesh, &members);
        self.counters += counters;
        stats.book_gathering(&counters.cost, gather_end - gather_start, elements);
        Some(Shot {
            irradiance,
            direct,
            power,
            emitted,
            shooters: members.len() as u64,
            selection_time: gather_start - start,
            booked: None,
        })
    }

    /// The transfers of `members` to `inputs.receivers` (their tree
    /// `tree`, or the solve's receivers' when `None`; its nodes'
    /// negligible irradiance `negligible`), summed in
    /// order: the irradiance, its direct part, what they cost. `None` when
    /// abandoned.
    pub(super) fn send_round(
        &mut self,
        inputs: &ShotInputs<'_>,
        members: &[Member],
        tree: Option<&Tree>,
        negligible: &[f64],
    ) -> Option<(Vec<DVec3>, Vec<DVec3>, Counters)> {
        let mut irradiance: Option<Vec<DVec3>> = None;
        let mut direct = Vec::new();
        let mut counters = Counters::default();
        for m in members {
            let (gathered, cost) = self.send(inputs, m.root, &m.plan, tree, negligible)?;
            add_direct(&mut direct, &gathered, m.share);
            counters += cost;
            match irradiance.as_mut() {
                // The first shooter's light is the sum so far (a round of
                // one costs no more than a shot).
                None => irradiance = Some(gathered),
                Some(total) => {
                    for (t, e) in total.iter_mut().zip(&gathered) {
                        *t += *e;
                    }
                }
            }
        }
        let irradiance = irradiance.unwrap_or_else(|| vec![DVec3::ZERO; inputs.receivers.len()]);
        Some((irradiance, direct, counters))
    }
}

#[cfg(test)]
mod tests {
    use super::round_rule;

    #[test]
    fn a_fraction_of_one_is_the_brightest_alone_the_first_of_equals() {
        let powers = [1.0, 3.0, 3.0, 2.9];
        assert_eq!(round_rule(&powers, |_| 1, 1.0, false, None, None), vec![1]);
    }

    #[test]
    fn a_round_takes_every_shooter_above_the_fraction_in_index_order() {
        let powers = [1.0, 3.0, 1.6, 2.9, 1.5, 0.0];
        assert_eq!(
            round_rule(&powers, |_| 1, 0.5, false, None, None),
            vec![1, 2, 3]
        );
        assert_eq!(
            round_rule(&powers, |_| 1, 0.1, false, None, None),
            vec![0, 1, 2, 3, 4]
        );
    }

    #[test]
    fn limits_keep_the_brightest_and_never_leave_a_round_empty() {
        let powers = [1.0, 3.0, 1.6, 2.9, 1.5];
        assert_eq!(
            round_rule(&powers, |_| 1, 0.1, false, Some(2), None),
            vec![1, 3]
        );
        assert_eq!(
            round_rule(&powers, |_| 1, 0.1, false, Some(0), None),
            vec![1]
        );
        // Taken while fewer than 5 elements are: 4 + 4 crosses it once.
        assert_eq!(
            round_rule(&powers, |_| 4, 0.1, false, None, Some(5)),
            vec![1, 3]
        );
    }

    #[test]
    fn nothing_to_shoot_is_one_shooter_and_nan_never_joins() {
        assert_eq!(
            round_rule(&[0.0, 0.0], |_| 1, 0.5, false, None, None),
            vec![0]
        );
        assert_eq!(
            round_rule(&[f64::NAN, 2.0, 1.5], |_| 1, 0.5, false, None, None),
            vec![1, 2]
        );
    }
}
