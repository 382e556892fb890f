//! The paper's shooting (Wallace, Elmquist & Haines 1989, as used by Wong &
//! Tsang 1993; design.md section 2): the patch with the largest unshot power
//! shoots its one uniform unshot radiosity, split into an `n x n` grid of
//! subsources, to every receiver, which gathers `dE_j = dB_i sum_k delta_kj
//! F_jk`. Visibility is a shadow ray from the subsource's centre (or from
//! the centroid of the part in front of the receiver), optionally decided
//! first by the hemicube pre-test of section 2; `F_jk` is equation (1), (3)
//! or (2). Book-keeping: each element's increment is the mean of its
//! vertices', each patch's unshot radiosity grows by the area-weighted mean
//! of its elements'.

use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

use super::method::{
    Counter, Emission, Kind, Method, MethodError, Parameter, Received, SetError, Shooter, Shot,
    ShotInputs, Stats, VISIBILITY, Value, Visibility,
};
use super::{Receiver, Settings};
use crate::accel::{self, Occluder};
use crate::form_factor::{self, FormFactor, Source};
use crate::geometry;
use crate::hemicube::{self, ItemBuffer, Pretest};
use crate::luminance;
use crate::mesh::{self, Mesh};
use crate::scene::Scene;
use crate::solver::costs;

/// The paper's method's own parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchSettings {
    /// How visibility is decided.
    pub visibility: Visibility,
    /// Pixels across the top face of the pre-test hemicube.
    pub hemicube_resolution: u32,
    /// A shooting patch is split into `subsources x subsources`
    /// subsources.
    pub subsources: u32,
}

impl Default for PatchSettings {
    /// Wallace et al.'s: rays for every pair, 3 x 3 subsources.
    fn default() -> Self {
        PatchSettings {
            visibility: Visibility::Ray,
            hemicube_resolution: hemicube::DEFAULT_RESOLUTION,
            subsources: 3,
        }
    }
}

/// `--hemicube-resolution`.
const HEMICUBE_RESOLUTION: Parameter = Parameter {
    name: "hemicube_resolution",
    value_name: "N",
    help: "Pixels across the top face of the pre-test hemicube",
    kind: Kind::Count,
};

/// `--subsources`.
const SUBSOURCES: Parameter = Parameter {
    name: "subsources",
    value_name: "N",
    help: "A shooting patch is split into N x N subsources",
    kind: Kind::Count,
};

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

/// Settings patch shooting cannot run with.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PatchSettingsError {
    /// Subsources per side out of range.
    #[error("--subsources must be between 1 and {MAX_SUBSOURCES_PER_SIDE}, not {0}")]
    Subsources(u64),
    /// Hemicube resolution out of range.
    #[error("--hemicube-resolution must be between 8 and {MAX_HEMICUBE_RESOLUTION}, not {0}")]
    HemicubeResolution(u64),
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
}

impl Method for PatchSettings {
    fn parameters(&self) -> &'static [Parameter] {
        &[VISIBILITY, HEMICUBE_RESOLUTION, SUBSOURCES]
    }

    fn set(&mut self, name: &str, value: &Value) -> Result<(), SetError> {
        // A count beyond u32 is out of range: refused with validate's words.
        let count = |error: fn(u64) -> PatchSettingsError| {
            let v = value.count(name)?;
            u32::try_from(v).map_err(|_| SetError::Refused(MethodError::new(error(v))))
        };
        match name {
            "visibility" => self.visibility = value.choice(name)?,
            "hemicube_resolution" => {
                self.hemicube_resolution = count(PatchSettingsError::HemicubeResolution)?;
            }
            "subsources" => self.subsources = count(PatchSettingsError::Subsources)?,
            _ => return Err(SetError::NotMine),
        }
        Ok(())
    }

    fn values(&self) -> Vec<(&'static str, serde_json::Value)> {
        vec![
            ("visibility", self.visibility.name().into()),
            ("hemicube_resolution", self.hemicube_resolution.into()),
            ("subsources", self.subsources.into()),
        ]
    }

    fn validate(&self) -> Result<(), MethodError> {
        if !(1..=MAX_SUBSOURCES_PER_SIDE).contains(&self.subsources) {
            return Err(MethodError::new(PatchSettingsError::Subsources(
                self.subsources.into(),
            )));
        }
        if !(8..=MAX_HEMICUBE_RESOLUTION).contains(&self.hemicube_resolution) {
            return Err(MethodError::new(PatchSettingsError::HemicubeResolution(
                self.hemicube_resolution.into(),
            )));
        }
        if self.visibility == Visibility::HemicubePretest {
            let bytes = item_buffer_bytes(self.subsources, self.hemicube_resolution);
            if bytes > MAX_ITEM_BUFFER_BYTES {
                return Err(MethodError::new(PatchSettingsError::ItemBuffers {
                    subsources: self.subsources,
                    resolution: self.hemicube_resolution,
                    bytes,
                }));
            }
        }
        Ok(())
    }

    fn zero_counters(&self) -> Vec<(&'static str, Counter)> {
        PatchCounters::default().list()
    }

    fn memory(&self) -> costs::SolverCosts {
        let mut parts = Vec::new();
        if self.visibility == Visibility::HemicubePretest {
            parts.push(costs::Part {
                name: "item buffers",
                count: 1,
                each: item_buffer_bytes(self.subsources, self.hemicube_resolution) as f64,
                remedy: "lower --hemicube-resolution or --subsources",
            });
        }
        // Measured on the shared scenes (EXPERIMENTS.md, "Memory").
        costs::SolverCosts {
            vertex: 264.0,
            element: 0.0,
            surface: 260.0,
            parts,
        }
    }

    fn start<'a>(
        &self,
        scene: &'a Scene,
        mesh: &'a Mesh,
        _settings: &Settings,
        _receivers: &[Receiver],
    ) -> Box<dyn Shooter + 'a> {
        Box::new(PatchShooting::new(scene, mesh, self))
    }
}

/// The pre-test's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct PatchCounters {
    /// Pairs the hemicube pre-test found visible without a ray.
    pretest_visible: u64,
    /// Pairs the hemicube pre-test found hidden without a ray.
    pretest_hidden: u64,
    /// Wall time rasterising the hemicube item buffers.
    hemicube_time: Duration,
}

impl PatchCounters {
    fn list(&self) -> Vec<(&'static str, Counter)> {
        vec![
            ("pretest_visible", Counter::Count(self.pretest_visible)),
            ("pretest_hidden", Counter::Count(self.pretest_hidden)),
            ("hemicube_seconds", Counter::Seconds(self.hemicube_time)),
        ]
    }
}

/// The state of patch shooting.
struct PatchShooting {
    settings: PatchSettings,
    /// Unshot radiosity of each patch.
    unshot: Vec<DVec3>,
    /// The patches whose emission is still unshot.
    emission: Emission,
    /// One item buffer per subsource, reused from shot to shot.
    item_buffers: Vec<ItemBuffer>,
    counters: PatchCounters,
}

impl PatchShooting {
    /// Unshot radiosity `E` of each patch's surface; item buffers allocated
    /// up front so no shot pays for them.
    fn new(scene: &Scene, mesh: &Mesh, settings: &PatchSettings) -> PatchShooting {
        PatchShooting {
            emission: Emission::new(scene, mesh.patches.len(), |i| mesh.patches[i].surface),
            settings: settings.clone(),
            unshot: mesh
                .patches
                .iter()
                .map(|p| scene.surfaces[p.surface as usize].emission)
                .collect(),
            item_buffers: match settings.visibility {
                Visibility::Ray => Vec::new(),
                Visibility::HemicubePretest => {
                    let bounds = scene.bounds();
                    (0..settings.subsources * settings.subsources)
                        .map(|_| ItemBuffer::for_scene(settings.hemicube_resolution, bounds))
                        .collect()
                }
            },
            counters: PatchCounters::default(),
        }
    }

    /// The patch with the largest unshot power `lum(dB_i) A_i`.
    fn brightest_patch(&self, mesh: &Mesh) -> usize {
        let mut best = 0;
        let mut best_power = f64::NEG_INFINITY;
        for (i, (p, u)) in mesh.patches.iter().zip(&self.unshot).enumerate() {
            let power = luminance(*u) * p.area;
            if power > best_power {
                best_power = power;
                best = i;
            }
        }
        best
    }
}

impl Shooter for PatchShooting {
    fn shooters(&self) -> usize {
        self.unshot.len()
    }

    fn unshot_power(&self, mesh: &Mesh) -> DVec3 {
        mesh.patches
            .iter()
            .zip(&self.unshot)
            .map(|(p, u)| *u * p.area)
            .sum()
    }

    /// One shot of the brightest patch; its unshot radiosity is zeroed.
    fn shoot(&mut self, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Option<Shot> {
        let start = Instant::now();
        let (scene, mesh) = (inputs.scene, inputs.mesh);
        let shooter = self.brightest_patch(mesh);
        let patch = &mesh.patches[shooter];
        let surface_index = patch.surface;
        let surface = &scene.surfaces[surface_index as usize];
        let unshot = self.unshot[shooter];
        let emitted = self
            .emission
            .take(scene, std::iter::once((shooter, patch.surface, patch.area)));
        let subsources = mesh::subsources(&patch.polygon, self.settings.subsources);

        let hemicube_start = Instant::now();
        let item_buffers = match self.settings.visibility {
            Visibility::Ray => None,
            Visibility::HemicubePretest => {
                // One buffer per subsource, allocated by `new`.
                debug_assert_eq!(self.item_buffers.len(), subsources.len());
                let surfaces = &scene.surfaces;
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
            occluder: inputs.occluder,
            item_buffers,
            form_factor: inputs.settings.form_factor,
            subsources: &subsources,
            source_polygon: &patch.polygon,
            source_normal: surface.normal,
            source_offset: surface.offset,
            source_group: surface.group,
            tolerance: 1e-9 * surface.area.sqrt().max(1e-9),
        };
        let gather_start = Instant::now();
        // Chunks of a fixed size (not a per-thread split) keep every sum in
        // the same order whatever the thread count.
        let chunk = (PAIRS_PER_CHUNK / subsources.len()).clamp(1, 256);
        let gathered: Vec<(Vec<Gathered>, PhaseTimes)> = inputs
            .receivers
            .par_chunks(chunk)
            .map(|receivers| {
                if inputs.abort.fired() {
                    (Vec::new(), PhaseTimes::default())
                } else {
                    context.gather(receivers)
                }
            })
            .collect();
        let gather_end = Instant::now();
        if inputs.abort.fired() {
            return None;
        }

        let mut irradiance = Vec::with_capacity(inputs.receivers.len());
        for (chunk, times) in &gathered {
            stats.pretest_time += times.pretest;
            stats.ray_time += times.rays;
            stats.form_factor_time += times.form_factors;
            for g in chunk {
                irradiance.push(unshot * g.factor);
                stats.pairs += u64::from(g.pairs);
                stats.rays_cast += u64::from(g.rays);
                self.counters.pretest_visible += u64::from(g.pretest_visible);
                self.counters.pretest_hidden += u64::from(g.pretest_hidden);
            }
        }
        self.unshot[shooter] = DVec3::ZERO;
        stats.subsources += subsources.len() as u64;
        self.counters.hemicube_time += gather_start - hemicube_start;
        stats.gather_time += gather_end - gather_start;
        Some(Shot::single(
            irradiance,
            unshot * patch.area,
            emitted,
            hemicube_start - start,
        ))
    }

    /// Adds the reflected part of what the elements received to their
    /// patches' unshot radiosity (the area-weighted mean over the patch).
    fn receive(
        &mut self,
        scene: &Scene,
        mesh: &Mesh,
        irradiance: &[DVec3],
        element_means: Option<&[DVec3]>,
    ) -> Received {
        let mut reflected = vec![DVec3::ZERO; mesh.patches.len()];
        let received = super::method::receive_at_elements(
            scene,
            mesh,
            irradiance,
            element_means,
            |e, radiosity| {
                let element = &mesh.elements[e];
                reflected[element.patch as usize] += radiosity * element.area;
            },
        );
        for ((u, r), p) in self.unshot.iter_mut().zip(reflected).zip(&mesh.patches) {
            *u += r / p.area;
        }
        received
    }

    fn counters(&self) -> Vec<(&'static str, Counter)> {
        self.counters.list()
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

/// Thread time spent in each phase of gathering a chunk of receivers.
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
    source_group: u32,
    tolerance: f64,
}

impl ShotContext<'_> {
    /// Gathers for a chunk of receivers in three timed phases: pairing with
    /// the pre-test, shadow rays for the undecided pairs, form factors for
    /// the visible ones.
    fn gather(&self, receivers: &[Receiver]) -> (Vec<Gathered>, PhaseTimes) {
        let t0 = Instant::now();
        let mut out = vec![Gathered::default(); receivers.len()];
        let mut pairs: Vec<Pair> = Vec::with_capacity(receivers.len() * self.subsources.len());
        let mut clipped = Vec::with_capacity(8);
        // Receivers in front of the source's plane.
        let in_front: Vec<usize> = (0..receivers.len())
            .filter(|&i| {
                receivers[i].group != self.source_group
                    && self.source_normal.dot(receivers[i].point) - self.source_offset > 0.0
            })
            .collect();
        // Subsource by subsource, so consecutive look-ups stay in one item
        // buffer (neighbouring vertices fall on neighbouring pixels); every
        // vertex still meets the subsources in the same order, so its sum
        // below does not depend on this.
        for (k, sub) in self.subsources.iter().enumerate() {
            for &i in &in_front {
                let (receiver, x) = (&receivers[i], receivers[i].point);
                let n = receiver.normal;
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
                    Some(buffers) if all_front => match buffers[k].classify(x, receiver.surface) {
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
            let (from, to) = accel::shorten(pair.origin, receivers[i].point);
            pair.visible =
                !self
                    .occluder
                    .occluded(from, to, [self.source_group, receivers[i].group]);
        }
        let t2 = Instant::now();
        // The analytic factor is additive over a partition of the source:
        // a receiver that sees every subsource whole gets the factor of the
        // whole patch, one contour of its outline instead of one per
        // subsource, equal to the sum to round-off (Figure 4.5 of the paper;
        // tests/experiments.rs checks it to 1e-9). The disk formulas are not
        // additive, so they always go subsource by subsource.
        let mut whole_patch = vec![false; receivers.len()];
        if self.form_factor == FormFactor::Analytic {
            let mut seen = vec![0usize; receivers.len()];
            for pair in pairs.iter().filter(|p| p.visible && p.whole) {
                seen[pair.vertex as usize] += 1;
            }
            for (i, count) in seen.into_iter().enumerate() {
                if count == self.subsources.len() {
                    whole_patch[i] = true;
                    out[i].factor = form_factor::analytic(
                        receivers[i].point,
                        receivers[i].normal,
                        self.source_polygon,
                    );
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
            out[i].factor +=
                self.form_factor
                    .evaluate(receivers[i].point, receivers[i].normal, &source);
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
