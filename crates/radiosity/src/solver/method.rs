//! The seam between the shooting loop and a way of solving (a *method*),
//! after pbrt's integrators and Mitsuba's plugins: the loop of design.md
//! section 2 (choose, shoot, gather, book-keep, stop) is the same for every
//! method; what a shooter is, how it sends its unshot radiosity to the
//! receivers and how their reflected light becomes unshot again is the
//! method's.
//!
//! A method is two things:
//!
//! * its **settings** ([`Method`]): a type of its own holding only the
//!   parameters it reads, which it declares ([`Parameter`]), parses
//!   ([`Method::set`]), checks, reports for the statistics file and costs
//!   in memory; the registry ([`super::registry`]) lists the methods;
//! * its **state during a solve** ([`Shooter`]), started from the settings:
//!   the unshot radiosity it keeps and the shots it makes, each returning
//!   the irradiance gathered at every receiver ([`Shot`]), plus the
//!   counters only it keeps ([`Counter`]).
//!
//! The loop ([`super::Solver`]) owns what every method shares: the
//! receivers, their irradiance and radiosity, the energy ledger, the shared
//! counters ([`Stats`]) and the stopping rules.

use std::time::Duration;

use glam::DVec3;

use super::{Abort, Receiver, Settings};
use crate::accel::Occluder;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::costs;

/// A way of solving, as its settings: what the registry lists and a
/// [`Settings`] carries.
pub trait Method: std::fmt::Debug + Send + Sync {
    /// The parameters it takes, in the order a command line lists them.
    fn parameters(&self) -> &'static [Parameter];

    /// Sets the parameter named `name` (a [`Parameter::name`]) from a
    /// front end's value; [`SetError::NotMine`] for a parameter it does not
    /// take. Values are checked by [`Method::validate`], not here, so a
    /// preset and a command line are checked alike.
    fn set(&mut self, name: &str, value: &Value) -> Result<(), SetError>;

    /// Its parameters' values, named as in [`Method::parameters`], for the
    /// statistics file.
    fn values(&self) -> Vec<(&'static str, serde_json::Value)>;

    /// Checks the values a user can get wrong.
    fn validate(&self) -> Result<(), MethodError>;

    /// The counters its solves keep beside the shared [`Stats`], all zero:
    /// their names and kinds, for a statistics file that lists every
    /// method's counters.
    fn zero_counters(&self) -> Vec<(&'static str, Counter)>;

    /// Its own memory, measured per item and in lumps ([`crate::memory::estimate`]
    /// adds the shared parts).
    fn memory(&self) -> costs::SolverCosts;

    /// Starts a solve of `scene` meshed as `mesh`, gathering at `receivers`
    /// (the mesh's vertices, then any sensors): unshot radiosity is the
    /// emission.
    fn start<'a>(
        &self,
        scene: &'a Scene,
        mesh: &'a Mesh,
        settings: &Settings,
        receivers: &[Receiver],
    ) -> Box<dyn Shooter + 'a>;
}

/// A method's state during a solve.
pub trait Shooter: Send {
    /// Its shooting units: how many there are.
    fn shooters(&self) -> usize;

    /// Unshot power left, per channel (W): the sum the energy ledger
    /// balances, where negative power (overshooting's) offsets positive.
    fn unshot_power(&self, mesh: &Mesh) -> DVec3;

    /// Unshot power left in magnitude, per channel (W): each shooting
    /// unit's counted as positive, what the stopping rule compares
    /// ([`super::Solver::unshot_fraction`]). The same as
    /// [`Shooter::unshot_power`] for a method whose unshot power is never
    /// negative.
    fn unshot_magnitude(&self, mesh: &Mesh) -> DVec3 {
        self.unshot_power(mesh)
    }

    /// One shot: the shooter it chooses sends its unshot radiosity to every
    /// receiver. Returns `None`, having changed nothing, when
    /// [`ShotInputs::abort`] fires during it.
    fn shoot(&mut self, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Option<Shot>;

    /// Takes the reflected part of what the mesh's vertices gathered in a
    /// shot (`irradiance`, one per vertex) as unshot radiosity; returns the
    /// power received and absorbed. `element_means`, when a shot knows
    /// them better than its elements' corners do (a light's shot across a
    /// shadow edge), is each element's mean irradiance.
    fn receive(
        &mut self,
        scene: &Scene,
        mesh: &Mesh,
        irradiance: &[DVec3],
        element_means: Option<&[DVec3]>,
    ) -> Received;

    /// Its own counters so far (the names of [`Method::zero_counters`]).
    fn counters(&self) -> Vec<(&'static str, Counter)>;

    /// Told, after a light that is not a surface has shot (before any of
    /// its own shots), the power that light brought to the elements: a
    /// method whose tolerances scale with the scene's emitted power counts
    /// it in. Nothing by default.
    fn light_received(&mut self, _power: DVec3) {}

    /// For a method whose state lives on a device: reads it back, its own
    /// into its host copy and each receiver's irradiance into
    /// `irradiance` (its direct part into `direct`), a checkpoint the
    /// solve can go back to.
    fn checkpoint(&mut self, _irradiance: &mut [DVec3], _direct: &mut [DVec3]) -> Checkpoint {
        Checkpoint::Host
    }

    /// True, once, after its device failed in a shot (which
    /// [`Shooter::shoot`] then answered with `None`): it is back at its last
    /// checkpoint, on the CPU, and the loop must go back there too.
    fn rolled_back(&mut self) -> bool {
        false
    }

    /// Where its shots' transfers ran: the CPU by default.
    fn device(&self) -> super::device::DeviceReport {
        super::device::DeviceReport::default()
    }

    /// Starts keeping its shots, so that they can be replayed to
    /// receivers added later ([`Shooter::replay`]: the vertices of a mesh
    /// refined during the solve); called before its first shot. False
    /// for a method that cannot (the default): its solve then refines by
    /// solving again from the start.
    fn record_shots(&mut self) -> bool {
        false
    }

    /// Its kept round `shot` (its own rounds counted from 0) sent again
    /// to `inputs.receivers`, which have gathered `inputs.irradiance` from
    /// the rounds before it: what they would have gathered from it had
    /// they been there then, and of that the direct part (as
    /// [`Shot::direct`]). `None` when abandoned or not kept.
    fn replay(&mut self, _inputs: &ShotInputs<'_>, _shot: usize) -> Option<Replayed> {
        None
    }

    /// Its state, element by element, for a solve that goes on on a
    /// refined mesh (the host's copy: a checkpoint reads a device's back);
    /// `None` for a method that keeps none (the default).
    fn element_state(&self) -> Option<ElementState> {
        None
    }

    /// Takes `state` (one entry per element of its mesh) in place of the
    /// fresh start's, before its first shot. Nothing by default.
    fn resume(&mut self, _mesh: &Mesh, _state: ElementState) {}
}

/// A method's state per element ([`Shooter::element_state`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ElementState {
    /// Unshot radiosity (W/m^2 per channel).
    pub unshot: Vec<DVec3>,
    /// Whether the element's emission is still to be shot.
    pub emission_pending: Vec<bool>,
    /// Luminance-weighted power brought into the scene so far (the
    /// emitters', and each light's once shot), which tolerances scale
    /// with.
    pub power: f64,
}

/// A parameter a method takes, as a front end offers it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Parameter {
    /// Its name in the statistics file (`hemicube_resolution`); the flag is
    /// the name with dashes (`--hemicube-resolution`).
    pub name: &'static str,
    /// What its value is called in help (`N`, `FRACTION`).
    pub value_name: &'static str,
    /// One paragraph of help.
    pub help: &'static str,
    /// What values it takes.
    pub kind: Kind,
}

impl Parameter {
    /// The command-line flag, without its dashes ([`flag`]).
    #[must_use]
    pub fn flag(&self) -> String {
        flag(self.name)
    }
}

/// The command-line flag of a parameter name, without its dashes: the name
/// with `-` for `_`.
#[must_use]
pub fn flag(name: &str) -> String {
    name.replace('_', "-")
}

/// The values a parameter takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// An integer, 1 or more ([`Value::Count`]).
    Count,
    /// A real number ([`Value::Number`]).
    Number,
    /// One of these names ([`Value::Choice`]).
    Choice(&'static [&'static str]),
}

/// A parameter's value from a front end.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// For [`Kind::Count`].
    Count(u64),
    /// For [`Kind::Number`].
    Number(f64),
    /// For [`Kind::Choice`]: one of its names.
    Choice(String),
}

/// Why [`Method::set`] did not take a value.
#[derive(Clone, Debug, PartialEq)]
pub enum SetError {
    /// The method has no parameter of that name.
    NotMine,
    /// A value of the wrong kind, or one the method refuses outright.
    Refused(MethodError),
}

/// A method's settings error: its own typed error, whose message names
/// the flag to change.
#[derive(Clone, Debug, thiserror::Error)]
#[error("{0}")]
pub struct MethodError(pub std::sync::Arc<dyn std::error::Error + Send + Sync>);

impl MethodError {
    /// Wraps a method's own error.
    pub fn new(error: impl std::error::Error + Send + Sync + 'static) -> MethodError {
        MethodError(std::sync::Arc::new(error))
    }
}

/// Errors are equal when they say the same.
impl PartialEq for MethodError {
    fn eq(&self, other: &MethodError) -> bool {
        self.0.to_string() == other.0.to_string()
    }
}

/// A value of the wrong kind for a parameter.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("--{flag} takes {kind}")]
pub struct WrongKind {
    /// The parameter's flag, without dashes.
    pub flag: String,
    /// What it takes.
    pub kind: &'static str,
}

/// One of a method's own counters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Counter {
    /// A count.
    Count(u64),
    /// A time, written in seconds.
    Seconds(Duration),
}

impl Counter {
    /// The count, if it is one.
    #[must_use]
    pub fn count(self) -> Option<u64> {
        match self {
            Counter::Count(n) => Some(n),
            Counter::Seconds(_) => None,
        }
    }

    /// The counter as JSON: an integer, or seconds.
    #[must_use]
    pub fn json(self) -> serde_json::Value {
        match self {
            Counter::Count(n) => n.into(),
            Counter::Seconds(t) => t.as_secs_f64().into(),
        }
    }
}

/// Counters and timings every method keeps. Serialised as the `--stats`
/// file's counters, the times in seconds under the names given below.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Stats {
    /// Shooters shot (a light counts as one).
    pub shots: u64,
    /// Rounds: the loop's steps, each a light's shot or a method's round
    /// of one or more shooters shot together ([`Shot::shooters`]).
    pub rounds: u64,
    /// The method's finest sources shot: a patch's subsources, or adaptive
    /// shooting's elements (`--max-subsources` counts them).
    pub subsources: u64,
    /// Receiver-source pairs considered: a receiver and a source that face
    /// each other, whether or not a ray was then needed.
    pub pairs: u64,
    /// Shadow segments traced.
    pub rays_cast: u64,
    /// Openings a sky's light was sampled through ([`super::sky`]): found
    /// in the geometry, marked, and glass panes.
    pub sky_portals: u64,
    /// Wall time gathering at receivers (the three phases below, in
    /// parallel).
    #[serde(rename = "gather_seconds", serialize_with = "super::seconds")]
    pub gather_time: Duration,
    /// Thread time choosing each receiver's sources (summed over threads):
    /// pairing and the pre-test for patches, refinement for adaptive
    /// shooting.
    #[serde(rename = "pretest_thread_seconds", serialize_with = "super::seconds")]
    pub pretest_time: Duration,
    /// Thread time casting shadow rays (summed over threads).
    #[serde(rename = "ray_thread_seconds", serialize_with = "super::seconds")]
    pub ray_time: Duration,
    /// Thread time evaluating form factors (summed over threads).
    #[serde(
        rename = "form_factor_thread_seconds",
        serialize_with = "super::seconds"
    )]
    pub form_factor_time: Duration,
    /// Time in book-keeping (selection, element and shooter updates).
    #[serde(rename = "bookkeeping_seconds", serialize_with = "super::seconds")]
    pub bookkeeping_time: Duration,
}

impl Stats {
    /// Books a shot's gathering on the CPU: what its transfers `cost`, the
    /// wall time `gathering` they took on every thread (what the rays and
    /// factors did not take was the refinement's), and its `subsources`.
    pub(crate) fn book_gathering(
        &mut self,
        cost: &super::hierarchy::transfer::Cost,
        gathering: Duration,
        subsources: u64,
    ) {
        self.pairs += cost.pairs;
        self.rays_cast += cost.rays;
        self.ray_time += cost.ray_time;
        self.form_factor_time += cost.form_factor_time;
        self.pretest_time += gathering
            .mul_f64(rayon::current_num_threads() as f64)
            .saturating_sub(cost.ray_time + cost.form_factor_time);
        self.subsources += subsources;
        self.gather_time += gathering;
    }
}

/// What a shot reads.
pub struct ShotInputs<'s> {
    /// The scene.
    pub scene: &'s Scene,
    /// Its mesh.
    pub mesh: &'s Mesh,
    /// The settings every method shares.
    pub settings: &'s Settings,
    /// Shadow segments.
    pub occluder: &'s dyn Occluder,
    /// Where light is gathered: the mesh's vertices, then any sensors.
    pub receivers: &'s [Receiver],
    /// Irradiance each receiver has gathered so far.
    pub irradiance: &'s [DVec3],
    /// Of it, the direct part ([`crate::solver::Solver::direct_irradiance`];
    /// empty where the shot needs none).
    pub direct: &'s [DVec3],
    /// When to abandon the shot.
    pub abort: &'s Abort,
}

/// What a shot produced: the irradiance each receiver gathered and the
/// power that left the shooter (or, for a round, the shooters).
pub struct Shot {
    /// One per receiver, in the order of [`ShotInputs::receivers`].
    pub irradiance: Vec<DVec3>,
    /// Of `irradiance`, the part that is direct light: each shooter's own
    /// emission sent for the first time ([`Emission::take`]), its share of
    /// what the shooter sent, per channel, times what the shooter gave the
    /// receiver; the loop books it apart
    /// ([`super::Solver::direct_irradiance`]). Empty when none.
    pub direct: Vec<DVec3>,
    /// Power shot, per channel (W).
    pub power: DVec3,
    /// Of `power`, the emitting surfaces' own emission shot for the first
    /// time.
    pub emitted: DVec3,
    /// Shooters shot together in it: 1, or a round's ([`Stats::rounds`]).
    pub shooters: u64,
    /// Time spent choosing the shooter, for [`Stats::bookkeeping_time`].
    pub selection_time: Duration,
    /// Set by a method whose state lives on a device, which booked the
    /// shot there (its direct part included): the power the elements
    /// received and absorbed. [`Shot::irradiance`] is then empty and
    /// [`Shooter::receive`] is not called.
    pub booked: Option<Received>,
}

impl Shot {
    /// One shooter's shot, booked on the host: `irradiance` from `power`,
    /// of which `emitted` was emission shot for the first time (its share
    /// of the irradiance is the direct part).
    #[must_use]
    pub fn single(
        irradiance: Vec<DVec3>,
        power: DVec3,
        emitted: DVec3,
        selection_time: Duration,
    ) -> Shot {
        let mut direct = Vec::new();
        add_direct(&mut direct, &irradiance, emission_share(emitted, power));
        Shot {
            irradiance,
            direct,
            power,
            emitted,
            shooters: 1,
            selection_time,
            booked: None,
        }
    }
}

/// Adds `irradiance` times `share` to `direct` (empty until some share is
/// not zero).
pub fn add_direct(direct: &mut Vec<DVec3>, irradiance: &[DVec3], share: DVec3) {
    if share == DVec3::ZERO {
        return;
    }
    if direct.is_empty() {
        direct.resize(irradiance.len(), DVec3::ZERO);
    }
    for (d, e) in direct.iter_mut().zip(irradiance) {
        *d += *e * share;
    }
}

/// The share of a shot's power that was emission, per channel (zero where
/// it sent none).
#[must_use]
pub fn emission_share(emitted: DVec3, power: DVec3) -> DVec3 {
    let share = emitted / power;
    DVec3::select(share.is_finite_mask(), share, DVec3::ZERO)
}

/// What a kept round gave the receivers it was replayed to
/// ([`Shooter::replay`]).
pub struct Replayed {
    /// Irradiance, one per receiver.
    pub irradiance: Vec<DVec3>,
    /// Of it, the direct part (empty when none).
    pub direct: Vec<DVec3>,
}

/// Which elements (or patches) still hold their surface's emission unshot:
/// every method's shooters start with it and shoot it whole in their first
/// shot, the part of a shot that is direct light.
#[derive(Clone, Debug, Default)]
pub struct Emission {
    pending: Vec<bool>,
}

impl Emission {
    /// Pending as `pending` says, unit by unit.
    #[must_use]
    pub fn from_pending(pending: Vec<bool>) -> Emission {
        Emission { pending }
    }

    /// Whether each unit's emission is still pending.
    #[must_use]
    pub fn pending(&self) -> &[bool] {
        &self.pending
    }

    /// Every unit whose surface emits, pending; `surface(i)` is unit `i`'s
    /// surface.
    #[must_use]
    pub fn new(scene: &Scene, units: usize, surface: impl Fn(usize) -> u32) -> Emission {
        Emission {
            pending: (0..units)
                .map(|i| scene.surfaces[surface(i) as usize].is_emitter())
                .collect(),
        }
    }

    /// The emission power of `units` (unit, its surface, its area) still
    /// pending, left pending ([`Emission::take`] takes it).
    #[must_use]
    pub fn pending_power(
        &self,
        scene: &Scene,
        units: impl Iterator<Item = (usize, u32, f64)>,
    ) -> DVec3 {
        units
            .filter(|&(i, _, _)| self.pending[i])
            .map(|(_, surface, area)| scene.surfaces[surface as usize].emission * area)
            .sum()
    }

    /// The emission power of `units` (unit, its surface, its area) still
    /// pending, which are now shot.
    pub fn take(&mut self, scene: &Scene, units: impl Iterator<Item = (usize, u32, f64)>) -> DVec3 {
        let mut power = DVec3::ZERO;
        for (i, surface, area) in units {
            if std::mem::take(&mut self.pending[i]) {
                power += scene.surfaces[surface as usize].emission * area;
            }
        }
        power
    }
}

/// What became of a checkpoint ([`Shooter::checkpoint`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Checkpoint {
    /// The method keeps its state on the host: nothing to read back.
    Host,
    /// The device's state was read back: the receivers' irradiance and the
    /// method's own.
    Taken,
    /// The device failed: the method is back at its last checkpoint, on
    /// the CPU, and the loop must go back there too.
    RolledBack,
}

/// Power arriving at the receiving elements in one shot.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Received {
    /// Arriving (W per channel).
    pub incident: DVec3,
    /// Absorbed: `(1 - rho)` of it.
    pub absorbed: DVec3,
}

/// Incident power on each element from its corners' irradiance (their
/// mean, times its area; or the element's own mean from `element_means`),
/// added as reflected unshot radiosity through `reflect(element, rho *
/// mean)`; returns the power received and absorbed. The book-keeping of
/// design.md section 2, step 5, for any method that keeps unshot radiosity
/// on elements or their patches.
pub fn receive_at_elements(
    scene: &Scene,
    mesh: &Mesh,
    irradiance: &[DVec3],
    element_means: Option<&[DVec3]>,
    mut reflect: impl FnMut(usize, DVec3),
) -> Received {
    let mut incident = DVec3::ZERO;
    let mut absorbed = DVec3::ZERO;
    for (i, e) in mesh.elements.iter().enumerate() {
        let corners = e.vertices();
        let mean = element_means.map_or_else(
            || {
                corners
                    .iter()
                    .map(|&c| irradiance[c as usize])
                    .sum::<DVec3>()
                    / corners.len() as f64
            },
            |means| means[i],
        );
        let rho = scene.surfaces[e.surface as usize].rho;
        incident += mean * e.area;
        absorbed += (DVec3::ONE - rho) * mean * e.area;
        reflect(i, rho * mean);
    }
    Received { incident, absorbed }
}

crate::choice::named_choice! {
    /// How a shot decides whether a receiver sees a source. A parameter of
    /// the methods that have a choice ([`VISIBILITY`]).
    pub enum Visibility: "visibility" {
        /// A shadow ray for every pair (Wallace et al. 1989).
        Ray = "ray",
        /// The hemicube item-buffer pre-test of Wong & Tsang, section 2;
        /// rays only where it cannot decide.
        HemicubePretest = "hemicube",
    }
}

/// The `visibility` parameter, as every method that takes it offers it.
pub const VISIBILITY: Parameter = Parameter {
    name: "visibility",
    value_name: "NAME",
    help: "Visibility: a ray for every pair, or the hemicube pre-test with rays only where it \
           cannot decide. Overrides the preset",
    kind: Kind::Choice(&Visibility::NAMES),
};

impl Value {
    /// A value as [`Method::values`] writes it: a string is a choice, an
    /// unsigned integer a count, any other number a number.
    #[must_use]
    pub fn from_json(value: &serde_json::Value) -> Value {
        match value {
            serde_json::Value::String(s) => Value::Choice(s.clone()),
            serde_json::Value::Number(n) => match n.as_u64() {
                Some(count) => Value::Count(count),
                None => Value::Number(n.as_f64().unwrap_or(f64::NAN)),
            },
            other => Value::Choice(other.to_string()),
        }
    }

    /// The count, or the error a method gives for a value of another kind.
    pub fn count(&self, name: &str) -> Result<u64, SetError> {
        match self {
            Value::Count(n) => Ok(*n),
            _ => Err(wrong_kind(name, "a positive integer")),
        }
    }

    /// The number (a count is one too).
    pub fn number(&self, name: &str) -> Result<f64, SetError> {
        match self {
            Value::Number(x) => Ok(*x),
            Value::Count(n) => Ok(*n as f64),
            Value::Choice(_) => Err(wrong_kind(name, "a number")),
        }
    }

    /// The choice named, parsed.
    pub fn choice<T: std::str::FromStr>(&self, name: &str) -> Result<T, SetError>
    where
        T::Err: std::fmt::Display,
    {
        match self {
            Value::Choice(text) => text.parse().map_err(|e: T::Err| {
                SetError::Refused(MethodError::new(UnknownValue(e.to_string())))
            }),
            _ => Err(wrong_kind(name, "a name")),
        }
    }
}

fn wrong_kind(name: &str, kind: &'static str) -> SetError {
    SetError::Refused(MethodError::new(WrongKind {
        flag: flag(name),
        kind,
    }))
}

/// A choice's value that names none of its choices.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct UnknownValue(pub String);
