//! The scale experiment end to end: each case runs the `radiosity` command
//! as a child, so this test lives with the command (the other experiment
//! tests are in `crates/experiments/tests`).

#[path = "../crates/experiments/tests/common/mod.rs"]
mod common;

use std::path::Path;

use common::assert_table;

fn context(dir: &Path) -> radiosity_experiments::Context {
    common::context(dir, "cargo test --test scale")
}

/// The scale experiment on the built-in scenes (quick: coarser meshes),
/// each case a child `radiosity render`: every case has its rows, shot,
/// converged on the room, measured its peak memory, and its phases fit in
/// its total; the pictures, statistics and plot are written and the
/// vertices CSVs removed.
#[test]
fn scale_on_the_builtin_scenes_measures_every_case() {
    use radiosity_experiments::scale::{self, configurations};
    let dir = tempfile::tempdir().unwrap();
    let context = context(dir.path());
    let scenes = scale::builtin_scenes();
    assert_eq!(
        scenes.iter().map(|s| s.spec.name).collect::<Vec<_>>(),
        ["cornell", "room"]
    );
    let cases = scale::measure(
        &context,
        &scenes,
        Path::new(env!("CARGO_BIN_EXE_radiosity")),
    )
    .unwrap();
    let report = scale::report(&context, &scenes, &cases).unwrap();
    assert_table(
        &report,
        "| scene | configuration | faces | surfaces | elements | vertices | load s |",
    );
    assert_table(
        &report,
        "| scene | configuration | shots | unshot | stopped | rays | rays/s/thread |",
    );
    let expected: usize = scenes.iter().map(|s| configurations(s, true).len()).sum();
    assert!(
        expected >= 4,
        "the default and another accelerator per scene"
    );
    assert_eq!(cases.len(), expected);
    for scene in &scenes {
        for configuration in configurations(scene, true) {
            let row = format!("| {} | {} | ", scene.spec.name, configuration.name);
            assert_eq!(
                report.body.matches(&row).count(),
                3,
                "{row} three times (once a table) in:\n{}",
                report.body
            );
        }
    }
    for case in &cases {
        let run = case
            .result
            .as_ref()
            .unwrap_or_else(|e| panic!("{} {}: {e}", case.scene, case.configuration));
        let name = format!("{} {}", case.scene, case.configuration);
        assert!(run.shots > 0 && run.rays > 0, "{name}: {run:?}");
        assert!(run.faces > 0 && run.surfaces > 0 && run.surfaces <= run.faces);
        assert!(run.elements > 0 && run.vertices > 0);
        assert!(run.peak_memory_bytes.is_some_and(|b| b > 0), "{name}");
        let phases = [
            run.load_seconds,
            run.mesh_seconds,
            run.accel_build_seconds,
            run.solve_seconds,
            run.write_seconds,
        ];
        assert!(phases.iter().all(|&t| t >= 0.0), "{name}: {phases:?}");
        let sum: f64 = phases.iter().sum();
        assert!(
            sum <= run.total_seconds && run.total_seconds <= case.wall_seconds,
            "{name}: phases {sum} s, total {} s, wall {} s",
            run.total_seconds,
            case.wall_seconds
        );
        assert!(run.rays_per_second_per_thread() > 0.0);
        if case.scene == "room" {
            assert!(run.converged(), "{name}: unshot {}", run.unshot_fraction);
            assert!(run.unshot_fraction <= 0.01 && run.stop_reason == "converged");
        }
    }
    // The same scene meshes alike whatever the accelerator.
    for scene in ["cornell", "room"] {
        let sizes: Vec<(u64, u64)> = cases
            .iter()
            .filter(|c| c.scene == scene)
            .map(|c| {
                let r = c.result.as_ref().unwrap();
                (r.faces, r.vertices)
            })
            .collect();
        assert!(sizes.windows(2).all(|w| w[0] == w[1]), "{scene}: {sizes:?}");
    }
    // Where the time goes, for every case; the early pictures for each
    // scene's default configuration.
    assert_table(
        &report,
        "| scene | configuration | solve s | gathering s | form factors | shadow rays |",
    );
    assert_table(
        &report,
        "| scene | final state | after 2 s | after 5 s | after 10 s |",
    );
    for case in &cases {
        let run = case.result.as_ref().unwrap();
        // The gathering counts the coarse pass of receiver refinement too,
        // which the mesh's time holds.
        assert!(
            run.gather_seconds <= run.solve_seconds + run.mesh_seconds,
            "{case:?}"
        );
        let default = scenes.iter().any(|s| {
            s.spec.name == case.scene && configurations(s, true)[0].name == case.configuration
        });
        assert_eq!(!case.early.is_empty(), default, "{case:?}");
        for early in &case.early {
            let name = format!("{} after {} s", case.scene, early.seconds);
            let Some(stop) = early.stop_reason.as_deref() else {
                panic!("{name}: the run failed: {early:?}");
            };
            // A coarse pass cut short by the limit makes another mesh than
            // the full run's (its vertices, when as many, are not the same
            // points): nothing to compare.
            if early.coarse_pass_cut() {
                continue;
            }
            let l1 = match &early.result {
                Ok((l1, unshot)) => {
                    assert!((0.0..1.0).contains(l1), "{name}: {early:?}");
                    assert!((0.0..=1.0).contains(unshot), "{name}: {early:?}");
                    *l1
                }
                Err(message) => panic!("{name}: {message}"),
            };
            // A run that converged within its limit, its coarse pass not
            // cut short, is the full run's solve to the last bit (the solve
            // is deterministic); how far a machine gets within a limit is
            // not, so that is all that is compared.
            if stop == "converged" && run.converged() {
                assert_eq!(l1, 0.0, "{name}: {early:?}");
            }
        }
    }
    let svg = std::fs::read_to_string(dir.path().join("scale.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("input faces"));
    for case in &cases {
        assert!(svg.contains(&case.configuration), "no legend for {case:?}");
    }
    assert_eq!(svg.matches("<circle").count(), 2 * cases.len());
    for path in &report.files {
        assert!(path.is_file(), "{}", path.display());
    }
    let left: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".csv") || n.ends_with(".log"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
