//! The form-factor experiments of the paper's section 4 (Figures 4.2, 4.3,
//! 4.5, 4.6 and the timing of 4,140 evaluations) in quick mode: they write
//! their tables and pictures, the pictures decode at the size announced,
//! and Figure 4.5's sum over 3x3 sub-squares equals the exact factor.

mod common;

use std::path::Path;

use approx::{assert_abs_diff_eq, relative_eq};
use common::assert_table;
use radiosity_experiments::fig4_3::{self, CrossSection};
use radiosity_experiments::{Context, plot};
use radiosity_experiments::{fig4_2, formula_timing};

fn context(dir: &Path) -> Context {
    common::context(dir, "cargo test --test experiments")
}

/// Decodes a PNG and returns its width and height.
fn png_size(path: &Path) -> (u32, u32) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let decoder = png::Decoder::new(std::io::BufReader::new(file));
    let mut reader = decoder.read_info().expect("a PNG header");
    let mut buffer = vec![0; reader.output_buffer_size().expect("a sized image")];
    let info = reader.next_frame(&mut buffer).expect("PNG data");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    (info.width, info.height)
}

#[test]
fn fig4_2_tables_the_paper_beside_ours() {
    let dir = tempfile::tempdir().unwrap();
    let report = fig4_2::fig4_2(&context(dir.path())).unwrap();
    assert_table(
        &report,
        "| r | eq. (1) average, ours | eq. (1) average, paper |",
    );
    assert_table(&report, "| tilt | formula | r | mean | RMS | max |");
    // The paper's protocol reproduces its numbers: the first row at 1R.
    assert!(
        report
            .body
            .contains("| 1R | 55.381% | 55.38% | 99.970% | 99.97% |")
    );
    for tilt in ["DiskAxis", "InPlane", "Sideways"] {
        assert!(report.body.contains(&format!("| {tilt} | eq. (3) | 10R |")));
    }
    assert!(report.files.is_empty());
}

#[test]
fn fig4_3_writes_decodable_pictures_of_the_announced_size() {
    let dir = tempfile::tempdir().unwrap();
    let report = fig4_3::fig4_3(&context(dir.path())).unwrap();
    assert_table(
        &report,
        "| picture | max, z < 0.2 | mean, z < 0.2 | max, z > 0.5 |",
    );
    let (w, h) = CrossSection::grid(true);
    let (pw, ph) = plot::panel_size(w, h);
    let names: Vec<String> = report
        .files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    for name in [
        "fig4-3a-exact.png",
        "fig4-3b-wallace.png",
        "fig4-3c-analytic-3x3.png",
        "fig4-3d-eq3.png",
        "fig4-3b-error.png",
        "fig4-3c-error.png",
        "fig4-3d-error.png",
        "fig4-3-all.png",
    ] {
        assert!(names.iter().any(|n| n == name), "{name} not in {names:?}");
    }
    for path in &report.files {
        assert!(path.starts_with(dir.path()));
        let size = png_size(path);
        if path.ends_with("fig4-3-all.png") {
            // Four panels a row, three rows, 8 pixels apart.
            assert_eq!(size, (4 * pw as u32 + 5 * 8, 3 * ph as u32 + 4 * 8));
        } else {
            assert_eq!(size, (pw as u32, ph as u32), "{}", path.display());
        }
        assert!(
            report
                .body
                .contains(&*path.file_name().unwrap().to_string_lossy())
        );
    }
}

#[test]
fn figure_4_5_equals_the_exact_factor() {
    let (w, h) = CrossSection::grid(true);
    let section = CrossSection::compute(w, h);
    assert_eq!(section.exact.len(), w * h);
    for (i, (c, a)) in section.analytic.iter().zip(&section.exact).enumerate() {
        assert!(*a > 0.0 && *a <= 1.0, "sample {i}: {a}");
        assert!(
            relative_eq!(c, a, epsilon = 0.0, max_relative = 1e-9),
            "sample {i}: {c} vs {a}"
        );
    }
    // The closed form of a parallel rectangle agrees with (a) as well, and
    // the disk formulas are visibly off near the source.
    for (a, r) in section.exact.iter().zip(&section.closed_form) {
        assert_abs_diff_eq!(a, r, epsilon = 1e-9 * a);
    }
    let worst = |f: &[f64]| {
        f.iter()
            .zip(&section.exact)
            .map(|(f, a)| ((f - a) / a).abs())
            .fold(0.0, f64::max)
    };
    assert!(worst(&section.wallace) > 0.5);
    assert!(worst(&section.disk) > 0.5);
}

#[test]
fn formula_timing_reports_the_three_formulas() {
    let dir = tempfile::tempdir().unwrap();
    let report = formula_timing::formula_timing(&context(dir.path())).unwrap();
    assert_table(
        &report,
        "| formula | source | ns per evaluation | ms for 4,140 |",
    );
    for row in [
        "| eq. (1) Wallace |",
        "| eq. (3) Wong-Tsang |",
        "| eq. (2) analytic (Baum) |",
    ] {
        assert!(report.body.contains(row), "{row}");
    }
    assert!(
        report
            .settings
            .iter()
            .any(|(k, v)| k == "cases" && v.starts_with("4140"))
    );
    assert!(report.files.is_empty());
}

/// `radiosity experiment rays` without the shared scenes: one clear error
/// naming the scenes, the folder looked in and the option to give.
#[test]
fn rays_fails_clearly_without_the_real_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-scenes-here");
    let context = Context {
        scenes: Some(missing.clone()),
        ..context(dir.path())
    };
    let error = radiosity_experiments::rays::rays(&context).unwrap_err();
    let message = error.to_string();
    for part in [
        "sponza_dabrovic/sponza_dabrovic.obj",
        "conference/conference.obj",
        &missing.display().to_string(),
        "--scenes",
    ] {
        assert!(message.contains(part), "{part:?} not in {message:?}");
    }
    assert!(std::fs::read_dir(dir.path()).unwrap().count() == 0);
}

/// The experiment on the built-in room (quick): the solver's recorded
/// segments, every accelerator agreeing with each other and with brute
/// force (the experiment fails otherwise), and the three tables.
#[test]
fn rays_on_the_room_tables_every_accelerator() {
    use radiosity_experiments::rays::{self, SCENES};
    let dir = tempfile::tempdir().unwrap();
    let room = SCENES.iter().find(|s| s.name == "room").unwrap();
    let report = rays::rays_on(&context(dir.path()), std::slice::from_ref(room)).unwrap();
    assert_table(
        &report,
        "| scene | surfaces | segments recorded | segments timed | blocked |",
    );
    assert_table(
        &report,
        "| scene | bsp ns | bsp, surface planes only, ns | bvh ns | embree ns |",
    );
    assert_table(&report, "| scene | accelerator | build s | nodes | depth |");
    // 171 surfaces; the quick budget of 4,096 segments is reached; 200
    // checked by brute force; Embree not measured.
    assert!(
        report.body.contains("| room | 171 | ") && report.body.contains(" | 4096 | "),
        "{}",
        report.body
    );
    assert!(report.body.contains("| 200 | - |"), "{}", report.body);
    for accelerator in [
        "| room | bsp |",
        "| room | bsp, surface planes only |",
        "| room | bvh |",
    ] {
        assert!(report.body.contains(accelerator), "{accelerator}");
    }
}

/// With a GPU (`--device gpu`), `rays` also traces every recorded segment
/// on it: the GPU table, the adapter named, and no segment of the room
/// answered otherwise than by the CPU but a few grazing ones. Without an adapter the test says it
/// did not run, unless `RADIOSITY_REQUIRE_GPU` is set (as CI sets it).
#[test]
fn rays_on_the_gpu_agrees_with_the_cpu() {
    use radiosity_experiments::rays::{self, SCENES};
    use radiosity_gpu::{DeviceChoice, Gpu, REQUIRE_ADAPTER};
    if let Err(e) = Gpu::open(DeviceChoice::Gpu) {
        let required = std::env::var(REQUIRE_ADAPTER).is_ok_and(|v| v != "0");
        assert!(!required, "{REQUIRE_ADAPTER} is set: {e}");
        eprintln!("GPU test did not run: {e}");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let room = SCENES.iter().find(|s| s.name == "room").unwrap();
    let context = Context {
        device: DeviceChoice::Gpu,
        ..context(dir.path())
    };
    let data = rays::rays_compute(&context, std::slice::from_ref(room)).unwrap();
    let adapter = data.adapter.clone().expect("an adapter");
    let run = data.scenes[0].gpu.clone().expect("the GPU's run");
    assert_eq!(run.segments, data.scenes[0].recorded);
    assert!(run.triangles >= data.scenes[0].surfaces);
    // At most one in a thousand answered otherwise, each grazing.
    assert!(run.differ * 1000 <= run.segments, "{run:?}");
    assert_eq!(run.differ_not_grazing, 0, "{run:?}");
    assert!(run.blocked > 0 && run.blocked < run.segments, "{run:?}");
    assert!(run.segments_per_second() > 0.0);
    // The kernel alone, where the device has timestamps: a time each
    // repetition.
    assert!(run.kernel_seconds.is_empty() || run.kernel_seconds.len() == run.seconds.len());
    assert!(
        run.kernel_segments_per_second().is_none_or(|k| k > 0.0),
        "{run:?}"
    );
    let report = rays::rays_report(&data);
    assert_table(
        &report,
        "| scene | triangles | segments | blocked | scene upload s | M segments/s | kernel M \
         segments/s | x one thread |",
    );
    assert!(report.body.contains(&adapter), "{}", report.body);
    // The CPU alone: no GPU table.
    let cpu = rays::rays_report(&rays::Rays {
        adapter: None,
        ..data
    });
    assert!(!cpu.body.contains("M segments/s"));
}

/// The file `tools/embree_rays.py` reads: header, counts, triangles (a
/// quad fans into two), segments, answers.
#[test]
fn rays_file_layout() {
    use glam::DVec3;
    use radiosity_experiments::rays::Segment;
    use radiosity_experiments::rays::embree::write_rays;
    let scene = radiosity::scene::load("room").unwrap();
    let triangles: usize = scene.surfaces.iter().map(|s| s.polygon.len() - 2).sum();
    let segments = [
        Segment {
            from: DVec3::ZERO,
            to: DVec3::ONE,
            skip: [0, 1],
        },
        Segment {
            from: DVec3::X,
            to: DVec3::Y,
            skip: [2, 3],
        },
    ];
    let mut bytes = Vec::new();
    write_rays(&mut bytes, &scene, &segments, &[true, false]).unwrap();
    assert_eq!(&bytes[..8], b"RADRAYS1");
    assert_eq!(
        u64::from_le_bytes(bytes[8..16].try_into().unwrap()),
        triangles as u64
    );
    assert_eq!(u64::from_le_bytes(bytes[16..24].try_into().unwrap()), 2);
    assert_eq!(bytes.len(), 24 + 72 * triangles + 48 * 2 + 2);
    assert_eq!(&bytes[bytes.len() - 2..], &[1, 0]);
    let first_to = 24 + 72 * triangles + 24;
    let x = f64::from_le_bytes(bytes[first_to..first_to + 8].try_into().unwrap());
    assert_eq!(x, 1.0);
}

/// `radiosity experiment scale` without the shared scenes: one clear error
/// naming them and the option to give, before any case runs.
#[test]
fn scale_fails_clearly_without_the_real_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-scenes-here");
    let context = Context {
        scenes: Some(missing.clone()),
        ..context(dir.path())
    };
    let error = radiosity_experiments::scale::scale(&context).unwrap_err();
    let message = error.to_string();
    for part in [
        "cornell_box/cornell_box.obj",
        "sponza_dabrovic/sponza_dabrovic.obj",
        "conference/conference.obj",
        "--scenes",
    ] {
        assert!(message.contains(part), "{part:?} not in {message:?}");
    }
    assert!(std::fs::read_dir(dir.path()).unwrap().count() == 0);
}
