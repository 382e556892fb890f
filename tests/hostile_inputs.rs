//! Hostile inputs to the command line: each refused with one exact
//! `error:` line (file, line, problem and what to change), exit status 1,
//! no output and no temporary file; or, where the intent is clear,
//! accepted.

use std::process::{Command, Output};

mod cli_common;
#[path = "../crates/radiosity/tests/common/mod.rs"]
mod common;

use cli_common::{Case, MTL, obj, run};

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
