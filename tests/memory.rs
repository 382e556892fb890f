//! Memory: the peak resident set in `--stats` and the
//! summary, the estimate against measured peaks, and the refusal of a run
//! whose estimate exceeds `--max-memory`. Each run is its own process, so
//! its peak is its own.

#[path = "../crates/radiosity/tests/common/mod.rs"]
mod common;

use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env("RADIOSITY_DEVICE", "cpu")
        .args(args)
        .output()
        .unwrap()
}

/// Runs `render` with `extra` arguments and returns its `--stats` object.
fn stats(scene: &str, extra: &[&str]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("s.json");
    let png = dir.path().join("p.png");
    let mut args = vec![
        "render",
        scene,
        "--output",
        png.to_str().unwrap(),
        "--stats",
        json.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = run(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(
        summary.contains("memory: peak ") && summary.contains(" resident (estimated "),
        "{summary}"
    );
    serde_json::from_slice(&std::fs::read(json).unwrap()).unwrap()
}

/// The estimate is within a factor of 1.5 of the measured peak, either
/// way, for both ways of shooting, with and without a picture's worth of
/// supersampling, on the built-in scenes and Sponza (66k triangles).
#[test]
fn estimates_are_within_a_factor_of_the_measured_peak() {
    let sponza = common::shared_scene("sponza_dabrovic/sponza_dabrovic.obj");
    let sponza = sponza.to_str().unwrap();
    let cases: [(&str, &[&str]); 5] = [
        ("room", &["--max-shots", "3"]),
        ("cornell", &["--preset", "wong-tsang93", "--max-shots", "3"]),
        (
            "room",
            &["--max-shots", "1", "--width", "64", "--height", "48"],
        ),
        (sponza, &["--max-shots", "1"]),
        (
            sponza,
            &[
                "--preset",
                "wong-tsang93",
                "--accel",
                "bvh",
                "--max-shots",
                "1",
            ],
        ),
    ];
    for (scene, extra) in cases {
        let s = stats(scene, extra);
        let peak = s["peak_memory_bytes"].as_u64().unwrap() as f64;
        let estimate = s["estimated_memory_bytes"].as_u64().unwrap() as f64;
        let ratio = estimate / peak;
        assert!(
            (1.0 / 1.5..=1.5).contains(&ratio),
            "{scene} {extra:?}: estimated {estimate}, peak {peak}"
        );
    }
}

#[test]
fn a_run_over_the_limit_is_refused_before_its_solve() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("room.png");
    let out = run(&[
        "render",
        "room",
        "--output",
        png.to_str().unwrap(),
        "--max-memory",
        "20M",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let line = stderr.lines().next().unwrap();
    assert!(line.starts_with("error: this run needs about "), "{stderr}");
    // The picture's 800 x 600 x 9 samples are the largest part.
    assert!(
        line.contains("(picture ")
            && line.contains(
                "; --max-memory allows 20 MiB: lower --width, --height or \
                 --supersampling, or "
            )
            && line.ends_with(", or raise --max-memory"),
        "{line}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);

    // Enough memory: the same run goes through.
    let out = run(&[
        "render",
        "room",
        "--output",
        png.to_str().unwrap(),
        "--max-memory",
        "1G",
        "--max-shots",
        "1",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn bad_sizes_are_named() {
    for (value, expected) in [
        (
            "lots",
            "error: --max-memory: 'lots' is not a size such as 512M, 24G or 1.5GiB",
        ),
        ("-1G", "error: --max-memory: '-1G' is not a positive size"),
        (
            "3X",
            "error: --max-memory: '3X': unknown unit 'X' (use K, M, G or T)",
        ),
    ] {
        let out = run(&["render", "room", "--max-memory", value]);
        assert_eq!(out.status.code(), Some(1));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.trim_end(), expected);
    }
}
