//! Adaptive shooting's transfers on the GPU against the CPU's: the same
//! solve of each built-in scene (the default settings, on its default
//! base mesh, with the coplanar faces merged as a run does) on both
//! devices, compared vertex by vertex; every surface shot must have run on
//! the GPU. The CPU is the oracle: the two differ only where `f32` tips a
//! decision the CPU makes in `f64` (a node accepted or refined, a grazing
//! ray), each worth at most the tolerance of that decision.
//!
//! Without an adapter the test says it did not run, unless
//! `RADIOSITY_REQUIRE_GPU` is set (CI sets it, with Mesa's software Vulkan
//! installed): then it fails.

use std::sync::Arc;

use glam::DVec3;
use radiosity::luminance;
use radiosity::mesh::Mesh;
use radiosity::scene;
use radiosity::solver::device::Device;
use radiosity::solver::{Flow, Settings, Solver, StopReason};
use radiosity_gpu::{DeviceChoice, Gpu, GpuBackend, REQUIRE_ADAPTER};

/// A GPU adapter (software ones included), or `None` with a note when
/// there is none and none is required.
fn gpu() -> Option<Gpu> {
    let required = std::env::var(REQUIRE_ADAPTER).is_ok_and(|v| v != "0");
    match Gpu::open(DeviceChoice::Gpu) {
        Ok(gpu) => gpu,
        Err(e) if required => panic!("{REQUIRE_ADAPTER} is set: {e}"),
        Err(e) => {
            eprintln!("GPU test did not run: {e} (set {REQUIRE_ADAPTER} to require one)");
            None
        }
    }
}

/// L1 difference of the vertices' radiosity (luminance) over the CPU's L1.
fn relative_l1(gpu: &[DVec3], cpu: &[DVec3]) -> f64 {
    let diff: f64 = gpu
        .iter()
        .zip(cpu)
        .map(|(g, c)| (luminance(*g) - luminance(*c)).abs())
        .sum();
    let total: f64 = cpu.iter().map(|c| luminance(*c).abs()).sum();
    diff / total
}

/// Every built-in scene solved to the default's convergence on both
/// devices: radiosity within 0.5% L1 of the CPU's, every shot of a surface
/// on the GPU, and (the Cornell box) a rerun on the GPU the same to the
/// last bit.
#[test]
fn gpu_shots_agree_with_the_cpu_on_the_built_in_scenes() {
    let Some(gpu) = gpu() else { return };
    let device = Device::backend(Arc::new(GpuBackend::new(gpu)));
    for name in scene::builtin::names() {
        let mut scene = scene::load(name).unwrap();
        scene::merge::merge_coplanar(&mut scene.surfaces);
        let sizes = scene.default_mesh_sizes();
        let mut settings = Settings::adaptive();
        settings.mesh.patch_size = sizes.patch_size;
        settings.mesh.element_size = sizes.element_size;
        let mesh = Mesh::build(&scene, &settings.mesh).unwrap();
        let solve = |device: Device| {
            let settings = Settings {
                device,
                ..settings.clone()
            };
            settings.validate().unwrap();
            let mut solver = Solver::new(&scene, &mesh, settings);
            let stop = solver.run(|_| Flow::Continue);
            assert_eq!(stop, StopReason::Converged, "{name}");
            let lights = scene.lights.len() as u64;
            (
                solver.radiosity().to_vec(),
                solver.stats().shots - lights,
                solver.device_report(),
            )
        };
        let (cpu, cpu_shots, cpu_report) = solve(Device::cpu());
        assert_eq!(cpu_report.device_shots, 0);
        let (on_gpu, gpu_shots, report) = solve(device.clone());
        assert_eq!(report.fault, None, "{name}");
        assert_eq!(
            report.device_shots, gpu_shots,
            "{name}: every surface shot on the GPU"
        );
        let l1 = relative_l1(&on_gpu, &cpu);
        eprintln!(
            "{name}: {} vertices, CPU {cpu_shots} shots, GPU {gpu_shots}: L1 {:.4}%",
            mesh.vertices.len(),
            100.0 * l1
        );
        assert!(l1 < 5e-3, "{name}: GPU differs from the CPU by {l1} (L1)");
        if name != "cornell" {
            continue;
        }
        let (again, _, _) = solve(device.clone());
        assert!(
            again.iter().zip(&on_gpu).all(|(a, b)| a == b),
            "{name}: a rerun on the same adapter differs"
        );
    }
}
