//! The command line end to end: every kind of bad input gets one
//! clear error naming the file (and line), a non-zero exit, no panic and no
//! output file; good input writes the picture, CSV and JSON of design.md
//! section 6.

use approx::assert_abs_diff_eq;

mod cli_common;
#[path = "../crates/radiosity/tests/common/mod.rs"]
mod common;

use cli_common::{Case, MTL, assert_rejected, obj, run};

#[test]
fn malformed_line() {
    assert_rejected(&obj("v 1 2\n"), MTL, &["scene.obj:14:", "takes x y z"]);
    assert_rejected(&obj("f 1 2\n"), MTL, &["scene.obj:14:", "at least 3"]);
    assert_rejected(&obj("f 1 x 2\n"), MTL, &["scene.obj:14:", "'x'"]);
}

#[test]
fn index_out_of_range() {
    assert_rejected(
        &obj("f 1 2 99\n"),
        MTL,
        &["scene.obj:14:", "99", "out of range"],
    );
    assert_rejected(&obj("f 1 2 0\n"), MTL, &["scene.obj:14:", "out of range"]);
}

#[test]
fn nan_and_infinite_numbers() {
    assert_rejected(
        &obj("v nan 0 0\n"),
        MTL,
        &["scene.obj:14:", "not a finite number"],
    );
    assert_rejected(
        &obj("v 0 inf 0\n"),
        MTL,
        &["scene.obj:14:", "not a finite number"],
    );
    let mtl = MTL.replace("Kd 0.7 0.7 0.7", "Kd 0.7 NaN 0.7");
    assert_rejected(&obj(""), &mtl, &["scene.mtl:5:", "finite"]);
}

#[test]
fn non_planar_polygon() {
    let extra = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0.3\nf 9 10 11 12\n";
    assert_rejected(
        &obj(extra),
        MTL,
        &["scene.obj:18:", "is not planar", "fold by 23 degrees"],
    );
}

#[test]
fn all_faces_degenerate_is_an_error() {
    let text = "mtllib scene.mtl\nv 0 0 0\nv 1 0 0\nv 2 0 0\nusemtl light\nf 1 2 3\n";
    assert_rejected(text, MTL, &["scene.obj", "degenerate"]);
}

#[test]
fn a_few_degenerate_faces_are_dropped_with_a_warning() {
    let extra = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 9 10 11\nf 9 9 10\n";
    let case = Case::new(&obj(extra), MTL);
    let out = case.render(&case.path("scene.obj"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning:") && stderr.contains("dropped 2 degenerate face(s)"),
        "{stderr}"
    );
    assert!(stderr.contains("line 17"), "{stderr}");
    assert!(case.path("out.png").exists());
}

#[test]
fn reflectance_outside_unit_interval() {
    let mtl = MTL.replace("Kd 0.7 0.7 0.7", "Kd 1.0 0.7 0.7");
    assert_rejected(&obj(""), &mtl, &["scene.mtl:5:", "outside [0, 1)"]);
    let mtl = MTL.replace("Kd 0.7 0.7 0.7", "Kd -0.1 0.7 0.7");
    assert_rejected(&obj(""), &mtl, &["scene.mtl:5:", "outside [0, 1)"]);
}

#[test]
fn negative_emission() {
    let mtl = MTL.replace("Ke 10 10 10", "Ke 10 -1 10");
    assert_rejected(&obj(""), &mtl, &["scene.mtl:3:", "negative"]);
}

#[test]
fn missing_material_library_and_material() {
    let text = obj("").replace("mtllib scene.mtl", "mtllib nowhere.mtl");
    assert_rejected(&text, MTL, &["scene.obj:1:", "nowhere.mtl"]);
    assert_rejected(&obj("usemtl marble\n"), MTL, &["scene.obj:14:", "'marble'"]);
    let text = obj("").replace("usemtl white\n", "");
    assert_rejected(&text, MTL, &["scene.obj:", "no material"]);
}

#[test]
fn scene_without_emitter() {
    let text = obj("").replace("usemtl light", "usemtl white");
    assert_rejected(&text, MTL, &["scene.obj", "no emitter"]);
}

#[test]
fn empty_and_binary_files() {
    assert_rejected("", MTL, &["scene.obj", "empty"]);
    assert_rejected("# only a comment\n\n", MTL, &["scene.obj", "empty"]);
    assert_rejected("\u{0}\u{1}\u{2}ELF", MTL, &["scene.obj", "binary"]);
}

#[test]
fn path_that_does_not_exist() {
    let case = Case::new(&obj(""), MTL);
    let out = case.render(&case.path("missing.obj"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("missing.obj") && stderr.to_lowercase().contains("no such file"),
        "{stderr}"
    );
    case.assert_no_output();
    let out = run(&["render", "no-such-scene"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("built-in scenes: room, cornell"),
        "{stderr}"
    );
}

#[test]
fn bad_settings_are_refused_before_any_work() {
    let case = Case::new(&obj(""), MTL);
    let scene = case.path("scene.obj");
    let cases: [(&[&str], &str); 24] = [
        (
            &[
                "--bake",
                "x.glb",
                "--bake-target",
                "lightmap",
                "--lightmap-density",
                "0",
            ],
            "--lightmap-density must be a number of texels per metre above 0",
        ),
        (
            &["--bake", "x.glb", "--lightmap-density", "nan"],
            "--lightmap-density",
        ),
        (
            &["--bake", "x.glb", "--lightmap-max-size", "8"],
            "--lightmap-max-size must be between 16 and 16384",
        ),
        (&["--bake-target", "texture"], "--bake-target"),
        (
            &["--refine-levels", "9"],
            "--refine-levels must be at most 8",
        ),
        (&["--refine-levels", "-1"], "--refine-levels"),
        (
            &["--refine-tolerance", "0"],
            "--refine-tolerance must be a positive number",
        ),
        (&["--refine-tolerance", "nan"], "--refine-tolerance"),
        (&["--threads", "0"], "--threads"),
        (&["--threads", "1000000"], "--threads"),
        (&["--element-size", "0"], "--element-size"),
        (&["--element-size", "1e-7"], "raise --element-size"),
        (&["--subsources", "0"], "--subsources"),
        (&["--converge", "1.5"], "--converge"),
        (&["--width", "0"], "--width"),
        (&["--width", "16000", "--height", "16000"], "lower --width"),
        (
            &["--preset", "wong-tsang93", "--subsources", "64"],
            "lower --subsources",
        ),
        (
            &["--visibility", "hemicube"],
            "use it with --shooting patches",
        ),
        (&["--tolerance", "0"], "--tolerance"),
        // A preset's hemicube pre-test kept when its method is switched.
        (
            &["--preset", "wong-tsang93", "--shooting", "adaptive"],
            "use it with --shooting patches",
        ),
        // Another method's parameter out of range, though not used.
        (
            &["--subsources", "65"],
            "--subsources must be between 1 and 64",
        ),
        (
            &["--shooting", "patches", "--tolerance", "2"],
            "--tolerance must be a fraction",
        ),
        (&["--camera", "1,2,3"], "10 numbers"),
        (&["--output", "/no/such/folder/x.png"], "does not exist"),
    ];
    for (flags, message) in cases {
        let mut args = vec!["render", scene.to_str().unwrap()];
        args.extend_from_slice(flags);
        let out = run(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{flags:?}");
        assert!(stderr.contains(message), "{flags:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

/// A parameter of a method other than the one running is checked, then
/// ignored with a warning naming the methods that take it.
#[test]
fn another_methods_parameter_is_ignored_with_a_warning() {
    let case = Case::new(&obj(""), MTL);
    let scene = case.path("scene.obj");
    let png = case.path("p.png");
    let out = run(&[
        "render",
        scene.to_str().unwrap(),
        "--subsources",
        "5",
        "--max-shots",
        "1",
        "--output",
        png.to_str().unwrap(),
        "--quiet",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(
        stderr.trim(),
        "warning: --subsources is a setting of --shooting patches; adaptive shooting does not use it"
    );
}

#[test]
fn cornell_writes_picture_vertices_and_stats() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let out = run(&[
        "render",
        "cornell",
        "--output",
        &p("c.png"),
        "--vertices",
        &p("c.csv"),
        "--stats",
        &p("s.json"),
        "--width",
        "64",
        "--height",
        "64",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("wrote"), "{stdout}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p("s.json")).unwrap()).unwrap();
    for key in [
        "surfaces",
        "patches",
        "elements",
        "vertices",
        "shots",
        "subsources",
        "pairs",
        "rays_cast",
        "pretest_visible",
        "pretest_hidden",
        "unshot_fraction",
        "solve_seconds",
        "total_seconds",
        "threads",
        "settings",
    ] {
        assert!(stats.get(key).is_some(), "missing {key}");
    }
    // The whole key set: design.md's list above and what was added since
    // (the phases' times, memory, the accelerator's build, the methods' own
    // counters).
    let keys = |value: &serde_json::Value| -> Vec<String> {
        value.as_object().unwrap().keys().cloned().collect()
    };
    assert_eq!(
        keys(&stats),
        [
            "absorbed_fraction",
            "accel_build",
            "accel_build_seconds",
            "base_elements",
            "bookkeeping_seconds",
            "coarse_device_shots",
            "coarse_shots",
            "coarse_stop_reason",
            "cut_entries",
            "cut_evaluations",
            "cut_samples",
            "cut_splits",
            "device",
            "device_bytes_read",
            "device_checkpoints",
            "device_fault",
            "device_host_waits",
            "device_kernel_seconds",
            "device_longest_visits",
            "device_mean_visits",
            "device_objects_made",
            "device_passes",
            "device_pipeline_cache",
            "device_pipeline_seconds",
            "device_readback_seconds",
            "device_shots",
            "device_stage_seconds",
            "device_submissions",
            "device_upload_seconds",
            "element_sources",
            "elements",
            "escaped_fraction",
            "estimated_memory_bytes",
            "final_gather_seconds",
            "form_factor_thread_seconds",
            "gather_seconds",
            "hemicube_seconds",
            "lightmap",
            "lights",
            "load_seconds",
            "mesh_seconds",
            "pairs",
            "patches",
            "peak_memory_bytes",
            "pretest_hidden",
            "pretest_thread_seconds",
            "pretest_visible",
            "ray_thread_seconds",
            "rays_cast",
            "receiver_walks",
            "refined_elements",
            "replayed_receivers",
            "replayed_shots",
            "rounds",
            "scene",
            "settings",
            "shadow_cache_hits",
            "shots",
            "sky_portals",
            "solve_seconds",
            "stop_reason",
            "subsources",
            "surface_ids",
            "surfaces",
            "threads",
            "total_seconds",
            "unshot_fraction",
            "vertices",
            "walk_node_visits",
            "write_seconds",
        ]
    );
    assert_eq!(
        keys(&stats["settings"]),
        [
            "accel",
            "conform",
            "converge",
            "cut_error",
            "element_size",
            "final_gather",
            "form_factor",
            "hemicube_resolution",
            "max_shots",
            "max_subsources",
            "merge_coplanar",
            "overshoot",
            "patch_size",
            "refine_levels",
            "refine_tolerance",
            "round",
            "shooting",
            "subsources",
            "time_limit",
            "tolerance",
            "visibility",
        ]
    );
    assert_eq!(stats["settings"]["accel"], "bvh");
    assert_eq!(stats["settings"]["overshoot"], 0.0);
    assert_eq!(stats["settings"]["final_gather"], "direct");
    assert!(stats["final_gather_seconds"].as_f64().unwrap() > 0.0);
    assert_eq!(stats["stop_reason"], "converged");
    assert!(!keys(&stats["accel_build"]).is_empty());
    assert!(stats["unshot_fraction"].as_f64().unwrap() < 0.01);
    // The ledger: what was emitted is unshot, absorbed or escaped (the
    // box is open at the front: about a third of the light leaves it).
    let fraction = |key: &str| stats[key].as_f64().unwrap();
    let total =
        fraction("unshot_fraction") + fraction("absorbed_fraction") + fraction("escaped_fraction");
    assert!((total - 1.0).abs() < 1e-6, "the ledger sums to {total}");
    assert!(
        (0.2..0.45).contains(&fraction("escaped_fraction")),
        "{}",
        stats["escaped_fraction"]
    );
    let csv = std::fs::read_to_string(p("c.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("x,y,z,nx,ny,nz,surface,r,g,b"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len() as u64, stats["vertices"].as_u64().unwrap());
    for row in &rows {
        assert_eq!(row.len(), 10);
        let normal_length = (row[3] * row[3] + row[4] * row[4] + row[5] * row[5]).sqrt();
        assert_abs_diff_eq!(normal_length, 1.0, epsilon = 1e-9);
        assert!(row[7..].iter().all(|b| b.is_finite() && *b >= 0.0));
    }
    let png = std::fs::read(p("c.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}

#[test]
fn scenes_lists_the_builtins() {
    let out = run(&["scenes"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        stdout.contains("room") && stdout.contains("cornell"),
        "{stdout}"
    );
}

#[test]
fn presets_set_every_switch_and_explicit_switches_override_them() {
    let dir = tempfile::tempdir().unwrap();
    let stats = |args: &[&str]| {
        let json = dir.path().join("s.json");
        let png = dir.path().join("c.png");
        let mut all = vec![
            "render",
            "cornell",
            "--max-shots",
            "1",
            "--width",
            "16",
            "--height",
            "16",
            "--stats",
            json.to_str().unwrap(),
            "--output",
            png.to_str().unwrap(),
        ];
        all.extend_from_slice(args);
        let out = run(&all);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let value: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let s = &value["settings"];
        [
            s["shooting"].as_str().unwrap().to_string(),
            s["visibility"].as_str().unwrap().to_string(),
            s["accel"].as_str().unwrap().to_string(),
            s["form_factor"].as_str().unwrap().to_string(),
            s["merge_coplanar"].to_string(),
        ]
    };
    let owned = |a: [&str; 5]| a.map(str::to_string);
    assert_eq!(
        stats(&[]),
        owned(["adaptive", "ray", "bvh", "analytic", "true"])
    );
    assert_eq!(
        stats(&["--preset", "wong-tsang93"]),
        owned(["patches", "hemicube", "bsp", "analytic", "false"])
    );
    assert_eq!(
        stats(&["--preset", "wallace89"]),
        owned(["patches", "ray", "brute", "wallace", "false"])
    );
    assert_eq!(
        stats(&["--preset", "wallace89", "--form-factor", "analytic"]),
        owned(["patches", "ray", "brute", "analytic", "false"])
    );
    assert_eq!(
        stats(&[
            "--preset",
            "wong-tsang93",
            "--visibility",
            "ray",
            "--accel",
            "brute",
            "--merge-coplanar",
            "on"
        ]),
        owned(["patches", "ray", "brute", "analytic", "true"])
    );
    assert_eq!(
        stats(&["--shooting", "patches", "--merge-coplanar", "off"]),
        owned(["patches", "ray", "bvh", "analytic", "false"])
    );
    let out = run(&["render", "cornell", "--accel", "octree"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("octree"));
}

#[test]
fn every_experiment_runs_in_quick_mode() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(&[
        "experiment",
        "all",
        "--quick",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in [
        "fig2-1",
        "fig4-2",
        "fig4-3",
        "formula-timing",
        "fig5-1",
        "fig5-2",
    ] {
        let report = std::fs::read_to_string(dir.path().join(format!("{name}.md"))).unwrap();
        assert!(
            report.contains("- revision:") && report.contains("| --- |"),
            "{name}"
        );
    }
    assert!(dir.path().join("fig5-1.png").exists());
    let out = run(&[
        "experiment",
        "fig9-9",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no experiment 'fig9-9'"));
}
