//! Times loading and meshing one scene file (a scene of a million small
//! triangles must load and mesh fast and in bounded memory):
//! `cargo run --release --example load_mesh_timing -- FILE.obj`.

use std::time::Instant;

use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene;

fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: load_mesh_timing FILE.obj")?;
    let start = Instant::now();
    let scene = scene::load(&path)?;
    let loaded = start.elapsed();
    println!(
        "{path}: {} surfaces loaded in {:.2} s",
        scene.surfaces.len(),
        loaded.as_secs_f64()
    );
    let settings = MeshSettings::default().sized_for(&scene);
    let start = Instant::now();
    let mesh = Mesh::build(&scene, &settings)?;
    println!(
        "{} patches, {} elements, {} vertices meshed in {:.2} s; peak RSS {:.0} MiB",
        mesh.patches.len(),
        mesh.elements.len(),
        mesh.vertices.len(),
        start.elapsed().as_secs_f64(),
        peak_rss_mib()
    );
    Ok(())
}
