//! The GPU's shadow segments against the CPU: every buffer's Rust struct
//! against its WGSL twin (sizes and offsets, from naga's reading of the
//! shader), and the `occluded` kernel against the CPU's brute-force oracle
//! on the built-in scenes: the same answer for every segment but those
//! that graze a surface (whose CPU answer itself flips when the segment
//! moves by a millionth of the scene), and exactly the right answer on a
//! segment through the shared edge and the shared corner of two triangles.
//!
//! Without an adapter the agreement tests say they did not run, unless
//! `RADIOSITY_REQUIRE_GPU` is set (CI sets it, with Mesa's software Vulkan
//! installed): then they fail.

#[allow(dead_code)]
#[path = "../../radiosity/tests/common/rng.rs"]
mod rng;

use glam::DVec3;
use radiosity::accel::Occluder;
use radiosity::accel::brute::BruteForce;
use radiosity::scene::Surface;
use radiosity_gpu::Gpu;
use radiosity_gpu::trace::{
    DISPATCH_SEGMENTS, GpuDispatch, GpuNode, GpuSegment, GpuTriangle, SceneTracer, Segment, grazes,
};
use rng::Rng;

/// The tests' adapter ([`radiosity_gpu::test_adapter`]).
fn gpu() -> Option<Gpu> {
    radiosity_gpu::test_adapter()
}

/// Size and member offsets of the WGSL struct `name` in the trace module.
fn wgsl_layout(name: &str) -> (u32, Vec<(String, u32)>) {
    let module = naga::front::wgsl::parse_str(&radiosity_gpu::shaders::trace_source()).unwrap();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    let (handle, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name} in the trace module"));
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("{name} is not a struct");
    };
    assert_eq!(layouter[handle].size, *span);
    (
        *span,
        members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
            .collect(),
    )
}

/// A struct's name, its Rust size and its members' Rust offsets.
type RustLayout = (&'static str, usize, Vec<(&'static str, usize)>);

#[test]
fn buffer_structs_match_their_wgsl_twins() {
    use std::mem::{offset_of, size_of};
    let cases: [RustLayout; 4] = [
        (
            "Node",
            size_of::<GpuNode>(),
            vec![
                ("lo", offset_of!(GpuNode, lo)),
                ("link", offset_of!(GpuNode, link)),
                ("hi", offset_of!(GpuNode, hi)),
                ("kind", offset_of!(GpuNode, kind)),
            ],
        ),
        (
            "Triangle",
            size_of::<GpuTriangle>(),
            vec![
                ("a", offset_of!(GpuTriangle, a)),
                ("group", offset_of!(GpuTriangle, group)),
                ("b", offset_of!(GpuTriangle, b)),
                ("pad0", offset_of!(GpuTriangle, pad0)),
                ("c", offset_of!(GpuTriangle, c)),
                ("pad1", offset_of!(GpuTriangle, pad1)),
                ("a_lo", offset_of!(GpuTriangle, a_lo)),
                ("pad2", offset_of!(GpuTriangle, pad2)),
                ("b_lo", offset_of!(GpuTriangle, b_lo)),
                ("pad3", offset_of!(GpuTriangle, pad3)),
                ("c_lo", offset_of!(GpuTriangle, c_lo)),
                ("pad4", offset_of!(GpuTriangle, pad4)),
                ("normal", offset_of!(GpuTriangle, normal)),
                ("pad5", offset_of!(GpuTriangle, pad5)),
            ],
        ),
        (
            "Segment",
            size_of::<GpuSegment>(),
            vec![
                ("p0", offset_of!(GpuSegment, p0)),
                ("skip0", offset_of!(GpuSegment, skip0)),
                ("p1", offset_of!(GpuSegment, p1)),
                ("skip1", offset_of!(GpuSegment, skip1)),
                ("p0_lo", offset_of!(GpuSegment, p0_lo)),
                ("pad0", offset_of!(GpuSegment, pad0)),
                ("p1_lo", offset_of!(GpuSegment, p1_lo)),
                ("pad1", offset_of!(GpuSegment, pad1)),
            ],
        ),
        (
            "Dispatch",
            size_of::<GpuDispatch>(),
            vec![
                ("first", offset_of!(GpuDispatch, first)),
                ("count", offset_of!(GpuDispatch, count)),
                ("pad0", offset_of!(GpuDispatch, pad0)),
                ("pad1", offset_of!(GpuDispatch, pad1)),
            ],
        ),
    ];
    for (name, size, offsets) in cases {
        let (span, members) = wgsl_layout(name);
        assert_eq!(span as usize, size, "{name}: WGSL size vs Rust");
        let rust: Vec<(String, u32)> = offsets
            .iter()
            .map(|(n, o)| ((*n).to_string(), *o as u32))
            .collect();
        assert_eq!(members, rust, "{name}: member names and offsets");
    }
}

/// A random point on a random surface, a hair in front of it (as a vertex
/// or a subsource is placed), and the surface's id.
fn surface_point(surfaces: &[Surface], random: &mut Rng, scale: f64) -> (DVec3, u32) {
    let s = &surfaces[random.below(surfaces.len())];
    let p = &s.polygon;
    let i = 1 + random.below(p.len() - 2);
    let (mut u, mut v) = (random.unit(), random.unit());
    if u + v > 1.0 {
        (u, v) = (1.0 - u, 1.0 - v);
    }
    let point = p[0] + u * (p[i] - p[0]) + v * (p[i + 1] - p[0]);
    (point + 1e-6 * scale * s.normal, s.group)
}

/// Segments between random surface points (shadow segments as the solve
/// casts them), and between random points of the scene's box.
fn segments(surfaces: &[Surface], count: usize) -> Vec<Segment> {
    let (lo, hi) = surfaces
        .iter()
        .flat_map(|s| s.polygon.iter())
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let scale = (hi - lo).max_element();
    let mut random = Rng(0x5eed);
    (0..count)
        .map(|k| {
            if k % 4 == 3 {
                let mut inside =
                    || lo + (hi - lo) * DVec3::new(random.unit(), random.unit(), random.unit());
                Segment {
                    from: inside(),
                    to: inside(),
                    skip: [u32::MAX; 2],
                }
            } else {
                let (from, a) = surface_point(surfaces, &mut random, scale);
                let (to, b) = surface_point(surfaces, &mut random, scale);
                Segment {
                    from,
                    to,
                    skip: [a, b],
                }
            }
        })
        .collect()
}

/// On the built-in scenes, the GPU blocks exactly the segments the CPU's
/// brute force does, but for grazing ones (at most one in a thousand).
#[test]
fn occluded_agrees_with_the_brute_force_oracle() {
    let Some(gpu) = gpu() else { return };
    eprintln!("adapter: {}", gpu.name());
    for name in ["cornell", "room"] {
        let scene = radiosity::scene::load(name).unwrap();
        let surfaces = &scene.surfaces;
        let tracer = SceneTracer::new(&gpu, surfaces).unwrap();
        let cpu = BruteForce::new(surfaces);
        let segments = segments(surfaces, 20_000);
        let gpu_answers = tracer.occluded(&segments).unwrap();
        assert_eq!(gpu_answers.len(), segments.len());
        let (lo, hi) = scene.bounds();
        let scale = (hi - lo).max_element();
        let mut blocked = 0;
        let mut differ = Vec::new();
        for (segment, &answer) in segments.iter().zip(&gpu_answers) {
            let expected = cpu.occluded(segment.from, segment.to, segment.skip);
            blocked += usize::from(expected);
            if answer != expected {
                differ.push(*segment);
            }
        }
        eprintln!(
            "{name}: {} triangles, {} segments, {blocked} blocked, {} differ",
            tracer.triangle_count(),
            segments.len(),
            differ.len()
        );
        // Both answers occur often: the comparison means something.
        assert!(blocked > segments.len() / 10 && blocked < 9 * segments.len() / 10);
        assert!(differ.len() * 1000 <= segments.len(), "{name}: {differ:?}");
        for segment in &differ {
            assert!(
                grazes(&cpu, segment, 1e-6 * scale),
                "{name}: the GPU and the CPU differ on a segment that grazes nothing: {segment:?}"
            );
        }
    }
}

/// A square of two triangles: a segment through their shared edge, or
/// through the corner they share, is blocked (watertight); one ending on
/// the square's plane, or skipping its surface, is not; no triangles, or
/// no segments, answer at once.
#[test]
fn shared_edges_and_corners_block() {
    let Some(gpu) = gpu() else { return };
    let square = Surface::new(
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ],
        DVec3::splat(0.5),
        DVec3::ZERO,
        0,
    )
    .unwrap();
    let group = square.group;
    let tracer = SceneTracer::new(&gpu, std::slice::from_ref(&square)).unwrap();
    assert_eq!(tracer.triangle_count(), 2);
    let through = |x: f64, y: f64| Segment {
        from: DVec3::new(x, y, 1.0),
        to: DVec3::new(x, y, -1.0),
        skip: [u32::MAX; 2],
    };
    let diagonal: Vec<Segment> = (0..=16)
        .map(|k| f64::from(k) / 16.0)
        .map(|t| through(t, t))
        .collect();
    let mut cases = diagonal.clone();
    cases.push(through(0.0, 0.0));
    cases.push(through(1.0, 1.0));
    cases.push(Segment {
        from: DVec3::new(0.5, 0.5, 1.0),
        to: DVec3::new(0.5, 0.5, 0.0),
        skip: [u32::MAX; 2],
    });
    cases.push(Segment {
        skip: [group, u32::MAX],
        ..through(0.5, 0.25)
    });
    cases.push(through(1.5, 0.5));
    let answers = tracer.occluded(&cases).unwrap();
    let n = diagonal.len();
    assert!(answers[..n].iter().all(|&b| b), "the diagonal: {answers:?}");
    assert_eq!(&answers[n..], [true, true, false, false, false]);
    assert!(tracer.occluded(&[]).unwrap().is_empty());
    let empty = SceneTracer::new(&gpu, &[]).unwrap();
    assert_eq!(empty.occluded(&cases[..2]).unwrap(), [false, false]);
}

/// More segments than one dispatch traces (several passes, the device's
/// timestamps around the first and the last): every one answered as the
/// CPU's BVH answers it but for a few grazing ones, and the kernel's time
/// read where the device has timestamps.
#[test]
fn more_segments_than_a_dispatch_are_all_answered() {
    let Some(gpu) = gpu() else { return };
    let scene = radiosity::scene::load("room").unwrap();
    let surfaces = &scene.surfaces;
    let tracer = SceneTracer::new(&gpu, surfaces).unwrap();
    let segments = segments(surfaces, 2 * DISPATCH_SEGMENTS + 1_000);
    let answers = tracer.occluded(&segments).unwrap();
    assert_eq!(answers.len(), segments.len());
    let bvh = radiosity::accel::bvh::Bvh::new(surfaces);
    let (lo, hi) = scene.bounds();
    let scale = (hi - lo).max_element();
    let differ: Vec<&Segment> = segments
        .iter()
        .zip(&answers)
        .filter(|(s, a)| **a != bvh.occluded(s.from, s.to, s.skip))
        .map(|(s, _)| s)
        .collect();
    assert!(
        differ.len() * 1000 <= segments.len(),
        "{} differ",
        differ.len()
    );
    assert!(differ.iter().all(|s| grazes(&bvh, s, 1e-6 * scale)));
    let timed = gpu
        .device
        .features()
        .contains(wgpu::Features::TIMESTAMP_QUERY);
    assert_eq!(tracer.traced_seconds().is_some(), timed);
    assert!(tracer.traced_seconds().is_none_or(|t| t > 0.0));
}
