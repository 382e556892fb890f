//! The progressive-refinement shooting loop (design.md section 2): the
//! brightest shooter sends its unshot radiosity to every receiver, which
//! gathers `dE_j = sum_k delta_kj F_jk dB_k` and keeps `dB_j = rho_j dE_j`
//! for a later shot of its own.
//!
//! Two ways of shooting, chosen by [`Settings::shooting`]:
//!
//! * [`Shooting::Patches`], the paper's (Wallace, Elmquist & Haines 1989, as
//!   used by Wong & Tsang 1993): a patch shoots one uniform unshot radiosity,
//!   split into a fixed grid of subsources ([`patches`]).
//! * [`Shooting::Adaptive`], beyond the paper: unshot radiosity is kept per
//!   element, shooters are clusters of elements, and each receiver refines
//!   the shooter's element hierarchy until the part it sees is accurate
//!   ([`adaptive`]).
//!
//! Receivers are the unique mesh vertices and any sensor points. They are
//! processed in parallel in chunks of a fixed size, each one's sum in a fixed
//! order, so the result does not depend on the number of threads.

pub mod adaptive;
pub mod hierarchy;
pub mod patches;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;

use crate::accel::{Accel, Occluder};
use crate::form_factor::FormFactor;
use crate::geometry;
use crate::hemicube;
use crate::luminance;
use crate::mesh::{Mesh, MeshSettings};
use crate::scene::Scene;

/// Every setting of a solve, apart from run state. Presets are named
/// constructors; each field can be overridden on its own. Serialised as
/// the `--stats` file's `settings` object: one flat object, the mesh's
/// sizes among the others, the time limit in seconds.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Settings {
    /// Patch and element sizes.
    #[serde(flatten)]
    pub mesh: MeshSettings,
    /// How shooters carry and send their unshot radiosity.
    pub shooting: Shooting,
    /// Give adjacent coplanar faces of one material one surface id
    /// ([`crate::scene::merge`]).
    pub merge_coplanar: bool,
    /// Point-to-polygon formula (for adaptive shooting: at the elements).
    pub form_factor: FormFactor,
    /// Shadow-segment accelerator.
    pub accel: Accel,
    /// How visibility is decided.
    pub visibility: Visibility,
    /// Pixels across the top face of the pre-test hemicube.
    pub hemicube_resolution: u32,
    /// A shooting patch is split into `subsources x subsources` subsources
    /// (patch shooting).
    pub subsources: u32,
    /// Accuracy of adaptive shooting: a receiver accepts a part of the
    /// shooter as one source when the irradiance that part can send is below
    /// this fraction of the scene's mean radiosity, or when it is far and
    /// below [`adaptive::FAR_FACTOR`] times that.
    pub tolerance: f64,
    /// Stop when the unshot power falls below this fraction of the emitted
    /// power.
    pub converge: f64,
    /// Stop after this many shots.
    pub max_shots: Option<u64>,
    /// Stop once this many subsources have been shot.
    pub max_subsources: Option<u64>,
    /// Stop before a shot once the solve has run this long.
    #[serde(serialize_with = "optional_seconds")]
    pub time_limit: Option<Duration>,
}

/// A duration as a number of seconds.
fn seconds<S: serde::Serializer>(time: &Duration, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_f64(time.as_secs_f64())
}

/// A duration as a number of seconds, `null` for none.
fn optional_seconds<S: serde::Serializer>(
    time: &Option<Duration>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&time.map(|t| t.as_secs_f64()), serializer)
}

/// Default `--converge`.
pub const DEFAULT_CONVERGE: f64 = 0.01;

/// Default `--tolerance` of adaptive shooting.
pub const DEFAULT_TOLERANCE: f64 = 1e-3;

impl Settings {
    /// Wallace, Elmquist & Haines (1989): patch shooting, a shadow ray for
    /// every pair against every surface, the disk form factor of equation
    /// (1), 3 x 3 subsources, every input face its own surface.
    #[must_use]
    pub fn wallace89() -> Settings {
        Settings {
            mesh: MeshSettings::default(),
            shooting: Shooting::Patches,
            merge_coplanar: false,
            form_factor: FormFactor::Wallace,
            accel: Accel::Brute,
            visibility: Visibility::Ray,
            hemicube_resolution: hemicube::DEFAULT_RESOLUTION,
            subsources: 3,
            tolerance: DEFAULT_TOLERANCE,
            converge: DEFAULT_CONVERGE,
            max_shots: None,
            max_subsources: None,
            time_limit: None,
        }
    }

    /// Wong & Tsang (1993), all three improvements: the hemicube pre-test
    /// (section 2), BSP-ordered shadow rays (section 3) and the analytic
    /// form factor of Baum et al. (section 4, equation 2).
    #[must_use]
    pub fn wong_tsang93() -> Settings {
        Settings {
            form_factor: FormFactor::Analytic,
            accel: Accel::Bsp,
            visibility: Visibility::HemicubePretest,
            ..Settings::wallace89()
        }
    }

    /// The default: adaptive element-resolution shooting from clusters
    /// ([`adaptive`]), the analytic factor at the elements, shadow rays
    /// through the BVH, coplanar faces merged into surfaces.
    #[must_use]
    pub fn adaptive() -> Settings {
        Settings {
            mesh: MeshSettings {
                bisect_triangles: true,
                ..MeshSettings::default()
            },
            shooting: Shooting::Adaptive,
            merge_coplanar: true,
            form_factor: FormFactor::Analytic,
            accel: Accel::Bvh,
            visibility: Visibility::Ray,
            ..Settings::wallace89()
        }
    }

    /// Checks the settings a user can get wrong.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if !(1..=MAX_SUBSOURCES_PER_SIDE).contains(&self.subsources) {
            return Err(SettingsError::Subsources(self.subsources));
        }
        if !(8..=MAX_HEMICUBE_RESOLUTION).contains(&self.hemicube_resolution) {
            return Err(SettingsError::HemicubeResolution(self.hemicube_resolution));
        }
        if self.visibility == Visibility::HemicubePretest {
            if self.shooting == Shooting::Adaptive {
                return Err(SettingsError::PretestWithAdaptiveShooting);
            }
            let bytes = item_buffer_bytes(self.subsources, self.hemicube_resolution);
            if bytes > MAX_ITEM_BUFFER_BYTES {
                return Err(SettingsError::ItemBuffers {
                    subsources: self.subsources,
                    resolution: self.hemicube_resolution,
                    bytes,
                });
            }
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0 && self.tolerance <= 1.0) {
            return Err(SettingsError::Tolerance(self.tolerance));
        }
        if !(self.converge.is_finite() && (0.0..1.0).contains(&self.converge)) {
            return Err(SettingsError::Converge(self.converge));
        }
        if self.converge == 0.0
            && self.max_shots.is_none()
            && self.max_subsources.is_none()
            && self.time_limit.is_none()
        {
            return Err(SettingsError::NeverStops);
        }
        Ok(())
    }
}

/// Settings a solve cannot run with ([`Settings::validate`]); each message
/// names the flag to change.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// Subsources per side out of range.
    #[error("--subsources must be between 1 and {MAX_SUBSOURCES_PER_SIDE}, not {0}")]
    Subsources(u32),
    /// Hemicube resolution out of range.
    #[error("--hemicube-resolution must be between 8 and {MAX_HEMICUBE_RESOLUTION}, not {0}")]
    HemicubeResolution(u32),
    /// The hemicube pre-test asked of adaptive shooting.
    #[error(
        "the hemicube pre-test places a hemicube at each subsource of a patch: use it with \
         --shooting patches (adaptive shooting picks its sources per receiver)"
    )]
    PretestWithAdaptiveShooting,
    /// The pre-test's item buffers would exceed [`MAX_ITEM_BUFFER_BYTES`].
    #[error(
        "{subsources} x {subsources} subsources with hemicubes of {resolution} pixels need \
         {gib:.1} GiB of item buffers (limit {limit} GiB): lower --subsources or \
         --hemicube-resolution",
        gib = *bytes as f64 / (1u64 << 30) as f64,
        limit = MAX_ITEM_BUFFER_BYTES >> 30
    )]
    ItemBuffers {
        /// Subsources per side.
        subsources: u32,
        /// Hemicube resolution.
        resolution: u32,
        /// Bytes the buffers would take.
        bytes: u64,
    },
    /// Tolerance outside (0, 1].
    #[error("--tolerance must be a fraction in (0, 1], not {0}")]
    Tolerance(f64),
    /// Convergence threshold outside [0, 1).
    #[error("--converge must be a fraction in [0, 1), not {0}")]
    Converge(f64),
    /// No stopping rule at all.
    #[error(
        "--converge 0 never stops by itself: give --max-shots, --max-subsources or --time-limit"
    )]
    NeverStops,
}

crate::choice::named_choice! {
    /// How shooters carry and send their unshot radiosity.
    pub enum Shooting: "shooting" {
        /// The paper's: a patch shoots one uniform unshot radiosity from a
        /// fixed grid of subsources (Wallace et al. 1989).
        Patches = "patches",
        /// Unshot radiosity per element, clusters of elements as shooters,
        /// the source refined per receiver ([`adaptive`]).
        Adaptive = "adaptive",
    }
}

crate::choice::named_choice! {
    /// How a shot decides whether a receiver sees a source.
    pub enum Visibility: "visibility" {
        /// A shadow ray for every pair (Wallace et al. 1989).
        Ray = "ray",
        /// The hemicube item-buffer pre-test of Wong & Tsang, section 2;
        /// rays only where it cannot decide.
        HemicubePretest = "hemicube",
    }
}

crate::choice::named_choice! {
    /// The named settings ([`Settings::adaptive`], [`Settings::wong_tsang93`],
    /// [`Settings::wallace89`]), in the order the command line lists them.
    pub enum Preset: "preset" {
        /// [`Settings::adaptive`], the default.
        Adaptive = "adaptive",
        /// [`Settings::wong_tsang93`], the paper's method.
        WongTsang93 = "wong-tsang93",
        /// [`Settings::wallace89`], the 1989 baseline.
        Wallace89 = "wallace89",
    }
}

impl Preset {
    /// The preset's settings.
    #[must_use]
    pub fn settings(self) -> Settings {
        match self {
            Preset::Adaptive => Settings::adaptive(),
            Preset::WongTsang93 => Settings::wong_tsang93(),
            Preset::Wallace89 => Settings::wallace89(),
        }
    }
}

/// Memory of the item buffers of one shot: one buffer per subsource, each
/// `3 resolution^2` pixels of a surface id and a depth.
#[must_use]
pub fn item_buffer_bytes(subsources: u32, resolution: u32) -> u64 {
    let pixels = 3 * u64::from(resolution) * u64::from(resolution);
    u64::from(subsources) * u64::from(subsources) * pixels * 8
}

/// Most memory the item buffers of a shot may take.
pub const MAX_ITEM_BUFFER_BYTES: u64 = 4 << 30;

/// Largest `--hemicube-resolution`: the item buffer's own limit.
pub const MAX_HEMICUBE_RESOLUTION: u32 = hemicube::MAX_RESOLUTION;

/// Largest `--subsources` (per side): 64 x 64 = 4,096 subsources a shot.
pub const MAX_SUBSOURCES_PER_SIDE: u32 = 64;

/// Counters and timings of a solve. Serialised as the `--stats` file's
/// counters, the times in seconds under the names given below.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Stats {
    /// Shooters shot.
    pub shots: u64,
    /// Subsources shot (adaptive shooting: elements shot, its finest
    /// subsources).
    pub subsources: u64,
    /// Receiver-source pairs that face each other (adaptive shooting: the
    /// parts of shooters receivers accepted as one source).
    pub pairs: u64,
    /// Shadow segments traced.
    pub rays_cast: u64,
    /// Pairs the hemicube pre-test found visible without a ray.
    pub pretest_visible: u64,
    /// Pairs the hemicube pre-test found hidden without a ray.
    pub pretest_hidden: u64,
    /// Wall time rasterising the hemicube item buffers.
    #[serde(rename = "hemicube_seconds", serialize_with = "seconds")]
    pub hemicube_time: Duration,
    /// Wall time gathering at receivers (the three phases below, in
    /// parallel).
    #[serde(rename = "gather_seconds", serialize_with = "seconds")]
    pub gather_time: Duration,
    /// Thread time pairing receivers with sources and applying the pre-test
    /// (summed over threads; adaptive shooting: choosing the sources).
    #[serde(rename = "pretest_thread_seconds", serialize_with = "seconds")]
    pub pretest_time: Duration,
    /// Thread time casting shadow rays (summed over threads).
    #[serde(rename = "ray_thread_seconds", serialize_with = "seconds")]
    pub ray_time: Duration,
    /// Thread time evaluating form factors (summed over threads).
    #[serde(rename = "form_factor_thread_seconds", serialize_with = "seconds")]
    pub form_factor_time: Duration,
    /// Time in book-keeping (selection, element and patch updates).
    #[serde(rename = "bookkeeping_seconds", serialize_with = "seconds")]
    pub bookkeeping_time: Duration,
}

/// Where the emitted power has gone, per channel (W): the book-keeping's
/// conservation law is `emitted = unshot + absorbed + escaped` at every
/// moment (tested to 1e-9 relative).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// Power the emitters put into the scene.
    pub emitted: DVec3,
    /// Power shot so far.
    pub shot: DVec3,
    /// Shot power that arrived at receiving elements.
    pub received: DVec3,
    /// Received power absorbed (`(1 - rho)` of it).
    pub absorbed: DVec3,
    /// Shot power that arrived at no element: it left through an opening,
    /// or is the difference between the exact transfer and its discrete
    /// estimate at the vertices.
    pub escaped: DVec3,
}

/// What an observer of the shooting loop wants after a shot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// Go on shooting.
    Continue,
    /// Stop now; the state reached is the result ([`StopReason::Stopped`]).
    Stop,
}

/// Why the loop stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The unshot fraction fell below `--converge`.
    Converged,
    /// `--max-shots` reached.
    MaxShots,
    /// `--max-subsources` reached.
    MaxSubsources,
    /// Nothing left to shoot.
    NothingUnshot,
    /// `--time-limit` reached.
    TimeLimit,
    /// Stopped from outside (Ctrl-C, or the live view's stop button).
    Stopped,
}

impl StopReason {
    /// A short description for summaries and statistics.
    #[must_use]
    pub fn describe(self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::MaxShots => "max-shots reached",
            StopReason::MaxSubsources => "max-subsources reached",
            StopReason::NothingUnshot => "no unshot power left",
            StopReason::TimeLimit => "time limit reached",
            StopReason::Stopped => "stopped",
        }
    }
}

/// A point that gathers light: a mesh vertex or a sensor.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// Where it gathers (a vertex is moved a hair into its surface, see
    /// [`GATHER_NUDGE`]).
    pub point: DVec3,
    /// Unit normal of its side.
    pub normal: DVec3,
    /// The surface it lies on.
    pub surface: u32,
    /// That surface's id ([`crate::scene::Surface::group`]).
    pub group: u32,
}

/// A vertex gathers at a point moved this fraction of the way towards its
/// surface's centroid. A vertex on the edge where two surfaces meet lies in
/// the neighbour's plane and sees it exactly edge-on (factor 0), while every
/// point of its own surface next to it sees the neighbour at up to half its
/// hemisphere; the displaced point takes the one-sided limit that the
/// element's interior tends to, and stays within 1e-6 of its size of the
/// vertex.
pub const GATHER_NUDGE: f64 = 1e-6;

/// The receivers of a mesh: its vertices at their gathering points.
#[must_use]
pub fn vertex_receivers(scene: &Scene, mesh: &Mesh) -> Vec<Receiver> {
    let centroids: Vec<DVec3> = scene
        .surfaces
        .iter()
        .map(|s| geometry::centroid(&s.polygon))
        .collect();
    mesh.vertices
        .iter()
        .map(|v| Receiver {
            point: v.position + (centroids[v.surface as usize] - v.position) * GATHER_NUDGE,
            normal: v.normal,
            surface: v.surface,
            group: v.group,
        })
        .collect()
}

/// The way of shooting in use, with its own state.
enum Method {
    Patches(patches::PatchShooting),
    Adaptive(Box<adaptive::AdaptiveShooting>),
}

/// The state of a progressive solve.
pub struct Solver<'a> {
    scene: &'a Scene,
    mesh: &'a Mesh,
    settings: Settings,
    occluder: Box<dyn Occluder + 'a>,
    method: Method,
    /// Vertices first, then sensors.
    receivers: Vec<Receiver>,
    /// Radiosity accumulated at each vertex (emission included).
    radiosity: Vec<DVec3>,
    /// Irradiance accumulated at each receiver (vertices, then sensors).
    irradiance: Vec<DVec3>,
    energy: Energy,
    stats: Stats,
    interrupt: Option<Arc<AtomicBool>>,
}

impl<'a> Solver<'a> {
    /// Starts a solve: `B_v = E`, unshot radiosity `E`.
    #[must_use]
    pub fn new(scene: &'a Scene, mesh: &'a Mesh, settings: Settings) -> Solver<'a> {
        Solver::with_sensors(scene, mesh, settings, Vec::new())
    }

    /// Starts a solve that also gathers at `sensors` (after the vertices).
    #[must_use]
    pub fn with_sensors(
        scene: &'a Scene,
        mesh: &'a Mesh,
        settings: Settings,
        sensors: Vec<Receiver>,
    ) -> Solver<'a> {
        let occluder = settings.accel.build(&scene.surfaces);
        Solver::with_sensors_and_occluder(scene, mesh, settings, sensors, occluder)
    }

    /// Like [`Solver::new`], answering visibility with `occluder` instead of
    /// building `settings.accel` (which then only names it): for instruments
    /// such as a wrapper recording the shadow segments a solve casts.
    #[must_use]
    pub fn with_occluder(
        scene: &'a Scene,
        mesh: &'a Mesh,
        settings: Settings,
        occluder: Box<dyn Occluder + 'a>,
    ) -> Solver<'a> {
        Solver::with_sensors_and_occluder(scene, mesh, settings, Vec::new(), occluder)
    }

    /// [`Solver::with_sensors`] with an accelerator built beforehand (so
    /// its build can be timed on its own) or an instrument in its place, as
    /// in [`Solver::with_occluder`].
    #[must_use]
    pub fn with_sensors_and_occluder(
        scene: &'a Scene,
        mesh: &'a Mesh,
        settings: Settings,
        sensors: Vec<Receiver>,
        occluder: Box<dyn Occluder + 'a>,
    ) -> Solver<'a> {
        let radiosity: Vec<DVec3> = mesh
            .vertices
            .iter()
            .map(|v| scene.surfaces[v.surface as usize].emission)
            .collect();
        let mut receivers = vertex_receivers(scene, mesh);
        receivers.extend(sensors);
        let method = match settings.shooting {
            Shooting::Patches => {
                Method::Patches(patches::PatchShooting::new(scene, mesh, &settings))
            }
            Shooting::Adaptive => Method::Adaptive(Box::new(adaptive::AdaptiveShooting::new(
                scene, mesh, &settings, &receivers,
            ))),
        };
        let mut solver = Solver {
            scene,
            mesh,
            occluder,
            settings,
            method,
            irradiance: vec![DVec3::ZERO; receivers.len()],
            receivers,
            radiosity,
            energy: Energy::default(),
            stats: Stats::default(),
            interrupt: None,
        };
        solver.energy.emitted = solver.unshot_power();
        solver
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The accelerator's build statistics (see
    /// [`Occluder::build_statistics`]).
    #[must_use]
    pub fn accel_statistics(&self) -> Vec<(&'static str, usize)> {
        self.occluder.build_statistics()
    }

    /// Counters so far.
    #[must_use]
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Where the emitted power has gone so far.
    #[must_use]
    pub fn energy(&self) -> &Energy {
        &self.energy
    }

    /// Radiosity `B` at each vertex (W/m^2, emission included, ambient
    /// excluded).
    #[must_use]
    pub fn radiosity(&self) -> &[DVec3] {
        &self.radiosity
    }

    /// Irradiance `E` at each vertex (W/m^2): the light arriving from every
    /// shot so far, so that `B = E_surface + rho E` (ambient excluded).
    #[must_use]
    pub fn irradiance(&self) -> &[DVec3] {
        &self.irradiance[..self.mesh.vertices.len()]
    }

    /// Irradiance `E` at each sensor (W/m^2), in the order given.
    #[must_use]
    pub fn sensor_irradiance(&self) -> &[DVec3] {
        &self.irradiance[self.mesh.vertices.len()..]
    }

    /// The scene being solved.
    #[must_use]
    pub fn scene(&self) -> &Scene {
        self.scene
    }

    /// The mesh being solved.
    #[must_use]
    pub fn mesh(&self) -> &Mesh {
        self.mesh
    }

    /// Shooting units: the mesh's patches, or adaptive shooting's shooters.
    #[must_use]
    pub fn shooters(&self) -> usize {
        match &self.method {
            Method::Patches(_) => self.mesh.patches.len(),
            Method::Adaptive(a) => a.shooters(),
        }
    }

    /// Unshot power left, per channel (W).
    #[must_use]
    pub fn unshot_power(&self) -> DVec3 {
        match &self.method {
            Method::Patches(p) => p.unshot_power(self.mesh),
            Method::Adaptive(a) => a.unshot_power(self.mesh),
        }
    }

    /// Unshot power left over emitted power (luminance-weighted).
    #[must_use]
    pub fn unshot_fraction(&self) -> f64 {
        let emitted = luminance(self.energy.emitted);
        if emitted <= 0.0 {
            return 0.0;
        }
        luminance(self.unshot_power()) / emitted
    }

    /// The ambient term of Cohen et al. (1988) for display:
    /// `(sum dB_p A_p / sum A_p) / (1 - rho_avg)`, per channel.
    #[must_use]
    pub fn ambient(&self) -> DVec3 {
        let total_area = self.mesh.total_area();
        let mut rho = DVec3::ZERO;
        for e in &self.mesh.elements {
            rho += self.scene.surfaces[e.surface as usize].rho * e.area;
        }
        (self.unshot_power() / total_area) / (DVec3::ONE - rho / total_area)
    }

    /// What each vertex is shown as: `B_v + rho_v * ambient` (or `B_v`).
    #[must_use]
    pub fn display_radiosity(&self, with_ambient: bool) -> Vec<DVec3> {
        let ambient = if with_ambient {
            self.ambient()
        } else {
            DVec3::ZERO
        };
        self.mesh
            .vertices
            .iter()
            .zip(&self.radiosity)
            .map(|(v, b)| *b + self.scene.surfaces[v.surface as usize].rho * ambient)
            .collect()
    }

    /// Why the loop should stop now, if it should.
    #[must_use]
    pub fn stop_reason(&self) -> Option<StopReason> {
        if self
            .settings
            .max_shots
            .is_some_and(|m| self.stats.shots >= m)
        {
            return Some(StopReason::MaxShots);
        }
        if self
            .settings
            .max_subsources
            .is_some_and(|m| self.stats.subsources >= m)
        {
            return Some(StopReason::MaxSubsources);
        }
        let fraction = self.unshot_fraction();
        if fraction <= 0.0 {
            return Some(StopReason::NothingUnshot);
        }
        if fraction < self.settings.converge {
            return Some(StopReason::Converged);
        }
        None
    }

    /// Stops the solve when `flag` is raised (Ctrl-C, a live view's stop
    /// button): within the current shot, which is then abandoned (its
    /// receivers keep what earlier shots gave them), so even a long shot
    /// of a large scene ends promptly.
    pub fn interrupt_on(&mut self, flag: Arc<AtomicBool>) {
        self.interrupt = Some(flag);
    }

    /// Shoots until a stopping rule holds or `after_shot`, called after
    /// each shot, returns [`Flow::Stop`]. `--time-limit` counts from this
    /// call and, like an interrupt, is obeyed within a shot (which is then
    /// abandoned).
    pub fn run(&mut self, mut after_shot: impl FnMut(&Solver<'_>) -> Flow) -> StopReason {
        let start = Instant::now();
        let abort = Abort {
            deadline: self.settings.time_limit.map(|limit| start + limit),
            flag: self.interrupt.clone(),
        };
        loop {
            if let Some(reason) = self.stop_reason() {
                return reason;
            }
            if let Some(reason) = abort.reason() {
                return reason;
            }
            if !self.shoot_unless(&abort) {
                return abort.reason().unwrap_or(StopReason::Stopped);
            }
            if after_shot(self) == Flow::Stop {
                return StopReason::Stopped;
            }
        }
    }

    /// One shot: the brightest shooter shoots its unshot radiosity to every
    /// receiver, then the book-keeping of design.md step 5.
    pub fn shoot(&mut self) {
        self.shoot_unless(&Abort::default());
    }

    /// [`Solver::shoot`], abandoned (returning false, nothing changed) if
    /// `abort` fires during it.
    fn shoot_unless(&mut self, abort: &Abort) -> bool {
        let context = ShotInputs {
            scene: self.scene,
            mesh: self.mesh,
            settings: &self.settings,
            occluder: self.occluder.as_ref(),
            receivers: &self.receivers,
            irradiance: &self.irradiance,
            abort,
        };
        let shot = match &mut self.method {
            Method::Patches(p) => p.shoot(&context, &mut self.stats),
            Method::Adaptive(a) => a.shoot(&context, &mut self.stats),
        };
        let Some(shot) = shot else {
            return false;
        };
        let book_start = Instant::now();
        let vertices = self.mesh.vertices.len();
        for (i, e) in shot.irradiance.iter().enumerate() {
            self.irradiance[i] += *e;
            if i < vertices {
                let rho = self.scene.surfaces[self.mesh.vertices[i].surface as usize].rho;
                self.radiosity[i] += rho * *e;
            }
        }
        let received = match &mut self.method {
            Method::Patches(p) => p.receive(self.scene, self.mesh, &shot.irradiance[..vertices]),
            Method::Adaptive(a) => a.receive(self.scene, self.mesh, &shot.irradiance[..vertices]),
        };
        self.energy.shot += shot.power;
        self.energy.received += received.incident;
        self.energy.absorbed += received.absorbed;
        self.energy.escaped += shot.power - received.incident;
        self.stats.shots += 1;
        self.stats.bookkeeping_time += (Instant::now() - book_start) + shot.selection_time;
        true
    }
}

/// When a shot must be abandoned: a deadline, a raised flag.
#[derive(Clone, Debug, Default)]
pub(crate) struct Abort {
    deadline: Option<Instant>,
    flag: Option<Arc<AtomicBool>>,
}

impl Abort {
    /// Why to stop now, if so.
    pub(crate) fn reason(&self) -> Option<StopReason> {
        if self
            .flag
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed))
        {
            return Some(StopReason::Stopped);
        }
        if self.deadline.is_some_and(|d| Instant::now() >= d) {
            return Some(StopReason::TimeLimit);
        }
        None
    }

    /// True when the shot must be abandoned.
    pub(crate) fn fired(&self) -> bool {
        self.reason().is_some()
    }
}

/// What a shot reads.
pub(crate) struct ShotInputs<'s> {
    pub(crate) scene: &'s Scene,
    pub(crate) mesh: &'s Mesh,
    pub(crate) settings: &'s Settings,
    pub(crate) occluder: &'s dyn Occluder,
    pub(crate) receivers: &'s [Receiver],
    /// Irradiance each receiver has gathered so far.
    pub(crate) irradiance: &'s [DVec3],
    /// When to abandon the shot.
    pub(crate) abort: &'s Abort,
}

/// What a shot produced: the irradiance each receiver gathered and the
/// power that left the shooter.
pub(crate) struct Shot {
    pub(crate) irradiance: Vec<DVec3>,
    pub(crate) power: DVec3,
    pub(crate) selection_time: Duration,
}

/// Power arriving at the receiving elements in one shot.
pub(crate) struct Received {
    pub(crate) incident: DVec3,
    pub(crate) absorbed: DVec3,
}

/// Incident power on each element from its corners' irradiance (their
/// mean, times its area), added as reflected unshot radiosity through
/// `reflect(element, rho * mean)`; returns the power received and absorbed.
pub(crate) fn receive_at_elements(
    scene: &Scene,
    mesh: &Mesh,
    irradiance: &[DVec3],
    mut reflect: impl FnMut(usize, DVec3),
) -> Received {
    let mut incident = DVec3::ZERO;
    let mut absorbed = DVec3::ZERO;
    for (i, e) in mesh.elements.iter().enumerate() {
        let corners = e.vertices();
        let mean = corners
            .iter()
            .map(|&c| irradiance[c as usize])
            .sum::<DVec3>()
            / corners.len() as f64;
        let rho = scene.surfaces[e.surface as usize].rho;
        incident += mean * e.area;
        absorbed += (DVec3::ONE - rho) * mean * e.area;
        reflect(i, rho * mean);
    }
    Received { incident, absorbed }
}
