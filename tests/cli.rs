//! The command line end to end: every bad-input case of the issue gets one
//! clear error naming the file (and line), a non-zero exit, no panic and no
//! output file; good input writes the picture, CSV and JSON of design.md
//! section 6.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

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
    assert_rejected(&obj("v 1 2\n"), MTL, &["scene.obj:14:", "3 coordinates"]);
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
    assert_rejected(&obj(extra), MTL, &["scene.obj:18:", "non-planar"]);
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
    let cases: [(&[&str], &str); 13] = [
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
    assert!(stats["unshot_fraction"].as_f64().unwrap() < 0.01);
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
        assert!((normal_length - 1.0).abs() < 1e-9);
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
