//! What the twin tests share: the adapter, a test kernel's run, the
//! device's `f32` views of `f64` values and random polygons about a
//! receiver (the kinds `twins.rs` lists: grazing, coplanar, clipped to
//! nothing, slivers).

#![allow(dead_code)]

#[path = "../../../radiosity/tests/common/rng.rs"]
pub mod rng;

use glam::DVec3;
use radiosity::geometry;
use radiosity_gpu::Gpu;
use rng::Rng;
use wgpu::util::DeviceExt;

/// `f32`'s unit round-off.
pub const EPS: f64 = f32::EPSILON as f64;

/// A polygon about a receiver at the origin (`Case` in the kernels).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Case {
    pub p: [[f32; 4]; 4],
    pub normal: [f32; 4],
    pub source_normal: [f32; 4],
    pub count: u32,
    pub tolerance: f32,
    pub pad: [u32; 2],
}

/// The tests' adapter ([`radiosity_gpu::test_adapter`]).
pub fn gpu() -> Option<Gpu> {
    radiosity_gpu::test_adapter()
}

/// The outputs of the entry point `entry` of `source` for `cases`: the
/// cases at binding `bindings.0`, one output each at `bindings.1`.
pub fn run_kernel<C: bytemuck::Pod, O: bytemuck::Pod>(
    gpu: &Gpu,
    source: &str,
    entry: &str,
    bindings: (u32, u32),
    cases: &[C],
) -> Vec<O> {
    let device = &gpu.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(entry),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module: &module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions::default(),
        cache: None,
    });
    let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("cases"),
        contents: bytemuck::cast_slice(cases),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let bytes = (cases.len() * size_of::<O>()) as u64;
    let output = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("outs"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(entry),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: bindings.0,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: bindings.1,
                resource: output.as_entire_binding(),
            },
        ],
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        let groups = (cases.len() as u32).div_ceil(radiosity_gpu::shaders::WORKGROUP);
        pass.dispatch_workgroups(groups, 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &readback, 0, bytes);
    gpu.queue.submit([encoder.finish()]);
    let slice = readback.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    bytemuck::cast_slice::<u8, O>(&slice.get_mapped_range().unwrap()).to_vec()
}

pub fn f32s(v: DVec3) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, 0.0]
}

pub fn read(v: [f32; 4]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
}

/// A random polygon around the receiver (at the origin, its normal
/// `normal`), of one of the kinds the header lists.
pub fn case(rng: &mut Rng, normal: DVec3) -> Case {
    let count = if rng.chance(0.5) { 3 } else { 4 };
    let size = rng.range(0.05, 2.0);
    let centre = rng.point_in(DVec3::splat(-3.0), DVec3::splat(3.0));
    let u = rng.unit_vector();
    let mut w = rng.unit_vector().cross(u).normalize_or_zero();
    if w == DVec3::ZERO {
        w = u.any_orthonormal_vector();
    }
    let mut corners: Vec<DVec3> = (0..count)
        .map(|k| {
            let a = std::f64::consts::TAU * (k as f64 + rng.range(-0.3, 0.3)) / count as f64;
            centre + size * (a.cos() * u + a.sin() * w)
        })
        .collect();
    // Polygons whose plane holds the receiver's normal are not sensible
    // sources of factors; the analytic twin handles them, the header's
    // kinds come next.
    match rng.below(6) {
        // Grazing: a corner or two on the tangent plane.
        0 => {
            for c in corners.iter_mut().take(1 + rng.below(2)) {
                *c -= normal * normal.dot(*c);
            }
        }
        // Coplanar: all in the tangent plane.
        1 => {
            for c in &mut corners {
                *c -= normal * normal.dot(*c);
            }
        }
        // Behind: clipped to nothing.
        2 => {
            for c in &mut corners {
                let d = normal.dot(*c);
                *c -= normal * (d.abs() + rng.range(0.01, 1.0) + d);
            }
        }
        // A sliver: two corners almost together.
        3 => corners[1] = corners[0] + (corners[1] - corners[0]) * 1e-3,
        _ => {}
    }
    // As the device reads them.
    let corners: Vec<[f32; 4]> = corners.iter().map(|c| f32s(*c)).collect();
    let back: Vec<DVec3> = corners.iter().map(|c| read(*c)).collect();
    let source_normal = geometry::normal(&back).unwrap_or(normal);
    let mut p = [[0.0; 4]; 4];
    p[..count].copy_from_slice(&corners);
    Case {
        p,
        normal: f32s(normal),
        source_normal: f32s(source_normal),
        count: count as u32,
        tolerance: if rng.chance(0.5) {
            0.0
        } else {
            (size * 1e-3) as f32
        },
        pad: [0; 2],
    }
}

/// `v` as the device holds a point: the nearest `f32` and its round-off.
pub fn split(v: DVec3) -> ([f32; 4], [f32; 4]) {
    let hi = f32s(v);
    (hi, f32s(v - read(hi)))
}

/// A random node's box about the origin (`lo`, `hi`: up to 2 m across,
/// flat in y at times), its middle and half extent, and a centre inside
/// it with the radius of the sphere about it that holds the box.
pub struct NodeBox {
    pub lo: DVec3,
    pub hi: DVec3,
    pub middle: DVec3,
    pub half: DVec3,
    pub centre: DVec3,
    pub radius: f64,
}

/// A [`NodeBox`] drawn from `rng`.
pub fn node_box(rng: &mut Rng) -> NodeBox {
    let half = DVec3::new(
        rng.range(0.01, 2.0),
        rng.range(0.0, 2.0),
        rng.range(0.01, 2.0),
    );
    let middle = rng.point_in(DVec3::splat(-5.0), DVec3::splat(5.0));
    let (lo, hi) = (middle - half, middle + half);
    let centre = rng.point_in(lo, hi);
    // The farthest corner from the centre.
    let radius = [lo, hi]
        .iter()
        .flat_map(|a| [lo, hi].map(move |b| (a, b)))
        .flat_map(|(a, b)| [lo, hi].map(move |c| DVec3::new(a.x, b.y, c.z)))
        .map(|corner| corner.distance(centre))
        .fold(0.0, f64::max);
    NodeBox {
        lo,
        hi,
        middle,
        half,
        centre,
        radius,
    }
}
