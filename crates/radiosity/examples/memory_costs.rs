//! Measures where a run's memory goes, stage by stage, with a counting
//! allocator: the heap bytes each stage keeps and the most it holds at once
//! while running, and the resident set at the end. The per-item costs of
//! the memory model in `src/memory.rs` come from these numbers (see
//! EXPERIMENTS.md, "Memory"):
//!
//! `cargo run --release --example memory_costs -- SCENE PRESET ACCEL SHOTS`
//!
//! PRESET is `adaptive` or `wong-tsang93`, ACCEL `bvh` or `bsp`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use radiosity::accel::Accel;
use radiosity::mesh::Mesh;
use radiosity::render::{self, RenderSettings};
use radiosity::scene;
use radiosity::solver::{Preset, Solver};
use radiosity::view;

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let now = CURRENT.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

// SAFETY: every call is passed on to the system allocator unchanged; only
// the byte counts are recorded.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
            grew(new_size);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs a stage; prints the heap it kept and the most it held above the
/// heap at its start.
fn stage<T>(name: &str, run: impl FnOnce() -> T) -> T {
    let before = CURRENT.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let value = run();
    let after = CURRENT.load(Ordering::Relaxed);
    let peak = PEAK.load(Ordering::Relaxed);
    println!(
        "{name:12} kept {:>10.3} MB  transient peak {:>10.3} MB  heap now {:>10.3} MB",
        (after as f64 - before as f64) / 1e6,
        (peak - before) as f64 / 1e6,
        after as f64 / 1e6
    );
    value
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, scene_name, preset, accel, shots] = &args[..] else {
        return Err("usage: memory_costs SCENE PRESET ACCEL SHOTS".into());
    };
    let mut settings = preset.parse::<Preset>()?.settings();
    settings.accel = accel.parse::<Accel>()?;
    let shots: u64 = shots.parse()?;
    let mut scene = stage("load", || scene::load(scene_name))?;
    if settings.merge_coplanar {
        stage("merge", || {
            scene::merge::merge_coplanar(&mut scene.surfaces)
        });
    }
    settings.mesh = settings.mesh.sized_for(&scene);
    let mesh = stage("mesh", || Mesh::build(&scene, &settings.mesh))?;
    let mut solver = stage("solver", || Solver::new(&scene, &mesh, settings.clone()));
    for shot in 0..shots {
        stage(&format!("shot {}", shot + 1), || solver.shoot());
    }
    let camera = stage("camera", || view::camera_or_framing(&scene));
    let display = stage("display", || solver.display_radiosity(true));
    stage("render", || {
        render::render(
            &scene,
            &mesh,
            &display,
            &RenderSettings {
                width: 800,
                height: 600,
                camera,
                supersampling: 3,
            },
        )
    });
    let statistics = solver.accel_statistics();
    let accel_bytes = statistics
        .iter()
        .find(|(k, _)| *k == "bytes")
        .map_or(0, |(_, v)| *v);
    println!(
        "counts: surfaces {} patches {} elements {} vertices {} shooters {} accel bytes {}",
        scene.surfaces.len(),
        mesh.patches.len(),
        mesh.elements.len(),
        mesh.vertices.len(),
        solver.shooters(),
        accel_bytes
    );
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    for line in status.lines() {
        if line.starts_with("VmHWM") || line.starts_with("VmRSS") {
            println!("{line}");
        }
    }
    Ok(())
}
