//! Helpers of the experiment tests, shared with the command's
//! `tests/scale.rs`: a quick context and a table check.

#![allow(dead_code)]

use std::path::Path;

use radiosity_experiments::{Context, Report};

/// A quick-mode context writing into `dir`, recording `command`.
pub fn context(dir: &Path, command: &str) -> Context {
    Context {
        out: dir.to_path_buf(),
        quick: true,
        command: command.into(),
        scenes: None,
        embree_python: None,
        reference: None,
        device: radiosity_gpu::DeviceChoice::Cpu,
    }
}

/// The report holds a Markdown table headed `header`.
pub fn assert_table(report: &Report, header: &str) {
    assert!(
        report.body.contains(header),
        "no table headed {header:?} in:\n{}",
        report.body
    );
    assert!(report.body.contains("| --- |"), "no Markdown table");
}
