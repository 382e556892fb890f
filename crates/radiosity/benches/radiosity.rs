//! Criterion benchmarks of the solver's hot paths on the built-in `room` at
//! its suggested mesh sizes (`#@mesh 2.5 0.15`: about 180 patches and 7,000
//! vertices), with the workloads the solver really produces.
//!
//! * `shadow_rays`: shadow segments from the centroids of the 3 x 3
//!   subsources of the room's emitting patches (the first patches shot) to
//!   every mesh vertex in front of the source's plane, shortened with
//!   [`accel::shorten`] and skipping the source's and the vertex's surfaces,
//!   subsampled deterministically to about 50,000. One thread answers the
//!   whole list with every accelerator of [`Accel::ALL`] (build excluded);
//!   the throughput is shadow rays per second on one core.
//! * `hemicube`: `render/<resolution>` rasterises one item buffer per
//!   subsource of those patches at 128, [`DEFAULT_RESOLUTION`] and 512
//!   pixels (throughput in renders per second; the time is for all of
//!   them); `classify/<resolution>` runs the pre-test on every
//!   vertex-subsource pair the solver would ask it about, against buffers
//!   rendered beforehand (throughput in pairs per second).
//! * `form_factors`: every formula of [`FormFactor::ALL`] over the
//!   vertex-subsource pairs of those patches that face each other, as the
//!   solver evaluates them (at the vertices' gathering points); throughput
//!   in evaluations per second.
//! * `shot`: the room's first shot (brightest patch, 3 x 3 subsources,
//!   every vertex) on a fresh [`Solver`] each iteration, for the
//!   `wallace89` and `wong-tsang93` presets, in a one-thread rayon pool and
//!   in a pool of the default size, to show the parallel speed-up. Building
//!   the solver (and its accelerator) is not timed; the shot's own
//!   allocations, item buffers included, are.
//!
//! Run everything with `cargo bench --bench radiosity`, one group with
//! `cargo bench --bench radiosity -- shadow_rays`, one benchmark with e.g.
//! `cargo bench --bench radiosity -- 'shot/wong-tsang93'`. Measurement times
//! are kept short (1 s warm-up, 3 s measurement, 20 samples) so the whole
//! run takes a few minutes on a shared machine.

use std::hint::black_box;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use radiosity::accel::{self, Accel};
use radiosity::form_factor::{FormFactor, Source};
use radiosity::geometry;
use radiosity::hemicube::{DEFAULT_RESOLUTION, ItemBuffer, Pretest};
use radiosity::mesh::{self, Mesh, MeshSettings, Subsource};
use radiosity::scene::{self, Scene};
use radiosity::solver::{GATHER_NUDGE, Settings, Solver};

/// Subsources per side, as both presets shoot.
const SUBSOURCES_PER_SIDE: u32 = 3;

/// About this many shadow segments are kept for `shadow_rays`.
const SHADOW_RAY_TARGET: usize = 50_000;

/// Hemicube resolutions benchmarked.
const RESOLUTIONS: [u32; 3] = [128, DEFAULT_RESOLUTION, 512];

/// One subsource of an emitting patch, with its surface's plane.
struct Shooter {
    sub: Subsource,
    surface: u32,
    normal: DVec3,
    offset: f64,
}

/// A vertex-subsource pair that faces each other, as the solver forms it.
struct Pair {
    /// Index into [`Room::shooters`].
    shooter: usize,
    /// Index into the mesh's vertices.
    vertex: usize,
    /// Every corner of the subsource lies in front of the receiver's plane,
    /// so the solver shoots from the centroid and may ask the pre-test.
    all_front: bool,
}

/// The built-in room, meshed, with the subsources of its emitting patches.
struct Room {
    scene: Scene,
    mesh: Mesh,
    mesh_settings: MeshSettings,
    /// Where each vertex gathers (the solver's nudged point).
    gather_points: Vec<DVec3>,
    shooters: Vec<Shooter>,
    pairs: Vec<Pair>,
}

fn room() -> &'static Room {
    static ROOM: OnceLock<Room> = OnceLock::new();
    ROOM.get_or_init(|| {
        let scene = scene::load("room").expect("the built-in room loads");
        let mesh_settings = MeshSettings::default().sized_for(&scene);
        let mesh = Mesh::build(&scene, &mesh_settings).expect("the room meshes");
        let centroids: Vec<DVec3> = scene
            .surfaces
            .iter()
            .map(|s| geometry::centroid(&s.polygon))
            .collect();
        let gather_points: Vec<DVec3> = mesh
            .vertices
            .iter()
            .map(|v| v.position + (centroids[v.surface as usize] - v.position) * GATHER_NUDGE)
            .collect();
        let shooters: Vec<Shooter> = mesh
            .patches
            .iter()
            .filter(|p| scene.surfaces[p.surface as usize].is_emitter())
            .flat_map(|p| {
                let surface = &scene.surfaces[p.surface as usize];
                mesh::subsources(&p.polygon, SUBSOURCES_PER_SIDE)
                    .into_iter()
                    .map(|sub| Shooter {
                        sub,
                        surface: p.surface,
                        normal: surface.normal,
                        offset: surface.offset,
                    })
            })
            .collect();
        // The solver's pairing rule (solver.rs, `ShotContext::gather`).
        let mut pairs = Vec::new();
        for (s, shooter) in shooters.iter().enumerate() {
            let tolerance = 1e-9
                * scene.surfaces[shooter.surface as usize]
                    .area
                    .sqrt()
                    .max(1e-9);
            for (v, (vertex, &x)) in mesh.vertices.iter().zip(&gather_points).enumerate() {
                if vertex.surface == shooter.surface
                    || shooter.normal.dot(x) - shooter.offset <= 0.0
                {
                    continue;
                }
                let heights = shooter
                    .sub
                    .polygon
                    .iter()
                    .map(|c| vertex.normal.dot(*c - x));
                let any_front = heights.clone().any(|h| h > tolerance);
                let all_front = heights.clone().all(|h| h > tolerance);
                if any_front {
                    pairs.push(Pair {
                        shooter: s,
                        vertex: v,
                        all_front,
                    });
                }
            }
        }
        Room {
            scene,
            mesh,
            mesh_settings,
            gather_points,
            shooters,
            pairs,
        }
    })
}

/// A criterion configuration short enough for a shared two-core machine.
fn quick() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .sample_size(20)
}

fn shadow_rays(c: &mut Criterion) {
    let room = room();
    let mut segments: Vec<(DVec3, DVec3, [u32; 2])> = Vec::new();
    for shooter in &room.shooters {
        let centroid = shooter.sub.centroid;
        for vertex in &room.mesh.vertices {
            if shooter.normal.dot(vertex.position) - shooter.offset > 0.0 {
                let (from, to) = accel::shorten(centroid, vertex.position);
                segments.push((from, to, [shooter.surface, vertex.surface]));
            }
        }
    }
    let all = segments.len();
    let stride = all.div_ceil(SHADOW_RAY_TARGET).max(1);
    let segments: Vec<_> = segments.into_iter().step_by(stride).collect();
    let n = segments.len() as u64;

    let mut group = c.benchmark_group("shadow_rays");
    group.throughput(Throughput::Elements(n));
    for accel in Accel::ALL {
        let occluder = accel.build(&room.scene.surfaces);
        let blocked = segments
            .iter()
            .filter(|(from, to, skip)| occluder.occluded(*from, *to, *skip))
            .count();
        eprintln!(
            "shadow_rays: {n} of {all} segments from {} subsources (every {stride}th), \
             {:.1}% blocked ({})",
            room.shooters.len(),
            100.0 * blocked as f64 / n as f64,
            accel.name(),
        );
        group.bench_function(accel.name(), |b| {
            b.iter(|| {
                let mut blocked = 0u32;
                for &(from, to, skip) in &segments {
                    blocked += u32::from(occluder.occluded(black_box(from), to, skip));
                }
                blocked
            });
        });
    }
    group.finish();
}

fn hemicube(c: &mut Criterion) {
    let room = room();
    let surfaces = &room.scene.surfaces;
    let mut group = c.benchmark_group("hemicube");
    group.throughput(Throughput::Elements(room.shooters.len() as u64));
    for resolution in RESOLUTIONS {
        let mut buffer = ItemBuffer::for_scene(resolution, room.scene.bounds());
        group.bench_with_input(
            BenchmarkId::new("render", resolution),
            &resolution,
            |b, _| {
                b.iter(|| {
                    for shooter in &room.shooters {
                        buffer.render(
                            surfaces,
                            shooter.sub.centroid,
                            shooter.normal,
                            shooter.surface,
                        );
                    }
                    buffer.stats().samples_tested
                });
            },
        );
    }

    // The pre-test is only asked about pairs shot from the centroid.
    let asked: Vec<&Pair> = room.pairs.iter().filter(|p| p.all_front).collect();
    group.throughput(Throughput::Elements(asked.len() as u64));
    for resolution in RESOLUTIONS {
        let buffers: Vec<ItemBuffer> = room
            .shooters
            .iter()
            .map(|shooter| {
                let mut buffer = ItemBuffer::for_scene(resolution, room.scene.bounds());
                buffer.render(
                    surfaces,
                    shooter.sub.centroid,
                    shooter.normal,
                    shooter.surface,
                );
                buffer
            })
            .collect();
        let decided = asked
            .iter()
            .filter(|p| {
                let buffer = &buffers[p.shooter];
                let surface = room.mesh.vertices[p.vertex].surface;
                buffer.classify(room.gather_points[p.vertex], surface) != Pretest::Uncertain
            })
            .count();
        eprintln!(
            "hemicube: {} subsources, {} pairs asked, {:.1}% decided at {resolution}",
            room.shooters.len(),
            asked.len(),
            100.0 * decided as f64 / asked.len() as f64,
        );
        group.bench_with_input(
            BenchmarkId::new("classify", resolution),
            &resolution,
            |b, _| {
                b.iter(|| {
                    let mut visible = 0u32;
                    for p in &asked {
                        let surface = room.mesh.vertices[p.vertex].surface;
                        let outcome = buffers[p.shooter]
                            .classify(black_box(room.gather_points[p.vertex]), surface);
                        visible += u32::from(outcome == Pretest::Visible);
                    }
                    visible
                });
            },
        );
    }
    group.finish();
}

fn form_factors(c: &mut Criterion) {
    let room = room();
    let sources: Vec<Source<'_>> = room
        .shooters
        .iter()
        .map(|s| Source {
            polygon: &s.sub.polygon,
            centroid: s.sub.centroid,
            normal: s.normal,
            area: s.sub.area,
        })
        .collect();
    let inputs: Vec<(DVec3, DVec3, &Source<'_>)> = room
        .pairs
        .iter()
        .map(|p| {
            let normal = room.mesh.vertices[p.vertex].normal;
            (room.gather_points[p.vertex], normal, &sources[p.shooter])
        })
        .collect();
    eprintln!(
        "form_factors: {} vertex-subsource pairs facing each other",
        inputs.len()
    );
    let mut group = c.benchmark_group("form_factors");
    group.throughput(Throughput::Elements(inputs.len() as u64));
    for formula in FormFactor::ALL {
        group.bench_function(formula.name(), |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for &(x, n, source) in &inputs {
                    sum += formula.evaluate(black_box(x), n, source);
                }
                sum
            });
        });
    }
    group.finish();
}

fn shot(c: &mut Criterion) {
    let room = room();
    let presets = [
        ("wallace89", Settings::wallace89()),
        ("wong-tsang93", Settings::wong_tsang93()),
    ];
    let default_threads = rayon::ThreadPoolBuilder::new()
        .build()
        .expect("a default rayon pool")
        .current_num_threads();
    let mut group = c.benchmark_group("shot");
    for (name, settings) in presets {
        let settings = Settings {
            mesh: room.mesh_settings,
            ..settings
        };
        for threads in [1, default_threads] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a rayon pool");
            group.bench_function(BenchmarkId::new(name, format!("threads={threads}")), |b| {
                // The solver is built and shot on the pool's thread: it is
                // not `Send`, and only the shot is timed.
                b.iter_custom(|iterations| {
                    pool.install(|| {
                        let mut total = Duration::ZERO;
                        for _ in 0..iterations {
                            let mut solver = Solver::new(&room.scene, &room.mesh, settings.clone());
                            let start = Instant::now();
                            solver.shoot();
                            total += start.elapsed();
                            assert_eq!(solver.stats().shots, 1, "a first shot");
                            black_box(solver.radiosity());
                        }
                        total
                    })
                });
            });
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = quick();
    targets = shadow_rays, hemicube, form_factors, shot
}
criterion_main!(benches);
