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

use super::{Received, Receiver, Settings, Shot, ShotInputs, Stats, Visibility};
use crate::accel::{self, Occluder};
use crate::form_factor::{self, FormFactor, Source};
use crate::geometry;
use crate::hemicube::{ItemBuffer, Pretest};
use crate::luminance;
use crate::mesh::{self, Mesh};
use crate::scene::Scene;

/// The state of patch shooting.
pub(crate) struct PatchShooting {
    /// Unshot radiosity of each patch.
    unshot: Vec<DVec3>,
    /// One item buffer per subsource, reused from shot to shot.
    item_buffers: Vec<ItemBuffer>,
}

impl PatchShooting {
    /// Unshot radiosity `E` of each patch's surface; item buffers allocated
    /// up front so no shot pays for them.
    pub(crate) fn new(scene: &Scene, mesh: &Mesh, settings: &Settings) -> PatchShooting {
        PatchShooting {
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
        }
    }

    /// Unshot power, per channel.
    pub(crate) fn unshot_power(&self, mesh: &Mesh) -> DVec3 {
        mesh.patches
            .iter()
            .zip(&self.unshot)
            .map(|(p, u)| *u * p.area)
            .sum()
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

    /// One shot of the brightest patch; its unshot radiosity is zeroed.
    pub(crate) fn shoot(&mut self, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Option<Shot> {
        let start = Instant::now();
        let (scene, mesh, settings) = (inputs.scene, inputs.mesh, inputs.settings);
        let shooter = self.brightest_patch(mesh);
        let patch = &mesh.patches[shooter];
        let surface_index = patch.surface;
        let surface = &scene.surfaces[surface_index as usize];
        let unshot = self.unshot[shooter];
        let subsources = mesh::subsources(&patch.polygon, settings.subsources);

        let hemicube_start = Instant::now();
        let item_buffers = match settings.visibility {
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
            form_factor: settings.form_factor,
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
                stats.pretest_visible += u64::from(g.pretest_visible);
                stats.pretest_hidden += u64::from(g.pretest_hidden);
            }
        }
        self.unshot[shooter] = DVec3::ZERO;
        stats.subsources += subsources.len() as u64;
        stats.hemicube_time += gather_start - hemicube_start;
        stats.gather_time += gather_end - gather_start;
        Some(Shot {
            irradiance,
            power: unshot * patch.area,
            selection_time: hemicube_start - start,
        })
    }

    /// Adds the reflected part of what the elements received to their
    /// patches' unshot radiosity (the area-weighted mean over the patch).
    pub(crate) fn receive(&mut self, scene: &Scene, mesh: &Mesh, irradiance: &[DVec3]) -> Received {
        let mut reflected = vec![DVec3::ZERO; mesh.patches.len()];
        let received = super::receive_at_elements(scene, mesh, irradiance, |e, radiosity| {
            let element = &mesh.elements[e];
            reflected[element.patch as usize] += radiosity * element.area;
        });
        for ((u, r), p) in self.unshot.iter_mut().zip(reflected).zip(&mesh.patches) {
            *u += r / p.area;
        }
        received
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
