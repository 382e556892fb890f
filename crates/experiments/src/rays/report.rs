//! The `rays` experiment's report: the recorded segments, the time per
//! shadow ray of each accelerator (the paper's BSP, the BVH, brute force
//! and Embree), their builds, and the default method's own segments and
//! the GPU's throughput where those were measured.

use super::{OURS, Rays, Timing, own};
use crate::{Report, table};

/// The report of `rays`: the segments, the time per ray, the builds.
#[must_use]
pub fn rays_report(data: &Rays) -> Report {
    let mut report = Report::default();
    report.setting("repetitions (interleaved; medians)", data.repetitions);
    report.setting("recorded shots", format!("{:?}", data.recorded_shots));
    report.setting(
        "clock",
        if data.thread_clock {
            "the timing thread's CPU time (CLOCK_THREAD_CPUTIME_ID), so time the thread waits \
             for a core on a shared machine does not count; Embree likewise (Python's \
             time.thread_time)"
        } else {
            "wall time"
        },
    );
    if let Some(folder) = &data.folder {
        report.setting("scenes", folder.display());
    }
    report.setting(
        "bvh slab test",
        format!(
            "a node's {} child boxes in groups of {} lanes",
            radiosity::accel::bvh::WIDTH,
            data.slab_lanes
        ),
    );
    report.setting(
        "embree",
        match &data.embree_python {
            Some(p) => format!("{} tools/embree_rays.py", p.display()),
            None => "not measured (give --embree-python PYTHON with embreex installed)".into(),
        },
    );
    report.setting(
        "GPU",
        data.adapter
            .clone()
            .unwrap_or_else(|| "none (--device gpu takes any adapter; auto, a real GPU)".into()),
    );
    let mut segment_rows = Vec::new();
    let mut time_rows = Vec::new();
    let mut build_rows = Vec::new();
    for measured in &data.scenes {
        let outcome = &measured.outcome;
        segment_rows.push(vec![
            measured.name.to_string(),
            measured.surfaces.to_string(),
            measured.recorded.to_string(),
            measured.timed.to_string(),
            share(outcome.blocked as f64, measured.timed as f64),
            outcome.brute_checked.to_string(),
            outcome
                .embree_agreement
                .map_or("-".into(), |a| format!("{:.2}%", 100.0 * a)),
        ]);
        let ns: Vec<f64> = outcome.ours.iter().map(Timing::per_ray).collect();
        let embree = outcome.embree.as_ref().map(Timing::per_ray);
        let (bsp, auto, bvh) = (ns[0], ns[1], ns[2]);
        time_rows.push(vec![
            measured.name.to_string(),
            format!("{bsp:.0}"),
            format!("{auto:.0}"),
            format!("{bvh:.0}"),
            embree.map_or("-".into(), |e| format!("{e:.0}")),
            format!("{:.0}", outcome.brute.per_ray()),
            format!("{:.2}", bsp / bvh),
            embree.map_or("-".into(), |e| format!("{:.2}", e / bvh)),
        ]);
        for (k, name) in OURS.iter().enumerate() {
            let stats = &outcome.stats[k];
            let stat = |key: &str| stats.iter().find(|(k, _)| *k == key).map(|(_, v)| *v);
            let text = |v: Option<usize>| v.map_or("-".to_string(), |v| v.to_string());
            build_rows.push(vec![
                measured.name.to_string(),
                (*name).to_string(),
                format!("{:.2}", outcome.ours[k].build()),
                text(stat("nodes")),
                text(stat("depth")),
                text(stat("fragments")),
                stat("bytes").map_or("-".into(), |b| format!("{:.1}", b as f64 / 1e6)),
                format!("{:.1}", outcome.per_ray[k][0]),
                format!("{:.1}", outcome.per_ray[k][1]),
            ]);
        }
        if let Some(e) = &outcome.embree {
            let mut row = vec![
                measured.name.to_string(),
                "embree".into(),
                format!("{:.2}", e.build()),
            ];
            row.extend(std::iter::repeat_n("-".to_string(), 6));
            build_rows.push(row);
        }
    }
    report.paragraph(
        "Segments: those the solver cast in the recorded shots (after its hemicube \
         pre-test), then a deterministic sample of blocks of 256 consecutive ones in receiver \
         order. Blocked: the share every accelerator found blocked (they agree on every \
         segment, and brute force on an evenly spaced sample of them, or the experiment \
         fails). Embree's agreement is with our answers: it works in f32 and does not skip the \
         source's and receiver's surfaces.",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "surfaces",
            "segments recorded",
            "segments timed",
            "blocked",
            "checked by brute force",
            "embree agrees",
        ],
        &segment_rows,
    ));
    report.paragraph(
        "Time per shadow ray on one thread, nanoseconds (median of the interleaved \
         repetitions; brute force on its sample). bsp/bvh: the default BSP's time over the \
         BVH's (target: at most 3). embree/bvh: Embree's time over the BVH's, i.e. the BVH's \
         share of Embree's throughput (target: at least 0.8).",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "bsp ns",
            "bsp, surface planes only, ns",
            "bvh ns",
            "embree ns",
            "brute ns",
            "bsp/bvh",
            "embree/bvh",
        ],
        &time_rows,
    ));
    report.paragraph(
        "Builds (median seconds on one thread; Embree's build uses its own thread pool) and \
         sizes: MB are the accelerator's own arrays (the prepared surfaces every accelerator \
         has are not counted). Per ray: surfaces tested with the exact segment test, and BSP \
         nodes visited or BVH child boxes tested (eight per node of its eight-wide tree), means \
         over the timed segments.",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "accelerator",
            "build s",
            "nodes",
            "depth",
            "fragments",
            "MB",
            "tests/ray",
            "nodes or boxes/ray",
        ],
        &build_rows,
    ));
    own::report(data, &mut report);
    if let Some(adapter) = &data.adapter {
        let rows: Vec<Vec<String>> = data
            .scenes
            .iter()
            .filter_map(|measured| {
                let run = measured.gpu.as_ref()?;
                let cpu_ns = measured.outcome.ours[2].per_ray();
                let per_second = run.segments_per_second();
                Some(vec![
                    measured.name.to_string(),
                    run.triangles.to_string(),
                    run.segments.to_string(),
                    share(run.blocked as f64, run.segments as f64),
                    format!("{:.3}", run.upload_seconds),
                    format!("{:.1}", per_second / 1e6),
                    run.kernel_segments_per_second()
                        .map_or_else(|| "-".to_string(), |k| format!("{:.1}", k / 1e6)),
                    format!("{:.1}", per_second * cpu_ns * 1e-9),
                    format!("{} ({} not grazing)", run.differ, run.differ_not_grazing),
                ])
            })
            .collect();
        report.paragraph(&format!(
            "On the GPU ({adapter}): every recorded segment at once, timed from the call to \
             the answers (segments uploaded, traced by the occluded kernel, read back; median \
             of the repetitions), the scene's tree and triangles uploaded once before; kernel: \
             the occluded kernel alone, by the device's timestamps (upload, conversion and \
             readback left out; - where the device has none). x one \
             thread: its throughput over the CPU BVH's on one thread. Differ: segments it \
             answered otherwise than the CPU's BVH (it works in f32), and of those the ones \
             whose CPU answer holds when their ends move by a millionth of the scene's size \
             (not grazing: a fault)."
        ));
        report.body.push_str(&table(
            &[
                "scene",
                "triangles",
                "segments",
                "blocked",
                "scene upload s",
                "M segments/s",
                "kernel M segments/s",
                "x one thread",
                "differ",
            ],
            &rows,
        ));
    }
    report
}

/// `part` as a percentage of `whole`, one decimal, for the tables.
pub(super) fn share(part: f64, whole: f64) -> String {
    format!("{:.1}%", 100.0 * part / whole.max(1.0))
}
