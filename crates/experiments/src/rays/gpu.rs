//! The `rays` experiment's GPU column, beyond the paper: every segment the
//! solver recorded, traced at once by the GPU back end's `occluded` kernel
//! ([`radiosity_gpu::trace`]), timed from the host's call to its answers
//! (segment upload, the kernel and the readback; the scene's upload
//! apart), and checked against the CPU's BVH on every segment. The GPU
//! works in `f32` relative to the scene's centre, so a few grazing
//! segments may be answered otherwise: they are counted, not hidden.

use std::time::Instant;

use rayon::prelude::*;

use super::Segment;
use crate::{Error, median};
use radiosity::accel::Occluder;
use radiosity::accel::bvh::Bvh;
use radiosity::scene::Scene;
use radiosity_gpu::Gpu;
use radiosity_gpu::trace::{self, SceneTracer};

/// What the GPU did on one scene's recorded segments.
#[derive(Clone, Debug)]
pub struct GpuRun {
    /// Triangles the surfaces were cut into.
    pub triangles: usize,
    /// Seconds to build the tree and upload the scene.
    pub upload_seconds: f64,
    /// Segments traced each time.
    pub segments: usize,
    /// Wall seconds of each repetition (upload of the segments, kernel,
    /// readback).
    pub seconds: Vec<f64>,
    /// The kernel's own seconds in each repetition, by the device's
    /// timestamps (empty where it has none).
    pub kernel_seconds: Vec<f64>,
    /// Segments the GPU answered otherwise than the CPU's BVH.
    pub differ: usize,
    /// Of those, the ones that do not graze a surface (the CPU's own answer
    /// holds when their ends move by a millionth of the scene's size): a
    /// fault, where there are any.
    pub differ_not_grazing: usize,
    /// Segments blocked, by the CPU's answer.
    pub blocked: usize,
}

impl GpuRun {
    /// Median segments a second.
    #[must_use]
    pub fn segments_per_second(&self) -> f64 {
        self.segments as f64 / median(&mut self.seconds.clone()).max(1e-12)
    }

    /// Median segments a second of the kernel alone, where the device
    /// timed it.
    #[must_use]
    pub fn kernel_segments_per_second(&self) -> Option<f64> {
        (!self.kernel_seconds.is_empty())
            .then(|| self.segments as f64 / median(&mut self.kernel_seconds.clone()).max(1e-12))
    }
}

/// Traces `segments` on `gpu` `repetitions` times and compares the answers
/// with the CPU's BVH.
///
/// # Errors
///
/// When the GPU fails.
pub fn measure(
    gpu: &Gpu,
    scene: &Scene,
    segments: &[Segment],
    repetitions: usize,
) -> Result<GpuRun, Error> {
    let failed = |e: radiosity_gpu::GpuError| Error::Experiment(e.to_string());
    let start = Instant::now();
    let tracer = SceneTracer::new(gpu, &scene.surfaces).map_err(failed)?;
    let upload_seconds = start.elapsed().as_secs_f64();
    let queries: Vec<trace::Segment> = segments
        .iter()
        .map(|s| trace::Segment {
            from: s.from,
            to: s.to,
            skip: s.skip,
        })
        .collect();
    let bvh = Bvh::new(&scene.surfaces);
    let expected: Vec<bool> = segments
        .par_iter()
        .map(|s| bvh.occluded(s.from, s.to, s.skip))
        .collect();
    let mut seconds = Vec::new();
    let mut kernel_seconds = Vec::new();
    let mut answers = Vec::new();
    for _ in 0..repetitions.max(1) {
        let start = Instant::now();
        answers = tracer.occluded(&queries).map_err(failed)?;
        seconds.push(start.elapsed().as_secs_f64());
        kernel_seconds.extend(tracer.traced_seconds());
    }
    let differing: Vec<&trace::Segment> = queries
        .iter()
        .zip(answers.iter().zip(&expected))
        .filter(|(_, (a, b))| a != b)
        .map(|(q, _)| q)
        .collect();
    let (lo, hi) = scene.bounds();
    let distance = 1e-6 * (hi - lo).max_element();
    let differ_not_grazing = differing
        .par_iter()
        .filter(|q| !trace::grazes(&bvh, q, distance))
        .count();
    Ok(GpuRun {
        triangles: tracer.triangle_count(),
        upload_seconds,
        segments: segments.len(),
        seconds,
        kernel_seconds,
        differ: differing.len(),
        differ_not_grazing,
        blocked: expected.iter().filter(|&&b| b).count(),
    })
}
