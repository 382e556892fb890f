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
use crate::form_factor::{FormFactor, Source};
use crate::geometry;
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
    /// A shooting patch is split into `subsources x subsources` subsources.
    pub subsources: u32,
    /// Stop when the unshot power falls below this fraction of the emitted
    /// power.
    pub converge: f64,
    /// Stop after this many shots (patches shot).
    pub max_shots: Option<u64>,
    /// Stop once this many subsources have been shot.
    pub max_subsources: Option<u64>,
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
            subsources: 3,
            converge: DEFAULT_CONVERGE,
            max_shots: None,
            max_subsources: None,
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
        if !(self.converge.is_finite() && (0.0..1.0).contains(&self.converge)) {
            return Err(format!(
                "--converge must be a fraction in [0, 1), not {}",
                self.converge
            ));
        }
        if self.converge == 0.0 && self.max_shots.is_none() && self.max_subsources.is_none() {
            return Err(
                "--converge 0 never stops by itself: give --max-shots or --max-subsources".into(),
            );
        }
        Ok(())
    }
}

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
    /// Time in shots (visibility and form factors, in parallel).
    pub gather_time: Duration,
    /// Time in book-keeping (selection, element and patch updates).
    pub bookkeeping_time: Duration,
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
    /// Unshot radiosity of each patch.
    unshot: Vec<DVec3>,
    /// Where each vertex gathers: the vertex moved a hair into its own
    /// surface (see [`GATHER_NUDGE`]).
    gather_points: Vec<DVec3>,
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
        let radiosity = mesh
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
            occluder: settings.accel.build(&scene.surfaces),
            settings,
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

    /// Shoots until a stopping rule holds; `progress` is called after each
    /// shot.
    pub fn run(&mut self, mut progress: impl FnMut(&Solver<'_>)) -> StopReason {
        loop {
            if let Some(reason) = self.stop_reason() {
                return reason;
            }
            self.shoot();
            progress(self);
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
        let context = ShotContext {
            occluder: self.occluder.as_ref(),
            form_factor: self.settings.form_factor,
            subsources: &subsources,
            source_normal: surface.normal,
            source_offset: surface.offset,
            source_surface: surface_index,
            tolerance: 1e-9 * surface.area.sqrt().max(1e-9),
        };
        let gather_start = Instant::now();
        let gathered: Vec<Gathered> = self
            .mesh
            .vertices
            .par_iter()
            .zip(&self.gather_points)
            .with_min_len(64)
            .map(|(v, x)| context.gather(v, *x))
            .collect();
        let gather_end = Instant::now();

        let mut increments = Vec::with_capacity(gathered.len());
        for ((v, g), b) in self
            .mesh
            .vertices
            .iter()
            .zip(&gathered)
            .zip(&mut self.radiosity)
        {
            let rho = self.scene.surfaces[v.surface as usize].rho;
            let increment = rho * unshot * g.factor;
            *b += increment;
            increments.push(increment);
            self.stats.pairs += u64::from(g.pairs);
            self.stats.rays_cast += u64::from(g.rays);
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
        self.stats.gather_time += gather_end - gather_start;
        self.stats.bookkeeping_time += (gather_start - start) + (Instant::now() - gather_end);
    }
}

/// What one vertex gathers in one shot.
#[derive(Clone, Copy, Debug, Default)]
struct Gathered {
    /// `sum_k delta_kj F_jk`.
    factor: f64,
    pairs: u32,
    rays: u32,
}

/// Everything a vertex needs to gather from the shooting patch.
struct ShotContext<'s> {
    occluder: &'s dyn Occluder,
    form_factor: FormFactor,
    subsources: &'s [mesh::Subsource],
    source_normal: DVec3,
    source_offset: f64,
    source_surface: u32,
    tolerance: f64,
}

impl ShotContext<'_> {
    fn gather(&self, vertex: &mesh::Vertex, x: DVec3) -> Gathered {
        let mut out = Gathered::default();
        if vertex.surface == self.source_surface {
            return out;
        }
        let n = vertex.normal;
        // The receiver must be in front of the source's plane.
        if self.source_normal.dot(x) - self.source_offset <= 0.0 {
            return out;
        }
        let mut clipped = Vec::with_capacity(8);
        for sub in self.subsources {
            // Some of the subsource must be in front of the receiver's plane.
            let heights = sub.polygon.iter().map(|c| n.dot(*c - x));
            let (mut any_front, mut all_front) = (false, true);
            for h in heights {
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
            out.pairs += 1;
            out.rays += 1;
            let (from, to) = accel::shorten(origin, x);
            if self
                .occluder
                .occluded(from, to, [self.source_surface, vertex.surface])
            {
                continue;
            }
            let source = Source {
                polygon: &sub.polygon,
                centroid: sub.centroid,
                normal: self.source_normal,
                area: sub.area,
            };
            out.factor += self.form_factor.evaluate(x, n, &source);
        }
        out
    }
}
