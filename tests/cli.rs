//! The command line end to end: every kind of bad input gets one
//! clear error naming the file (and line), a non-zero exit, no panic and no
//! output file; good input writes the picture, CSV and JSON of design.md
//! section 6.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use approx::assert_abs_diff_eq;

#[path = "../crates/radiosity/tests/common/mod.rs"]
mod common;

const MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 10 10 10\nnewmtl white\nKd 0.7 0.7 0.7\n";

/// A floor under a light, with a hole for one bad line.
fn obj(extra: &str) -> String {
    format!(
        "mtllib scene.mtl\n\
         v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\n\
         v -0.2 1 -0.2\nv 0.2 1 -0.2\nv 0.2 1 0.2\nv -0.2 1 0.2\n\
         usemtl white\nf 4 3 2 1\nusemtl light\nf 5 6 7 8\n{extra}"
    )
}

struct Case {
    dir: tempfile::TempDir,
}

impl Case {
    fn new(obj: &str, mtl: &str) -> Case {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("scene.obj"), obj).unwrap();
        std::fs::write(dir.path().join("scene.mtl"), mtl).unwrap();
        Case { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn render(&self, scene: &Path) -> Output {
        run(&[
            "render",
            scene.to_str().unwrap(),
            "--output",
            self.path("out.png").to_str().unwrap(),
            "--vertices",
            self.path("out.csv").to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "24",
            "--max-shots",
            "2",
        ])
    }

    /// Nothing was written: no picture, no CSV, no stray temporary file.
    fn assert_no_output(&self) {
        let mut names: Vec<String> = std::fs::read_dir(self.dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["scene.mtl", "scene.obj"]);
    }
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env("RADIOSITY_DEVICE", "cpu")
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Runs a bad scene and checks the error: one `error:` line that contains
/// every expected fragment, non-zero exit, no panic, no output.
fn assert_rejected(obj_text: &str, mtl: &str, expected: &[&str]) {
    let case = Case::new(obj_text, mtl);
    let out = case.render(&case.path("scene.obj"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "accepted: {stderr}");
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    for fragment in expected {
        assert!(
            errors[0].contains(fragment),
            "'{fragment}' not in: {stderr}"
        );
    }
    case.assert_no_output();
}

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

// Hostile inputs: each refused with one exact `error:` line
// (file, line, problem and what to change), exit status 1, no output and
// no temporary file; or, where the intent is clear, accepted.

/// Runs `render` on `scene` with extra flags, writing into the case's
/// folder.
fn render_with(case: &Case, scene: &str, flags: &[&str]) -> Output {
    let out_png = case.path("out.png");
    let mut args = vec!["render", scene];
    args.extend_from_slice(flags);
    for (flag, value) in [
        ("--output", out_png.to_str().unwrap()),
        ("--width", "16"),
        ("--height", "12"),
        ("--max-shots", "1"),
    ] {
        if !flags.contains(&flag) {
            args.extend([flag, value]);
        }
    }
    run(&args)
}

/// The exact one-line refusal: `error: MESSAGE` with `{dir}` standing for
/// the case's folder, status 1, nothing written.
fn assert_refused_exactly(case: &Case, out: &Output, expected: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    let expected = expected.replace("{dir}", case.dir.path().to_str().unwrap());
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.trim_end(), format!("error: {expected}"));
    case.assert_no_output();
}

/// A scene (`obj` text, `mtl` text) refused with exactly `expected`.
fn refused(obj_text: &str, mtl: &str, flags: &[&str], expected: &str) {
    let case = Case::new(obj_text, mtl);
    let scene = case.path("scene.obj");
    let out = render_with(&case, scene.to_str().unwrap(), flags);
    assert_refused_exactly(&case, &out, expected);
}

#[test]
fn wrong_counts_and_malformed_references_are_errors_with_file_and_line() {
    let kd2 = MTL.replace("Kd 0.7 0.7 0.7", "Kd 0.5 0.5");
    refused(
        &obj(""),
        &kd2,
        &[],
        "{dir}/scene.mtl:5: 'Kd' takes 1 number (grey) or 3 (r g b), found 2",
    );
    let ke4 = MTL.replace("Ke 10 10 10", "Ke 1 2 3 4");
    refused(
        &obj(""),
        &ke4,
        &[],
        "{dir}/scene.mtl:3: 'Ke' takes 1 number (grey) or 3 (r g b), found 4",
    );
    refused(
        &obj("f 1/2/3/4 2 3\n"),
        MTL,
        &[],
        "{dir}/scene.obj:14: '1/2/3/4' is not a vertex reference (v, v/vt, v//vn or v/vt/vn)",
    );
    refused(
        &obj("vt 0 0\nf 1/x/2 2 3\n"),
        MTL,
        &[],
        "{dir}/scene.obj:15: 'x' in '1/x/2' is not a texture coordinate index",
    );
}

#[test]
fn self_intersecting_faces_are_refused() {
    refused(
        &obj("v 0 0 0\nv 1 0 1\nv 1 0 0\nv 0 0 1\nf 9 10 11 12\n"),
        MTL,
        &[],
        "{dir}/scene.obj:18: the face's outline crosses itself (its edge from corner 1 to 2 \
         meets its edge from corner 3 to 4): a face must be a simple polygon, so split it into \
         faces that are",
    );
    let mut star = String::new();
    for i in 0..5 {
        let a = std::f64::consts::TAU * (2 * i) as f64 / 5.0;
        star += &format!("v {} 0.5 {}\n", a.cos(), a.sin());
    }
    star += "f 9 10 11 12 13\n";
    refused(
        &obj(&star),
        MTL,
        &[],
        "{dir}/scene.obj:19: the face's outline crosses itself (its edge from corner 2 to 3 \
         meets its edge from corner 4 to 5): a face must be a simple polygon, so split it into \
         faces that are",
    );
}

#[test]
fn strongly_warped_face_is_refused_and_slightly_warped_face_is_split() {
    refused(
        &obj("v 0 0 0\nv 1 0 0\nv 1 0.5 1\nv 0 0 1\nf 9 10 11 12\n"),
        MTL,
        &[],
        "{dir}/scene.obj:18: the face is not planar: a corner is 11.8 cm (7.9% of its size) off \
         its plane, and split into triangles it would fold by 35 degrees (more than 10), so the \
         intended shape is unclear: split it into triangles or planar faces yourself",
    );
    let case = Case::new(
        &obj("v 0 0.1 0\nv 1 0.1 0\nv 1 0.11 1\nv 0 0.1 1\nf 12 11 10 9\n"),
        MTL,
    );
    let out = case.render(&case.path("scene.obj"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "warning: {}:18: the face is not planar (a corner is 2.50 mm off its plane, 0.177% \
             of its size): split into 2 triangles folding by 0.81 degrees",
            case.path("scene.obj").display()
        )),
        "{stderr}"
    );
}

#[test]
fn measured_cornell_box_loads_with_a_warning_naming_the_red_wall() {
    let path = common::shared_scene("cornell_box/cornell_box.obj");
    let case = Case::new("", "");
    let out = render_with(&case, path.to_str().unwrap(), &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let obj_text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(obj_text.lines().nth(41), Some("f 18 17 20 19"));
    let warning = format!(
        "warning: {}:42: the face is not planar (a corner is ",
        path.display()
    );
    assert!(stderr.contains(&warning), "{stderr}");
    assert!(stderr.contains("split into 2 triangles folding by 0.47 degrees"));
    assert!(case.path("out.png").exists());
}

#[test]
fn byte_order_marks_and_old_mac_line_ends_are_read() {
    let case = Case::new(&format!("\u{feff}{}", obj("")), &format!("\u{feff}{MTL}"));
    let out = case.render(&case.path("scene.obj"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let case = Case::new(&obj("").replace('\n', "\r"), &MTL.replace('\n', "\r"));
    let out = case.render(&case.path("scene.obj"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    refused(
        &obj("f 1 2 99\n").replace('\n', "\r"),
        MTL,
        &[],
        "{dir}/scene.obj:14: vertex index 99 is out of range (8 defined so far)",
    );
}

#[test]
fn nul_bytes_and_long_names_are_reported_readably() {
    refused(
        &obj("# a comment \0 with a NUL\n"),
        MTL,
        &[],
        "{dir}/scene.obj:14: a NUL byte: this looks like a binary file, not Wavefront OBJ/MTL \
         text",
    );
    let name = "m".repeat(1_000_000);
    refused(
        &obj(&format!("usemtl {name}\n")),
        MTL,
        &[],
        &format!(
            "{{dir}}/scene.obj:14: material '{}...' (1000000 bytes) is not defined in any loaded \
             material library (mtllib)",
            "m".repeat(40)
        ),
    );
}

#[test]
fn inputs_that_are_not_regular_files_are_refused_before_reading() {
    let not_regular =
        "this is not a regular file (a device, pipe or socket can be endless): give a file";
    refused(
        &obj("").replace("mtllib scene.mtl", "mtllib /dev/zero"),
        MTL,
        &[],
        &format!("{{dir}}/scene.obj:1: cannot read material library '/dev/zero': {not_regular}"),
    );
    let case = Case::new(&obj(""), MTL);
    let out = render_with(&case, "/dev/zero", &[]);
    assert_refused_exactly(&case, &out, &format!("/dev/zero: {not_regular}"));

    let case = Case::new(&obj(""), MTL);
    let link = case.dir.path().join("random.obj");
    std::os::unix::fs::symlink("/dev/urandom", &link).unwrap();
    let out = render_with(&case, link.to_str().unwrap(), &[]);
    std::fs::remove_file(&link).unwrap();
    assert_refused_exactly(&case, &out, &format!("{{dir}}/random.obj: {not_regular}"));

    // glTF alike: the file itself, and a buffer its JSON names.
    let case = Case::new(&obj(""), MTL);
    let link = case.dir.path().join("zero.glb");
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    let out = render_with(&case, link.to_str().unwrap(), &[]);
    std::fs::remove_file(&link).unwrap();
    assert_refused_exactly(&case, &out, &format!("{{dir}}/zero.glb: {not_regular}"));

    let case = Case::new(&obj(""), MTL);
    let gltf = case.dir.path().join("scene.gltf");
    std::fs::write(
        &gltf,
        r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"zero.bin","byteLength":36}]}"#,
    )
    .unwrap();
    let link = case.dir.path().join("zero.bin");
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    let out = render_with(&case, gltf.to_str().unwrap(), &[]);
    std::fs::remove_file(&link).unwrap();
    std::fs::remove_file(&gltf).unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("zero.bin") && stderr.contains(not_regular),
        "{stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");

    let case = Case::new(&obj(""), MTL);
    let fifo = case.dir.path().join("fifo.obj");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let out = render_with(&case, fifo.to_str().unwrap(), &[]);
    std::fs::remove_file(&fifo).unwrap();
    assert_refused_exactly(&case, &out, &format!("{{dir}}/fifo.obj: {not_regular}"));

    let case = Case::new(&obj(""), MTL);
    let folder = case.dir.path().join("folder.obj");
    std::fs::create_dir(&folder).unwrap();
    let out = render_with(&case, folder.to_str().unwrap(), &[]);
    std::fs::remove_dir(&folder).unwrap();
    assert_refused_exactly(
        &case,
        &out,
        "{dir}/folder.obj: this is a folder, not a file",
    );
}

#[test]
fn limits_name_the_option_that_raises_them() {
    let big = format!("{}{}", obj(""), "# padding\n".repeat(120_000));
    refused(
        &big,
        MTL,
        &["--max-file-size", "1"],
        &format!(
            "{{dir}}/scene.obj: the file is {} bytes, more than the limit of 1 MiB (raise it \
             with --max-file-size)",
            big.len()
        ),
    );
    // A million corners: refused at once, not triangulated for minutes.
    let corners: String = (0..1_000_000).map(|i| format!(" {}", i % 12 + 1)).collect();
    refused(
        &obj(&format!("f{corners}\n")),
        MTL,
        &[],
        "{dir}/scene.obj:14: the face has 1000000 corners, more than the limit of 100000 (raise \
         it with --max-corners)",
    );
    let line = format!("# {}\n", "x".repeat(10 << 20));
    refused(
        &obj(&line),
        MTL,
        &[],
        "{dir}/scene.obj:14: the line is 10485762 bytes long, more than the limit of 4194304 \
         bytes (raise it with --max-line-length)",
    );
    refused(
        &obj("f 1 2 3\n"),
        MTL,
        &["--max-faces", "2"],
        "{dir}/scene.obj:14: more than 2 faces, the limit (raise it with --max-faces)",
    );
    refused(
        &obj(""),
        MTL,
        &["--max-vertices", "4"],
        "{dir}/scene.obj:6: more than 4 vertices, the limit (raise it with --max-vertices)",
    );
    refused(
        &obj(""),
        MTL,
        &["--max-elements", "10"],
        "meshing would create 820 elements, more than the limit of 10: give a --element-size \
         larger than 0.075 m (the default: 1/40 of the scene's size), or raise \
         --max-elements",
    );
}

#[test]
fn mesh_size_errors_name_the_flag_or_directive_at_fault() {
    refused(
        &format!("#@mesh 1e-9 1e-9\n{}", obj("")),
        MTL,
        &[],
        "meshing would create 4160000000000000000 elements, more than the limit of 4000000: \
         raise the patch size of the #@mesh directive at {dir}/scene.obj:1 (now 1e-9 m) or give \
         a larger --patch-size, or raise --max-elements",
    );
    refused(
        &format!("#@mesh 1 1e-5\n{}", obj("")),
        MTL,
        &[],
        "meshing would create 41600000000 elements, more than the limit of 4000000: raise the \
         element size of the #@mesh directive at {dir}/scene.obj:1 (now 1e-5 m) or give a larger \
         --element-size, or raise --max-elements",
    );
    refused(
        &obj(""),
        MTL,
        &["--patch-size", "1e-9"],
        "meshing would create 4160000000000000000 elements, more than the limit of 4000000: \
         raise --patch-size (now 1e-9 m), or raise --max-elements",
    );
}

#[test]
fn negative_and_malformed_option_values_get_one_line() {
    for (flags, expected) in [
        (
            &["--width", "-5"][..],
            "--width must be a positive integer, not -5",
        ),
        (
            &["--converge", "-0.5"],
            "--converge must be a fraction in [0, 1), not -0.5",
        ),
        (
            &["--element-size", "-5"],
            "--element-size must be a positive number of metres, not -5",
        ),
        (
            &["--threads", "-2"],
            "--threads must be a positive integer, not -2",
        ),
        (
            &["--max-shots", "-1"],
            "--max-shots must be a whole number (0 or more), not -1",
        ),
        (
            &["--height", "1e3"],
            "--height must be a positive integer, not 1e3",
        ),
        (
            &["--width", "99999999999"],
            "--width must be at most 4294967295, not 99999999999",
        ),
    ] {
        let case = Case::new(&obj(""), MTL);
        let scene = case.path("scene.obj");
        let out = render_with(&case, scene.to_str().unwrap(), flags);
        assert_refused_exactly(&case, &out, expected);
    }
}

#[test]
fn file_errors_do_not_repeat_their_cause() {
    let case = Case::new(&obj(""), MTL);
    let missing = case.path("missing.obj");
    let out = render_with(&case, missing.to_str().unwrap(), &[]);
    assert_refused_exactly(&case, &out, "{dir}/missing.obj: no such file");
    let out = render_with(
        &case,
        case.path("scene.obj").to_str().unwrap(),
        &["--output", "/sys/picture.png"],
    );
    assert_refused_exactly(
        &case,
        &out,
        "/sys/picture.png: cannot write: Permission denied (os error 13)",
    );
}

#[test]
fn outputs_are_checked_before_the_solve() {
    let case = Case::new(&obj(""), MTL);
    let scene = case.path("scene.obj");
    let inside_a_file = case.path("scene.obj").join("out.png");
    let out = render_with(
        &case,
        scene.to_str().unwrap(),
        &["--output", inside_a_file.to_str().unwrap()],
    );
    assert_refused_exactly(
        &case,
        &out,
        "{dir}/scene.obj/out.png: cannot write: {dir}/scene.obj is a file, not a folder",
    );
    let folder = case.path("folder.png");
    std::fs::create_dir(&folder).unwrap();
    let out = render_with(
        &case,
        scene.to_str().unwrap(),
        &["--output", folder.to_str().unwrap()],
    );
    std::fs::remove_dir(&folder).unwrap();
    assert_refused_exactly(
        &case,
        &out,
        "{dir}/folder.png: cannot write: this is a folder: give a file name",
    );
}

#[test]
fn a_symbolic_link_is_written_through() {
    let case = Case::new(&obj(""), MTL);
    let real = tempfile::tempdir().unwrap();
    let target = real.path().join("picture.png");
    std::fs::write(&target, b"old").unwrap();
    let link = case.path("link.png");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let out = render_with(
        &case,
        case.path("scene.obj").to_str().unwrap(),
        &["--output", link.to_str().unwrap()],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(&std::fs::read(&target).unwrap()[1..4], b"PNG");
    let mut left: Vec<_> = std::fs::read_dir(real.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    left.sort();
    assert_eq!(left, ["picture.png"]);
}

#[test]
fn a_write_failure_midway_leaves_nothing_behind() {
    // The child may write at most 16 KiB a file (RLIMIT_FSIZE, set by the
    // shell's ulimit in 512-byte blocks) and ignores SIGXFSZ, so the large
    // vertex CSV fails midway with EFBIG, as on a full disk, after the
    // small picture has been staged.
    let case = Case::new(&obj(""), MTL);
    let p = |name: &str| case.path(name).to_str().unwrap().to_string();
    let out = Command::new("sh")
        .env("RADIOSITY_DEVICE", "cpu")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 32; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_radiosity"))
        .args([
            "render",
            &p("scene.obj"),
            "--output",
            &p("out.png"),
            "--vertices",
            &p("out.csv"),
            "--width",
            "16",
            "--height",
            "12",
            "--max-shots",
            "1",
            "--element-size",
            "0.02",
        ])
        .output()
        .unwrap();
    assert_refused_exactly(
        &case,
        &out,
        "{dir}/out.csv: cannot write: File too large (os error 27)",
    );
}

#[test]
fn limit_defaults_in_the_help_are_the_library_defaults() {
    let out = run(&["render", "--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    let limits = radiosity::scene::Limits::default();
    let max_elements = radiosity::mesh::MeshSettings::default().max_elements;
    for (flag, value) in [
        ("--max-file-size", (limits.max_file_bytes >> 20) as usize),
        ("--max-line-length", limits.max_line_bytes),
        ("--max-corners", limits.max_corners),
        ("--max-faces", limits.max_faces),
        ("--max-vertices", limits.max_vertices),
        ("--max-elements", max_elements),
    ] {
        let line = help.lines().find(|l| l.contains(flag)).unwrap();
        assert!(line.contains(&format!("[default: {value}]")), "{line}");
    }
}

/// `render --help` groups its flags under headings, as cargo's and
/// ripgrep's do: each flag under its own.
#[test]
fn the_help_groups_flags_under_headings() {
    let out = run(&["render", "--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    let heading_of = |flag: &str| -> String {
        let mut heading = String::new();
        for line in help.lines() {
            if !line.starts_with(' ') && line.ends_with(':') {
                heading = line.trim_end_matches(':').to_string();
            }
            if line.trim_start().starts_with(flag) || line.contains(&format!(" {flag} ")) {
                return heading;
            }
        }
        panic!("{flag} not in the help");
    };
    for (flag, heading) in [
        ("--bake <", "Outputs"),
        ("--sensors-out", "Outputs"),
        ("--emission-scale", "Scene and lights"),
        ("--sky <", "Daylight"),
        ("--preset", "Solver"),
        ("--converge", "Solver"),
        ("--supersampling", "Picture"),
        ("--device", "Device"),
        ("--progress-json", "Progress and stopping"),
        ("--tolerance", "Solver"),
        ("--max-memory", "Limits (each error says which to raise)"),
    ] {
        assert_eq!(heading_of(flag), heading, "{flag}");
    }
}

/// A lightmap bake from the command line: the `.glb`, the `.lightmap.exr`
/// beside it and the lightmap's figures in `--stats`.
#[test]
fn lightmap_bake_writes_the_file_the_exr_and_its_statistics() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let out = run(&[
        "render",
        "cornell",
        "-q",
        "--converge",
        "0.05",
        "--width",
        "64",
        "--height",
        "64",
        "--output",
        &path("c.png"),
        "--bake",
        &path("c.glb"),
        "--bake-target",
        "lightmap",
        "--lightmap-density",
        "40",
        "--stats",
        &path("c.json"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.path().join("c.glb").is_file());
    assert!(dir.path().join("c.lightmap.exr").is_file());
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("c.json")).unwrap()).unwrap();
    let lightmap = &stats["lightmap"];
    assert_eq!(lightmap["density"], 40.0);
    assert!(lightmap["texels"].as_u64().unwrap() > 100);
    assert_eq!(lightmap["missing"], 0);
}

/// A lightmap too large for `--max-memory` is refused before the solve,
/// with the flags that shrink it; nothing is written.
#[test]
fn an_oversized_lightmap_is_refused_before_the_solve() {
    let dir = tempfile::tempdir().unwrap();
    let bake = dir.path().join("big.glb");
    let out = run(&[
        "render",
        "cornell",
        "-q",
        "--output",
        dir.path().join("big.png").to_str().unwrap(),
        "--bake",
        bake.to_str().unwrap(),
        "--bake-target",
        "lightmap",
        "--lightmap-density",
        "1000",
        "--lightmap-max-size",
        "16384",
        "--max-memory",
        "200M",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("lower --lightmap-density or --lightmap-max-size"),
        "{stderr}"
    );
    assert!(!bake.exists());
}

/// A `--time-limit` that cuts refinement's coarse pass short says so: in
/// `--stats` (`coarse_stop_reason`), and in the summary, since the mesh
/// then depends on how fast the machine was. The coarse pass has a quarter
/// of the limit: a quarter of a nanosecond rounds to nothing, so it stops
/// before its first shot on any machine. Without a limit the pass stops by
/// its own rules.
#[test]
fn a_coarse_pass_cut_by_the_time_limit_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let stats = |name: &str, extra: &[&str]| {
        let path = dir.path().join(name);
        let mut args = vec![
            "render", "cornell", "--width", "16", "--height", "12", "--output",
        ];
        let picture = dir.path().join(format!("{name}.png"));
        args.push(picture.to_str().unwrap());
        args.extend(["--stats", path.to_str().unwrap()]);
        args.extend(extra);
        let out = run(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        (json, String::from_utf8_lossy(&out.stdout).into_owned())
    };
    let (cut, summary) = stats("cut.json", &["--time-limit", "1e-9"]);
    assert_eq!(cut["coarse_stop_reason"], "time limit reached");
    assert_eq!(cut["coarse_shots"], 0);
    assert_eq!(cut["stop_reason"], "time limit reached");
    assert!(summary.contains("the coarse pass ran out of its quarter of --time-limit"));
    let (whole, summary) = stats("whole.json", &["--max-shots", "1"]);
    let reason = whole["coarse_stop_reason"].as_str().unwrap();
    assert!(
        ["converged", "max-shots reached"].contains(&reason),
        "{reason}"
    );
    assert!(!summary.contains("coarse pass ran out"), "{summary}");
    let (unrefined, _) = stats(
        "unrefined.json",
        &["--refine-levels", "0", "--max-shots", "1"],
    );
    assert!(unrefined["coarse_stop_reason"].is_null());
}
