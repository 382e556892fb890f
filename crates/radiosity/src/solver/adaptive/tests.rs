//! A device that fails is a fault to survive: the device seam
//! ([`crate::solver::device`]) driven by a stand-in device that makes each
//! shot's transfers with the CPU's own code, and fails on purpose at a
//! chosen shot. The solve carries on on the CPU from where it was, to the
//! very answer the CPU alone reaches, and reports where its shots ran.

use std::sync::Arc;

use glam::DVec3;

use super::gather::Gatherer;
use crate::accel::Accel;
use crate::form_factor::FormFactor;
use crate::mesh::Mesh;
use crate::scene::{self, Scene};
use crate::solver::device::{
    AdaptiveShot, AdaptiveSolve, AdaptiveTransfers, Backend, Device, DeviceError, Gathered,
};
use crate::solver::hierarchy::transfer::Transfer;
use crate::solver::hierarchy::{self, Hierarchy};
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
}

impl Backend for Stand {
    fn name(&self) -> String {
        "stand-in".into()
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
        }))
    }
}

impl AdaptiveTransfers for StandTransfers {
    fn gather(&mut self, shot: &AdaptiveShot<'_>) -> Result<Option<Gathered>, DeviceError> {
        self.shots += 1;
        if self.fail_at == Some(self.shots) {
            return Err(DeviceError("device lost".into()));
        }
        let occluder = Accel::Bvh.build(&self.scene.surfaces);
        // A tree of single receivers' groups: each receiver walks the
        // source for itself whatever tree spreads the work.
        let tree = hierarchy::receiver_tree(&self.receivers, 1.0);
        let mut negligible = vec![0.0; tree.nodes.len()];
        for n in (0..tree.nodes.len()).rev() {
            let node = &tree.nodes[n];
            negligible[n] = if node.is_leaf() {
                shot.negligible[tree.items[node.first as usize] as usize]
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
        let mut irradiance = vec![DVec3::ZERO; self.receivers.len()];
        for (&r, e) in tree.items.iter().zip(in_tree_order) {
            irradiance[r as usize] = e;
        }
        Ok(Some(Gathered {
            irradiance,
            pairs: counters.cost.pairs,
            rays: counters.cost.rays,
            walks: counters.walks,
            node_visits: counters.node_visits,
            element_sources: counters.element_sources,
            ..Gathered::default()
        }))
    }
}

/// A device failing at the start, at the first shot, in the middle or
/// never: the answer is the CPU's to the last bit, the shots before the
/// failure are counted as the device's, and the failure is reported.
#[test]
fn a_failing_device_leaves_the_solve_to_the_cpu() {
    let mut scene = scene::load("cornell").unwrap();
    scene::merge::merge_coplanar(&mut scene.surfaces);
    let sizes = scene.default_mesh_sizes();
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = sizes.patch_size;
    settings.mesh.element_size = sizes.element_size;
    settings.max_shots = Some(40);
    let mesh = Mesh::build(&scene, &settings.mesh).unwrap();
    let solve = |device: Device| {
        let mut solver = Solver::new(
            &scene,
            &mesh,
            Settings {
                device,
                ..settings.clone()
            },
        );
        solver.run(|_| Flow::Continue);
        (solver.radiosity().to_vec(), solver.device_report())
    };
    let (cpu, report) = solve(Device::cpu());
    assert_eq!(report.name, None);
    for (fail_at, device_shots) in [(Some(0), 0), (Some(1), 0), (Some(17), 16), (None, 40)] {
        let (radiosity, report) = solve(Device::backend(Arc::new(Stand { fail_at })));
        assert_eq!(report.name.as_deref(), Some("stand-in"));
        assert_eq!(report.device_shots, device_shots, "failing at {fail_at:?}");
        assert_eq!(
            report.fault.is_some(),
            fail_at.is_some(),
            "failing at {fail_at:?}"
        );
        assert!(
            radiosity.iter().zip(&cpu).all(|(a, b)| a == b),
            "failing at {fail_at:?}: the answer differs from the CPU's"
        );
    }
}
