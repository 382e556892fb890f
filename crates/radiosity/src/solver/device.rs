//! The seam between a method and the device its shots run on, beyond the
//! paper (whose shooting loop, Wallace, Elmquist & Haines 1989, ran on the
//! CPU). The loop's rules (stopping, the ledger, the lights first), the
//! choice of a round's shooters and the preparation of their sources stay
//! on the host, written once for both; a [`Backend`] (the GPU back end in
//! the `radiosity-gpu` crate) keeps the state that grows with the scene,
//! each receiver's irradiance and each element's unshot radiosity, and
//! makes each round's work there: every receiver's walk of each shooting
//! node's tree, the book-keeping of design.md section 2 step 5 once a
//! round, the sums of the ledger. A round sends the device its shooters'
//! sources, pass by pass ([`AdaptiveTransfers::send`]), and reads back
//! only the ledger's sums, the shooters' powers and the next round as the
//! device chose it ([`AdaptiveTransfers::book`]); the whole state comes
//! back at checkpoints (a few times a second, and at the end). The CPU is
//! the oracle the device is tested against.
//!
//! A solve names its device in [`super::Settings::device`]; the CPU when it
//! names none. A device that fails, at the start, in a shot or at a
//! checkpoint, is a fault to survive: the solve goes back to its last
//! checkpoint and carries on on the CPU, and says so once
//! ([`DeviceReport::fault`]).

use std::fmt;
use std::sync::Arc;
use std::time::Duration;

use glam::DVec3;

use super::hierarchy::Hierarchy;
use super::hierarchy::sources::Sources;
use super::method::Received;
use super::{Abort, Receiver};
use crate::mesh::Mesh;
use crate::scene::Scene;

/// A device that runs transfers.
pub trait Backend: Send + Sync {
    /// The device's name as a run reports it (an adapter's name and
    /// backend).
    fn name(&self) -> String;

    /// The setting, as its flag, among `settings` that this device does
    /// not run (`--shooting patches`, say); `None` when it runs them all.
    /// The back end decides, not the solver.
    fn refuses(&self, settings: &super::Settings) -> Option<String>;

    /// Starts adaptive shooting's transfers for one solve: what stays the
    /// same from shot to shot (the scene, the element tree, the receivers)
    /// goes to the device now.
    ///
    /// # Errors
    ///
    /// When the device cannot hold or run them.
    fn adaptive(
        &self,
        solve: &AdaptiveSolve<'_>,
    ) -> Result<Box<dyn AdaptiveTransfers>, DeviceError>;

    /// The memory, bytes, a solve of `mesh` with `receivers` receivers
    /// would take on the device; an error naming the limit when it is over
    /// one (the adapter's largest buffer, a cap the user set).
    ///
    /// # Errors
    ///
    /// When the solve would not fit.
    fn check(&self, scene: &Scene, mesh: &Mesh, receivers: usize) -> Result<u64, DeviceError>;

    /// The scene's surfaces on the device, to answer shadow segments many
    /// at a time: the lights' shots (made on the host, which draws their
    /// points and directions, as on the CPU) send it theirs.
    ///
    /// # Errors
    ///
    /// When the device cannot hold or run them.
    fn segments(&self, scene: &Scene) -> Result<Box<dyn Segments>, DeviceError>;
}

/// A shadow segment: is it crossed by a surface other than those of
/// `skip` (as [`crate::accel::Occluder::occluded`])?
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Start.
    pub from: DVec3,
    /// End.
    pub to: DVec3,
    /// Surface ids not to test.
    pub skip: [u32; 2],
}

/// Shadow segments answered many at a time, on a device.
pub trait Segments: Send + Sync {
    /// Whether each segment is blocked.
    ///
    /// # Errors
    ///
    /// When the device fails.
    fn occluded(&self, segments: &[Segment]) -> Result<Vec<bool>, DeviceError>;
}

/// What adaptive shooting's transfers keep for a whole solve.
pub struct AdaptiveSolve<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its mesh.
    pub mesh: &'a Mesh,
    /// The tree over the mesh's elements.
    pub hierarchy: &'a Hierarchy,
    /// The receivers (vertices, then sensors).
    pub receivers: &'a [Receiver],
    /// The receivers' order on the device (neighbours together): each
    /// receiver's index, in that order.
    pub order: &'a [u32],
    /// `--round`: a round takes, with the brightest shooter, those whose
    /// power is more than this fraction of its (the device chooses the
    /// next round by this rule, as the host does).
    pub round: f64,
}

/// Adaptive shooting on a device that keeps the solve's state: each
/// receiver's irradiance and each element's unshot radiosity stay there
/// from round to round. The host chooses each round's shooters from the
/// powers the device reports and prepares their sources; the device
/// gathers, books and reports the ledger's sums; the state comes back only
/// at checkpoints.
pub trait AdaptiveTransfers: Send {
    /// Takes over the solve's state: each receiver's irradiance so far (in
    /// the solver's order), its direct part (zero where `direct` is
    /// shorter) and each element's unshot radiosity.
    ///
    /// # Errors
    ///
    /// When the device fails.
    fn begin(
        &mut self,
        irradiance: &[DVec3],
        direct: &[DVec3],
        unshot: &[DVec3],
    ) -> Result<(), DeviceError>;

    /// The unshot radiosity the device holds for `elements` (element
    /// ids), in that order: a round's shooters', for the host to prepare
    /// their sources.
    ///
    /// # Errors
    ///
    /// When the device fails.
    fn unshot(&mut self, elements: &[u32]) -> Result<Vec<DVec3>, DeviceError>;

    /// One pass of one of a round's shooters (overshooting sends a shooter
    /// in a pass per sign): every receiver gathers from the shooting node;
    /// the device adds what it gathered (times [`AdaptiveShot::sign`]) to
    /// the round's irradiance, its [`AdaptiveShot::direct`] share to the
    /// round's direct part, and keeps [`AdaptiveShot::leave`] for the
    /// round's end. Nothing of the solve's state changes until
    /// [`AdaptiveTransfers::book`]. False when the pass was abandoned
    /// ([`AdaptiveShot::abort`]): the whole round is then dropped.
    ///
    /// # Errors
    ///
    /// When the device fails; the solve then goes back to its last
    /// checkpoint on the CPU.
    fn send(&mut self, shot: &AdaptiveShot<'_>) -> Result<bool, DeviceError>;

    /// Ends the round its passes sent: the shooters' elements are set to
    /// what they are left with, the round's irradiance is added to the
    /// receivers' (its direct part to theirs) and each element's reflected
    /// share to its unshot radiosity; the ledger's sums and the shooters'
    /// powers are read back.
    ///
    /// # Errors
    ///
    /// When the device fails.
    fn book(&mut self) -> Result<Booked, DeviceError>;

    /// The state, read back: each receiver's irradiance (the solver's
    /// order), its direct part, and each element's unshot radiosity.
    ///
    /// # Errors
    ///
    /// When the device fails.
    fn state(
        &mut self,
        irradiance: &mut [DVec3],
        direct: &mut [DVec3],
        unshot: &mut [DVec3],
    ) -> Result<(), DeviceError>;

    /// What crossed between host and device since the solve began: the
    /// same counts on any adapter, so the cost of the loop on the host is
    /// measured without a fast GPU. Zero for a device that does not count.
    fn traffic(&self) -> Traffic {
        Traffic::default()
    }

    /// How the device's kernels were made.
    fn kernels(&self) -> Kernels {
        Kernels::default()
    }
}

/// How a device's kernels were made for its solves
/// ([`AdaptiveTransfers::kernels`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Kernels {
    /// Time making them on the device in the run so far (compiling them,
    /// or loading them from a cache kept across runs).
    pub time: Duration,
    /// That cache: `off`, `unsupported` (the adapter keeps none),
    /// `compiled` (none to load: made and saved) or `loaded` (`None`
    /// where the device does not say).
    pub cache: Option<&'static str>,
}

/// What crossed between host and device ([`AdaptiveTransfers::traffic`]),
/// the checkpoints counted apart: they come by the clock, the rest by the
/// shot, the same on any machine.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Traffic {
    /// Times the host waited for the device (a blocking readback), but
    /// for checkpoints.
    pub host_waits: u64,
    /// Checkpoints: the whole state read back, every
    /// [`crate::solver::CHECKPOINT_INTERVAL`] of the clock (so their count
    /// depends on the machine, the other counts do not).
    pub checkpoints: u64,
    /// Command buffers submitted, but for checkpoints.
    pub submissions: u64,
    /// Bytes read back from the device, but for checkpoints.
    pub bytes_read: u64,
    /// Bind groups and buffers made after the solve's setup: a buffer
    /// grown to hold a larger upload, and the bind groups made anew to
    /// read it (a few a solve, not some every round).
    pub made: u64,
}

/// What one adaptive shot sends.
pub struct AdaptiveShot<'a> {
    /// The shooting node of the element tree.
    pub root: u32,
    /// Its centre: the origin of its sources' positions.
    pub origin: DVec3,
    /// Its subtree's sources.
    pub sources: &'a Sources,
    /// Unshot radiosity of each element: current for the shooter's. In a
    /// pass of overshooting, what each of the shooter's elements sends in
    /// it (see `sign`).
    pub unshot: &'a [DVec3],
    /// 1, or -1 for a pass that sends overshooting's negative light
    /// negated (its sources need power of one sign): the irradiance
    /// gathered is booked times this.
    pub sign: f64,
    /// The share of the irradiance gathered that is direct light, per
    /// channel: the share of the shot's power that was the shooter's own
    /// emission sent for the first time (zero for reflected light).
    pub direct: DVec3,
    /// What the shooter's elements (`items` of its node, in the tree's
    /// order) are left with when the round is booked, before its light is:
    /// zero, or minus their overshoot. `None` for a shot's second pass,
    /// which leaves them as the first did.
    pub leave: Option<&'a [DVec3]>,
    /// A receiver's negligible irradiance (luminance) is this...
    pub negligible: f64,
    /// ... times its irradiance's luminance over this, if more than one.
    pub mean_radiosity: f64,
    /// When to abandon the shot.
    pub abort: &'a Abort,
}

/// What a shot booked on the device, and what it cost.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Booked {
    /// Power that arrived at the elements, and the part absorbed.
    pub received: Received,
    /// Unshot power left after the shot, per channel (W).
    pub unshot_power: DVec3,
    /// The same in magnitude, element by element (overshooting leaves
    /// negative unshot power): what the stopping rule compares.
    pub unshot_magnitude: DVec3,
    /// Each shooter's unshot power (luminance) after the shot.
    pub shooter_power: Vec<f64>,
    /// Receiver-source pairs considered.
    pub pairs: u64,
    /// Shadow rays traced.
    pub rays: u64,
    /// Receivers that walked the source tree.
    pub walks: u64,
    /// Source nodes the walks visited.
    pub node_visits: u64,
    /// Elements taken as exact sources.
    pub element_sources: u64,
    /// The most source nodes one thread of the receivers' walks visited:
    /// with [`Booked::longest_item`], the shot's critical path, against
    /// the mean walk's `node_visits / walks`.
    pub longest_walk: u64,
    /// The most source nodes one thread of the split walks' items visited
    /// (0 where no walk was split).
    pub longest_item: u64,
    /// The next round as the device chose it after this one, by the
    /// host's rule ([`AdaptiveSolve::round`], the powers compared in
    /// `f32` as reported), read back with the round: the next round then
    /// asks for nothing ([`AdaptiveTransfers::unshot`]). `None` where the
    /// device does not say, or its elements were more than it read back.
    pub next_round: Option<NextRound>,
    /// Time preparing and sending the shot's data (host clock).
    pub upload_time: Duration,
    /// Time the kernels took, waited for (host clock).
    pub kernel_time: Duration,
    /// Time reading the results back (host clock).
    pub readback_time: Duration,
    /// The device's own time for each stage of the shot, where it can
    /// measure it (timestamps).
    pub stages: Option<StageTimes>,
}

/// The next round as a device chose it ([`Booked::next_round`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NextRound {
    /// How many shooters it takes.
    pub shooters: usize,
    /// Their elements' unshot radiosity: shooter by shooter in index
    /// order, each's elements in the tree's order.
    pub unshot: Vec<DVec3>,
}

/// A device's time for the stages of its shots, read from the device's
/// own timestamps: where a shot's kernel time goes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StageTimes {
    /// The receivers' walks of the shooting node (each up to its
    /// frontier, where a walk is split across threads).
    pub walk: Duration,
    /// The split walks' items (sizing their dispatch, and walking them).
    pub items: Duration,
    /// Joining each receiver's items.
    pub join: Duration,
    /// The book-keeping: the shooter left, the elements' and receivers'
    /// sums, the shooters' powers.
    pub book: Duration,
}

impl std::ops::Add for StageTimes {
    type Output = StageTimes;

    fn add(self, other: StageTimes) -> StageTimes {
        StageTimes {
            walk: self.walk + other.walk,
            items: self.items + other.items,
            join: self.join + other.join,
            book: self.book + other.book,
        }
    }
}

impl StageTimes {
    /// The stages by name, in order.
    #[must_use]
    pub fn named(&self) -> [(&'static str, Duration); 4] {
        [
            ("walk", self.walk),
            ("items", self.items),
            ("join", self.join),
            ("book", self.book),
        ]
    }

    /// `a` and `b` added, where either is known.
    #[must_use]
    pub fn add_known(a: Option<StageTimes>, b: Option<StageTimes>) -> Option<StageTimes> {
        match (a, b) {
            (Some(a), Some(b)) => Some(a + b),
            (a, b) => a.or(b),
        }
    }
}

/// A device's failure, as it said it.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct DeviceError(pub String);

/// The device a solve's transfers run on: the CPU, or a [`Backend`],
/// asked for by name (`--device gpu`) or taken because it was there
/// (`auto`).
#[derive(Clone, Default)]
pub struct Device {
    backend: Option<Arc<dyn Backend>>,
    required: bool,
}

impl Device {
    /// The CPU.
    #[must_use]
    pub fn cpu() -> Device {
        Device::default()
    }

    /// `backend`, asked for: a solve it cannot hold is an error.
    #[must_use]
    pub fn backend(backend: Arc<dyn Backend>) -> Device {
        Device {
            backend: Some(backend),
            required: true,
        }
    }

    /// `backend`, taken because it was there: a solve it cannot hold runs
    /// on the CPU, with a note.
    #[must_use]
    pub fn preferred(backend: Arc<dyn Backend>) -> Device {
        Device {
            backend: Some(backend),
            required: false,
        }
    }

    /// The backend, if not the CPU.
    #[must_use]
    pub fn get(&self) -> Option<&Arc<dyn Backend>> {
        self.backend.as_ref()
    }

    /// Whether the backend was asked for by name.
    #[must_use]
    pub fn required(&self) -> bool {
        self.required
    }

    /// Whether the solve of `mesh` with `receivers` receivers fits the
    /// device ([`Backend::check`]): a device asked for by name that cannot
    /// hold it is an error; one taken because it was there becomes the CPU,
    /// and the note saying so is returned.
    ///
    /// # Errors
    ///
    /// When a device asked for by name cannot hold the solve.
    pub fn fit(
        &mut self,
        scene: &Scene,
        mesh: &Mesh,
        receivers: usize,
    ) -> Result<Option<String>, DeviceError> {
        let Some(backend) = &self.backend else {
            return Ok(None);
        };
        match backend.check(scene, mesh, receivers) {
            Ok(_) => Ok(None),
            Err(e) if self.required => Err(e),
            Err(e) => {
                *self = Device::cpu();
                Ok(Some(format!(
                    "--device auto: {}; the solve runs on the CPU",
                    e.0
                )))
            }
        }
    }

    /// The device's name: `cpu`, or the backend's.
    #[must_use]
    pub fn name(&self) -> String {
        self.backend
            .as_ref()
            .map_or_else(|| "cpu".to_string(), |b| b.name())
    }
}

impl fmt::Debug for Device {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Device({})", self.name())
    }
}

/// Two devices are equal when they are the same one (or both the CPU).
impl PartialEq for Device {
    fn eq(&self, other: &Device) -> bool {
        self.required == other.required
            && match (&self.backend, &other.backend) {
                (None, None) => true,
                (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                _ => false,
            }
    }
}

/// Where a solve's shots ran.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeviceReport {
    /// The device asked for (`None`: the CPU).
    pub name: Option<String>,
    /// Shots whose transfers ran on it.
    pub device_shots: u64,
    /// Why it stopped being used, if it did: later shots ran on the CPU.
    pub fault: Option<String>,
    /// Its shots' time preparing and sending data ([`Booked::upload_time`]).
    pub upload_time: Duration,
    /// Its shots' kernel time ([`Booked::kernel_time`]).
    pub kernel_time: Duration,
    /// Its shots' time reading results back ([`Booked::readback_time`]).
    pub readback_time: Duration,
    /// Its shots' time by stage, by the device's clock
    /// ([`Booked::stages`]; `None` where it does not say).
    pub stages: Option<StageTimes>,
    /// What crossed between host and device ([`AdaptiveTransfers::traffic`]).
    pub traffic: Traffic,
    /// How its kernels were made ([`AdaptiveTransfers::kernels`]).
    pub kernels: Kernels,
    /// Passes the device ran: one a shot, two for a shot that also sends
    /// negative light (overshooting's, or unshot light left below zero by
    /// round-off).
    pub passes: u64,
    /// Its shots' critical paths summed: each shot's most nodes visited by
    /// one thread of the walks plus one of the split items
    /// ([`Booked::longest_walk`], [`Booked::longest_item`]).
    pub longest_visits: u64,
    /// Its shots' mean walks summed: each shot's node visits over its
    /// walks. Against [`DeviceReport::longest_visits`], how unevenly the
    /// work is spread over the device's threads.
    pub mean_visits: f64,
}
