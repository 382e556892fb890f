//! The command on the GPU (`--device`): a default render of the built-in
//! Cornell box through `--device gpu` against the same through `--device
//! cpu` (the statistics say every shot, the coarse pass's too, ran on the
//! GPU; the values at sensor points, the same points whatever mesh each
//! device's coarse pass refined, agree within 0.5% L1), and the clear
//! errors: settings the GPU does not run, a solve over `--max-gpu-memory`,
//! and no adapter at all; and the lights' shots through the GPU.
//!
//! Without an adapter the comparison says it did not run, unless
//! `RADIOSITY_REQUIRE_GPU` is set (CI sets it, with Mesa's software Vulkan
//! installed): then it fails.

use std::path::Path;
use std::process::{Command, Output};

fn run(dir: &Path, args: &[&str]) -> Output {
    run_cached(dir, args, &dir.join("cache"))
}

/// [`run`] with the compiled kernels kept in `cache`.
fn run_cached(dir: &Path, args: &[&str], cache: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env_remove("RADIOSITY_DEVICE")
        .env("RADIOSITY_CACHE_DIR", cache)
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Whether there is an adapter to test on ([`radiosity_gpu::test_adapter`]).
fn adapter() -> bool {
    radiosity_gpu::test_adapter().is_some()
}

/// Sensor points spread over every surface of the built-in Cornell box:
/// on each surface's fan of triangles, five fixed barycentric points per
/// triangle, each facing out of the surface's front.
fn sensor_points() -> String {
    let scene = radiosity::scene::load("cornell").unwrap();
    let mut out = String::new();
    let weights = [
        [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
        [0.6, 0.2, 0.2],
        [0.2, 0.6, 0.2],
        [0.2, 0.2, 0.6],
        [0.45, 0.45, 0.1],
    ];
    for s in &scene.surfaces {
        let p = &s.polygon;
        for i in 1..p.len() - 1 {
            for w in weights {
                let x = p[0] * w[0] + p[i] * w[1] + p[i + 1] * w[2];
                let n = s.normal;
                out += &format!("{} {} {} {} {} {}\n", x.x, x.y, x.z, n.x, n.y, n.z);
            }
        }
    }
    out
}

/// The irradiance (luminance) of each row of a sensors CSV.
fn sensor_values(path: &Path) -> Vec<f64> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|line| {
            let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            0.2126 * v[6] + 0.7152 * v[7] + 0.0722 * v[8]
        })
        .collect()
}

fn stats(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn a_default_render_on_the_gpu_agrees_with_the_cpu() {
    if !adapter() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("points.txt"), sensor_points()).unwrap();
    for device in ["cpu", "gpu"] {
        let out = run(
            dir.path(),
            &[
                "render",
                "cornell",
                "--device",
                device,
                "--width",
                "32",
                "--height",
                "24",
                "--output",
                &format!("{device}.png"),
                "--stats",
                &format!("{device}.json"),
                "--sensors",
                "points.txt",
                "--sensors-out",
                &format!("{device}.csv"),
            ],
        );
        assert!(
            out.status.success(),
            "{device}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let summary = String::from_utf8_lossy(&out.stdout);
        assert_eq!(summary.contains("device: "), device == "gpu", "{summary}");
    }
    // Over --max-gpu-memory: refused by name before the solve, nothing
    // written.
    let out = run(
        dir.path(),
        &[
            "render",
            "cornell",
            "--device",
            "gpu",
            "--max-gpu-memory",
            "1M",
            "--output",
            "small.png",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("over --max-gpu-memory 1 MiB"), "{stderr}");
    assert!(!dir.path().join("small.png").exists());
    let cpu = stats(&dir.path().join("cpu.json"));
    let gpu = stats(&dir.path().join("gpu.json"));
    assert_eq!(cpu["device"], "cpu");
    assert_eq!(cpu["device_shots"], 0);
    let name = gpu["device"].as_str().unwrap();
    assert!(name != "cpu" && name.contains('('), "{name}");
    assert!(gpu["device_fault"].is_null(), "{}", gpu["device_fault"]);
    // The built-in box has no lights but its surfaces: every shot, the
    // coarse pass's too, ran on the GPU.
    assert_eq!(gpu["device_shots"], gpu["shots"]);
    assert_eq!(gpu["coarse_device_shots"], gpu["coarse_shots"]);
    assert_eq!(gpu["stop_reason"], "converged");
    // What crossed between host and device, counted the same on any
    // adapter: none on the CPU; on the GPU at most one wait a round (its
    // ledger, which brings the next round's unshot light back with it),
    // the checkpoints counted apart (they come by the clock); its critical path is at least its
    // mean walk; bind groups and uniforms made once a solve (and again
    // only when an upload outgrows its buffer), not every pass. The same
    // on the CPU: rounds of several shooters.
    for key in [
        "device_host_waits",
        "device_checkpoints",
        "device_submissions",
        "device_bytes_read",
        "device_objects_made",
    ] {
        assert_eq!(cpu[key], 0, "{key}");
    }
    let count = |key: &str| {
        gpu[key]
            .as_u64()
            .unwrap_or_else(|| panic!("{key}: {}", gpu[key]))
    };
    let passes = count("device_passes");
    let waits = count("device_host_waits");
    let rounds = count("rounds");
    assert!(passes >= count("device_shots"));
    assert_eq!(cpu["rounds"], gpu["rounds"]);
    assert!(4 * rounds < count("shots"), "{rounds} rounds");
    assert!(
        waits > 0 && waits <= rounds,
        "{waits} host waits for {rounds} rounds"
    );
    assert!(count("device_submissions") >= passes);
    let made = count("device_objects_made");
    assert!(
        made > 0 && 4 * made < passes,
        "{made} objects made in {passes} passes"
    );
    assert!(count("device_bytes_read") > 0);
    let mean = gpu["device_mean_visits"].as_f64().unwrap();
    assert!(
        mean > 0.0 && count("device_longest_visits") as f64 >= mean,
        "{mean}"
    );
    // Where a shot's time went, by the device's clock: none on the CPU;
    // on an adapter with timestamps, each stage's seconds.
    assert!(cpu["device_stage_seconds"].is_null());
    assert!(cpu["device_pipeline_cache"].is_null());
    assert_eq!(cpu["device_pipeline_seconds"], 0.0);
    if let Some(stages) = gpu["device_stage_seconds"].as_object() {
        let names: Vec<&str> = stages.keys().map(String::as_str).collect();
        assert_eq!(names, ["book", "items", "join", "walk"]);
        assert!(
            stages
                .values()
                .all(|t| t.as_f64().is_some_and(|t| t >= 0.0))
        );
        assert!(stages["walk"].as_f64().unwrap() > 0.0, "{stages:?}");
    }
    let (c, g) = (
        sensor_values(&dir.path().join("cpu.csv")),
        sensor_values(&dir.path().join("gpu.csv")),
    );
    assert_eq!(c.len(), g.len());
    let diff: f64 = c.iter().zip(&g).map(|(a, b)| (a - b).abs()).sum();
    let total: f64 = c.iter().sum();
    eprintln!(
        "sensors: L1 {:.4}% between the devices",
        100.0 * diff / total
    );
    assert!(
        diff / total < 5e-3,
        "GPU and CPU differ by {} (L1)",
        diff / total
    );
}

/// The paper's presets and the settings only the CPU runs are refused on
/// the GPU by name, before anything is loaded; `auto` runs them on the CPU.
/// The compiled kernels are kept across runs where the adapter keeps a
/// pipeline cache: the first run compiles and saves them, the next loads
/// them and renders the same picture; a damaged file is compiled over and
/// replaced, never given to the driver; `off` keeps nothing.
#[test]
fn the_kernels_are_kept_across_runs() {
    if !adapter() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("kept");
    let render = |name: &str, cache: &Path| {
        let args = [
            "render",
            "cornell",
            "--device",
            "gpu",
            "--max-shots",
            "3",
            "--width",
            "16",
            "--height",
            "12",
            "--output",
            &format!("{name}.png"),
            "--stats",
            &format!("{name}.json"),
        ];
        let out = run_cached(dir.path(), &args, cache);
        assert!(out.status.success(), "{out:?}");
        let s = stats(&dir.path().join(format!("{name}.json")));
        assert!(s["device_pipeline_seconds"].as_f64().unwrap() > 0.0, "{s}");
        s["device_pipeline_cache"].as_str().unwrap().to_string()
    };
    let files = || -> Vec<std::path::PathBuf> {
        std::fs::read_dir(&cache)
            .map(|d| d.map(|e| e.unwrap().path()).collect())
            .unwrap_or_default()
    };
    let first = render("first", &cache);
    if first == "unsupported" {
        eprintln!("the adapter keeps no pipeline cache");
        assert!(files().is_empty());
        return;
    }
    assert_eq!(first, "compiled");
    let kept = files();
    assert_eq!(kept.len(), 1, "{kept:?}");
    // Whole: the magic, the data's length, its checksum, the data.
    let is_whole = |bytes: &[u8]| {
        bytes.starts_with(b"RADPLC01")
            && bytes.len() >= 24
            && u64::from_le_bytes(bytes[8..16].try_into().unwrap()) == bytes.len() as u64 - 24
    };
    let whole = std::fs::read(&kept[0]).unwrap();
    assert!(is_whole(&whole));
    assert_eq!(render("second", &cache), "loaded");
    let picture = |name: &str| std::fs::read(dir.path().join(format!("{name}.png"))).unwrap();
    assert_eq!(picture("first"), picture("second"));
    // Damaged: compiled over and written whole again.
    std::fs::write(&kept[0], &whole[..whole.len() - 3]).unwrap();
    assert_eq!(render("damaged", &cache), "compiled");
    assert!(is_whole(&std::fs::read(&kept[0]).unwrap()));
    assert_eq!(picture("damaged"), picture("first"));
    assert_eq!(files().len(), 1);
    assert_eq!(render("off", Path::new("off")), "off");
    assert!(!dir.path().join("off").exists());
}

#[test]
fn settings_the_gpu_does_not_run_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    for (extra, named) in [
        (&["--preset", "wallace89"][..], "the wallace89 preset"),
        (&["--preset", "wong-tsang93"][..], "the wong-tsang93 preset"),
        (&["--shooting", "cuts"][..], "--shooting cuts"),
        (&["--accel", "bsp"][..], "--accel bsp"),
        (&["--form-factor", "disk"][..], "--form-factor disk"),
    ] {
        let mut args = vec!["render", "cornell", "--device", "gpu", "--quiet"];
        args.extend_from_slice(extra);
        let out = run(dir.path(), &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{extra:?}");
        assert!(stderr.contains(named), "{extra:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    }
    let out = run(
        dir.path(),
        &[
            "render",
            "cornell",
            "--preset",
            "wallace89",
            "--max-shots",
            "2",
            "--width",
            "8",
            "--height",
            "6",
            "--stats",
            "s.json",
            "--quiet",
        ],
    );
    assert!(out.status.success());
    assert_eq!(stats(&dir.path().join("s.json"))["device"], "cpu");
    assert!(std::fs::read_dir(dir.path()).unwrap().count() == 2);
}

/// `--device gpu` where Vulkan finds no driver: one line saying so, a
/// non-zero exit, no output; `auto` there runs on the CPU.
#[test]
fn no_adapter_is_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let nothing = dir.path().join("no-driver.json");
    let out = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env_remove("RADIOSITY_DEVICE")
        .env("VK_ICD_FILENAMES", &nothing)
        .env("VK_DRIVER_FILES", &nothing)
        .current_dir(dir.path())
        .args(["render", "cornell", "--device", "gpu", "--output", "x.png"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("--device gpu: no GPU adapter"), "{stderr}");
    assert!(!dir.path().join("x.png").exists());
    let out = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env_remove("RADIOSITY_DEVICE")
        .env("VK_ICD_FILENAMES", &nothing)
        .env("VK_DRIVER_FILES", &nothing)
        .current_dir(dir.path())
        .args([
            "render",
            "cornell",
            "--max-shots",
            "2",
            "--width",
            "8",
            "--height",
            "6",
            "--stats",
            "s.json",
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(stats(&dir.path().join("s.json"))["device"], "cpu");
}

/// The lights' shots on the GPU: a lamp room (point lights) and a window
/// room (sun and clear sky) shot by their lights alone on both devices.
/// The host draws every point and direction, the GPU answers their shadow
/// segments: the same irradiance to `f32` round-off, every light's shot
/// counted on the GPU.
#[test]
fn lights_shoot_through_the_gpu() {
    if !adapter() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/experiments/scenes");
    for (scene, daylight) in [
        ("lamp_room", &[][..]),
        (
            "window_room",
            &[
                "--sun",
                "35",
                "200",
                "60000",
                "--sky",
                "clear",
                "--sky-illuminance",
                "12000",
            ][..],
        ),
    ] {
        let path = scenes.join(format!("{scene}.obj"));
        for device in ["cpu", "gpu"] {
            let mut args = vec![
                "render".to_string(),
                path.to_string_lossy().into_owned(),
                "--device".into(),
                device.into(),
                "--max-shots".into(),
                "2".into(),
                "--refine-levels".into(),
                "0".into(),
                "--width".into(),
                "16".into(),
                "--height".into(),
                "12".into(),
                "--output".into(),
                format!("{scene}-{device}.png"),
                "--vertices".into(),
                format!("{scene}-{device}.csv"),
                "--stats".into(),
                format!("{scene}-{device}.json"),
                "--quiet".into(),
            ];
            args.extend(daylight.iter().map(|s| s.to_string()));
            let out = run(
                dir.path(),
                &args.iter().map(String::as_str).collect::<Vec<_>>(),
            );
            assert!(
                out.status.success(),
                "{scene} {device}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        let gpu = stats(&dir.path().join(format!("{scene}-gpu.json")));
        assert_eq!(gpu["lights"].as_array().unwrap().len(), 2, "{scene}");
        assert_eq!(gpu["shots"], 2, "{scene}: the lights alone");
        assert_eq!(gpu["device_shots"], 2, "{scene}: both lights on the GPU");
        assert!(gpu["device_fault"].is_null(), "{}", gpu["device_fault"]);
        let values = |device: &str| -> Vec<f64> {
            std::fs::read_to_string(dir.path().join(format!("{scene}-{device}.csv")))
                .unwrap()
                .lines()
                .skip(1)
                .map(|line| {
                    let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
                    0.2126 * v[7] + 0.7152 * v[8] + 0.0722 * v[9]
                })
                .collect()
        };
        let (c, g) = (values("cpu"), values("gpu"));
        assert_eq!(c.len(), g.len());
        let diff: f64 = c.iter().zip(&g).map(|(a, b)| (a - b).abs()).sum();
        let total: f64 = c.iter().sum();
        assert!(
            diff / total < 1e-5,
            "{scene}: the lights' shots differ by {} (L1)",
            diff / total
        );
    }
}

/// Glass between surfaces on the GPU: a lamp over a grey floor behind a
/// pane of transmittance 0.2 (`d 0.8`), solved on both devices; the
/// sensors agree, every shot ran on the GPU, and the pane dims the floor
/// (against the same scene without it).
#[test]
fn glass_dims_the_gpus_transfers_as_the_cpus() {
    if !adapter() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let obj = |pane: bool| {
        format!(
            "mtllib glass.mtl\nv -2 0 -2\nv -2 0 2\nv 2 0 2\nv 2 0 -2\n\
             v -0.5 2 -0.5\nv 0.5 2 -0.5\nv 0.5 2 0.5\nv -0.5 2 0.5\n\
             v -3 1 -3\nv 3 1 -3\nv 3 1 3\nv -3 1 3\n\
             usemtl floor\nf 1 2 3 4\nusemtl lamp\nf 5 6 7 8\n{}",
            if pane {
                "usemtl pane\nf 9 10 11 12\n"
            } else {
                ""
            }
        )
    };
    std::fs::write(dir.path().join("glass.obj"), obj(true)).unwrap();
    std::fs::write(dir.path().join("open.obj"), obj(false)).unwrap();
    std::fs::write(
        dir.path().join("glass.mtl"),
        "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl lamp\nKe 10 10 10\nnewmtl pane\nd 0.8\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("p.txt"),
        "0 0 0 0 1 0\n0.7 0 -0.4 0 1 0\n-1.5 0 1.2 0 1 0\n1.9 0 1.9 0 1 0\n",
    )
    .unwrap();
    let solve = |scene: &str, device: &str| -> (Vec<f64>, serde_json::Value) {
        let out = run(
            dir.path(),
            &[
                "render",
                scene,
                "--device",
                device,
                "--width",
                "8",
                "--height",
                "6",
                "--sensors",
                "p.txt",
                "--sensors-out",
                "s.csv",
                "--stats",
                "s.json",
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        (
            sensor_values(&dir.path().join("s.csv")),
            stats(&dir.path().join("s.json")),
        )
    };
    let (cpu, _) = solve("glass.obj", "cpu");
    let (gpu, gpu_stats) = solve("glass.obj", "gpu");
    assert_eq!(gpu_stats["device_shots"], gpu_stats["shots"], "{gpu_stats}");
    for (c, g) in cpu.iter().zip(&gpu) {
        assert!((c - g).abs() <= 1e-4 * c, "cpu {c}, gpu {g}");
    }
    // Without the pane the floor reads more: the lamp's light reaches it
    // at a fifth (and the light it reflects back up comes back dimmed).
    let (open, _) = solve("open.obj", "cpu");
    for (o, g) in open.iter().zip(&gpu) {
        assert!(*g > 0.15 * o && *g < 0.3 * o, "glazed {g}, open {o}");
    }
}
