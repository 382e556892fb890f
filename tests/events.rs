//! The command line as other programs drive it (the Blender add-on among
//! them): `--progress-json`'s events and `--stop-file`.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

use serde_json::Value;

fn radiosity() -> Command {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
}

fn events(text: &str) -> Vec<Value> {
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

/// Reads events from `lines` up to the first of kind `event`, which it
/// returns, or to the end, returning the last.
fn read_until(lines: &mut impl Iterator<Item = std::io::Result<String>>, event: &str) -> Value {
    let mut last = Value::Null;
    for line in lines {
        last = serde_json::from_str(&line.unwrap()).unwrap();
        if last["event"] == event {
            break;
        }
    }
    last
}

#[test]
fn progress_json_streams_the_run_and_ends_with_done() {
    let dir = tempfile::tempdir().unwrap();
    let picture = dir.path().join("c.png");
    let out = radiosity()
        .args([
            "render",
            "cornell",
            "--threads",
            "1",
            "--progress-json",
            "-",
            "-o",
        ])
        .arg(&picture)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Standard output holds the events only (no summary).
    let events = events(&String::from_utf8(out.stdout).unwrap());
    let kinds: Vec<&str> = events
        .iter()
        .map(|e| e["event"].as_str().unwrap())
        .collect();
    assert_eq!(kinds.last(), Some(&"done"));
    assert_eq!(kinds.iter().filter(|k| **k == "done").count(), 1);
    let solving = events
        .iter()
        .position(|e| e["stage"] == "solving")
        .expect("a solving stage");
    assert!(events[solving]["elements"].as_u64().unwrap() > 0);
    let progress: Vec<&Value> = events.iter().filter(|e| e["event"] == "progress").collect();
    assert!(!progress.is_empty());
    assert!(
        events
            .iter()
            .position(|e| e["event"] == "progress")
            .unwrap()
            > solving
    );
    // Shots only grow, and the last progress is the last shot's.
    let shots: Vec<u64> = progress
        .iter()
        .map(|e| e["shots"].as_u64().unwrap())
        .collect();
    assert!(shots.windows(2).all(|w| w[0] < w[1]), "{shots:?}");
    // The solve's last progress comes before the outputs are made, then
    // the final pass shows its own, to every point.
    let writing = events
        .iter()
        .position(|e| e["stage"] == "writing")
        .expect("a writing stage");
    let last_progress = events
        .iter()
        .rposition(|e| e["event"] == "progress")
        .unwrap();
    assert!(last_progress < writing, "{kinds:?}");
    let final_stage = events
        .iter()
        .position(|e| e["stage"] == "final pass")
        .expect("a final pass stage");
    assert!(final_stage > writing);
    assert_eq!(events[final_stage]["what"], "picture");
    let passes: Vec<&Value> = events
        .iter()
        .filter(|e| e["event"] == "final_pass")
        .collect();
    let total = passes.last().unwrap()["total"].as_u64().unwrap();
    assert!(total > 100_000, "{total} samples shaded");
    assert_eq!(passes.last().unwrap()["done"].as_u64(), Some(total));
    let done_counts: Vec<u64> = passes.iter().map(|e| e["done"].as_u64().unwrap()).collect();
    assert!(
        done_counts.windows(2).all(|w| w[0] <= w[1]),
        "{done_counts:?}"
    );
    let done = events.last().unwrap();
    assert_eq!(done["stop_reason"], "converged");
    assert_eq!(done["shots"].as_u64(), shots.last().copied());
    let last = progress.last().unwrap();
    assert!(last["unshot_fraction"].as_f64().unwrap() < last["stop_at"].as_f64().unwrap());
    assert_eq!(
        done["written"],
        serde_json::json!([picture.display().to_string()])
    );
    assert!(picture.exists());
}

#[test]
fn progress_json_to_a_file_keeps_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("events.jsonl");
    let out = radiosity()
        .args(["render", "cornell", "--progress-json"])
        .arg(&file)
        .arg("-o")
        .arg(dir.path().join("c.png"))
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("solved:"));
    let events = events(&std::fs::read_to_string(&file).unwrap());
    assert_eq!(events.last().unwrap()["event"], "done");
}

#[test]
fn a_failed_run_ends_the_stream_with_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.obj");
    let out = radiosity()
        .arg("render")
        .arg(&missing)
        .args(["--progress-json", "-"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let events = events(&String::from_utf8(out.stdout).unwrap());
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0]["event"], "error");
    let message = events[0]["message"].as_str().unwrap();
    assert!(message.contains("missing.obj"), "{message}");
    // The same words on standard error.
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.obj"));
}

#[test]
fn the_stop_file_stops_the_solve_and_writes_the_state_reached() {
    let dir = tempfile::tempdir().unwrap();
    let stop = dir.path().join("stop");
    let vertices = dir.path().join("v.csv");
    // A stopping rule no solve reaches (and a time limit as a backstop that
    // would fail the test): only the stop file ends it.
    let mut child = radiosity()
        .args([
            "render",
            "room",
            "--converge",
            "1e-12",
            "--time-limit",
            "600",
            "--progress-json",
            "-",
            "--stop-file",
        ])
        .arg(&stop)
        .arg("--vertices")
        .arg(&vertices)
        .arg("-o")
        .arg(dir.path().join("room.png"))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    assert_eq!(read_until(&mut lines, "progress")["event"], "progress");
    std::fs::write(&stop, "stop").unwrap();
    let last = read_until(&mut lines, "none");
    assert!(child.wait().unwrap().success());
    assert_eq!(last["event"], "done");
    assert_eq!(last["stop_reason"], "stopped");
    assert!(last["shots"].as_u64().unwrap() >= 1);
    let rows = std::fs::read_to_string(&vertices).unwrap().lines().count();
    assert!(rows > 100, "{rows} rows");
}

#[test]
fn a_stop_file_that_exists_already_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let stop = dir.path().join("stop");
    std::fs::write(&stop, "").unwrap();
    let picture = dir.path().join("c.png");
    let out = radiosity()
        .args(["render", "cornell", "--stop-file"])
        .arg(&stop)
        .arg("-o")
        .arg(&picture)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("exists already"), "{stderr}");
    assert!(!picture.exists());
    let out = radiosity()
        .args(["render", "cornell", "--stop-file"])
        .arg(Path::new("/no/such/folder/stop"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not exist"));
}

#[test]
fn serve_refuses_the_flags_for_programs() {
    for flag in ["--progress-json", "--stop-file"] {
        let out = radiosity()
            .args(["serve", "cornell", flag, "x", "--port", "0"])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{flag}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("are for `render`"));
    }
}

/// SIGTERM during the final pass of a picture that would take minutes to
/// shade: the process ends within 2 s, having written the outputs that
/// were complete (the vertices, the statistics) and not the picture, and
/// says so (a non-zero exit, an `error` event naming the picture).
#[cfg(unix)]
#[test]
fn sigterm_during_the_final_pass_ends_the_run_with_the_outputs_complete() {
    let dir = tempfile::tempdir().unwrap();
    let (picture, vertices, stats) = (
        dir.path().join("room.png"),
        dir.path().join("v.csv"),
        dir.path().join("s.json"),
    );
    let mut child = radiosity()
        .args([
            "render",
            "room",
            "--max-shots",
            "3",
            "--width",
            "1200",
            "--height",
            "900",
            "--supersampling",
            "3",
            "--progress-json",
            "-",
            "-o",
        ])
        .arg(&picture)
        .arg("--vertices")
        .arg(&vertices)
        .arg("--stats")
        .arg(&stats)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let last = read_until(&mut lines, "final_pass");
    assert_eq!(
        last["event"], "final_pass",
        "the run reached its final pass"
    );
    let total = last["total"].as_u64().unwrap();
    let sent = std::time::Instant::now();
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let last = read_until(&mut lines, "none");
    let status = child.wait().unwrap();
    let took = sent.elapsed();
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert!(
        took < std::time::Duration::from_secs(2),
        "SIGTERM to exit took {took:?} ({total} samples to shade)"
    );
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert_eq!(last["event"], "error", "{last}");
    let message = last["message"].as_str().unwrap();
    assert!(
        message.contains("room.png") && message.contains("not written"),
        "{message}"
    );
    assert!(stderr.contains("not written"), "{stderr}");
    assert!(!picture.exists(), "no picture of a cut-short final pass");
    let rows = std::fs::read_to_string(&vertices).unwrap().lines().count();
    assert!(rows > 100, "{rows} rows");
    let stats: Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(stats["shots"].as_u64(), Some(3));
    // Nothing half-written beside them.
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}
