//! The paper's experiments, reproduced (Wong & Tsang 1993, sections 2, 4
//! and 5): `radiosity experiment NAME` writes a Markdown report and its
//! pictures into an output folder, with the machine, revision, command and
//! settings recorded, so every number in EXPERIMENTS.md can be regenerated.
//!
//! | name | paper | what |
//! | --- | --- | --- |
//! | `fig2-1` | Figure 2.1 | time to shoot one subsource, ray-only vs pre-test |
//! | `fig4-2` | Figures 4.2, 4.6 | errors of eq. (1) and eq. (3) against the exact disk factor |
//! | `fig4-3` | Figures 4.3, 4.5 | colour-scale pictures of the factor above a unit square |
//! | `formula-timing` | section 4 | cost of one evaluation of each formula |
//! | `fig5-1` | Figure 5.1 | the room after 9, 48 and 72 subsources, both presets |
//! | `fig5-2` | Figure 5.2 | solve times at 9, 48 and 72 subsources |
//! | `rays` | section 3 | BSP, BVH, brute force and Embree on real scenes' shadow segments (by name only, not in `all`) |
//! | `validate` | beyond the paper | L1, bias, median and p90 against the Radiance reference per scene and preset, error pictures (by name only) |
//! | `pictures` | beyond the paper | pictures at 2,000 pixel centres against the Radiance reference, for each `--final-gather` (by name only) |
//! | `accuracy-curve` | beyond the paper | L1 against solve time for both presets and `rtrace` on the Cornell boxes (by name only) |
//! | `scale` | beyond the paper | a whole render job's phases, memory and rays from the built-in scenes to the conference room, default preset with either accelerator, where the solve's time goes, and the picture's error after 2, 5 and 10 s (by name only) |

// One module per experiment (`EXPERIMENTS` lists them in the paper's order).
pub mod accuracy;
pub mod fig2_1;
pub mod fig4_2;
pub mod fig4_3;
pub mod fig5_1;
pub mod fig5_2;
pub mod formula_timing;
pub mod lightmap;
pub mod pictures;
pub mod rays;
pub mod scale;
pub mod validate;

// What the experiments share.
pub mod charts;
pub mod early;
pub mod error_picture;
pub mod form_factor_accuracy;
pub mod grain;
pub mod plot;
pub mod points;
pub mod reference;
pub mod report;
mod solving;

use std::path::{Path, PathBuf};
use std::time::Instant;

pub use report::{Report, table};

/// Where and how to run.
#[derive(Clone, Debug)]
pub struct Context {
    /// Output folder (created if missing).
    pub out: PathBuf,
    /// Smaller grids and fewer repetitions, for tests; the numbers are not
    /// the ones to quote.
    pub quick: bool,
    /// The command line that ran the experiments, for the record.
    pub command: String,
    /// The folder holding the shared real scenes (`rays`, `scale`); `None` looks
    /// for `../shared/scenes`.
    pub scenes: Option<PathBuf>,
    /// A Python interpreter with the `embreex` package, to time Embree
    /// beside our accelerators (`rays`); `None` skips Embree.
    pub embree_python: Option<PathBuf>,
    /// The Radiance reference harness's folder (`validate`,
    /// `accuracy-curve`); `None` looks for `../shared/reference`.
    pub reference: Option<PathBuf>,
    /// The device beside the CPU (`rays`: its GPU column, when a GPU is
    /// chosen).
    pub device: radiosity_gpu::DeviceChoice,
}

impl Context {
    /// Repetitions of a timed measurement (the median is reported).
    #[must_use]
    pub fn repetitions(&self) -> usize {
        if self.quick { 1 } else { 7 }
    }

    /// A path in the output folder.
    #[must_use]
    pub fn path(&self, name: &str) -> PathBuf {
        self.out.join(name)
    }
}

/// Why an experiment failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene, mesh or setting problem.
    #[error(transparent)]
    App(#[from] radiosity::app::Error),
    /// A file could not be written.
    #[error("{path}: cannot write: {source}", path = path.display())]
    Output {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// An experiment's input is missing or its results fail a check.
    #[error("{0}")]
    Experiment(String),
    /// The name is not an experiment.
    #[error("no experiment '{0}' (experiments: {names}, all)", names = names().join(", "))]
    Unknown(String),
}

/// One experiment: its name, the paper's figure, and how to run it.
pub struct Experiment {
    /// Command-line name.
    pub name: &'static str,
    /// Title of its report.
    pub title: &'static str,
    /// Runs it, writing pictures into the context's folder, and returns the
    /// report.
    pub run: fn(&Context) -> Result<Report, Error>,
    /// Whether `all` runs it: the paper's experiments. `rays` needs the
    /// shared real scenes and minutes, so it runs only by name.
    pub in_all: bool,
}

/// Every experiment, in the paper's order.
pub const EXPERIMENTS: &[Experiment] = &[
    Experiment {
        name: "fig2-1",
        title: "Figure 2.1: time to shoot one subsource",
        run: fig2_1::fig2_1,
        in_all: true,
    },
    Experiment {
        name: "fig4-2",
        title: "Figures 4.2 and 4.6: errors of the disk formulas",
        run: fig4_2::fig4_2,
        in_all: true,
    },
    Experiment {
        name: "fig4-3",
        title: "Figures 4.3 and 4.5: the form factor above a unit square",
        run: fig4_3::fig4_3,
        in_all: true,
    },
    Experiment {
        name: "formula-timing",
        title: "Section 4: cost of one form-factor evaluation",
        run: formula_timing::formula_timing,
        in_all: true,
    },
    Experiment {
        name: "fig5-1",
        title: "Figure 5.1: the room after 9, 48 and 72 subsources",
        run: fig5_1::fig5_1,
        in_all: true,
    },
    Experiment {
        name: "fig5-2",
        title: "Figure 5.2: solve times",
        run: fig5_2::fig5_2,
        in_all: true,
    },
    Experiment {
        name: "rays",
        title: "Section 3 at scale: shadow-ray accelerators on real scenes",
        run: rays::rays,
        in_all: false,
    },
    Experiment {
        name: "pictures",
        title: "Pictures against the Radiance reference, under each final pass",
        run: pictures::pictures,
        in_all: false,
    },
    Experiment {
        name: "validate",
        title: "Validation against the Radiance reference",
        run: validate::validate,
        in_all: false,
    },
    Experiment {
        name: "accuracy-curve",
        title: "Accuracy against time: our presets and Radiance",
        run: accuracy::accuracy_curve,
        in_all: false,
    },
    Experiment {
        name: "lightmap",
        title: "Lightmap bakes: layout, accuracy at sensor points, time",
        run: lightmap::lightmap,
        in_all: false,
    },
    Experiment {
        name: "scale",
        title: "Scale: a whole render job from the built-in scenes to 277k triangles",
        run: scale::scale,
        in_all: false,
    },
];

/// Names of every experiment.
#[must_use]
pub fn names() -> Vec<&'static str> {
    EXPERIMENTS.iter().map(|e| e.name).collect()
}

/// Runs the named experiments (`all` for the paper's, those marked
/// [`Experiment::in_all`]), writing `NAME.md` for each and the pictures into
/// `context.out`. Returns the files written.
pub fn run(
    names: &[String],
    context: &Context,
    mut progress: impl FnMut(&str),
) -> Result<Vec<PathBuf>, Error> {
    let selected: Vec<&Experiment> = if names.iter().any(|n| n == "all") {
        EXPERIMENTS.iter().filter(|e| e.in_all).collect()
    } else {
        names
            .iter()
            .map(|n| {
                EXPERIMENTS
                    .iter()
                    .find(|e| e.name == n)
                    .ok_or_else(|| Error::Unknown(n.clone()))
            })
            .collect::<Result<_, _>>()?
    };
    std::fs::create_dir_all(&context.out).map_err(|source| Error::Output {
        path: context.out.clone(),
        source,
    })?;
    let mut written = Vec::new();
    for experiment in selected {
        progress(experiment.name);
        let start = Instant::now();
        let report = (experiment.run)(context)?;
        let text = report.render(experiment.title, context, start.elapsed());
        let path = context.path(&format!("{}.md", experiment.name));
        write_file(&path, text.as_bytes())?;
        written.extend(report.files);
        written.push(path);
    }
    Ok(written)
}

/// The solver's device for `--device` (`validate`, `scale`): the GPU as
/// a back end when one opens, `None` for the CPU (`cpu`, or `auto` without
/// a real GPU).
///
/// # Errors
///
/// When `--device gpu` finds no adapter, or one will not open.
pub fn gpu_device(context: &Context) -> Result<Option<radiosity::solver::device::Device>, Error> {
    let gpu = radiosity_gpu::Gpu::open(context.device)
        .map_err(|e| Error::Experiment(format!("--device: {e}")))?;
    Ok(gpu.map(|gpu| {
        radiosity::solver::device::Device::backend(std::sync::Arc::new(
            radiosity_gpu::GpuBackend::new(gpu),
        ))
    }))
}

/// Writes a whole file through a temporary name.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    radiosity::export::Staged::write(path, |w| std::io::Write::write_all(w, bytes))
        .and_then(radiosity::export::Staged::commit)
        .map_err(|source| Error::Output {
            path: path.to_path_buf(),
            source,
        })
}

/// The median of some durations in seconds (sorts them).
#[must_use]
pub fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}
