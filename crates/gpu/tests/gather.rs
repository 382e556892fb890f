//! Adaptive shooting's transfers on the GPU against the CPU's: every
//! buffer's Rust struct against its WGSL twin, and the same
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
use radiosity::solver::{Flow, MethodSettings, Settings, Solver, StopReason};
use radiosity_gpu::gather::{
    GpuBin, GpuBook, GpuElement, GpuElementBook, GpuLeave, GpuNodeSource, GpuPane, GpuPartial,
    GpuReceiver, GpuShot, GpuSurface, GpuTreeNode,
};
use radiosity_gpu::{DeviceChoice, Gpu, GpuBackend};

/// Size and member offsets of the WGSL struct `name` of the transfer
/// kernel (its whole module, as the device compiles it).
fn wgsl_layout(name: &str) -> (u32, Vec<(String, u32)>) {
    let source = radiosity_gpu::shaders::gather_source();
    let module = naga::front::wgsl::parse_str(&source).unwrap();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    let (handle, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name} in the transfer module"));
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

/// A struct's WGSL name, its Rust size and its members' Rust offsets.
type RustLayout = (&'static str, usize, Vec<(&'static str, usize)>);

/// A [`RustLayout`] of a Rust struct, its fields named as in WGSL.
macro_rules! layout {
    ($wgsl:literal, $rust:ty, [$($field:ident),* $(,)?]) => {
        (
            $wgsl,
            std::mem::size_of::<$rust>(),
            vec![$((stringify!($field), std::mem::offset_of!($rust, $field))),*],
        )
    };
}

#[test]
fn transfer_buffers_match_their_wgsl_twins() {
    let cases: Vec<RustLayout> = vec![
        layout!(
            "TreeNode",
            GpuTreeNode,
            [
                centre, radius, centre_lo, second, group, surface, element, pad0, box_middle, pad1,
                box_half, pad2
            ]
        ),
        layout!(
            "Surface",
            GpuSurface,
            [normal, group, corner, pad0, corner_lo, pad1]
        ),
        layout!(
            "Pane",
            GpuPane,
            [a, pad0, b, pad1, c, pad2, transmittance, pad3]
        ),
        layout!(
            "Element",
            GpuElement,
            [
                corners,
                corners_lo,
                centroid,
                surface,
                centroid_lo,
                count,
                area,
                pad0,
                pad1,
                pad2
            ]
        ),
        layout!(
            "Receiver",
            GpuReceiver,
            [point, group, point_lo, pad0, normal, pad1]
        ),
        layout!(
            "NodeSource",
            GpuNodeSource,
            [weight, first_bin, bins, pad0, unshot, pad1]
        ),
        layout!(
            "Bin",
            GpuBin,
            [
                power,
                weight,
                normal,
                length,
                centre,
                representative,
                diagonal,
                axis,
                off_diagonal,
                pad0
            ]
        ),
        layout!(
            "Shot",
            GpuShot,
            [
                root,
                first,
                count,
                negligible,
                origin,
                mean,
                origin_lo,
                frontier,
                item_groups
            ]
        ),
        layout!("ElementBook", GpuElementBook, [corners, rho, area]),
        layout!(
            "Partial",
            GpuPartial,
            [incident, absorbed, unshot, magnitude]
        ),
        layout!(
            "Book",
            GpuBook,
            [
                count,
                large,
                elements,
                receivers,
                shooters,
                sign,
                fraction,
                serial_items,
                direct,
                pad3
            ]
        ),
        layout!("Leave", GpuLeave, [value, element]),
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

/// The tests' adapter ([`radiosity_gpu::test_adapter`]).
fn gpu() -> Option<Gpu> {
    radiosity_gpu::test_adapter()
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

/// The built-in scene `name` as the command line solves it by default:
/// coplanar faces merged, the scene's mesh sizes, the adaptive settings,
/// and its base mesh.
fn built_in(name: &str) -> (scene::Scene, Settings, Mesh) {
    let mut scene = scene::load(name).unwrap();
    scene::merge::merge_coplanar(&mut scene.surfaces);
    let sizes = scene.default_mesh_sizes();
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = sizes.patch_size;
    settings.mesh.element_size = sizes.element_size;
    let mesh = Mesh::build(&scene, &settings.mesh).unwrap();
    (scene, settings, mesh)
}

/// Every built-in scene solved to the default's convergence on both
/// devices: radiosity, and its direct part, within 0.5% L1 of the CPU's,
/// every shot of a surface
/// on the GPU, and (the Cornell box) a rerun on the GPU, and one with the
/// walk cut into dispatches of 1,000 receivers, the same to the last bit;
/// one with every shooter's power summed by a workgroup within 0.5% too.
#[test]
fn gpu_shots_agree_with_the_cpu_on_the_built_in_scenes() {
    let Some(gpu) = gpu() else { return };
    let device = Device::backend(Arc::new(GpuBackend::new(gpu)));
    for name in scene::builtin::names() {
        let (scene, settings, mesh) = built_in(name);
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
            assert!(solver.direct_complete(), "{name}: the direct part booked");
            (
                solver.radiosity().to_vec(),
                solver.stats().shots - lights,
                solver.device_report(),
                solver.direct_irradiance()[..mesh.vertices.len()].to_vec(),
            )
        };
        let (cpu, cpu_shots, cpu_report, cpu_direct) = solve(Device::cpu());
        assert_eq!(cpu_report.device_shots, 0);
        let (on_gpu, gpu_shots, report, gpu_direct) = solve(device.clone());
        // The device books the direct part (the emitting surfaces' first
        // shots) beside the total, as the CPU does.
        let direct_l1 = relative_l1(&gpu_direct, &cpu_direct);
        assert!(
            direct_l1 < 5e-3,
            "{name}: the GPU's direct part differs from the CPU's by {direct_l1} (L1)"
        );
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
        let (again, _, _, _) = solve(device.clone());
        assert!(
            again.iter().zip(&on_gpu).all(|(a, b)| a == b),
            "{name}: a rerun on the same adapter differs"
        );
        // The walk cut into many dispatches, each its own submission:
        // the same answer to the last bit.
        let chunked = Device::backend(Arc::new(
            GpuBackend::new(Gpu::open(DeviceChoice::Gpu).unwrap().unwrap())
                .with_dispatch_receivers(1000),
        ));
        let (cut, _, _, _) = solve(chunked);
        assert!(
            cut.iter().zip(&on_gpu).all(|(a, b)| a == b),
            "{name}: the walk in dispatches of 1,000 receivers differs"
        );
        // Every shooter's unshot power summed by a workgroup, as the
        // large shooters' are (pairwise, not one element after another):
        // the same rounds but for the order of the sums.
        let pooled = Device::backend(Arc::new(
            GpuBackend::new(Gpu::open(DeviceChoice::Gpu).unwrap().unwrap())
                .with_serial_power_items(0),
        ));
        let (summed, summed_shots, _, _) = solve(pooled);
        let l1 = relative_l1(&summed, &cpu);
        eprintln!(
            "{name}: every power by a workgroup, {summed_shots} shots: L1 {:.4}%",
            100.0 * l1
        );
        assert!(
            l1 < 5e-3,
            "{name}: pooled powers differ from the CPU by {l1} (L1)"
        );
    }
}

/// Overshooting on the GPU: a shooter's negative light goes in a pass of
/// its own, booked with the sign -1, and its elements are left with minus
/// their overshoot. The Cornell box solved with `--overshoot 1` on both
/// devices: radiosity within 0.5% L1, every surface shot on the GPU, in
/// fewer shots than without overshooting, and a rerun the same to the last
/// bit.
#[test]
fn overshooting_on_the_gpu_agrees_with_the_cpu() {
    let Some(gpu) = gpu() else { return };
    let device = Device::backend(Arc::new(GpuBackend::new(gpu)));
    let (scene, settings, mesh) = built_in("cornell");
    let solve = |device: Device, overshoot: f64| {
        let mut settings = Settings {
            device,
            ..settings.clone()
        };
        let MethodSettings::Adaptive(adaptive) = &mut settings.method else {
            unreachable!("the adaptive settings")
        };
        adaptive.overshoot = overshoot;
        settings.validate().unwrap();
        let mut solver = Solver::new(&scene, &mesh, settings);
        assert_eq!(solver.run(|_| Flow::Continue), StopReason::Converged);
        (
            solver.radiosity().to_vec(),
            solver.stats().shots,
            solver.device_report(),
        )
    };
    let (_, plain_shots, _) = solve(Device::cpu(), 0.0);
    let (cpu, cpu_shots, _) = solve(Device::cpu(), 1.0);
    let (on_gpu, gpu_shots, report) = solve(device.clone(), 1.0);
    assert_eq!(report.fault, None);
    assert_eq!(
        report.device_shots, gpu_shots,
        "every surface shot on the GPU"
    );
    let l1 = relative_l1(&on_gpu, &cpu);
    eprintln!(
        "cornell, --overshoot 1: CPU {cpu_shots} shots (without: {plain_shots}), GPU \
         {gpu_shots}: L1 {:.4}%",
        100.0 * l1
    );
    assert!(l1 < 5e-3, "GPU differs from the CPU by {l1} (L1)");
    assert!(gpu_shots < plain_shots, "{gpu_shots} against {plain_shots}");
    let (again, _, _) = solve(device, 1.0);
    assert!(
        again.iter().zip(&on_gpu).all(|(a, b)| a == b),
        "a rerun on the same adapter differs"
    );
}

/// A receiver's walk split across threads (its frontier's subtrees walked
/// as items of their own, `gather_items`) sends what one thread walking
/// all of it sends, but for the order of the sums: the Cornell box's
/// first 40 shots with the walk never split, split once two nodes are
/// left, and split at the widest frontier, each within 1e-5 (L1) of the
/// default's; the default the same to the last bit when each dispatch
/// takes 100 receivers (how many items a chunk holds, and in which order
/// threads took them, never changes the answer).
#[test]
fn a_split_walk_sends_what_one_thread_sends() {
    let Some(gpu) = gpu() else { return };
    let (scene, settings, mesh) = built_in("cornell");
    let solve = |backend: GpuBackend| {
        let settings = Settings {
            device: Device::backend(Arc::new(backend)),
            max_shots: Some(40),
            ..settings.clone()
        };
        settings.validate().unwrap();
        let mut solver = Solver::new(&scene, &mesh, settings);
        solver.run(|_| Flow::Continue);
        assert_eq!(solver.device_report().fault, None);
        assert_eq!(solver.stats().shots, 40);
        solver.radiosity().to_vec()
    };
    let open = || Gpu::open(DeviceChoice::Gpu).unwrap().unwrap();
    let default = solve(GpuBackend::new(gpu));
    for frontier in [1, 2, radiosity_gpu::gather::MAX_FRONTIER] {
        let other = solve(GpuBackend::new(open()).with_frontier(frontier));
        let l1 = relative_l1(&other, &default);
        eprintln!("frontier {frontier}: L1 {l1:.2e} from the default's");
        assert!(l1 < 1e-5, "frontier {frontier}: L1 {l1} from the default's");
    }
    let chunked = solve(GpuBackend::new(open()).with_dispatch_receivers(100));
    assert!(
        chunked.iter().zip(&default).all(|(a, b)| a == b),
        "the split walk in dispatches of 100 receivers differs"
    );
    // Every item walked when there are more than a dispatch's threads:
    // one workgroup of 64 threads, each taking items 64 apart.
    let narrow = solve(GpuBackend::new(open()).with_item_workgroups(1));
    assert!(
        narrow.iter().zip(&default).all(|(a, b)| a == b),
        "the items in one workgroup differ"
    );
}

/// A dispatch takes the whole scene where the adapter binds its split
/// walks and within the workgroups a dispatch may have: as many as the
/// binding holds at WebGPU's default limits, as many as the workgroups
/// allow where the binding is larger.
#[test]
fn a_dispatch_takes_what_the_adapter_allows() {
    use radiosity_gpu::gather::{MAX_WORKGROUPS, dispatch_receivers};
    let limits = wgpu::Limits::default();
    let per_receiver = 16 * (1 + 32);
    assert_eq!(
        dispatch_receivers(&limits, 32),
        limits.max_storage_buffer_binding_size as usize / per_receiver
    );
    let large = wgpu::Limits {
        max_storage_buffer_binding_size: u64::from(u32::MAX),
        max_buffer_size: u64::MAX,
        ..limits
    };
    assert_eq!(dispatch_receivers(&large, 32), MAX_WORKGROUPS as usize * 64);
}
