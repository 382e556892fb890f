//! Lights and daylight through the command line: a scene lit by a
//! `#@light` alone renders and its sensors read the closed form in lux;
//! `--sun` and `--sky` light a scene with no emitter; the `--stats` file
//! lists the lights; bad directives and daylight flags get one error, a
//! non-zero exit and no output file.

use std::path::Path;
use std::process::{Command, Output};

/// A grey 10 x 10 m floor, no emitter, with `directives` above it.
fn floor(directives: &str) -> String {
    format!(
        "{directives}mtllib scene.mtl\nusemtl grey\n\
         v -5 0 -5\nv -5 0 5\nv 5 0 5\nv 5 0 -5\nf 1 2 3 4\n"
    )
}

fn run(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env("RADIOSITY_DEVICE", "cpu")
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the binary runs")
}

fn case(obj: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.obj"), obj).unwrap();
    std::fs::write(
        dir.path().join("scene.mtl"),
        "newmtl grey\nKd 0.5 0.5 0.5\n",
    )
    .unwrap();
    dir
}

/// `render scene.obj` with a small picture and the sensors of
/// `points.txt` written to `lux.csv`, and `extra` flags.
fn render_with_sensors(dir: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        "scene.obj",
        "--output",
        "out.png",
        "--width",
        "32",
        "--height",
        "24",
        "--sensors",
        "points.txt",
        "--sensors-out",
        "lux.csv",
    ];
    args.extend(extra);
    run(dir, &args)
}

/// The lux column of a sensors CSV.
fn lux(path: &Path) -> Vec<f64> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
        .collect()
}

#[test]
fn a_scene_lit_by_a_point_light_alone_renders_and_its_sensors_read_lux() {
    let dir = case(&floor("#@light point 0 2 0 100\n"));
    std::fs::write(dir.path().join("points.txt"), "0 0 0 0 1 0\n2 0 0 0 1 0\n").unwrap();
    let out = render_with_sensors(dir.path(), &["--stats", "stats.json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got = lux(&dir.path().join("lux.csv"));
    // 100 cd, 2 m up: 25 lux below; at 2 m aside, 100 x 2 / 8^1.5.
    assert!((got[0] / 25.0 - 1.0).abs() < 1e-5, "{got:?}");
    assert!(
        (got[1] / (200.0 / 8f64.powf(1.5)) - 1.0).abs() < 1e-5,
        "{got:?}"
    );
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("stats.json")).unwrap())
            .unwrap();
    let lights = stats["lights"].as_array().unwrap();
    assert_eq!(lights.len(), 1);
    assert_eq!(lights[0]["type"], "point");
    assert_eq!(lights[0]["name"], "#@light at line 1");
    // The flux of 100 cd: 400 pi lumens.
    let lumens = lights[0]["lumens"].as_f64().unwrap();
    assert!(
        (lumens / (400.0 * std::f64::consts::PI) - 1.0).abs() < 1e-9,
        "{lumens}"
    );
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(summary.contains("lights: 1 (point)"), "{summary}");
}

#[test]
fn daylight_lights_a_scene_with_no_emitter() {
    let dir = case(&floor(""));
    std::fs::write(dir.path().join("points.txt"), "0 0 0 0 1 0\n").unwrap();
    let out = render_with_sensors(
        dir.path(),
        &[
            "--sun",
            "30",
            "120",
            "60000",
            "--sky",
            "overcast",
            "--sky-illuminance",
            "10000",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The sun 30 degrees up gives 60000 sin 30 on the open floor, the sky
    // its horizontal illuminance (within its sampling noise).
    let got = lux(&dir.path().join("lux.csv"))[0];
    assert!((got / 40_000.0 - 1.0).abs() < 0.01, "{got}");
}

#[test]
fn bad_lights_and_daylight_get_one_error_and_no_output() {
    for (obj, flags, says) in [
        (
            floor("#@light spot 0 3 0 0 -1 0 50 30 20\n"),
            &[][..],
            "scene.obj:1: bad #@light directive: its cone angles are wrong",
        ),
        (
            floor("#@light lamp 0 3 0 50\n"),
            &[][..],
            "scene.obj:1: bad #@light directive: unknown light type 'lamp'",
        ),
        (
            floor("#@light point 0 3 0 -5\n"),
            &[][..],
            "its intensity -5 is not a finite number at least 0",
        ),
        (
            floor("#@light ies missing.ies 0 2 0\n"),
            &[][..],
            "scene.obj:1: bad #@light directive: cannot read 'missing.ies'",
        ),
        (floor(""), &[][..], "scene.obj: the scene has no emitter"),
        (
            floor(""),
            &["--sky", "clear", "--sky-illuminance", "10000"][..],
            "the clear sky needs the sun's position: give --sun",
        ),
        (
            floor(""),
            &["--sun", "95", "0", "1000"][..],
            "--sun: the altitude must be above 0 and at most 90 degrees",
        ),
        (
            floor(""),
            &["--sky", "uniform", "--sky-illuminance", "nan"][..],
            "--sky-illuminance must be a finite number of lux at least 0",
        ),
        (
            floor(""),
            &[
                "--sky",
                "uniform",
                "--sky-illuminance",
                "10000",
                "--ground-reflectance",
                "1.5",
            ][..],
            "--ground-reflectance must be from 0 to below 1, not 1.5",
        ),
    ] {
        let dir = case(&obj);
        let mut args = vec!["render", "scene.obj", "--output", "out.png"];
        args.extend(flags);
        let out = run(dir.path(), &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{says}: {stderr}");
        assert!(stderr.contains(says), "{says}: {stderr}");
        assert_eq!(stderr.matches("error:").count(), 1, "{stderr}");
        assert!(!dir.path().join("out.png").exists(), "{says}");
    }
}

#[test]
fn an_overcast_sky_alone_gives_the_daylight_factor_and_a_sun_refuses_it() {
    let dir = case(&floor(""));
    std::fs::write(dir.path().join("points.txt"), "0 0 0 0 1 0\n1 0 1 0 1 0\n").unwrap();
    let overcast = ["--sky", "overcast", "--sky-illuminance", "10000"];
    let out = render_with_sensors(dir.path(), &overcast);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(dir.path().join("lux.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("x,y,z,nx,ny,nz,er,eg,eb,br,bg,bb,lux,daylight_factor")
    );
    for line in lines {
        // The open floor: the factor is the lux over 10,000, in percent,
        // near 100.
        let columns: Vec<f64> = line.split(',').map(|c| c.parse().unwrap()).collect();
        let (lux, factor) = (columns[12], columns[13]);
        assert!((factor - lux / 100.0).abs() < 1e-9 * factor, "{line}");
        assert!((factor - 100.0).abs() < 1.0, "{line}");
    }
    // Asked for with a sun: one error, no output.
    std::fs::remove_file(dir.path().join("lux.csv")).unwrap();
    let mut flags = overcast.to_vec();
    flags.extend(["--sun", "30", "120", "60000", "--daylight-factor"]);
    let out = render_with_sensors(dir.path(), &flags);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--daylight-factor: the daylight factor is defined without the sun"),
        "{stderr}"
    );
    assert!(!dir.path().join("lux.csv").exists());
    // Without it, a sun just leaves the column out.
    let mut flags = overcast.to_vec();
    flags.extend(["--sun", "30", "120", "60000"]);
    let out = render_with_sensors(dir.path(), &flags);
    assert!(out.status.success());
    let csv = std::fs::read_to_string(dir.path().join("lux.csv")).unwrap();
    assert!(
        csv.starts_with("x,y,z,nx,ny,nz,er,eg,eb,br,bg,bb,lux\n"),
        "{csv}"
    );
}
