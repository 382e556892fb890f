//! What a run did: its [`Outcome`] (counts, counters, times, files written)
//! and the `--stats` file of design.md section 6 made from it.

use std::path::PathBuf;
use std::time::Duration;

use crate::final_gather::FinalGather;
use crate::memory;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::device::DeviceReport;
use crate::solver::{Counter, MethodSettings, Settings, Stats, StopReason};

/// What a run did.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Scene name.
    pub scene: String,
    /// Surface, patch, element and vertex counts.
    pub counts: Counts,
    /// Solver counters.
    pub stats: Stats,
    /// The method's own counters ([`crate::solver::Solver::counters`]).
    pub counters: Vec<(&'static str, Counter)>,
    /// Why the solve stopped.
    pub stop: StopReason,
    /// Unshot fraction at the end.
    pub unshot_fraction: f64,
    /// Where the emitted power went ([`crate::solver::Solver::energy`]).
    pub energy: crate::solver::Energy,
    /// Time to read the scene and merge its coplanar faces.
    pub load_time: Duration,
    /// Time to build the element mesh.
    pub mesh_time: Duration,
    /// Time of the solve alone: building the accelerator, setting up the
    /// solver and shooting.
    pub solve_time: Duration,
    /// Time to build the shadow-ray accelerator (part of `solve_time`).
    pub accel_build_time: Duration,
    /// Time to draw the picture and write the outputs, the statistics file
    /// excepted (it cannot time its own writing).
    pub write_time: Duration,
    /// Of `write_time`, the final pass's ([`crate::final_gather`]): setting
    /// it up, the picture's samples and the sensors (a lightmap's texels
    /// are in its own report).
    pub final_gather_time: Duration,
    /// Time of the whole run.
    pub total_time: Duration,
    /// Worker threads.
    pub threads: usize,
    /// The accelerator's build statistics.
    pub accel_statistics: Vec<(&'static str, usize)>,
    /// Files written.
    pub written: Vec<PathBuf>,
    /// Outputs asked for but not written: the run was ended
    /// ([`super::Observer::abort`]) before the final pass had made them.
    pub unwritten: Vec<PathBuf>,
    /// Warnings from loading.
    pub warnings: Vec<String>,
    /// The most memory the process held resident, bytes, when the outputs
    /// were written (`None` where the system does not say).
    pub peak_memory_bytes: Option<u64>,
    /// The estimate the run was checked against before its solve.
    pub memory_estimate: memory::Estimate,
    /// The scene's lights and the power each sent.
    pub lights: Vec<LightPower>,
    /// What a lightmap bake made.
    pub lightmap: Option<crate::export::lightmap::LightmapReport>,
    /// Where the solve's shots ran (the coarse pass's are counted in
    /// [`Counts::coarse_device_shots`]).
    pub device: DeviceReport,
}

/// A light of the run and the power it sent (the `--stats` file's
/// `lights`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LightPower {
    /// How messages name it.
    pub name: String,
    /// `point`, `spot`, `sun`, `sky` or `ies`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// W per channel: a point, spot or luminaire's flux; what a sun or sky
    /// delivered to the surfaces; zero for a light not shot.
    pub power_watts: [f64; 3],
    /// The same in lumens (Radiance's 179 lm/W and RGB weights).
    pub lumens: f64,
}

impl LightPower {
    /// The lights of `scene` with the power `power` gives each.
    #[must_use]
    pub fn of(scene: &crate::scene::Scene, power: &[glam::DVec3]) -> Vec<LightPower> {
        scene
            .lights
            .iter()
            .zip(power)
            .map(|(light, p)| LightPower {
                name: light.name.clone(),
                kind: light.kind.name(),
                power_watts: p.to_array(),
                lumens: crate::photometry::lux(*p),
            })
            .collect()
    }
}

/// Sizes of a meshed scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    /// Planar convex input surfaces.
    pub surfaces: usize,
    /// Surface ids: surfaces after merging adjacent coplanar faces.
    pub surface_ids: usize,
    /// Shooting units: patches, or the shooters of adaptive shooting.
    pub patches: usize,
    /// Receiving elements.
    pub elements: usize,
    /// Shared vertices.
    pub vertices: usize,
    /// Elements of the base grid, before receiver refinement.
    pub base_elements: usize,
    /// Base elements the refinement split.
    pub refined_elements: usize,
    /// Shots of refinement's coarse pass (0 without refinement).
    pub coarse_shots: u64,
    /// Why the coarse pass stopped (`None` without refinement), written as
    /// [`StopReason::describe`] says it: "time limit reached" says a
    /// `--time-limit` cut it short, so the mesh depends on how fast the
    /// machine was.
    #[serde(serialize_with = "describe_stop")]
    pub coarse_stop_reason: Option<StopReason>,
    /// Shots of the coarse pass whose transfers ran on the device (`--device`).
    pub coarse_device_shots: u64,
    /// Receivers the coarse pass's shots were replayed to when the solve
    /// went on on the refined mesh: its new vertices and the sensors (0
    /// when it did not go on).
    pub replayed_receivers: usize,
    /// Shots replayed to them.
    pub replayed_shots: usize,
}

/// A stop reason as its description, `null` for none.
fn describe_stop<S: serde::Serializer>(
    reason: &Option<StopReason>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    match reason {
        Some(reason) => serializer.serialize_str(reason.describe()),
        None => serializer.serialize_none(),
    }
}

impl Counts {
    /// Counts of a meshed scene.
    #[must_use]
    pub fn of(scene: &Scene, mesh: &Mesh) -> Counts {
        let mut ids: Vec<u32> = scene.surfaces.iter().map(|s| s.group).collect();
        ids.sort_unstable();
        ids.dedup();
        Counts {
            surfaces: scene.surfaces.len(),
            surface_ids: ids.len(),
            patches: mesh.patches.len(),
            elements: mesh.elements.len(),
            vertices: mesh.vertices.len(),
            base_elements: mesh.elements.len(),
            refined_elements: 0,
            coarse_shots: 0,
            coarse_stop_reason: None,
            coarse_device_shots: 0,
            replayed_receivers: 0,
            replayed_shots: 0,
        }
    }
}

/// The `--stats` file of design.md section 6: one JSON object of the run's
/// counts, counters, phase times (seconds) and the settings in force. The
/// keys are written sorted, whatever the order of the fields below.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StatsFile {
    /// Scene name.
    pub scene: String,
    /// `surfaces`, `surface_ids`, `patches` (shooters), `elements`,
    /// `vertices`.
    #[serde(flatten)]
    pub counts: Counts,
    /// `shots`, `subsources`, `pairs`, `rays_cast` and the solver's times:
    /// `gather_seconds`, `pretest_thread_seconds`, `ray_thread_seconds`,
    /// `form_factor_thread_seconds`, `bookkeeping_seconds`.
    #[serde(flatten)]
    pub solver: Stats,
    /// Every method's own counters: the run's method's, and the others' at
    /// zero, so the keys are the same whatever the method (`pretest_visible`,
    /// `pretest_hidden`, `hemicube_seconds` are patch shooting's).
    #[serde(flatten, serialize_with = "all_counters")]
    pub counters: Vec<(&'static str, Counter)>,
    /// Unshot power left over emitted power.
    pub unshot_fraction: f64,
    /// Shot power that arrived at no element, over the emitted power
    /// (luminance): light that left through an opening, and the difference
    /// between the exact transfers and their estimate at the vertices
    /// (each element takes its corners' mean irradiance), which in a closed
    /// scene is light lost.
    pub escaped_fraction: f64,
    /// Power absorbed over the emitted power (luminance).
    pub absorbed_fraction: f64,
    /// Why the solve stopped ([`StopReason::describe`]).
    pub stop_reason: &'static str,
    /// Reading the scene and merging its coplanar faces.
    pub load_seconds: f64,
    /// Building the element mesh.
    pub mesh_seconds: f64,
    /// The solve: accelerator build, solver set-up and shooting.
    pub solve_seconds: f64,
    /// Building the shadow-ray accelerator (part of `solve_seconds`).
    pub accel_build_seconds: f64,
    /// Drawing the picture and writing the other outputs.
    pub write_seconds: f64,
    /// Of `write_seconds`, the final pass: its set-up, the picture's
    /// samples and the sensors.
    pub final_gather_seconds: f64,
    /// The whole run up to writing this file.
    pub total_seconds: f64,
    /// Most memory held resident, bytes (`null` where the system does not
    /// say).
    pub peak_memory_bytes: Option<u64>,
    /// The estimate the run was checked against before its solve, bytes.
    pub estimated_memory_bytes: u64,
    /// Worker threads.
    pub threads: usize,
    /// The accelerator's build statistics by name
    /// ([`crate::accel::Occluder::build_statistics`]).
    pub accel_build: std::collections::BTreeMap<&'static str, usize>,
    /// The settings in force, the mesh sizes being those the run used.
    pub settings: RunSettings,
    /// The scene's lights that are not surfaces (point, spot, sun, sky,
    /// IES) and the power each sent.
    pub lights: Vec<LightPower>,
    /// The lightmap of a `--bake-target lightmap` run (`null` otherwise).
    pub lightmap: Option<crate::export::lightmap::LightmapReport>,
    /// The device the transfers ran on: `cpu`, or the GPU adapter's name
    /// and backend.
    pub device: String,
    /// Shots that ran on that device (a GPU: every shot unless it failed;
    /// a light's shot draws its points on the host and traces them there).
    pub device_shots: u64,
    /// Why the device stopped being used, when it failed (`null`
    /// otherwise): the solve went on on the CPU.
    pub device_fault: Option<String>,
    /// Times the host waited for the device (blocking readbacks) over the
    /// solve, but for checkpoints: the same count on any adapter.
    pub device_host_waits: u64,
    /// Passes the device ran (one a shot, two for a shot that also sends
    /// negative light): each waits once for its ledger.
    pub device_passes: u64,
    /// Checkpoints of the solve on the device (the state read back, every
    /// quarter of a second of the clock).
    pub device_checkpoints: u64,
    /// Command buffers submitted to the device over the solve, but for
    /// checkpoints.
    pub device_submissions: u64,
    /// Bytes read back from the device over the solve, but for checkpoints.
    pub device_bytes_read: u64,
    /// Seconds making the device's kernels (compiling them, or loading
    /// them from the cache kept across runs); 0 on the CPU.
    pub device_pipeline_seconds: f64,
    /// That cache: `off`, `unsupported`, `compiled` or `loaded` (`null`
    /// on the CPU).
    pub device_pipeline_cache: Option<String>,
    /// Bind groups and buffers the device's solve made after its setup
    /// (a buffer grown for a larger upload and the bind groups that read
    /// it): a few a solve, where each round once made its own.
    pub device_objects_made: u64,
    /// The device's shots' critical paths summed: each shot's most source
    /// nodes visited by one thread (walks, then split items).
    pub device_longest_visits: u64,
    /// The device's shots' mean walks summed (node visits over walks):
    /// against `device_longest_visits`, how evenly a shot's work spreads.
    pub device_mean_visits: f64,
    /// The device's shots' time preparing and sending their data, seconds.
    pub device_upload_seconds: f64,
    /// The device's shots' kernel time (waited for), seconds.
    pub device_kernel_seconds: f64,
    /// The device's shots' time reading results back, seconds.
    pub device_readback_seconds: f64,
    /// The device's shots' time by stage (`walk`, `items`, `join`,
    /// `book`), seconds by the device's own clock (`null` on the CPU, or
    /// where the device does not say).
    pub device_stage_seconds: Option<std::collections::BTreeMap<&'static str, f64>>,
}

/// The settings of a run as the statistics file gives them: one flat
/// object, the solve's settings and the job's final pass beside them.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RunSettings {
    /// The solve's settings.
    #[serde(flatten)]
    pub solve: Settings,
    /// What the outputs showed (`--final-gather`).
    pub final_gather: FinalGather,
}

/// A run's method counters with every other method's at zero, as a map.
fn all_counters<S: serde::Serializer>(
    counters: &[(&'static str, Counter)],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut all = MethodSettings::all_zero_counters();
    for (name, value) in counters {
        match all.iter_mut().find(|c| c.0 == *name) {
            Some(slot) => slot.1 = *value,
            None => all.push((name, *value)),
        }
    }
    let mut map = serializer.serialize_map(Some(all.len()))?;
    for (name, value) in all {
        map.serialize_entry(name, &value.json())?;
    }
    map.end()
}

impl StatsFile {
    /// The statistics of a run that solved with `settings` and showed its
    /// results through the final pass `final_gather`.
    #[must_use]
    pub fn of(settings: &Settings, final_gather: FinalGather, outcome: &Outcome) -> StatsFile {
        StatsFile {
            scene: outcome.scene.clone(),
            counts: outcome.counts,
            solver: outcome.stats.clone(),
            counters: outcome.counters.clone(),
            unshot_fraction: outcome.unshot_fraction,
            escaped_fraction: share(outcome.energy.escaped, outcome.energy.emitted),
            absorbed_fraction: share(outcome.energy.absorbed, outcome.energy.emitted),
            stop_reason: outcome.stop.describe(),
            load_seconds: outcome.load_time.as_secs_f64(),
            mesh_seconds: outcome.mesh_time.as_secs_f64(),
            solve_seconds: outcome.solve_time.as_secs_f64(),
            accel_build_seconds: outcome.accel_build_time.as_secs_f64(),
            write_seconds: outcome.write_time.as_secs_f64(),
            final_gather_seconds: outcome.final_gather_time.as_secs_f64(),
            total_seconds: outcome.total_time.as_secs_f64(),
            peak_memory_bytes: outcome.peak_memory_bytes,
            estimated_memory_bytes: outcome.memory_estimate.total(),
            threads: outcome.threads,
            accel_build: outcome.accel_statistics.iter().copied().collect(),
            settings: RunSettings {
                solve: settings.clone(),
                final_gather,
            },
            lights: outcome.lights.clone(),
            lightmap: outcome.lightmap.clone(),
            device: outcome
                .device
                .name
                .clone()
                .unwrap_or_else(|| "cpu".to_string()),
            device_shots: outcome.device.device_shots,
            device_fault: outcome.device.fault.clone(),
            device_host_waits: outcome.device.traffic.host_waits,
            device_checkpoints: outcome.device.traffic.checkpoints,
            device_passes: outcome.device.passes,
            device_submissions: outcome.device.traffic.submissions,
            device_bytes_read: outcome.device.traffic.bytes_read,
            device_objects_made: outcome.device.traffic.made,
            device_pipeline_seconds: outcome.device.kernels.time.as_secs_f64(),
            device_pipeline_cache: outcome.device.kernels.cache.map(str::to_string),
            device_longest_visits: outcome.device.longest_visits,
            device_mean_visits: outcome.device.mean_visits,
            device_upload_seconds: outcome.device.upload_time.as_secs_f64(),
            device_kernel_seconds: outcome.device.kernel_time.as_secs_f64(),
            device_readback_seconds: outcome.device.readback_time.as_secs_f64(),
            device_stage_seconds: outcome.device.stages.map(|s| {
                s.named()
                    .into_iter()
                    .map(|(name, time)| (name, time.as_secs_f64()))
                    .collect()
            }),
        }
    }

    /// Writes the file as pretty-printed JSON with its keys sorted, and a
    /// final newline.
    pub fn write(&self, w: &mut dyn std::io::Write) -> std::io::Result<()> {
        // Through a `Value`, whose objects keep their keys sorted.
        let value = serde_json::to_value(self)?;
        serde_json::to_writer_pretty(&mut *w, &value)?;
        w.write_all(b"\n")
    }
}

/// `part` over `whole`, by luminance (0 for no emission).
fn share(part: glam::DVec3, whole: glam::DVec3) -> f64 {
    let whole = crate::luminance(whole);
    if whole > 0.0 {
        crate::luminance(part) / whole
    } else {
        0.0
    }
}
