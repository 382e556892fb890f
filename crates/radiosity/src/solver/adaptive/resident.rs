//! Adaptive shooting ([`super`]) with its state on a device, beyond the
//! paper (whose solver kept everything on the CPU): from its first shot of
//! a surface the device holds each receiver's irradiance and each
//! element's unshot radiosity ([`crate::solver::device`]). Each round the
//! host chooses the shooters from the powers the device last reported (the
//! CPU's rule, written once: `round.rs`), takes their elements' unshot
//! radiosity from what the device sent back with the last round (it chose
//! the same round) or asks for it, prepares their sources as the CPU does,
//! and lets the device gather each and book the round; the whole state
//! comes back at checkpoints. A device that fails leaves the method at its
//! last checkpoint, on the CPU.

use std::time::Instant;

use glam::DVec3;

use super::AdaptiveShooting;
use super::gather::Counters;
use crate::solver::device::{AdaptiveShot, AdaptiveTransfers, DeviceError, NextRound, StageTimes};
use crate::solver::hierarchy::transfer::Cost;
use crate::solver::method::{Checkpoint, Shot, ShotInputs, Stats};

/// What the device holds for a solve, as the host last heard it.
pub(super) struct Resident {
    /// Unshot power left, per channel, after the last shot.
    pub(super) unshot_power: DVec3,
    /// The same in magnitude, element by element.
    pub(super) unshot_magnitude: DVec3,
    /// Every element's unshot radiosity at the last checkpoint.
    saved: Vec<DVec3>,
    /// Shots on the device since then (undone if it fails).
    since_checkpoint: u64,
    /// The next round as the device chose it with the last
    /// ([`crate::solver::device::Booked::next_round`]).
    next: Option<NextRound>,
    /// The host's unshot radiosity is the device's: no round has been
    /// booked since the device took the state over. (A checkpoint reads
    /// it back too, but by the clock: the rounds after one still ask, so
    /// the device's counts are the same on any machine.)
    host_current: bool,
}

impl AdaptiveShooting {
    /// One round on the device; `None` when abandoned, or when the device
    /// failed (then [`AdaptiveShooting::rolled_back`] is set and the
    /// method is back at its last checkpoint, on the CPU).
    pub(super) fn shoot_on_device(
        &mut self,
        inputs: &ShotInputs<'_>,
        stats: &mut Stats,
    ) -> Option<Shot> {
        let mut device = self.device.take()?;
        match self.try_shoot_on_device(device.as_mut(), inputs, stats) {
            Ok(shot) => {
                self.device = Some(device);
                shot
            }
            Err(e) => {
                self.fail(e);
                None
            }
        }
    }

    fn try_shoot_on_device(
        &mut self,
        device: &mut dyn AdaptiveTransfers,
        inputs: &ShotInputs<'_>,
        stats: &mut Stats,
    ) -> Result<Option<Shot>, DeviceError> {
        let start = Instant::now();
        let (scene, mesh) = (inputs.scene, inputs.mesh);
        if self.resident.is_none() {
            // The lights have shot on the host: the device takes over the
            // state as it stands.
            device.begin(inputs.irradiance, inputs.direct, &self.unshot)?;
            self.resident = Some(Resident {
                unshot_power: mesh
                    .elements
                    .iter()
                    .zip(&self.unshot)
                    .map(|(e, u)| *u * e.area)
                    .sum(),
                unshot_magnitude: mesh
                    .elements
                    .iter()
                    .zip(&self.unshot)
                    .map(|(e, u)| u.abs() * e.area)
                    .sum(),
                saved: self.unshot.clone(),
                since_checkpoint: 0,
                next: None,
                host_current: true,
            });
        }
        let round = self.choose_round(inputs.settings, stats, true);
        // The round's shooters' elements, in order.
        let wanted: Vec<u32> = round
            .iter()
            .flat_map(|&s| self.hierarchy.tree.items_of(self.hierarchy.shooters[s]))
            .copied()
            .collect();
        // Read back with the last round when the device chose the same
        // (it chooses as the host does, but for --max-shots and
        // --max-subsources); else asked for.
        let resident = self.resident.as_mut();
        let host_current = resident.as_ref().is_some_and(|r| r.host_current);
        let prefetched = resident
            .and_then(|r| r.next.take())
            .filter(|n| n.shooters == round.len() && n.unshot.len() == wanted.len());
        let fresh = match prefetched {
            Some(next) => next.unshot,
            // The host holds what the device does (to the f32 it keeps).
            None if host_current => wanted.iter().map(|&e| self.unshot[e as usize]).collect(),
            None => device.unshot(&wanted)?,
        };
        for (&e, u) in wanted.iter().zip(fresh) {
            // The device holds f32s: where its value is the host's rounded
            // (an emitter not yet lit by anything), the host's exact value
            // stands, so the sources are the CPU's to the last bit (a
            // representative among equals is picked by round-off).
            let host = &mut self.unshot[e as usize];
            if u.as_vec3() != host.as_vec3() {
                *host = u;
            }
        }
        // What each element sends, in a pass per sign (overshooting's,
        // as on the CPU: `overshoot.rs`); one pass of its unshot radiosity
        // without.
        let members = self.members(inputs, &round);
        let gather_start = Instant::now();
        // A round is abandoned only before it is booked.
        for m in &members {
            let node = self.hierarchy.tree.nodes[m.root as usize];
            let left = m.plan.left();
            let mut first = true;
            for (pass, sign) in [(0, 1.0), (1, -1.0)] {
                if !m.plan.passes()[pass] {
                    continue;
                }
                let sending = self.begin_pass(scene, mesh, m.root, &m.plan, sign);
                let shot = AdaptiveShot {
                    root: m.root,
                    origin: node.centre,
                    sources: &self.sources,
                    unshot: &sending,
                    sign,
                    direct: m.share,
                    leave: first.then_some(left.as_slice()),
                    negligible: self.negligible,
                    mean_radiosity: self.mean_radiosity,
                    abort: inputs.abort,
                };
                let sent = device.send(&shot);
                self.report.passes += 1;
                self.end_pass(m.root, sending);
                if !sent? {
                    return Ok(None);
                }
                first = false;
            }
        }
        let booked = device.book()?;
        let gather_end = Instant::now();
        let (power, emitted, elements) = self.end_round(scene, mesh, &members);
        if booked.shooter_power.len() != self.shooter_power.len() {
            return Err(DeviceError(format!(
                "the device reported {} shooters' powers, not {}",
                booked.shooter_power.len(),
                self.shooter_power.len()
            )));
        }
        self.shooter_power = booked.shooter_power;
        let counters = Counters {
            cost: Cost {
                pairs: booked.pairs,
                rays: booked.rays,
                ..Cost::default()
            },
            walks: booked.walks,
            node_visits: booked.node_visits,
            element_sources: booked.element_sources,
        };
        self.counters += counters;
        stats.pairs += booked.pairs;
        stats.rays_cast += booked.rays;
        stats.subsources += elements;
        stats.gather_time += gather_end - gather_start;
        self.report.device_shots += members.len() as u64;
        self.report.upload_time += booked.upload_time;
        self.report.kernel_time += booked.kernel_time;
        self.report.readback_time += booked.readback_time;
        self.report.stages = StageTimes::add_known(self.report.stages, booked.stages);
        self.report.traffic = device.traffic();
        self.report.longest_visits += booked.longest_walk + booked.longest_item;
        if booked.walks > 0 {
            self.report.mean_visits += booked.node_visits as f64 / booked.walks as f64;
        }
        if let Some(resident) = self.resident.as_mut() {
            resident.unshot_power = booked.unshot_power;
            resident.unshot_magnitude = booked.unshot_magnitude;
            resident.since_checkpoint += members.len() as u64;
            resident.next = booked.next_round;
            resident.host_current = false;
        }
        Ok(Some(Shot {
            irradiance: Vec::new(),
            direct: Vec::new(),
            power,
            emitted,
            shooters: members.len() as u64,
            selection_time: gather_start - start,
            booked: Some(booked.received),
        }))
    }

    /// Reads the device's state back ([`crate::solver::Shooter::checkpoint`]).
    pub(super) fn checkpoint_device(
        &mut self,
        irradiance: &mut [DVec3],
        direct: &mut [DVec3],
    ) -> Checkpoint {
        let (Some(device), Some(_)) = (self.device.as_mut(), self.resident.as_ref()) else {
            return Checkpoint::Host;
        };
        let read = device.state(irradiance, direct, &mut self.unshot);
        self.report.traffic = device.traffic();
        match read {
            Ok(()) => {
                if let Some(resident) = self.resident.as_mut() {
                    resident.saved.clone_from(&self.unshot);
                    resident.since_checkpoint = 0;
                }
                Checkpoint::Taken
            }
            Err(e) => {
                self.fail(e);
                self.rolled_back = false;
                Checkpoint::RolledBack
            }
        }
    }

    /// The device failed: the method goes back to its last checkpoint (the
    /// shots since are not counted as the device's) and on to the CPU.
    fn fail(&mut self, e: DeviceError) {
        self.report.fault = Some(e.0);
        self.device = None;
        if let Some(resident) = self.resident.take() {
            self.unshot = resident.saved;
            self.report.device_shots -= resident.since_checkpoint;
        }
        // Recomputed from the restored unshot radiosity at the next shot.
        self.stale_powers = true;
        self.rolled_back = true;
    }
}
