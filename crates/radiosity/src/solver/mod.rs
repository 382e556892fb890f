//! The progressive-refinement shooting loop (design.md section 2): the
//! brightest shooter sends its unshot radiosity to every receiver, which
//! gathers `dE_j = sum_k delta_kj F_jk dB_k` and keeps `dB_j = rho_j dE_j`
//! for a later shot of its own.
//!
//! What a shooter is and how it sends is a method's ([`method`]; the
//! methods are listed in [`registry`]):
//!
//! * [`patches`], the paper's (Wallace, Elmquist & Haines 1989, as used by
//!   Wong & Tsang 1993): a patch shoots one uniform unshot radiosity, split
//!   into a fixed grid of subsources.
//! * [`adaptive`], beyond the paper: unshot radiosity is kept per element,
//!   shooters are clusters of elements, and each receiver refines the
//!   shooter's element hierarchy until the part it sees is accurate.
//!
//! The loop here is the same for every method: it owns the receivers (the
//! unique mesh vertices and any sensor points), their irradiance and
//! radiosity, the energy ledger and the stopping rules. It also shoots the
//! scene's point, spot and sun lights ([`lights`]), each once and before
//! any surface, whatever the method: the method then takes what they
//! reflect as unshot light of its own. Receivers are
//! processed in parallel in chunks of a fixed size, each one's sum in a
//! fixed order, so the result does not depend on the number of threads.
//!
//! A solve may run on a device ([`device`], the GPU): the method then
//! keeps the receivers' irradiance and its unshot radiosity there, books
//! each shot there and reports the ledger's sums; the loop's rules stay
//! here, and the state comes back at checkpoints ([`CHECKPOINT_INTERVAL`]),
//! which a device's failure goes back to.

mod abort;
pub mod adaptive;
pub mod costs;
pub mod cuts;
pub mod device;
pub mod hierarchy;
pub mod lights;
pub mod method;
pub mod patches;
mod receiver;
pub mod refine;
pub mod registry;
mod resume;
mod settings;
pub mod sky;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use glam::DVec3;

pub use self::abort::Abort;
use self::method::{Checkpoint, Received, ShotInputs};
pub use self::method::{Counter, Method, Shooter, Stats, Visibility};
pub use self::receiver::{GATHER_NUDGE, Receiver, surface_receivers, vertex_receivers};
pub use self::registry::{MethodSettings, Shooting};
pub use self::resume::Start;
pub use self::settings::{ADAPTIVE_CONVERGE, DEFAULT_CONVERGE, Preset, Settings, SettingsError};
use crate::accel::Occluder;
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::Scene;

/// A duration as a number of seconds.
fn seconds<S: serde::Serializer>(time: &Duration, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_f64(time.as_secs_f64())
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

    /// Its name for programs (`--progress-json`'s `done` event): one word,
    /// stable.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::MaxShots => "max-shots",
            StopReason::MaxSubsources => "max-subsources",
            StopReason::NothingUnshot => "nothing-unshot",
            StopReason::TimeLimit => "time-limit",
            StopReason::Stopped => "stopped",
        }
    }
}

/// The state of a progressive solve.
pub struct Solver<'a> {
    scene: &'a Scene,
    mesh: &'a Mesh,
    settings: Settings,
    occluder: Box<dyn Occluder + 'a>,
    shooter: Box<dyn Shooter + 'a>,
    /// Vertices first, then sensors.
    receivers: Vec<Receiver>,
    /// Radiosity accumulated at each vertex (emission included).
    radiosity: Vec<DVec3>,
    /// Irradiance accumulated at each receiver (vertices, then sensors).
    irradiance: Vec<DVec3>,
    /// The part of `irradiance` that came straight from a source: the
    /// scene's lights' shots (point, spot, IES, sun, sky) and the emitting
    /// surfaces' first shots, booked apart (by a device that keeps the
    /// state, current at each checkpoint).
    direct: Vec<DVec3>,
    /// The part of `direct` from skies, which the final pass leaves to the
    /// mesh ([`Solver::sky_irradiance`]).
    sky: Vec<DVec3>,
    /// Set when a device's failure made shots again on the CPU: `direct`
    /// then holds the lights' part only.
    direct_partial: bool,
    energy: Energy,
    stats: Stats,
    interrupt: Option<Arc<AtomicBool>>,
    /// The scene's lights not shot yet, next first.
    lights_pending: Vec<usize>,
    /// Power each of the scene's lights has sent (W per channel): a point,
    /// spot or luminaire's flux, what a sun or sky delivered to the
    /// elements; zero until it shoots.
    light_power: Vec<DVec3>,
    /// The ledger and counters at the last checkpoint (after every shot
    /// booked on the host; at each read-back of a device's state), which a
    /// device's failure goes back to.
    saved: (Energy, Stats),
    /// When the device's state was last read back.
    synced: Instant,
    /// The lights' shadow segments on the device (`None`: on the CPU);
    /// set up at the first light's shot.
    light_segments: Option<Box<dyn device::Segments>>,
    /// Shots the device made that the method's report leaves out: the
    /// lights' whose segments it answered, and a coarse pass's that this
    /// solve goes on from ([`resume`]).
    other_device_shots: u64,
    /// Why the lights' segments went back to the CPU, if they did.
    light_fault: Option<String>,
    /// Its shots so far, kept when the solve may go on on a refined mesh
    /// ([`Solver::record_shots`]).
    record: Option<Vec<resume::Step>>,
}

/// How often the state of a solve on a device is read back: what the live
/// view and the progress show between checkpoints is at most this old,
/// and a device lost mid-solve costs at most this much work again.
pub const CHECKPOINT_INTERVAL: Duration = Duration::from_millis(250);

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
        let shooter = settings
            .method
            .method()
            .start(scene, mesh, &settings, &receivers);
        let mut solver = Solver {
            scene,
            mesh,
            occluder,
            settings,
            shooter,
            irradiance: vec![DVec3::ZERO; receivers.len()],
            direct: vec![DVec3::ZERO; receivers.len()],
            direct_partial: false,
            sky: vec![DVec3::ZERO; receivers.len()],
            receivers,
            radiosity,
            energy: Energy::default(),
            stats: Stats::default(),
            interrupt: None,
            lights_pending: lights::shooting_order(&scene.lights),
            light_power: vec![DVec3::ZERO; scene.lights.len()],
            saved: (Energy::default(), Stats::default()),
            synced: Instant::now(),
            light_segments: None,
            other_device_shots: 0,
            light_fault: None,
            record: None,
        };
        solver.energy.emitted = solver.unshot_power();
        solver.saved = (solver.energy, solver.stats.clone());
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

    /// The part of each receiver's irradiance (vertices, then sensors)
    /// that came straight from a source, booked apart from the rest on
    /// every method: the scene's lights' shots (point, spot, IES, sun,
    /// sky), and the emitting surfaces' first shots (each shot's
    /// irradiance times the share of its power that was emission, per
    /// channel: exact for a shooter whose unshot radiosity was its own
    /// emission alone). When [`Solver::direct_complete`] is false it holds
    /// the lights' part only.
    #[must_use]
    pub fn direct_irradiance(&self) -> &[DVec3] {
        &self.direct
    }

    /// The part of [`Solver::direct_irradiance`] that skies sent (vertices,
    /// then sensors). A sky's light changes slowly across a surface, and
    /// its estimate at one point takes hundreds of rays, so the final pass
    /// ([`crate::final_gather`]) takes it from the mesh, as the indirect
    /// part, rather than at every point shown.
    #[must_use]
    pub fn sky_irradiance(&self) -> &[DVec3] {
        &self.sky
    }

    /// Whether [`Solver::direct_irradiance`] holds the emitting surfaces'
    /// part too: false once a device's failure made shots again on the
    /// CPU (a device books the direct part beside the total, and it comes
    /// back with the state at each checkpoint).
    #[must_use]
    pub fn direct_complete(&self) -> bool {
        !self.direct_partial
    }

    /// The receivers: the mesh's vertices at their gathering points, then
    /// the sensors.
    #[must_use]
    pub fn receivers(&self) -> &[Receiver] {
        &self.receivers
    }

    /// The structure answering the solve's shadow rays.
    #[must_use]
    pub fn occluder(&self) -> &dyn Occluder {
        self.occluder.as_ref()
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

    /// The method's own counters so far ([`Method::zero_counters`] names
    /// them).
    #[must_use]
    pub fn counters(&self) -> Vec<(&'static str, Counter)> {
        self.shooter.counters()
    }

    /// The method's own counter called `name`, if it keeps one.
    #[must_use]
    pub fn counter(&self, name: &str) -> Option<Counter> {
        self.counters()
            .into_iter()
            .find(|(n, _)| *n == name)
            .map(|(_, c)| c)
    }

    /// Where the shots ran: the device asked for, how many shots ran on it
    /// (a light's when the device answered its shadow segments, [`lights`];
    /// the method's when it made them), and why it stopped being used if it
    /// did.
    #[must_use]
    pub fn device_report(&self) -> device::DeviceReport {
        let mut report = self.shooter.device();
        if report.name.is_none() {
            report.name = self.settings.device.get().map(|b| b.name());
        }
        report.device_shots += self.other_device_shots;
        if report.fault.is_none() {
            report.fault.clone_from(&self.light_fault);
        }
        report
    }

    /// The method's own count called `name`; 0 if it keeps none.
    #[must_use]
    pub fn count(&self, name: &str) -> u64 {
        self.counter(name).and_then(Counter::count).unwrap_or(0)
    }

    /// Shooting units: the mesh's patches, or adaptive shooting's shooters.
    #[must_use]
    pub fn shooters(&self) -> usize {
        self.shooter.shooters()
    }

    /// Unshot power left, per channel (W): the method's, and the flux of
    /// the point and spot lights not shot yet (a sun's power is counted
    /// when it shoots: what reaches the scene's surfaces).
    #[must_use]
    pub fn unshot_power(&self) -> DVec3 {
        self.shooter.unshot_power(self.mesh)
            + self
                .lights_pending
                .iter()
                .filter_map(|&i| self.scene.lights[i].flux())
                .sum::<DVec3>()
    }

    /// Lights not shot yet.
    #[must_use]
    pub fn lights_pending(&self) -> usize {
        self.lights_pending.len()
    }

    /// The scene's point, spot and IES lights shut inside closed geometry
    /// ([`lights::enclosed`]), whose light cannot get out.
    #[must_use]
    pub fn enclosed_lights(&self) -> Vec<usize> {
        let reach = lights::sun_reach(self.scene);
        (0..self.scene.lights.len())
            .filter(|&i| {
                lights::enclosed(
                    &self.scene.lights[i],
                    self.scene,
                    self.occluder.as_ref(),
                    reach,
                )
            })
            .collect()
    }

    /// Power each of the scene's lights has sent so far, W per channel (a
    /// point, spot or luminaire: its flux once shot; a sun or sky: what it
    /// delivered to the mesh's elements).
    #[must_use]
    pub fn light_power(&self) -> &[DVec3] {
        &self.light_power
    }

    /// Unshot power left over emitted power (luminance-weighted). The
    /// unshot power is taken in magnitude, element by element
    /// ([`Shooter::unshot_magnitude`]): with `--overshoot` an element may
    /// hold negative unshot radiosity, which must be shot back too, so it
    /// counts as much as positive radiosity still to be shot.
    #[must_use]
    pub fn unshot_fraction(&self) -> f64 {
        let emitted = luminance(self.energy.emitted);
        if emitted <= 0.0 {
            return 0.0;
        }
        let pending: DVec3 = self
            .lights_pending
            .iter()
            .filter_map(|&i| self.scene.lights[i].flux())
            .sum();
        luminance(self.shooter.unshot_magnitude(self.mesh) + pending) / emitted
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
        if !self.lights_pending.is_empty() {
            return None;
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
    /// abandoned). The time spent in `after_shot` (a live view held paused)
    /// does not count against the limit.
    pub fn run(&mut self, mut after_shot: impl FnMut(&Solver<'_>) -> Flow) -> StopReason {
        let start = Instant::now();
        let mut abort = Abort {
            deadline: self.settings.time_limit.map(|limit| start + limit),
            flag: self.interrupt.clone(),
        };
        let reason = loop {
            if let Some(reason) = self.stop_reason() {
                break reason;
            }
            if let Some(reason) = abort.reason() {
                break reason;
            }
            if !self.shoot_unless(&abort) {
                break abort.reason().unwrap_or(StopReason::Stopped);
            }
            if self.synced.elapsed() >= CHECKPOINT_INTERVAL {
                self.checkpoint();
            }
            let called = Instant::now();
            let flow = after_shot(self);
            abort.postpone(called.elapsed());
            if flow == Flow::Stop {
                break StopReason::Stopped;
            }
        };
        self.checkpoint();
        reason
    }

    /// Reads a device's state back (nothing for a method that keeps it on
    /// the host): the receivers' irradiance and the vertices' radiosity,
    /// `B = E_surface + rho E`, become current, and the ledger is saved
    /// with them. A device that fails here leaves the solve at its last
    /// checkpoint, on the CPU.
    fn checkpoint(&mut self) {
        self.synced = Instant::now();
        match self
            .shooter
            .checkpoint(&mut self.irradiance, &mut self.direct)
        {
            Checkpoint::Host => {}
            Checkpoint::Taken => {
                for (i, v) in self.mesh.vertices.iter().enumerate() {
                    let s = &self.scene.surfaces[v.surface as usize];
                    self.radiosity[i] = s.emission + s.rho * self.irradiance[i];
                }
                self.saved = (self.energy, self.stats.clone());
            }
            Checkpoint::RolledBack => self.roll_back(),
        }
    }

    /// Back to the last checkpoint's ledger and counters (the receivers'
    /// irradiance and radiosity are still the checkpoint's: a device's
    /// shots change them only when its state is read back).
    fn roll_back(&mut self) {
        // The shots made again are not replayed twice: no going on.
        self.record = None;
        let (energy, stats) = self.saved.clone();
        self.energy = energy;
        self.stats = stats;
    }

    /// One step: a light's shot, or the method's round (the brightest
    /// shooter and those shooting with it send their unshot radiosity to
    /// every receiver), then the book-keeping of design.md step 5.
    pub fn shoot(&mut self) {
        self.shoot_unless(&Abort::default());
        self.checkpoint();
    }

    /// [`Solver::shoot`], abandoned (returning false, nothing changed) if
    /// `abort` fires during it. Lights not shot yet go first, each once; a
    /// sun's or sky's power is what arrives at the mesh's elements, added
    /// to the emitted power as it shoots.
    fn shoot_unless(&mut self, abort: &Abort) -> bool {
        let context = ShotInputs {
            scene: self.scene,
            mesh: self.mesh,
            settings: &self.settings,
            occluder: self.occluder.as_ref(),
            receivers: &self.receivers,
            irradiance: &self.irradiance,
            direct: &self.direct,
            abort,
        };
        let light = self.lights_pending.first().copied();
        if light.is_some()
            && self.light_segments.is_none()
            && self.light_fault.is_none()
            && let Some(backend) = self.settings.device.get()
        {
            match backend.segments(self.scene) {
                Ok(segments) => self.light_segments = Some(segments),
                Err(e) => self.light_fault = Some(e.0),
            }
        }
        let (irradiance, direct, element_means, power, selection_time, shooters) = match light {
            Some(index) => {
                let light = &self.scene.lights[index];
                let on_device = self.light_segments.as_deref();
                let shot = match lights::shoot(light, &context, on_device, &mut self.stats) {
                    Ok(shot) => {
                        self.other_device_shots += u64::from(on_device.is_some() && shot.is_some());
                        shot
                    }
                    // The device failed: this light and the rest on the CPU.
                    Err(e) => {
                        self.light_fault = Some(e.0);
                        self.light_segments = None;
                        lights::shoot(light, &context, None, &mut self.stats).unwrap_or(None)
                    }
                };
                let Some(shot) = shot else {
                    return false;
                };
                // A light's shot is direct.
                (
                    shot.irradiance,
                    None,
                    shot.element_means,
                    light.flux(),
                    Duration::ZERO,
                    1,
                )
            }
            None => {
                let Some(shot) = self.shooter.shoot(&context, &mut self.stats) else {
                    if self.shooter.rolled_back() {
                        // The device failed: the shots since the last
                        // checkpoint are made again, on the CPU.
                        self.direct_partial = true;
                        self.roll_back();
                        return true;
                    }
                    return false;
                };
                if let Some(received) = shot.booked {
                    self.keep(resume::Step::Method);
                    let book_start = Instant::now();
                    self.book_ledger(received, shot.power, shot.shooters);
                    self.stats.bookkeeping_time +=
                        (Instant::now() - book_start) + shot.selection_time;
                    return true;
                }
                (
                    shot.irradiance,
                    Some(shot.direct),
                    None,
                    Some(shot.power),
                    shot.selection_time,
                    shot.shooters,
                )
            }
        };
        let book_start = Instant::now();
        let received_before = self.energy.received;
        let sent = self.book(&irradiance, element_means.as_deref(), power, shooters);
        for (d, e) in self
            .direct
            .iter_mut()
            .zip(direct.as_ref().unwrap_or(&irradiance))
        {
            *d += *e;
        }
        if let Some(index) = light
            && self.scene.lights[index].sky().is_some()
        {
            for (d, e) in self.sky.iter_mut().zip(&irradiance) {
                *d += *e;
            }
        }
        if self.record.is_some() {
            self.keep(match light {
                Some(index) => resume::Step::Light {
                    index,
                    vertex: irradiance[..self.mesh.vertices.len()].to_vec(),
                    means: element_means,
                },
                None => resume::Step::Method,
            });
        }
        if let Some(index) = light {
            self.lights_pending.remove(0);
            self.light_power[index] = sent;
            self.shooter
                .light_received(self.energy.received - received_before);
        }
        self.stats.bookkeeping_time += (Instant::now() - book_start) + selection_time;
        self.saved = (self.energy, self.stats.clone());
        true
    }

    /// The ledger's part of the book-keeping, for a shot booked on a
    /// device: the power sent, received, absorbed and escaped.
    fn book_ledger(&mut self, received: Received, power: DVec3, shooters: u64) {
        self.energy.shot += power;
        self.energy.received += received.incident;
        self.energy.absorbed += received.absorbed;
        self.energy.escaped += power - received.incident;
        self.stats.shots += shooters;
        self.stats.rounds += 1;
    }

    /// The book-keeping of design.md step 5 after a shot that gave the
    /// receivers `irradiance` and sent `power` (`None` for a sun or sky:
    /// the power that arrived at the elements, which then also counts as
    /// emitted); returns the power sent.
    fn book(
        &mut self,
        irradiance: &[DVec3],
        element_means: Option<&[DVec3]>,
        power: Option<DVec3>,
        shooters: u64,
    ) -> DVec3 {
        let vertices = self.mesh.vertices.len();
        for (i, e) in irradiance.iter().enumerate() {
            self.irradiance[i] += *e;
            if i < vertices {
                let rho = self.scene.surfaces[self.mesh.vertices[i].surface as usize].rho;
                self.radiosity[i] += rho * *e;
            }
        }
        let received = self.shooter.receive(
            self.scene,
            self.mesh,
            &irradiance[..vertices],
            element_means,
        );
        let power = power.unwrap_or_else(|| {
            self.energy.emitted += received.incident;
            received.incident
        });
        self.book_ledger(received, power, shooters);
        power
    }
}
