//! Adaptive shooting ([`super`]) with its state on a device, beyond the
//! paper (whose solver kept everything on the CPU): from its first shot of
//! a surface the device holds each receiver's irradiance and each
//! element's unshot radiosity ([`crate::solver::device`]). Each shot the
//! host chooses the shooter from the powers the device last reported (the
//! CPU's rule, written once), reads back that shooter's elements' unshot
//! radiosity, prepares its sources as the CPU does, and lets the device
//! gather and book; the whole state comes back at checkpoints. A device
//! that fails leaves the method at its last checkpoint, on the CPU.

use std::time::Instant;

use glam::DVec3;

use super::gather::Counters;
use super::{AdaptiveShooting, overshoot};
use crate::solver::Abort;
use crate::solver::device::{AdaptiveShot, AdaptiveTransfers, Booked, DeviceError, StageTimes};
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
    /// The shooter the device reported with the last shot as the next,
    /// and its elements' unshot radiosity ([`Booked::next_shooter`]).
    next: Option<(usize, Vec<DVec3>)>,
}

impl AdaptiveShooting {
    /// One shot on the device; `None` when abandoned, or when the device
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
            });
        }
        let shooter = self.choose_shooter();
        let root = self.hierarchy.shooters[shooter];
        let node = self.hierarchy.tree.nodes[root as usize];
        // Read back with the last shot when the device chose the same
        // shooter (it chooses as the host does); else asked for.
        let prefetched =
            self.resident
                .as_mut()
                .and_then(|r| r.next.take())
                .filter(|(s, values)| {
                    *s == shooter && values.len() == (node.last - node.first) as usize
                });
        let fresh = match prefetched {
            Some((_, values)) => values,
            None => device.unshot(node.first, node.last)?,
        };
        let items = self.hierarchy.tree.items_of(root);
        for (&e, u) in items.iter().zip(fresh) {
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
        let plan = overshoot::Plan::new(self, scene, mesh, root);
        let power = plan.power;
        let emitted = self.emission.take(
            scene,
            items.iter().map(|&e| {
                let element = &mesh.elements[e as usize];
                (e as usize, element.surface, element.area)
            }),
        );
        let elements = items.len() as u64;
        let direct = crate::solver::resume::emission_share(emitted, power);
        let gather_start = Instant::now();
        let left = plan.left();
        let mut booked: Option<Booked> = None;
        // A second pass is not abandoned: the first is booked already.
        let finish = Abort::default();
        for (pass, sign) in [(0, 1.0), (1, -1.0)] {
            if !plan.passes()[pass] {
                continue;
            }
            let sending = self.begin_pass(scene, mesh, root, &plan, sign);
            let shot = AdaptiveShot {
                root,
                origin: node.centre,
                sources: &self.sources,
                unshot: &sending,
                sign,
                direct,
                leave: booked.is_none().then_some(left.as_slice()),
                negligible: self.negligible,
                mean_radiosity: self.mean_radiosity,
                abort: if booked.is_none() {
                    inputs.abort
                } else {
                    &finish
                },
            };
            let result = device.shoot(&shot);
            self.report.passes += 1;
            self.end_pass(root, sending);
            let Some(this) = result? else {
                return Ok(None);
            };
            booked = Some(match booked {
                None => this,
                Some(first) => first.then(this),
            });
        }
        let Some(booked) = booked else {
            return Ok(None);
        };
        let gather_end = Instant::now();
        self.keep_record(root, &plan);
        plan.leave(self, root);
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
        self.report.device_shots += 1;
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
            resident.since_checkpoint += 1;
            resident.next = booked.next_shooter;
        }
        Ok(Some(Shot {
            irradiance: Vec::new(),
            power,
            emitted,
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
