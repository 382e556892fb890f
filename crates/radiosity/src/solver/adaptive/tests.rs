//! The device seam ([`crate::solver::device`]) driven by a stand-in device
//! that keeps the state and makes each shot with the CPU's own code (the
//! gathering, then the host's book-keeping), and fails on purpose at a
//! chosen shot: the state kept on a device reaches the CPU's answer, and a
//! device that fails is a fault to survive, the solve going back to its
//! last checkpoint and on on the CPU.

use std::sync::Arc;

use glam::DVec3;

use super::gather::Gatherer;
use crate::accel::Accel;
use crate::form_factor::FormFactor;
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::{self, Scene};
use crate::solver::device::{
    AdaptiveShot, AdaptiveSolve, AdaptiveTransfers, Backend, Booked, Device, DeviceError,
};
use crate::solver::hierarchy::transfer::Transfer;
use crate::solver::hierarchy::{self, Hierarchy};
use crate::solver::method;
use crate::solver::{Flow, Receiver, Settings, Solver};

/// A device that answers as the CPU does and fails at its `fail_at`-th
/// shot (counting from 1; 0 fails at the start).
struct Stand {
    fail_at: Option<u64>,
}

struct StandTransfers {
    scene: Scene,
    mesh: Mesh,
    hierarchy: Hierarchy,
    receivers: Vec<Receiver>,
    shots: u64,
    fail_at: Option<u64>,
    irradiance: Vec<DVec3>,
    direct: Vec<DVec3>,
    unshot: Vec<DVec3>,
    /// The round sent so far: its irradiance, direct part and what its
    /// shooters' elements are left with.
    round: Vec<DVec3>,
    round_direct: Vec<DVec3>,
    leaves: Vec<(u32, DVec3)>,
    counters: super::Counters,
}

impl Backend for Stand {
    fn name(&self) -> String {
        "stand-in".into()
    }

    fn refuses(&self, _: &crate::solver::Settings) -> Option<String> {
        None
    }

    fn segments(&self, _: &Scene) -> Result<Box<dyn crate::solver::device::Segments>, DeviceError> {
        Err(DeviceError("no segments on this device".into()))
    }

    fn check(&self, _: &Scene, _: &Mesh, _: usize) -> Result<u64, DeviceError> {
        Ok(0)
    }

    fn adaptive(
        &self,
        solve: &AdaptiveSolve<'_>,
    ) -> Result<Box<dyn AdaptiveTransfers>, DeviceError> {
        if self.fail_at == Some(0) {
            return Err(DeviceError("no such device".into()));
        }
        Ok(Box::new(StandTransfers {
            scene: solve.scene.clone(),
            mesh: solve.mesh.clone(),
            hierarchy: solve.hierarchy.clone(),
            receivers: solve.receivers.to_vec(),
            shots: 0,
            fail_at: self.fail_at,
            irradiance: Vec::new(),
            direct: Vec::new(),
            unshot: Vec::new(),
            round: vec![DVec3::ZERO; solve.receivers.len()],
            round_direct: vec![DVec3::ZERO; solve.receivers.len()],
            leaves: Vec::new(),
            counters: super::Counters::default(),
        }))
    }
}

impl AdaptiveTransfers for StandTransfers {
    fn begin(
        &mut self,
        irradiance: &[DVec3],
        direct: &[DVec3],
        unshot: &[DVec3],
    ) -> Result<(), DeviceError> {
        self.irradiance = irradiance.to_vec();
        self.direct = direct.to_vec();
        self.direct.resize(irradiance.len(), DVec3::ZERO);
        self.unshot = unshot.to_vec();
        Ok(())
    }

    fn unshot(&mut self, elements: &[u32]) -> Result<Vec<DVec3>, DeviceError> {
        Ok(elements.iter().map(|&e| self.unshot[e as usize]).collect())
    }

    fn send(&mut self, shot: &AdaptiveShot<'_>) -> Result<bool, DeviceError> {
        self.shots += 1;
        if self.fail_at == Some(self.shots) {
            return Err(DeviceError("device lost".into()));
        }
        let occluder = Accel::Bvh.build(&self.scene.surfaces);
        // Each receiver walks the source for itself whatever tree spreads
        // the work.
        let tree = hierarchy::receiver_tree(&self.receivers, 1.0);
        let mut negligible = vec![0.0; tree.nodes.len()];
        for n in (0..tree.nodes.len()).rev() {
            let node = &tree.nodes[n];
            negligible[n] = if node.is_leaf() {
                let r = tree.items[node.first as usize] as usize;
                shot.negligible * (luminance(self.irradiance[r]) / shot.mean_radiosity).max(1.0)
            } else {
                negligible[n + 1].min(negligible[node.second as usize])
            };
        }
        let gatherer = Gatherer {
            transfer: Transfer {
                scene: &self.scene,
                mesh: &self.mesh,
                hierarchy: &self.hierarchy,
                unshot: shot.unshot,
                sources: shot.sources,
                root: shot.root,
                origin: shot.origin,
                occluder: occluder.as_ref(),
                form_factor: FormFactor::Analytic,
            },
            receiver_tree: &tree,
            receivers: &self.receivers,
            negligible: &negligible,
            abort: shot.abort,
        };
        let mut in_tree_order = vec![DVec3::ZERO; self.receivers.len()];
        let counters = gatherer.refine(shot.root, 0, &mut in_tree_order);
        let mut gathered = vec![DVec3::ZERO; self.receivers.len()];
        for (&r, e) in tree.items.iter().zip(in_tree_order) {
            gathered[r as usize] = e;
        }
        // The round's sums, booked when it ends.
        for ((round, direct), e) in self
            .round
            .iter_mut()
            .zip(&mut self.round_direct)
            .zip(&gathered)
        {
            let e = *e * shot.sign;
            *round += e;
            *direct += e * shot.direct;
        }
        if let Some(leave) = shot.leave {
            let items = self.hierarchy.tree.items_of(shot.root);
            self.leaves
                .extend(items.iter().copied().zip(leave.iter().copied()));
        }
        self.counters += counters;
        Ok(true)
    }

    /// The book-keeping the host does for the CPU, here on the "device".
    fn book(&mut self) -> Result<Booked, DeviceError> {
        for (e, l) in self.leaves.drain(..) {
            self.unshot[e as usize] = l;
        }
        let gathered = std::mem::replace(&mut self.round, vec![DVec3::ZERO; self.receivers.len()]);
        let direct = std::mem::replace(
            &mut self.round_direct,
            vec![DVec3::ZERO; self.receivers.len()],
        );
        for ((total, d), (e, g)) in self
            .irradiance
            .iter_mut()
            .zip(&mut self.direct)
            .zip(gathered.iter().zip(&direct))
        {
            *total += *e;
            *d += *g;
        }
        let vertices = self.mesh.vertices.len();
        let unshot = &mut self.unshot;
        let received = method::receive_at_elements(
            &self.scene,
            &self.mesh,
            &gathered[..vertices],
            None,
            |e, r| unshot[e] += r,
        );
        let mut shooter_power = vec![0.0; self.hierarchy.shooters.len()];
        for ((e, u), s) in self
            .mesh
            .elements
            .iter()
            .zip(&self.unshot)
            .zip(&self.hierarchy.shooter_of)
        {
            shooter_power[*s as usize] += luminance(*u).abs() * e.area;
        }
        let counters = std::mem::take(&mut self.counters);
        Ok(Booked {
            received,
            unshot_power: self
                .mesh
                .elements
                .iter()
                .zip(&self.unshot)
                .map(|(e, u)| *u * e.area)
                .sum(),
            unshot_magnitude: self
                .mesh
                .elements
                .iter()
                .zip(&self.unshot)
                .map(|(e, u)| u.abs() * e.area)
                .sum(),
            shooter_power,
            pairs: counters.cost.pairs,
            rays: counters.cost.rays,
            walks: counters.walks,
            node_visits: counters.node_visits,
            element_sources: counters.element_sources,
            ..Booked::default()
        })
    }

    fn state(
        &mut self,
        irradiance: &mut [DVec3],
        direct: &mut [DVec3],
        unshot: &mut [DVec3],
    ) -> Result<(), DeviceError> {
        irradiance.copy_from_slice(&self.irradiance);
        direct.copy_from_slice(&self.direct);
        unshot.copy_from_slice(&self.unshot);
        Ok(())
    }
}

/// A device failing at the start, at the first shot, in the middle or
/// never: the answer is the CPU's (to round-off: a device's radiosity is
/// its surface's emission plus `rho E`, summed once), the shots kept are
/// counted as the device's (a failure goes back to the last checkpoint,
/// wherever the clock put it), and the failure is reported. Also with
/// overshooting, whose shots take a pass per sign on the device: there
/// the device books each pass's light apart (the CPU sums the passes
/// first), so the answer is the CPU's to round-off, not to the bit.
#[test]
fn a_failing_device_leaves_the_solve_to_the_cpu() {
    let mut scene = scene::load("cornell").unwrap();
    scene::merge::merge_coplanar(&mut scene.surfaces);
    let sizes = scene.default_mesh_sizes();
    for overshoot in [0.0, 1.0] {
        let mut settings = Settings::adaptive();
        settings.mesh.patch_size = sizes.patch_size;
        settings.mesh.element_size = sizes.element_size;
        settings.max_shots = Some(SHOTS);
        let crate::solver::MethodSettings::Adaptive(adaptive) = &mut settings.method else {
            unreachable!("the adaptive settings")
        };
        adaptive.overshoot = overshoot;
        failing_devices(&scene, &settings, overshoot);
    }
}

/// Shots of each solve: enough for overshooting's negative light to be
/// shot back (a pass of its own) several times.
const SHOTS: u64 = 150;

fn failing_devices(scene: &Scene, settings: &Settings, overshoot: f64) {
    let mesh = Mesh::build(scene, &settings.mesh).unwrap();
    let solve = |device: Device| {
        let mut solver = Solver::new(
            scene,
            &mesh,
            Settings {
                device,
                ..settings.clone()
            },
        );
        solver.run(|_| Flow::Continue);
        (
            solver.radiosity().to_vec(),
            solver.irradiance().to_vec(),
            *solver.energy(),
            solver.stats().shots,
            solver.device_report(),
            solver
                .direct_complete()
                .then(|| solver.direct_irradiance().to_vec()),
        )
    };
    let (cpu, cpu_irradiance, cpu_energy, _, report, cpu_direct) = solve(Device::cpu());
    let cpu_direct = cpu_direct.expect("the CPU books the direct part");
    assert_eq!(report.name, None);
    let close = |a: DVec3, b: DVec3, scale: f64| (a - b).abs().max_element() <= 1e-9 * scale;
    for (fail_at, most) in [(Some(0), 0), (Some(1), 0), (Some(17), 16), (None, SHOTS)] {
        let case = format!("overshoot {overshoot}, failing at {fail_at:?}");
        let (radiosity, irradiance, energy, shots, report, direct) =
            solve(Device::backend(Arc::new(Stand { fail_at })));
        // The device books the direct part too: complete unless a failure
        // made shots again on the CPU, and the CPU's.
        assert!(direct.is_some() || fail_at.is_some(), "{case}");
        let peak = cpu_direct
            .iter()
            .fold(0.0_f64, |m, e| m.max(e.max_element()));
        assert!(peak > 0.0);
        for (a, b) in direct.iter().flatten().zip(&cpu_direct) {
            assert!(
                close(*a, *b, peak),
                "{case}: direct {a} against the CPU's {b}"
            );
        }
        assert_eq!(shots, SHOTS, "{case}");
        assert_eq!(report.name.as_deref(), Some("stand-in"));
        assert!(report.device_shots <= most, "{case}: {report:?}");
        if fail_at.is_none() {
            assert_eq!(report.device_shots, SHOTS);
        }
        assert_eq!(report.fault.is_some(), fail_at.is_some(), "{case}");
        if overshoot == 0.0 {
            assert_eq!(irradiance, cpu_irradiance, "{case}");
            assert_eq!(energy, cpu_energy, "{case}");
        } else {
            let peak = cpu_irradiance
                .iter()
                .fold(0.0_f64, |m, e| m.max(e.max_element()));
            for (a, b) in irradiance.iter().zip(&cpu_irradiance) {
                assert!(close(*a, *b, peak), "{case}: {a} against the CPU's {b}");
            }
            let scale = cpu_energy.emitted.max_element();
            for (a, b) in [
                (energy.shot, cpu_energy.shot),
                (energy.received, cpu_energy.received),
                (energy.absorbed, cpu_energy.absorbed),
                (energy.escaped, cpu_energy.escaped),
            ] {
                assert!(close(a, b, scale), "{case}: ledger {a} against {b}");
            }
        }
        let tolerance = if overshoot == 0.0 { 1e-12 } else { 1e-9 };
        for (a, b) in radiosity.iter().zip(&cpu) {
            assert!(
                (*a - *b).abs().max_element() <= tolerance * b.max_element().max(1.0),
                "{case}: {a} against the CPU's {b}"
            );
        }
    }
}

/// Each receiver-tree node's negligible irradiance, computed subtree by
/// subtree in parallel, is the smallest of its receivers' (counted by
/// brute force over every node's range), on a tree large enough to be
/// split between threads.
#[test]
fn a_node_s_negligible_irradiance_is_its_receivers_smallest() {
    let scene = scene::load("room").unwrap();
    let sizes = scene.default_mesh_sizes();
    let mut settings = Settings::adaptive();
    settings.mesh.element_size = 0.25 * sizes.element_size;
    let mesh = Mesh::build(&scene, &settings.mesh).unwrap();
    let receivers = crate::solver::receiver::vertex_receivers(&scene, &mesh);
    let tree = hierarchy::receiver_tree(&receivers, sizes.patch_size);
    assert!(tree.nodes[0].last - tree.nodes[0].first >= 4 * super::PARALLEL_RECEIVERS);
    // Irradiance varying over five orders of magnitude, some of it below
    // the mean radiosity's share.
    let irradiance: Vec<DVec3> = (0..receivers.len())
        .map(|i| DVec3::splat(10f64.powf(((i * 7919) % 1000) as f64 / 200.0 - 2.0)))
        .collect();
    let (negligible, mean) = (1e-3, 1.0);
    let out = super::receiver_negligible(&tree, negligible, mean, &irradiance);
    for (n, node) in tree.nodes.iter().enumerate() {
        let smallest = tree.items[node.first as usize..node.last as usize]
            .iter()
            .map(|&r| negligible * (luminance(irradiance[r as usize]) / mean).max(1.0))
            .fold(f64::INFINITY, f64::min);
        assert_eq!(out[n], smallest, "node {n}");
    }
}
