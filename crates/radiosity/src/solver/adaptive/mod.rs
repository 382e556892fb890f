//! Adaptive shooting, beyond the paper: shooters carry their radiosity at
//! element resolution, and each transfer is refined until it is accurate.
//!
//! The paper's patches shoot one uniform unshot radiosity, so a receiver
//! near a large patch whose radiosity varies across it (a wall brighter near
//! the light) gets the patch's average. Here:
//!
//! * **Unshot radiosity per element.** An element's share of a shot is the
//!   mean of its vertices' irradiance times its reflectance; a shooter sends
//!   each element's own unshot radiosity. Book-keeping is exact: the power
//!   shot, received, absorbed and reflected balance to round-off
//!   ([`super::Energy`]).
//! * **What shoots** ([`hierarchy`]): the shooter (a node of the element
//!   tree no larger than the patch size) with the most unshot power, as in
//!   Wallace et al. (1989) and Cohen et al. (1988), and with it, in one
//!   round, every shooter within [`AdaptiveSettings::round`] of its power
//!   (`round.rs`).
//! * **Receivers one by one**: the receivers' tree only prunes groups no
//!   point of the shooter can reach and spreads the work over threads.
//!   Letting a group far from a dim source share one visibility estimate
//!   (a link, as in Smits, Arvo & Greenberg 1994) smeared shadow edges and
//!   contacts over the group (0.8 points of L1 against Radiance on the
//!   built-in room) and saved no measurable time on Sponza.
//! * **Per-receiver refinement** (the adaptive source subdivision of
//!   Wallace, Elmquist & Haines 1989, section 4): a single receiver walks
//!   the source's tree, accepting a node as one source when the irradiance
//!   it can send is negligible, or when the receiver is beyond
//!   [`FAR_RATIO`] of its radius and either that irradiance is below
//!   [`FAR_FACTOR`] times negligible or four shadow rays spread over the
//!   node agree; otherwise it visits the node's children. Elements are the
//!   finest sources: the analytic factor of the paper's equation (2) on the
//!   element's polygon (clipped to the receiver's front), a shadow ray from
//!   its centre. So the near field sees element resolution and the far
//!   field a few sources.
//! * **Negligible** is the tolerance ([`AdaptiveSettings::tolerance`]) times
//!   what the receiver has gathered so far (or the scene's mean radiosity,
//!   if more): a bright source is shot carefully everywhere, a dim one
//!   coarsely where it adds little. A node accepted as dim has its
//!   geometry integrated to within [`DIM_SHARE`] of the negligible
//!   irradiance, not to the quadrature's full accuracy (its one shadow
//!   ray can miss by all of it).
//!
//! * **Overshooting** (`--overshoot`, off by default; `overshoot.rs`): a
//!   shooter may also send light it is bound to receive, estimated by the
//!   ambient term, and keep the negative remainder for a later shot (Feda
//!   & Purgathofer 1992): fewer shots to the stopping rule.
//!
//! How accurate an accepted node's geometry is, is said once, at
//! [`super::hierarchy::sources::point_factor`].

mod gather;
mod overshoot;
mod replay;
mod resident;
mod round;

use glam::DVec3;

use self::gather::{Counters, Gatherer};
use super::device::{AdaptiveSolve, AdaptiveTransfers, DeviceReport};
use super::hierarchy::sources::Sources;
use super::hierarchy::transfer::Transfer;
pub use super::hierarchy::transfer::{DIM_SHARE, FAR_RATIO};
use super::hierarchy::{self, Hierarchy, Tree};
use super::method::{
    self, Checkpoint, Counter, ElementState, Emission, Kind, Method, MethodError, Parameter,
    Received, Replayed, SetError, Shooter, Shot, ShotInputs, Stats, VISIBILITY, Value, Visibility,
};
use super::{Receiver, Settings};
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::costs;

/// Adaptive shooting's own parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct AdaptiveSettings {
    /// Accuracy: a receiver accepts a part of the shooter as one source when
    /// the irradiance that part can send is below this fraction of the
    /// scene's mean radiosity (or of what the receiver has gathered, if
    /// more), or when it is far and below [`FAR_FACTOR`] times that.
    pub tolerance: f64,
    /// Overshooting (Feda & Purgathofer 1992): each lit element of a
    /// shooter also sends this many times its reflectance times the ambient
    /// irradiance of the power still unshot elsewhere, light it is bound to
    /// receive and reflect; 0 shoots exactly what has arrived.
    pub overshoot: f64,
    /// Rounds (`round.rs`): with the brightest shooter, every shooter whose
    /// unshot power is more than this fraction of its shoots in the same
    /// round; 1 shoots the brightest alone.
    pub round: f64,
}

/// Default `--tolerance`.
pub const DEFAULT_TOLERANCE: f64 = 1e-3;

/// Default `--overshoot`: off. It saves shots (the room's base mesh: 538
/// against 902), but at the default stopping rule its scores against
/// Radiance are not yet equal or better on every validation scene (the
/// measured Cornell box: 0.73% against 0.68%).
pub const DEFAULT_OVERSHOOT: f64 = 0.0;

/// Default `--round`: on Sponza 83 rounds to the default stopping rule
/// against 3,522 shooters one at a time, for 1.04 times the node visits
/// and rays (EXPERIMENTS.md, "Shots in rounds").
pub const DEFAULT_ROUND: f64 = 0.7;

impl Default for AdaptiveSettings {
    fn default() -> Self {
        AdaptiveSettings {
            tolerance: DEFAULT_TOLERANCE,
            overshoot: DEFAULT_OVERSHOOT,
            round: DEFAULT_ROUND,
        }
    }
}

/// `--overshoot`.
const OVERSHOOT: Parameter = Parameter {
    name: "overshoot",
    value_name: "FACTOR",
    help: "Overshooting (Feda & Purgathofer 1992): a shooter also sends FACTOR times its \
           reflectance times the ambient irradiance of the power still unshot elsewhere, which \
           leaves it negative unshot radiosity that a later shot sends back; fewer shots to \
           converge. 0 (the default) is off",
    kind: Kind::Number,
};

/// `--round`.
const ROUND: Parameter = Parameter {
    name: "round",
    value_name: "FRACTION",
    help: "Shots in rounds: with the brightest shooter, every shooter whose unshot power is more \
           than FRACTION of its shoots in the same round, each sending what it held when the \
           round began (fewer, larger steps for a parallel device). 1 shoots the brightest \
           alone, as the paper's loop",
    kind: Kind::Number,
};

/// `--tolerance`.
const TOLERANCE: Parameter = Parameter {
    name: "tolerance",
    value_name: "FRACTION",
    help: "Adaptive shooting's accuracy: a receiver takes a part of a shooter as one source \
           when the irradiance it can send is below this fraction of the scene's mean radiosity \
           (default 1e-3)",
    kind: Kind::Number,
};

/// Settings adaptive shooting cannot run with.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AdaptiveSettingsError {
    /// Tolerance outside (0, 1].
    #[error("--tolerance must be a fraction in (0, 1], not {0}")]
    Tolerance(f64),
    /// Overshoot outside [0, 2].
    #[error("--overshoot must be a factor in [0, 2], not {0}")]
    Overshoot(f64),
    /// Round fraction outside (0, 1].
    #[error("--round must be a fraction in (0, 1], not {0}")]
    Round(f64),
    /// The hemicube pre-test asked of adaptive shooting.
    #[error(
        "the hemicube pre-test places a hemicube at each subsource of a patch: use it with \
         --shooting patches (adaptive shooting picks its sources per receiver)"
    )]
    Pretest,
}

impl Method for AdaptiveSettings {
    /// Its tolerance, and visibility, which is rays only: it takes
    /// `--visibility ray` and refuses the pre-test.
    fn parameters(&self) -> &'static [Parameter] {
        &[TOLERANCE, OVERSHOOT, ROUND, VISIBILITY]
    }

    fn set(&mut self, name: &str, value: &Value) -> Result<(), SetError> {
        match name {
            "tolerance" => self.tolerance = value.number(name)?,
            "overshoot" => self.overshoot = value.number(name)?,
            "round" => self.round = value.number(name)?,
            "visibility" => match value.choice(name)? {
                Visibility::Ray => {}
                Visibility::HemicubePretest => {
                    return Err(SetError::Refused(MethodError::new(
                        AdaptiveSettingsError::Pretest,
                    )));
                }
            },
            _ => return Err(SetError::NotMine),
        }
        Ok(())
    }

    fn values(&self) -> Vec<(&'static str, serde_json::Value)> {
        vec![
            ("tolerance", self.tolerance.into()),
            ("overshoot", self.overshoot.into()),
            ("round", self.round.into()),
            ("visibility", Visibility::Ray.name().into()),
        ]
    }

    fn validate(&self) -> Result<(), MethodError> {
        if !(self.tolerance.is_finite() && self.tolerance > 0.0 && self.tolerance <= 1.0) {
            return Err(MethodError::new(AdaptiveSettingsError::Tolerance(
                self.tolerance,
            )));
        }
        if !(0.0..=2.0).contains(&self.overshoot) {
            return Err(MethodError::new(AdaptiveSettingsError::Overshoot(
                self.overshoot,
            )));
        }
        if !(self.round > 0.0 && self.round <= 1.0) {
            return Err(MethodError::new(AdaptiveSettingsError::Round(self.round)));
        }
        Ok(())
    }

    fn zero_counters(&self) -> Vec<(&'static str, Counter)> {
        Counters::default().list()
    }

    fn memory(&self) -> costs::SolverCosts {
        // Measured on the shared scenes (EXPERIMENTS.md, "Memory"), plus
        // 24 bytes an element for the buffer each pass sends from.
        costs::SolverCosts {
            vertex: 104.0,
            element: 294.0,
            surface: 400.0,
            parts: Vec::new(),
        }
    }

    fn start<'a>(
        &self,
        scene: &'a Scene,
        mesh: &'a Mesh,
        settings: &Settings,
        receivers: &[Receiver],
    ) -> Box<dyn Shooter + 'a> {
        Box::new(AdaptiveShooting::new(
            scene, mesh, settings, self, receivers,
        ))
    }
}

/// A far node is accepted with one shadow ray a bin while the irradiance
/// it can send is below this many times the negligible irradiance.
pub const FAR_FACTOR: f64 = 30.0;

/// Receiver groups at least this large check whether the shot is to be
/// abandoned before they are refined.
pub(super) const ABORT_CHECK_RECEIVERS: u32 = 64;

/// Receiver groups at least this large are refined in parallel.
pub(super) const PARALLEL_RECEIVERS: u32 = 1024;

/// The state of adaptive shooting.
struct AdaptiveShooting {
    hierarchy: Hierarchy,
    /// The receivers' tree (vertices, then sensors).
    receiver_tree: Tree,
    /// Unshot radiosity of each element (negative where overshooting sent
    /// more than had arrived).
    unshot: Vec<DVec3>,
    /// `--overshoot`.
    overshoot: f64,
    /// `--round`.
    round: f64,
    /// What the shooter's elements send in the current pass, zero
    /// elsewhere ([`overshoot`]).
    sending: Vec<DVec3>,
    /// The elements whose emission is still unshot.
    emission: Emission,
    /// Unshot power (luminance, its magnitude element by element) of each
    /// shooter.
    shooter_power: Vec<f64>,
    /// Irradiance (luminance, W/m^2) a source may send and still be
    /// accepted whole, for a receiver with no more than the scene's mean
    /// radiosity: the tolerance times that mean.
    /// `--tolerance`.
    tolerance: f64,
    /// Luminance-weighted power brought into the scene so far: the
    /// emitters', and each light's once it has shot.
    power: f64,
    /// Mean radiosity per watt of `power` (the ambient term's estimate).
    per_watt: f64,
    negligible: f64,
    /// The scene's mean radiosity, estimated (luminance).
    mean_radiosity: f64,
    /// The current shot's sources.
    sources: Sources,
    /// What the shots so far did.
    counters: Counters,
    /// The device the transfers run on, `None` for the CPU (or after it
    /// failed).
    device: Option<Box<dyn AdaptiveTransfers>>,
    /// Where the shots ran.
    report: DeviceReport,
    /// The state the device took over, once it has.
    resident: Option<resident::Resident>,
    /// Set when the device failed in a shot, until the loop asks.
    rolled_back: bool,
    /// Its shots so far, kept when the solve may refine its mesh and
    /// replay them to the new vertices ([`replay`]).
    record: Option<Vec<replay::Recorded>>,
    /// The shooters' powers are to be recomputed (after a device's
    /// failure restored the unshot radiosity).
    stale_powers: bool,
}

impl AdaptiveShooting {
    /// Unshot radiosity `E` on every element; the trees over the mesh and
    /// the receivers.
    fn new(
        scene: &Scene,
        mesh: &Mesh,
        settings: &Settings,
        method: &AdaptiveSettings,
        receivers: &[Receiver],
    ) -> AdaptiveShooting {
        let tolerance = method.tolerance;
        let hierarchy = Hierarchy::build(scene, mesh, settings.mesh.patch_size);
        let receiver_tree = hierarchy::receiver_tree(receivers, settings.mesh.patch_size);
        let unshot: Vec<DVec3> = mesh
            .elements
            .iter()
            .map(|e| scene.surfaces[e.surface as usize].emission)
            .collect();
        // The mean radiosity of the converged solution, estimated from the
        // emitted power and the mean reflectance as the ambient term is.
        let (mut area, mut power, mut rho) = (0.0, 0.0, 0.0);
        for (e, u) in mesh.elements.iter().zip(&unshot) {
            area += e.area;
            power += luminance(*u) * e.area;
            rho += luminance(scene.surfaces[e.surface as usize].rho) * e.area;
        }
        // Radiosity per watt of luminance-weighted power brought in.
        let per_watt = if area > 0.0 {
            1.0 / area / (1.0 - rho / area).max(1e-3)
        } else {
            0.0
        };
        let mean_radiosity = power * per_watt;
        let mut shooting = AdaptiveShooting {
            shooter_power: vec![0.0; hierarchy.shooters.len()],
            emission: Emission::new(scene, mesh.elements.len(), |i| mesh.elements[i].surface),
            hierarchy,
            receiver_tree,
            sending: vec![DVec3::ZERO; unshot.len()],
            unshot,
            overshoot: method.overshoot,
            round: method.round,
            tolerance,
            power,
            per_watt,
            negligible: tolerance * mean_radiosity,
            mean_radiosity: mean_radiosity.max(f64::MIN_POSITIVE),
            sources: Sources::default(),
            counters: Counters::default(),
            device: None,
            report: DeviceReport::default(),
            resident: None,
            rolled_back: false,
            record: None,
            stale_powers: false,
        };
        if let Some(backend) = settings.device.get() {
            shooting.report.name = Some(backend.name());
            let solve = AdaptiveSolve {
                scene,
                mesh,
                hierarchy: &shooting.hierarchy,
                receivers,
                order: &shooting.receiver_tree.items,
                round: method.round,
            };
            match backend.adaptive(&solve) {
                Ok(device) => {
                    shooting.report.kernels = device.kernels();
                    shooting.device = Some(device);
                }
                Err(e) => shooting.report.fault = Some(e.0),
            }
        }
        shooting.total_shooter_power(mesh);
        shooting
    }

    /// The emission of the elements under `root` not shot yet, which its
    /// shot now sends.
    fn take_emission(&mut self, scene: &Scene, mesh: &Mesh, root: u32) -> DVec3 {
        let items = self.hierarchy.tree.items_of(root);
        let emission = &mut self.emission;
        emission.take(
            scene,
            items.iter().map(|&e| {
                let element = &mesh.elements[e as usize];
                (e as usize, element.surface, element.area)
            }),
        )
    }

    fn total_shooter_power(&mut self, mesh: &Mesh) {
        self.shooter_power.fill(0.0);
        for ((e, u), s) in mesh
            .elements
            .iter()
            .zip(&self.unshot)
            .zip(&self.hierarchy.shooter_of)
        {
            self.shooter_power[*s as usize] += luminance(*u).abs() * e.area;
        }
    }

    /// The negligible irradiance of each receiver-tree node: the smallest
    /// of its receivers', each the tolerance times what it has gathered (or
    /// the scene's mean radiosity, if more). A receiver that has gathered
    /// much takes a dim source's small errors in its stride.
    fn receiver_negligible(&self, irradiance: &[DVec3]) -> Vec<f64> {
        receiver_negligible(
            &self.receiver_tree,
            self.negligible,
            self.mean_radiosity,
            irradiance,
        )
    }
}

/// The negligible irradiance of each node of `tree` (over receivers
/// that have gathered `irradiance`), for a scene whose negligible
/// irradiance is `negligible` at its mean radiosity `mean_radiosity`
/// ([`AdaptiveShooting::receiver_negligible`]).
fn receiver_negligible(
    tree: &Tree,
    negligible: f64,
    mean_radiosity: f64,
    irradiance: &[DVec3],
) -> Vec<f64> {
    let mut out = vec![0.0; tree.nodes.len()];
    if !out.is_empty() {
        let leaf = |r: usize| negligible * (luminance(irradiance[r]) / mean_radiosity).max(1.0);
        subtree_negligible(tree, 0, &mut out, &leaf);
    }
    out
}

/// Fills `out`, the entries of the nodes of node `n`'s subtree (which
/// are `n..n + out.len()`, the tree being depth first), with their
/// negligible irradiance, the smallest of their receivers' (`leaf`);
/// returns node `n`'s. Large subtrees in parallel: it runs before every
/// shot's transfers, which wait for it.
fn subtree_negligible(
    tree: &Tree,
    n: usize,
    out: &mut [f64],
    leaf: &(impl Fn(usize) -> f64 + Sync),
) -> f64 {
    let node = &tree.nodes[n];
    let value = if node.is_leaf() {
        leaf(tree.items[node.first as usize] as usize)
    } else {
        let second = node.second as usize;
        let (left, right) = out[1..].split_at_mut(second - n - 1);
        let (a, b) = if node.last - node.first >= PARALLEL_RECEIVERS {
            rayon::join(
                || subtree_negligible(tree, n + 1, left, leaf),
                || subtree_negligible(tree, second, right, leaf),
            )
        } else {
            (
                subtree_negligible(tree, n + 1, left, leaf),
                subtree_negligible(tree, second, right, leaf),
            )
        };
        a.min(b)
    };
    out[0] = value;
    value
}

impl AdaptiveShooting {
    /// The transfers from `root` (its elements sending `unshot`, its
    /// sources prepared) to `inputs.receivers`, over their tree `tree`
    /// whose nodes' negligible irradiance is `negligible`; `None` when
    /// abandoned.
    fn gather_to(
        &self,
        inputs: &ShotInputs<'_>,
        root: u32,
        unshot: &[DVec3],
        tree: &Tree,
        negligible: &[f64],
    ) -> Option<(Vec<DVec3>, Counters)> {
        let gatherer = Gatherer {
            transfer: Transfer {
                scene: inputs.scene,
                mesh: inputs.mesh,
                hierarchy: &self.hierarchy,
                unshot,
                sources: &self.sources,
                root,
                origin: self.hierarchy.tree.nodes[root as usize].centre,
                occluder: inputs.occluder,
                form_factor: inputs.settings.form_factor,
            },
            receiver_tree: tree,
            receivers: inputs.receivers,
            negligible,
            abort: inputs.abort,
        };
        // Irradiance in the receiver tree's order, then put back in order.
        let mut gathered = vec![DVec3::ZERO; inputs.receivers.len()];
        let counters = if gathered.is_empty() {
            Counters::default()
        } else {
            gatherer.refine(root, 0, &mut gathered)
        };
        if inputs.abort.fired() {
            return None;
        }
        let mut irradiance = vec![DVec3::ZERO; inputs.receivers.len()];
        for (&r, e) in tree.items.iter().zip(gathered) {
            irradiance[r as usize] = e;
        }
        Some((irradiance, counters))
    }
}

impl AdaptiveShooting {
    /// `sum unshot_e A_e` over the elements (in magnitude, `|unshot_e|`,
    /// when `magnitude`), or the device's sum while it holds the state.
    fn unshot_sum(&self, mesh: &Mesh, magnitude: bool) -> DVec3 {
        if let Some(r) = self.resident.as_ref() {
            return if magnitude {
                r.unshot_magnitude
            } else {
                r.unshot_power
            };
        }
        mesh.elements
            .iter()
            .zip(&self.unshot)
            .map(|(e, u)| (if magnitude { u.abs() } else { *u }) * e.area)
            .sum()
    }
}

impl Shooter for AdaptiveShooting {
    fn shooters(&self) -> usize {
        self.hierarchy.shooters.len()
    }

    fn unshot_power(&self, mesh: &Mesh) -> DVec3 {
        self.unshot_sum(mesh, false)
    }

    /// Element by element, so overshooting's negative unshot power does
    /// not cancel positive power still to be shot elsewhere.
    fn unshot_magnitude(&self, mesh: &Mesh) -> DVec3 {
        self.unshot_sum(mesh, true)
    }

    /// One round ([`round`]): each shooter's elements' unshot radiosity
    /// and overshoot ([`overshoot`]), in a pass per sign; what they leave
    /// is minus the overshoot (zero without).
    fn shoot(&mut self, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Option<Shot> {
        if self.device.is_some() {
            return self.shoot_on_device(inputs, stats);
        }
        self.shoot_round(inputs, stats)
    }

    /// Adds the reflected part of what the elements received to their
    /// unshot radiosity.
    fn receive(
        &mut self,
        scene: &Scene,
        mesh: &Mesh,
        irradiance: &[DVec3],
        element_means: Option<&[DVec3]>,
    ) -> Received {
        let unshot = &mut self.unshot;
        let received =
            method::receive_at_elements(scene, mesh, irradiance, element_means, |e, radiosity| {
                unshot[e] += radiosity;
            });
        self.total_shooter_power(mesh);
        received
    }

    fn counters(&self) -> Vec<(&'static str, Counter)> {
        self.counters.list()
    }

    fn device(&self) -> DeviceReport {
        self.report.clone()
    }

    fn checkpoint(&mut self, irradiance: &mut [DVec3], direct: &mut [DVec3]) -> Checkpoint {
        self.checkpoint_device(irradiance, direct)
    }

    fn rolled_back(&mut self) -> bool {
        std::mem::take(&mut self.rolled_back)
    }

    fn record_shots(&mut self) -> bool {
        self.record = Some(Vec::new());
        true
    }

    fn replay(&mut self, inputs: &ShotInputs<'_>, shot: usize) -> Option<Replayed> {
        self.replay_shot(inputs, shot)
    }

    fn element_state(&self) -> Option<ElementState> {
        Some(ElementState {
            unshot: self.unshot.clone(),
            emission_pending: self.emission.pending().to_vec(),
            power: self.power,
        })
    }

    fn resume(&mut self, mesh: &Mesh, state: ElementState) {
        self.unshot = state.unshot;
        self.emission = Emission::from_pending(state.emission_pending);
        self.power = state.power;
        let mean_radiosity = self.power * self.per_watt;
        self.negligible = self.tolerance * mean_radiosity;
        self.mean_radiosity = mean_radiosity.max(f64::MIN_POSITIVE);
        self.total_shooter_power(mesh);
    }

    /// A light's power counts towards the mean radiosity the tolerance
    /// scales with, as the emitters' does (a scene lit by lights alone
    /// would otherwise have a tolerance of zero).
    fn light_received(&mut self, power: DVec3) {
        self.power += luminance(power);
        let mean_radiosity = self.power * self.per_watt;
        self.negligible = self.tolerance * mean_radiosity;
        self.mean_radiosity = mean_radiosity.max(f64::MIN_POSITIVE);
    }
}

#[cfg(test)]
mod tests;
