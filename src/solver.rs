//! The progressive-refinement shooting loop of Wallace, Elmquist & Haines
//! (1989), as used by Wong & Tsang (1993) and fixed by design.md section 2.
//!
//! Each shot takes the patch with the largest unshot power, splits it into
//! subsources, and lets every unique mesh vertex gather
//! `dB_j = rho_j dB_i sum_k delta_kj F_jk`. Vertices are processed in
//! parallel, each one's sum in a fixed order, so the result does not depend
//! on the number of threads.

use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

use crate::accel::{self, Accel, Occluder};
use crate::form_factor::{self, FormFactor, Source};
use crate::geometry;
use crate::hemicube::{self, ItemBuffer, Pretest};
use crate::luminance;
use crate::mesh::{self, Mesh, MeshSettings};
use crate::scene::Scene;

/// Every setting of a solve, apart from run state. Presets are named
/// constructors; each field can be overridden on its own.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Patch and element sizes.
    pub mesh: MeshSettings,
    /// Point-to-polygon formula.
    pub form_factor: FormFactor,
    /// Shadow-segment accelerator.
    pub accel: Accel,
    /// How visibility is decided.
    pub visibility: Visibility,
    /// Pixels across the top face of the pre-test hemicube.
    pub hemicube_resolution: u32,
    /// A shooting patch is split into `subsources x subsources` subsources.
    pub subsources: u32,
    /// Stop when the unshot power falls below this fraction of the emitted
    /// power.
    pub converge: f64,
    /// Stop after this many shots (patches shot).
    pub max_shots: Option<u64>,
    /// Stop once this many subsources have been shot.
    pub max_subsources: Option<u64>,
    /// Stop before a shot once the solve has run this long.
    pub time_limit: Option<Duration>,
}

/// Default `--converge`.
pub const DEFAULT_CONVERGE: f64 = 0.01;

impl Settings {
    /// Wallace, Elmquist & Haines (1989): a shadow ray for every pair against
    /// every surface, the disk form factor of equation (1), 3 x 3 subsources.
    #[must_use]
    pub fn wallace89() -> Settings {
        Settings {
            mesh: MeshSettings::default(),
            form_factor: FormFactor::Wallace,
            accel: Accel::Brute,
            visibility: Visibility::Ray,
            hemicube_resolution: hemicube::DEFAULT_RESOLUTION,
            subsources: 3,
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

    /// Checks the settings a user can get wrong.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=MAX_SUBSOURCES_PER_SIDE).contains(&self.subsources) {
            return Err(format!(
                "--subsources must be between 1 and {MAX_SUBSOURCES_PER_SIDE}, not {}",
                self.subsources
            ));
        }
        if !(8..=MAX_HEMICUBE_RESOLUTION).contains(&self.hemicube_resolution) {
            return Err(format!(
                "--hemicube-resolution must be between 8 and {MAX_HEMICUBE_RESOLUTION}, not {}",
                self.hemicube_resolution
            ));
        }
        if self.visibility == Visibility::HemicubePretest {
            let bytes = item_buffer_bytes(self.subsources, self.hemicube_resolution);
            if bytes > MAX_ITEM_BUFFER_BYTES {
                return Err(format!(
                    "{0} x {0} subsources with hemicubes of {1} pixels need {2:.1} GiB of item \
                     buffers (limit {3} GiB): lower --subsources or --hemicube-resolution",
                    self.subsources,
                    self.hemicube_resolution,
                    bytes as f64 / (1u64 << 30) as f64,
                    MAX_ITEM_BUFFER_BYTES >> 30
                ));
            }
        }
        if !(self.converge.is_finite() && (0.0..1.0).contains(&self.converge)) {
            return Err(format!(
                "--converge must be a fraction in [0, 1), not {}",
                self.converge
            ));
        }
        if self.converge == 0.0
            && self.max_shots.is_none()
            && self.max_subsources.is_none()
            && self.time_limit.is_none()
        {
            return Err(
                "--converge 0 never stops by itself: give --max-shots, --max-subsources or \
                 --time-limit"
                    .into(),
            );
        }
        Ok(())
    }
}

/// How a shot decides whether a vertex sees a subsource.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Visibility {
    /// A shadow ray for every pair (Wallace et al. 1989).
    Ray,
    /// The hemicube item-buffer pre-test of Wong & Tsang, section 2; rays
    /// only where it cannot decide.
    HemicubePretest,
}

impl Visibility {
    /// Every mode, in the order the command line lists them.
    pub const ALL: [Visibility; 2] = [Visibility::Ray, Visibility::HemicubePretest];

    /// The name used on the command line and in statistics.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Visibility::Ray => "ray",
            Visibility::HemicubePretest => "hemicube",
        }
    }

    /// Parses a command-line name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Visibility> {
        Visibility::ALL.into_iter().find(|v| v.name() == name)
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

/// Largest `--hemicube-resolution`.
pub const MAX_HEMICUBE_RESOLUTION: u32 = 4096;

/// Largest `--subsources` (per side): 64 x 64 = 4,096 subsources a shot.
pub const MAX_SUBSOURCES_PER_SIDE: u32 = 64;

/// Counters and timings of a solve.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// Patches shot.
    pub shots: u64,
    /// Subsources shot.
    pub subsources: u64,
    /// Vertex-subsource pairs that face each other.
    pub pairs: u64,
    /// Shadow segments traced.
    pub rays_cast: u64,
    /// Pairs the hemicube pre-test found visible without a ray.
    pub pretest_visible: u64,
    /// Pairs the hemicube pre-test found hidden without a ray.
    pub pretest_hidden: u64,
    /// Wall time rasterising the hemicube item buffers.
    pub hemicube_time: Duration,
    /// Wall time gathering at vertices (the three phases below, in
    /// parallel).
    pub gather_time: Duration,
    /// Thread time pairing vertices with subsources and applying the
    /// pre-test (summed over threads).
    pub pretest_time: Duration,
    /// Thread time casting shadow rays (summed over threads).
    pub ray_time: Duration,
    /// Thread time evaluating form factors (summed over threads).
    pub form_factor_time: Duration,
    /// Time in book-keeping (selection, element and patch updates).
    pub bookkeeping_time: Duration,
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

/// The state of a progressive solve.
pub struct Solver<'a> {
    scene: &'a Scene,
    mesh: &'a Mesh,
    settings: Settings,
    occluder: Box<dyn Occluder + 'a>,
    /// Radiosity accumulated at each vertex (emission included).
    radiosity: Vec<DVec3>,
    /// Irradiance accumulated at each vertex (W/m^2).
    irradiance: Vec<DVec3>,
    /// Unshot radiosity of each patch.
    unshot: Vec<DVec3>,
    /// Where each vertex gathers: the vertex moved a hair into its own
    /// surface (see [`GATHER_NUDGE`]).
    gather_points: Vec<DVec3>,
    /// One item buffer per subsource, reused from shot to shot.
    item_buffers: Vec<ItemBuffer>,
    emitted_power: f64,
    stats: Stats,
}

/// A vertex gathers at a point moved this fraction of the way towards its
/// surface's centroid. A vertex on the edge where two surfaces meet lies in
/// the neighbour's plane and sees it exactly edge-on (factor 0), while every
/// point of its own surface next to it sees the neighbour at up to half its
/// hemisphere; the displaced point takes the one-sided limit that the
/// element's interior tends to, and stays within 1e-6 of its size of the
/// vertex.
pub const GATHER_NUDGE: f64 = 1e-6;

impl<'a> Solver<'a> {
    /// Starts a solve: `B_v = E`, `dB_p = E` of their surfaces.
    #[must_use]
    pub fn new(scene: &'a Scene, mesh: &'a Mesh, settings: Settings) -> Solver<'a> {
        let occluder = settings.accel.build(&scene.surfaces);
        Solver::with_occluder(scene, mesh, settings, occluder)
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
        let radiosity: Vec<DVec3> = mesh
            .vertices
            .iter()
            .map(|v| scene.surfaces[v.surface as usize].emission)
            .collect();
        let unshot: Vec<DVec3> = mesh
            .patches
            .iter()
            .map(|p| scene.surfaces[p.surface as usize].emission)
            .collect();
        let emitted_power = mesh
            .patches
            .iter()
            .zip(&unshot)
            .map(|(p, e)| luminance(*e) * p.area)
            .sum();
        let centroids: Vec<DVec3> = scene
            .surfaces
            .iter()
            .map(|s| geometry::centroid(&s.polygon))
            .collect();
        let gather_points = mesh
            .vertices
            .iter()
            .map(|v| v.position + (centroids[v.surface as usize] - v.position) * GATHER_NUDGE)
            .collect();
        Solver {
            scene,
            mesh,
            gather_points,
            // Allocated up front so no shot pays for it.
            item_buffers: match settings.visibility {
                Visibility::Ray => Vec::new(),
                Visibility::HemicubePretest => (0..settings.subsources * settings.subsources)
                    .map(|_| ItemBuffer::new(settings.hemicube_resolution))
                    .collect(),
            },
            occluder,
            settings,
            irradiance: vec![DVec3::ZERO; radiosity.len()],
            radiosity,
            unshot,
            emitted_power,
            stats: Stats::default(),
        }
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
        &self.irradiance
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

    /// Unshot radiosity of each patch.
    #[must_use]
    pub fn unshot(&self) -> &[DVec3] {
        &self.unshot
    }

    /// Unshot power left over emitted power (luminance-weighted).
    #[must_use]
    pub fn unshot_fraction(&self) -> f64 {
        if self.emitted_power <= 0.0 {
            return 0.0;
        }
        let unshot: f64 = self
            .mesh
            .patches
            .iter()
            .zip(&self.unshot)
            .map(|(p, u)| luminance(*u) * p.area)
            .sum();
        unshot / self.emitted_power
    }

    /// The ambient term of Cohen et al. (1988) for display:
    /// `(sum dB_p A_p / sum A_p) / (1 - rho_avg)`, per channel.
    #[must_use]
    pub fn ambient(&self) -> DVec3 {
        let total_area = self.mesh.total_area();
        let mut unshot = DVec3::ZERO;
        let mut rho = DVec3::ZERO;
        for (p, u) in self.mesh.patches.iter().zip(&self.unshot) {
            unshot += *u * p.area;
            rho += self.scene.surfaces[p.surface as usize].rho * p.area;
        }
        (unshot / total_area) / (DVec3::ONE - rho / total_area)
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

    /// Shoots until a stopping rule holds or `after_shot`, called after
    /// each shot, returns [`Flow::Stop`]. `--time-limit` counts from this
    /// call.
    pub fn run(&mut self, mut after_shot: impl FnMut(&Solver<'_>) -> Flow) -> StopReason {
        let start = Instant::now();
        loop {
            if let Some(reason) = self.stop_reason() {
                return reason;
            }
            if self
                .settings
                .time_limit
                .is_some_and(|limit| start.elapsed() >= limit)
            {
                return StopReason::TimeLimit;
            }
            self.shoot();
            if after_shot(self) == Flow::Stop {
                return StopReason::Stopped;
            }
        }
    }

    /// The patch with the largest unshot power `lum(dB_i) A_i`.
    fn brightest_patch(&self) -> usize {
        let mut best = 0;
        let mut best_power = f64::NEG_INFINITY;
        for (i, (p, u)) in self.mesh.patches.iter().zip(&self.unshot).enumerate() {
            let power = luminance(*u) * p.area;
            if power > best_power {
                best_power = power;
                best = i;
            }
        }
        best
    }

    /// One shot: the brightest patch shoots its unshot radiosity to every
    /// vertex, then the element and patch book-keeping of design.md step 5.
    pub fn shoot(&mut self) {
        let start = Instant::now();
        let shooter = self.brightest_patch();
        let patch = &self.mesh.patches[shooter];
        let surface_index = patch.surface;
        let surface = &self.scene.surfaces[surface_index as usize];
        let unshot = self.unshot[shooter];
        let subsources = mesh::subsources(&patch.polygon, self.settings.subsources);

        let hemicube_start = Instant::now();
        let item_buffers = match self.settings.visibility {
            Visibility::Ray => None,
            Visibility::HemicubePretest => {
                // One buffer per subsource, allocated by `new`.
                debug_assert_eq!(self.item_buffers.len(), subsources.len());
                let surfaces = &self.scene.surfaces;
                self.item_buffers
                    .par_iter_mut()
                    .zip(&subsources)
                    .for_each(|(buffer, sub)| {
                        buffer.render(surfaces, sub.centroid, surface.normal, surface_index);
                    });
                Some(&self.item_buffers[..])
            }
        };
        let context = ShotContext {
            occluder: self.occluder.as_ref(),
            item_buffers,
            form_factor: self.settings.form_factor,
            subsources: &subsources,
            source_polygon: &patch.polygon,
            source_normal: surface.normal,
            source_offset: surface.offset,
            source_surface: surface_index,
            tolerance: 1e-9 * surface.area.sqrt().max(1e-9),
        };
        let gather_start = Instant::now();
        // Chunks of a fixed size (not a per-thread split) keep every sum in
        // the same order whatever the thread count.
        let chunk = (PAIRS_PER_CHUNK / subsources.len()).clamp(1, 256);
        let gathered: Vec<(Vec<Gathered>, PhaseTimes)> = self
            .mesh
            .vertices
            .par_chunks(chunk)
            .zip(self.gather_points.par_chunks(chunk))
            .map(|(vertices, points)| context.gather(vertices, points))
            .collect();
        let gather_end = Instant::now();

        let mut increments = Vec::with_capacity(self.mesh.vertices.len());
        let mut vertex = 0;
        for (chunk, times) in &gathered {
            self.stats.pretest_time += times.pretest;
            self.stats.ray_time += times.rays;
            self.stats.form_factor_time += times.form_factors;
            for g in chunk {
                let rho = self.scene.surfaces[self.mesh.vertices[vertex].surface as usize].rho;
                let irradiance = unshot * g.factor;
                let increment = rho * irradiance;
                self.irradiance[vertex] += irradiance;
                self.radiosity[vertex] += increment;
                increments.push(increment);
                self.stats.pairs += u64::from(g.pairs);
                self.stats.rays_cast += u64::from(g.rays);
                self.stats.pretest_visible += u64::from(g.pretest_visible);
                self.stats.pretest_hidden += u64::from(g.pretest_hidden);
                vertex += 1;
            }
        }
        self.unshot[shooter] = DVec3::ZERO;
        for (p, patch) in self.mesh.patches.iter().enumerate() {
            let mut sum = DVec3::ZERO;
            for e in &self.mesh.elements[patch.elements.clone()] {
                let corners = e.vertices();
                let mean = corners
                    .iter()
                    .map(|&c| increments[c as usize])
                    .sum::<DVec3>()
                    / corners.len() as f64;
                sum += mean * e.area;
            }
            self.unshot[p] += sum / patch.area;
        }
        self.stats.shots += 1;
        self.stats.subsources += subsources.len() as u64;
        self.stats.hemicube_time += gather_start - hemicube_start;
        self.stats.gather_time += gather_end - gather_start;
        self.stats.bookkeeping_time += (hemicube_start - start) + (Instant::now() - gather_end);
    }
}

/// Vertex-subsource pairs handled together by one task.
const PAIRS_PER_CHUNK: usize = 1024;

/// What one vertex gathers in one shot.
#[derive(Clone, Copy, Debug, Default)]
struct Gathered {
    /// `sum_k delta_kj F_jk`.
    factor: f64,
    pairs: u32,
    rays: u32,
    pretest_visible: u32,
    pretest_hidden: u32,
}

/// Thread time spent in each phase of gathering a chunk of vertices.
#[derive(Clone, Copy, Debug, Default)]
struct PhaseTimes {
    pretest: Duration,
    rays: Duration,
    form_factors: Duration,
}

/// One vertex-subsource pair awaiting a visibility answer or its factor.
#[derive(Clone, Copy, Debug)]
struct Pair {
    /// Index of the vertex within the chunk.
    vertex: u32,
    /// Index of the subsource.
    subsource: u32,
    /// Where the shadow segment starts.
    origin: DVec3,
    /// Decided visible (true) or still to be decided by a ray (false).
    visible: bool,
    /// The whole subsource is in front of the receiver (the segment starts
    /// at its centre).
    whole: bool,
}

/// Everything a vertex needs to gather from the shooting patch.
struct ShotContext<'s> {
    occluder: &'s dyn Occluder,
    item_buffers: Option<&'s [ItemBuffer]>,
    form_factor: FormFactor,
    subsources: &'s [mesh::Subsource],
    source_polygon: &'s [DVec3],
    source_normal: DVec3,
    source_offset: f64,
    source_surface: u32,
    tolerance: f64,
}

impl ShotContext<'_> {
    /// Gathers for a chunk of vertices in three timed phases: pairing with
    /// the pre-test, shadow rays for the undecided pairs, form factors for
    /// the visible ones. `points` are the vertices' gathering points.
    fn gather(&self, vertices: &[mesh::Vertex], points: &[DVec3]) -> (Vec<Gathered>, PhaseTimes) {
        let t0 = Instant::now();
        let mut out = vec![Gathered::default(); vertices.len()];
        let mut pairs: Vec<Pair> = Vec::with_capacity(vertices.len() * self.subsources.len());
        let mut clipped = Vec::with_capacity(8);
        // Receivers in front of the source's plane.
        let receivers: Vec<usize> = (0..vertices.len())
            .filter(|&i| {
                vertices[i].surface != self.source_surface
                    && self.source_normal.dot(points[i]) - self.source_offset > 0.0
            })
            .collect();
        // Subsource by subsource, so consecutive look-ups stay in one item
        // buffer (neighbouring vertices fall on neighbouring pixels); every
        // vertex still meets the subsources in the same order, so its sum
        // below does not depend on this.
        for (k, sub) in self.subsources.iter().enumerate() {
            for &i in &receivers {
                let (vertex, x) = (&vertices[i], points[i]);
                let n = vertex.normal;
                // Some of the subsource must be in front of the receiver's
                // plane; if only some is, visibility is tested from the
                // centroid of that part.
                let (mut any_front, mut all_front) = (false, true);
                for c in &sub.polygon {
                    let h = n.dot(*c - x);
                    any_front |= h > self.tolerance;
                    all_front &= h > self.tolerance;
                }
                if !any_front {
                    continue;
                }
                let origin = if all_front {
                    sub.centroid
                } else {
                    geometry::clip_to_half_space(&sub.polygon, x, n, 0.0, &mut clipped);
                    if geometry::area(&clipped) <= 0.0 {
                        continue;
                    }
                    geometry::centroid(&clipped)
                };
                out[i].pairs += 1;
                // The item buffer sits at the subsource's centre, so it can
                // only speak for pairs that use that centre.
                let visible = match self.item_buffers {
                    Some(buffers) if all_front => match buffers[k].classify(x, vertex.surface) {
                        Pretest::Visible => {
                            out[i].pretest_visible += 1;
                            true
                        }
                        Pretest::Hidden => {
                            out[i].pretest_hidden += 1;
                            continue;
                        }
                        Pretest::Uncertain => false,
                    },
                    _ => false,
                };
                pairs.push(Pair {
                    vertex: i as u32,
                    subsource: k as u32,
                    origin,
                    visible,
                    whole: all_front,
                });
            }
        }
        let t1 = Instant::now();
        for pair in pairs.iter_mut().filter(|p| !p.visible) {
            let i = pair.vertex as usize;
            out[i].rays += 1;
            let (from, to) = accel::shorten(pair.origin, points[i]);
            pair.visible =
                !self
                    .occluder
                    .occluded(from, to, [self.source_surface, vertices[i].surface]);
        }
        let t2 = Instant::now();
        // The analytic factor is additive over a partition of the source:
        // a receiver that sees every subsource whole gets the factor of the
        // whole patch, one contour of its outline instead of one per
        // subsource, equal to the sum to round-off (Figure 4.5 of the paper;
        // tests/experiments.rs checks it to 1e-9). The disk formulas are not
        // additive, so they always go subsource by subsource.
        let mut whole_patch = vec![false; vertices.len()];
        if self.form_factor == FormFactor::Analytic {
            let mut seen = vec![0usize; vertices.len()];
            for pair in pairs.iter().filter(|p| p.visible && p.whole) {
                seen[pair.vertex as usize] += 1;
            }
            for (i, count) in seen.into_iter().enumerate() {
                if count == self.subsources.len() {
                    whole_patch[i] = true;
                    out[i].factor =
                        form_factor::analytic(points[i], vertices[i].normal, self.source_polygon);
                }
            }
        }
        for pair in pairs
            .iter()
            .filter(|p| p.visible && !whole_patch[p.vertex as usize])
        {
            let i = pair.vertex as usize;
            let sub = &self.subsources[pair.subsource as usize];
            let source = Source {
                polygon: &sub.polygon,
                centroid: sub.centroid,
                normal: self.source_normal,
                area: sub.area,
            };
            out[i].factor += self
                .form_factor
                .evaluate(points[i], vertices[i].normal, &source);
        }
        let t3 = Instant::now();
        (
            out,
            PhaseTimes {
                pretest: t1 - t0,
                rays: t2 - t1,
                form_factors: t3 - t2,
            },
        )
    }
}
