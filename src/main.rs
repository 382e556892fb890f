//! The `radiosity` command: parses flags into a validated [`Job`] and calls
//! [`radiosity::app::run`]. All logic lives in the library.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, anyhow};
use clap::error::ErrorKind;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use radiosity::accel::Accel;
use radiosity::app::{self, ImageJob, Job, Outcome};
use radiosity::experiments;
use radiosity::form_factor::FormFactor;
use radiosity::render::Exposure;
use radiosity::scene::{Camera, Limits, builtin};
use radiosity::solver::{DEFAULT_CONVERGE, Settings, Visibility};

/// Diffuse global illumination by progressive radiosity with ray-traced
/// visibility (Wallace et al. 1989; Wong & Tsang 1993).
///
/// With no arguments, renders the built-in room to room.png.
#[derive(Parser, Debug)]
#[command(name = "radiosity", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Solve a scene and write its picture (and optionally vertex radiosities
    /// and statistics).
    Render(Box<RenderArgs>),
    /// List the built-in scenes.
    Scenes,
    /// Reproduce the paper's experiments: a Markdown report and pictures
    /// per experiment in the output folder.
    Experiment(ExperimentArgs),
}

#[derive(Parser, Debug)]
struct ExperimentArgs {
    /// Experiments to run, or `all`: fig2-1, fig4-2, fig4-3,
    /// formula-timing, fig5-1, fig5-2.
    #[arg(required = true, value_name = "NAME")]
    names: Vec<String>,

    /// Output folder.
    #[arg(long, value_name = "DIR", default_value = "experiments-out")]
    out: PathBuf,

    /// Smaller grids and one repetition: checks the experiments run, the
    /// numbers are not for quoting.
    #[arg(long)]
    quick: bool,

    /// Worker threads (default: every core).
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = positive::<usize>("--threads"))]
    threads: Option<usize>,
}

#[derive(Parser, Debug)]
struct RenderArgs {
    /// A built-in scene (see `radiosity scenes`) or an .obj file with its
    /// .mtl.
    #[arg(default_value = "room")]
    scene: String,

    /// The picture: .png (tone-mapped sRGB) or .pfm (linear radiosity).
    /// Default: SCENE-NAME.png in the current folder.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,

    /// Write one CSV row per vertex: x,y,z,nx,ny,nz,surface,r,g,b.
    #[arg(long, value_name = "FILE.csv")]
    vertices: Option<PathBuf>,

    /// Write the run's counters and settings as JSON.
    #[arg(long, value_name = "FILE.json")]
    stats: Option<PathBuf>,

    /// Named settings: wong-tsang93 (hemicube pre-test, BSP shadow rays,
    /// analytic form factor: the paper's method) or wallace89 (a ray per
    /// pair against every surface, Wallace's disk formula, eq. 1).
    #[arg(long, default_value = "wong-tsang93", value_parser = ["wong-tsang93", "wallace89"])]
    preset: String,

    /// Point-to-polygon form factor: wallace (eq. 1), disk (eq. 3) or
    /// analytic (eq. 2). Overrides the preset.
    #[arg(long, value_name = "NAME", value_parser = names(&FormFactor::ALL.map(FormFactor::name)))]
    form_factor: Option<String>,

    /// Shadow-ray accelerator. Overrides the preset.
    #[arg(long, value_name = "NAME", value_parser = names(&Accel::ALL.map(Accel::name)))]
    accel: Option<String>,

    /// Visibility: a ray for every pair, or the hemicube pre-test with rays
    /// only where it cannot decide. Overrides the preset.
    #[arg(long, value_name = "NAME", value_parser = names(&Visibility::ALL.map(Visibility::name)))]
    visibility: Option<String>,

    /// Pixels across the top face of the pre-test hemicube.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = positive::<u32>("--hemicube-resolution"))]
    hemicube_resolution: Option<u32>,

    /// A shooting patch is split into N x N subsources.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = positive::<u32>("--subsources"))]
    subsources: Option<u32>,

    /// Longest patch edge, metres (default: the scene's #@mesh suggestion,
    /// else a third of the scene's bounding-box diagonal).
    #[arg(long, value_name = "METRES", allow_negative_numbers = true,
          value_parser = metres("--patch-size"))]
    patch_size: Option<f64>,

    /// Longest element edge, metres (default: the scene's #@mesh
    /// suggestion, else 1/40 of the scene's bounding-box diagonal).
    #[arg(long, value_name = "METRES", allow_negative_numbers = true,
          value_parser = metres("--element-size"))]
    element_size: Option<f64>,

    /// Stop when unshot power falls below this fraction of emitted power.
    #[arg(long, value_name = "FRACTION", default_value_t = DEFAULT_CONVERGE,
          allow_negative_numbers = true, value_parser = fraction("--converge"))]
    converge: f64,

    /// Stop after N patches have shot.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = whole::<u64>("--max-shots"))]
    max_shots: Option<u64>,

    /// Stop once N subsources have shot.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = whole::<u64>("--max-subsources"))]
    max_subsources: Option<u64>,

    /// Worker threads (default: every core).
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = positive::<usize>("--threads"))]
    threads: Option<usize>,

    /// Picture width in pixels.
    #[arg(long, default_value_t = 800, allow_negative_numbers = true,
          value_parser = positive::<u32>("--width"))]
    width: u32,

    /// Picture height in pixels.
    #[arg(long, default_value_t = 600, allow_negative_numbers = true,
          value_parser = positive::<u32>("--height"))]
    height: u32,

    /// The view as eye,target,up,fov: ten numbers, e.g.
    /// 0,1.6,4,0,1,0,0,1,0,60 (default: the scene's camera, or one framing
    /// the scene).
    #[arg(long, value_name = "EYE,TARGET,UP,FOV", allow_hyphen_values = true)]
    camera: Option<String>,

    /// Anti-aliasing: N x N samples a pixel.
    #[arg(long, value_name = "N", default_value_t = 3, allow_negative_numbers = true,
          value_parser = positive::<u32>("--supersampling"))]
    supersampling: u32,

    /// Exposure adjustment in stops, on top of automatic exposure.
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    exposure: f64,

    /// Show the solution without the ambient term.
    #[arg(long)]
    no_ambient: bool,

    /// No progress bar and no summary.
    #[arg(short, long)]
    quiet: bool,

    /// Largest scene file (OBJ or MTL) read, MiB [default: 1024].
    #[arg(long, value_name = "MIB", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<u64>("--max-file-size"))]
    max_file_size: Option<u64>,

    /// Longest line of a scene file, bytes [default: 4194304].
    #[arg(long, value_name = "BYTES", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>("--max-line-length"))]
    max_line_length: Option<usize>,

    /// Most corners of one face [default: 100000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>("--max-corners"))]
    max_corners: Option<usize>,

    /// Most faces in a scene [default: 5000000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>("--max-faces"))]
    max_faces: Option<usize>,

    /// Most vertices (`v` lines) in a scene [default: 10000000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>("--max-vertices"))]
    max_vertices: Option<usize>,

    /// Most elements in the mesh [default: 4000000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>("--max-elements"))]
    max_elements: Option<usize>,
}

/// Help heading of the options that bound a load.
const LIMITS: &str = "Limits (each error says which to raise)";

/// The value of an option as echoed in a message: cut to a readable length.
fn shown(value: &str) -> String {
    const SHOWN: usize = 40;
    if value.chars().count() <= SHOWN {
        value.to_string()
    } else {
        format!(
            "{}... ({} bytes)",
            value.chars().take(SHOWN).collect::<String>(),
            value.len()
        )
    }
}

/// An integer option of at least `min`; messages name the flag and the
/// value, negative values included (clap lets them through as values).
fn integer<T: TryFrom<i128> + std::fmt::Display + Copy + Send + Sync + 'static>(
    flag: &'static str,
    min: i128,
    kind: &'static str,
    max: T,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    move |text: &str| {
        let value: i128 = text
            .trim()
            .parse()
            .ok()
            .filter(|v| *v >= min)
            .ok_or_else(|| format!("{flag} must be {kind}, not {}", shown(text)))?;
        T::try_from(value).map_err(|_| format!("{flag} must be at most {max}, not {}", shown(text)))
    }
}

/// A positive integer option (1 or more).
fn positive<T: TryFrom<i128> + std::fmt::Display + Copy + Send + Sync + 'static + num_max::Max>(
    flag: &'static str,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    integer(flag, 1, "a positive integer", T::MAX)
}

/// A whole-number option (0 or more).
fn whole<T: TryFrom<i128> + std::fmt::Display + Copy + Send + Sync + 'static + num_max::Max>(
    flag: &'static str,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    integer(flag, 0, "a whole number (0 or more)", T::MAX)
}

/// The largest value of an integer type, for messages.
mod num_max {
    pub trait Max {
        const MAX: Self;
    }
    macro_rules! max {
        ($($t:ty),*) => { $(impl Max for $t { const MAX: Self = <$t>::MAX; })* };
    }
    max!(u32, u64, usize);
}

/// A length option: a positive finite number of metres.
fn metres(flag: &'static str) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |text: &str| {
        text.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v > 0.0)
            .ok_or_else(|| {
                format!(
                    "{flag} must be a positive number of metres, not {}",
                    shown(text)
                )
            })
    }
}

/// A fraction option in [0, 1).
fn fraction(flag: &'static str) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |text: &str| {
        text.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| (0.0..1.0).contains(v))
            .ok_or_else(|| format!("{flag} must be a fraction in [0, 1), not {}", shown(text)))
    }
}

fn names(names: &[&'static str]) -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(names.iter().copied())
}

impl RenderArgs {
    /// The validated job (second stage after clap's raw values).
    fn job(&self) -> Result<Job> {
        let mut settings = match self.preset.as_str() {
            "wallace89" => Settings::wallace89(),
            "wong-tsang93" => Settings::wong_tsang93(),
            other => return Err(anyhow!("unknown preset '{other}'")),
        };
        // clap has already checked the names against the lists above.
        if let Some(name) = &self.form_factor {
            settings.form_factor = FormFactor::from_name(name).context("form factor")?;
        }
        if let Some(name) = &self.accel {
            settings.accel = Accel::from_name(name).context("accelerator")?;
        }
        if let Some(name) = &self.visibility {
            settings.visibility = Visibility::from_name(name).context("visibility")?;
        }
        if let Some(n) = self.hemicube_resolution {
            settings.hemicube_resolution = n;
        }
        if let Some(n) = self.subsources {
            settings.subsources = n;
        }
        settings.converge = self.converge;
        if let Some(n) = self.max_elements {
            settings.mesh.max_elements = n;
        }
        let defaults = Limits::default();
        let limits = Limits {
            max_file_bytes: self
                .max_file_size
                .map_or(defaults.max_file_bytes, |mib| mib.saturating_mul(1 << 20)),
            max_line_bytes: self.max_line_length.unwrap_or(defaults.max_line_bytes),
            max_corners: self.max_corners.unwrap_or(defaults.max_corners),
            max_faces: self.max_faces.unwrap_or(defaults.max_faces),
            max_vertices: self.max_vertices.unwrap_or(defaults.max_vertices),
        };
        settings.max_shots = self.max_shots;
        settings.max_subsources = self.max_subsources;
        let camera = self
            .camera
            .as_deref()
            .map(Camera::parse)
            .transpose()
            .map_err(|m| anyhow!("--camera: {m}"))?;
        if !self.exposure.is_finite() {
            return Err(anyhow!("--exposure must be a finite number of stops"));
        }
        let stem = std::path::Path::new(&self.scene)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "render".into());
        Ok(Job {
            scene: self.scene.clone(),
            settings,
            patch_size: self.patch_size,
            element_size: self.element_size,
            image: Some(ImageJob {
                path: self
                    .output
                    .clone()
                    .unwrap_or_else(|| PathBuf::from(format!("{stem}.png"))),
                width: self.width,
                height: self.height,
                camera,
                supersampling: self.supersampling,
                exposure: Exposure::Auto { ev: self.exposure },
                ambient: !self.no_ambient,
            }),
            vertices_csv: self.vertices.clone(),
            stats_json: self.stats.clone(),
            limits,
        })
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // An option's value checked by one of the parsers above: one line
        // in the words of that parser, like every other bad input.
        Err(e) if e.kind() == ErrorKind::ValueValidation => {
            match std::error::Error::source(&e) {
                Some(source) => eprintln!("error: {source}"),
                None => eprintln!("{e}"),
            }
            return ExitCode::FAILURE;
        }
        Err(e) => e.exit(),
    };
    match real_main(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", message(&error));
            ExitCode::FAILURE
        }
    }
}

/// An error and its causes on one line, each cause once: a cause whose
/// text the message already holds (an I/O error a library message quotes)
/// is not repeated.
fn message(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let part = cause.to_string();
        if text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text
}

fn real_main(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Scenes) => {
            for (name, description) in builtin::list() {
                println!("{name:10} {description}");
            }
            Ok(())
        }
        Some(Command::Render(args)) => render(&args),
        Some(Command::Experiment(args)) => experiment(&args),
        None => render(&RenderArgs::parse_from(["radiosity"])),
    }
}

/// Most worker threads `--threads` accepts.
const MAX_THREADS: usize = 1024;

/// A rayon pool with `threads` workers (default: every core).
fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = threads {
        if !(1..=MAX_THREADS).contains(&threads) {
            return Err(anyhow!(
                "--threads must be between 1 and {MAX_THREADS}, not {threads}"
            ));
        }
        pool = pool.num_threads(threads);
    }
    pool.build().context("cannot start worker threads")
}

fn experiment(args: &ExperimentArgs) -> Result<()> {
    let context = experiments::Context {
        out: args.out.clone(),
        quick: args.quick,
        command: std::env::args()
            .enumerate()
            .map(|(i, a)| if i == 0 { "radiosity".to_string() } else { a })
            .collect::<Vec<_>>()
            .join(" "),
    };
    let written = pool(args.threads)?
        .install(|| experiments::run(&args.names, &context, |name| eprintln!("running {name}")))?;
    for path in written {
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn render(args: &RenderArgs) -> Result<()> {
    let job = args.job()?;
    app::validate(&job)?;
    let pool = pool(args.threads)?;

    let bar = if !args.quiet && std::io::stderr().is_terminal() {
        let bar = ProgressBar::new(1000);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} eta {eta} {msg}",
            )
            .expect("static template"),
        );
        Some(bar)
    } else {
        None
    };
    let outcome = pool.install(|| {
        app::run(&job, &mut |p: app::Progress| {
            if let Some(bar) = &bar {
                bar.set_position((p.completion * 1000.0) as u64);
                bar.set_message(format!(
                    "{} shots, {} subsources, unshot {:.2}%",
                    p.shots,
                    p.subsources,
                    100.0 * p.unshot_fraction
                ));
            }
        })
    });
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let outcome = outcome?;
    for warning in &outcome.warnings {
        eprintln!("warning: {warning}");
    }
    if !args.quiet {
        print_summary(&outcome);
    }
    Ok(())
}

fn print_summary(o: &Outcome) {
    let c = o.counts;
    println!(
        "{}: {} surfaces, {} patches, {} elements, {} vertices",
        o.scene, c.surfaces, c.patches, c.elements, c.vertices
    );
    println!(
        "solved: {} shots, {} subsources, {} rays, unshot {:.2}% ({}) in {:.2} s on {} thread(s)",
        o.stats.shots,
        o.stats.subsources,
        o.stats.rays_cast,
        100.0 * o.unshot_fraction,
        o.stop.describe(),
        o.solve_time.as_secs_f64(),
        o.threads
    );
    for path in &o.written {
        println!("wrote {}", path.display());
    }
}
