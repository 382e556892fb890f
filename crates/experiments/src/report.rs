//! Markdown reports of the experiments, headed by what a reader needs to
//! reproduce them: the command, the revision, the machine and the settings.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use super::Context;

/// What an experiment produced.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Markdown body: tables and notes.
    pub body: String,
    /// Pictures and other files it wrote.
    pub files: Vec<PathBuf>,
    /// Settings worth recording, as (name, value).
    pub settings: Vec<(String, String)>,
}

impl Report {
    /// Appends a paragraph.
    pub fn paragraph(&mut self, text: &str) {
        self.body.push_str(text.trim());
        self.body.push_str("\n\n");
    }

    /// Records a setting.
    pub fn setting(&mut self, name: &str, value: impl ToString) {
        self.settings.push((name.to_string(), value.to_string()));
    }

    /// The whole Markdown file.
    #[must_use]
    pub fn render(&self, title: &str, context: &Context, elapsed: Duration) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "# {title}\n");
        let _ = writeln!(out, "- command: `{}`", context.command);
        let _ = writeln!(out, "- revision: {}", revision());
        let _ = writeln!(out, "- machine: {}", machine());
        let _ = writeln!(
            out,
            "- build: radiosity {} ({})",
            env!("CARGO_PKG_VERSION"),
            if cfg!(debug_assertions) {
                "debug build: timings are not representative"
            } else {
                "release build"
            }
        );
        if context.quick {
            let _ = writeln!(
                out,
                "- quick mode: reduced grids and repetitions, not for quoting"
            );
        }
        for (name, value) in &self.settings {
            let _ = writeln!(out, "- {name}: {value}");
        }
        let _ = writeln!(out, "- took {:.1} s\n", elapsed.as_secs_f64());
        out.push_str(&self.body);
        out
    }
}

/// A Markdown table.
#[must_use]
pub fn table(headers: &[&str], rows: &[Vec<String>]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "| {} |", headers.join(" | "));
    let _ = writeln!(
        out,
        "|{}",
        headers.iter().map(|_| " --- |").collect::<String>()
    );
    for row in rows {
        let _ = writeln!(out, "| {} |", row.join(" | "));
    }
    out.push('\n');
    out
}

/// The git revision of the working folder, with `+changes` when it has
/// uncommitted changes; `unknown` outside a checkout.
#[must_use]
pub fn revision() -> String {
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    match git(&["rev-parse", "--short=12", "HEAD"]) {
        Some(hash) => {
            let dirty = git(&[
                "status",
                "--porcelain",
                "--untracked-files=no",
                "--",
                "src",
                "scenes",
                "Cargo.toml",
                "Cargo.lock",
            ])
            .is_some_and(|s| !s.is_empty());
            if dirty {
                format!("{hash}+changes")
            } else {
                hash
            }
        }
        None => "unknown".into(),
    }
}

/// CPU model and core count.
#[must_use]
pub fn machine() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!(
        "{model}, {cores} core(s) available, {} threads in use, {}",
        rayon::current_num_threads(),
        std::env::consts::OS
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_has_a_separator_per_column() {
        let t = table(&["a", "b"], &[vec!["1".into(), "2".into()]]);
        assert_eq!(t, "| a | b |\n| --- | --- |\n| 1 | 2 |\n\n");
    }
}
