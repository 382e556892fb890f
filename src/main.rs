//! The `radiosity` command: parses flags into a validated [`Job`] and calls
//! [`radiosity::app::run`]. All logic lives in the library.

use std::io::IsTerminal;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow};
use clap::error::ErrorKind;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

mod serve;
mod viewer;

use radiosity::accel::Accel;
use radiosity::app::{self, BakeJob, ImageJob, Job, Outcome, SensorJob};
use radiosity::export::gltf::BakeMode;
use radiosity::form_factor::FormFactor;
use radiosity::mesh::Mesh;
use radiosity::render::Exposure;
use radiosity::scene::Scene;
use radiosity::scene::{Camera, DEFAULT_REFLECTANCE_CAP, Limits, LoadOptions, builtin};
use radiosity::sensors;
use radiosity::solver::{DEFAULT_CONVERGE, Flow, Preset, Shooting, Solver, Visibility};
use radiosity_experiments as experiments;

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
    /// Solve a scene while a local web page shows the solution converging,
    /// with pause, stop (writes the outputs asked for), ambient and
    /// exposure controls; Ctrl-C quits.
    Serve(Box<ServeArgs>),
    /// Write a built-in or file scene as glTF 2.0 (.glb, or .gltf with a
    /// .bin): reflectance as baseColorFactor, exitance as emissive (the
    /// inverse of the glTF reader's mapping), one polygon per surface.
    ExportScene(ExportSceneArgs),
    /// Show a baked .glb/.gltf in the browser: serves the viewer page on
    /// 127.0.0.1 and prints its address (Ctrl-C to stop).
    View(ViewArgs),
}

#[derive(Parser, Debug)]
struct ServeArgs {
    #[command(flatten)]
    render: RenderArgs,

    /// Port to listen on; 0 takes any free port.
    #[arg(long, value_name = "N", default_value_t = serve::DEFAULT_PORT)]
    port: u16,

    /// Address to listen on. The default takes connections from this
    /// machine only; 0.0.0.0 (or ::) opens the page to every network the
    /// machine is on.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1")]
    host: IpAddr,
}

#[derive(Parser, Debug)]
struct ExportSceneArgs {
    /// A built-in scene (see `radiosity scenes`) or an .obj/.gltf/.glb file.
    scene: String,

    /// The glTF file to write: .glb or .gltf.
    #[arg(value_name = "OUT")]
    out: PathBuf,

    #[command(flatten)]
    load: LoadArgs,
}

#[derive(Parser, Debug)]
struct ViewArgs {
    /// The baked file (.glb or .gltf).
    file: PathBuf,

    /// Port on 127.0.0.1 (0: any free port).
    #[arg(long, default_value_t = 8417)]
    port: u16,
}

/// How glTF materials become reflectance and exitance.
#[derive(clap::Args, Debug)]
struct LoadArgs {
    /// glTF input: largest reflectance per channel; brighter base colours
    /// (white is common) are clamped to it with a warning, since a closed
    /// scene with reflectance 1 never converges. Must be below 1.
    #[arg(long, value_name = "RHO", default_value_t = DEFAULT_REFLECTANCE_CAP)]
    reflectance_cap: f64,

    /// glTF input: exitance (W/m^2) = pi x SCALE x emissiveFactor x
    /// KHR_materials_emissive_strength. glTF emissive is read as radiance in
    /// W/(m^2 sr): a Blender Emission strength S (colour C) gives exitance
    /// pi S C W/m^2 at scale 1. To make a lamp of area A emit P watts, set
    /// its strength to P / (pi A), or scale all emitters with this flag.
    #[arg(long, value_name = "SCALE", default_value_t = 1.0)]
    emission_scale: f64,
}

impl LoadArgs {
    fn options(&self, limits: Limits) -> LoadOptions {
        LoadOptions {
            limits,
            reflectance_cap: self.reflectance_cap,
            emission_scale: self.emission_scale,
        }
    }
}

#[derive(Parser, Debug)]
struct ExperimentArgs {
    /// Experiments to run, or `all` (the paper's): fig2-1, fig4-2, fig4-3,
    /// formula-timing, fig5-1, fig5-2; and, by name only, rays (the shared
    /// real scenes), validate (against the Radiance reference harness),
    /// accuracy-curve (L1 against time, ours and Radiance's) and scale (a
    /// whole render job on scenes up to the shared conference room).
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

    /// Folder holding the shared real scenes, for `rays` and `scale`
    /// (default: ../shared/scenes).
    #[arg(long, value_name = "DIR")]
    scenes: Option<PathBuf>,

    /// A Python interpreter with the embreex package: `rays` then times
    /// Embree too (tools/embree_rays.py).
    #[arg(long, value_name = "PYTHON")]
    embree_python: Option<PathBuf>,

    /// The Radiance reference harness's folder, for `validate` and
    /// `accuracy-curve` (default: ../shared/reference). Its Python
    /// environment is installed by its setup.sh.
    #[arg(long, value_name = "DIR")]
    reference: Option<PathBuf>,
}

#[derive(Parser, Debug)]
struct RenderArgs {
    /// A built-in scene (see `radiosity scenes`), an .obj file with its
    /// .mtl, or a glTF 2.0 file (.gltf with its buffers, or .glb).
    #[arg(default_value = "room")]
    scene: String,

    /// The picture: .png (tone-mapped sRGB), .pfm or .exr (linear
    /// radiosity). Default: SCENE-NAME.png in the current folder.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,

    /// Write one CSV row per vertex: x,y,z,nx,ny,nz,surface,r,g,b.
    #[arg(long, value_name = "FILE.csv")]
    vertices: Option<PathBuf>,

    /// Write the run's counters and settings as JSON.
    #[arg(long, value_name = "FILE.json")]
    stats: Option<PathBuf>,

    /// Write the element mesh as glTF 2.0 (.glb, or .gltf with a .bin) with
    /// per-vertex baked colours (COLOR_0), normals and the view's camera.
    #[arg(long, value_name = "FILE.glb")]
    bake: Option<PathBuf>,

    /// What the bake's COLOR_0 holds: lit (the picture's radiance, exposure
    /// and ambient term included, under an unlit material: opens lit in any
    /// viewer) or irradiance (E/pi, scaled, with the input's materials and
    /// UVs kept, for engines that multiply it with their own base colour).
    #[arg(long, value_name = "MODE", default_value_t = BakeMode::Lit)]
    bake_mode: BakeMode,

    /// Write the element mesh as binary PLY: positions, normals, the
    /// picture's 8-bit sRGB colours and float radiosity (W/m^2).
    #[arg(long, value_name = "FILE.ply")]
    ply: Option<PathBuf>,

    /// Sensor points, in Radiance's `rtrace -I` input format: one point a
    /// line, `x y z nx ny nz` (metres; the normal says which side of the
    /// surface to measure), `#` comments. Each point must lie on a surface
    /// (within 1e-4 of the scene's size). Needs --sensors-out.
    #[arg(long, value_name = "POINTS.txt", requires = "sensors_out")]
    sensors: Option<PathBuf>,

    /// Write the values at the --sensors points as CSV, one row a point in
    /// input order: x,y,z,nx,ny,nz (as given, normal normalised),
    /// er,eg,eb (irradiance E, W/m^2), br,bg,bb (radiosity B = Ke + Kd E
    /// of the surface, W/m^2), lux (Radiance's 179 x (0.265 R + 0.670 G +
    /// 0.065 B) of E).
    #[arg(long, value_name = "FILE.csv", requires = "sensors")]
    sensors_out: Option<PathBuf>,

    #[command(flatten)]
    load: LoadArgs,

    /// Named settings. adaptive (the default, the most accurate and
    /// fastest): unshot radiosity per element, clusters of elements as
    /// shooters refined per receiver, analytic factor, BVH shadow rays,
    /// coplanar faces merged. wong-tsang93: the paper's method (patches,
    /// hemicube pre-test, BSP shadow rays, analytic factor). wallace89: the
    /// 1989 baseline (patches, a ray per pair against every surface,
    /// Wallace's disk formula, eq. 1).
    #[arg(long, default_value_t = Preset::Adaptive)]
    preset: Preset,

    /// How shooters send their unshot radiosity: patches (the paper's: one
    /// uniform radiosity per patch, a fixed grid of subsources) or adaptive
    /// (per element, refined per receiver). Overrides the preset.
    #[arg(long, value_name = "NAME")]
    shooting: Option<Shooting>,

    /// Adaptive shooting's accuracy: a receiver takes a part of a shooter
    /// as one source when the irradiance it can send is below this fraction
    /// of the scene's mean radiosity (default 1e-3).
    #[arg(long, value_name = "FRACTION")]
    tolerance: Option<f64>,

    /// Give adjacent coplanar faces of one material one surface id (on in
    /// the adaptive preset, off in the paper's). Overrides the preset.
    #[arg(long, value_name = "on|off")]
    merge_coplanar: Option<OnOff>,

    /// Point-to-polygon form factor: wallace (eq. 1), disk (eq. 3) or
    /// analytic (eq. 2). Overrides the preset.
    #[arg(long, value_name = "NAME")]
    form_factor: Option<FormFactor>,

    /// Shadow-ray accelerator. Overrides the preset.
    #[arg(long, value_name = "NAME")]
    accel: Option<Accel>,

    /// Visibility: a ray for every pair, or the hemicube pre-test with rays
    /// only where it cannot decide. Overrides the preset.
    #[arg(long, value_name = "NAME")]
    visibility: Option<Visibility>,

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

    /// Stop the solve after this many seconds and write every output from
    /// the state reached (pictures with the ambient term for the rest).
    #[arg(long, value_name = "SECONDS")]
    time_limit: Option<f64>,

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

    /// Most points in a --sensors file [default: 1000000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>("--max-sensors"))]
    max_sensors: Option<usize>,
    /// Memory the run may use, e.g. 8G, 1.5GiB or 512M (a bare number is
    /// MiB). A run whose estimated peak exceeds it is refused before its
    /// solve, naming the setting to change [default: the machine's
    /// available memory].
    #[arg(long, value_name = "SIZE", help_heading = LIMITS, allow_hyphen_values = true,
          value_parser = memory_size)]
    max_memory: Option<u64>,
}

/// `--max-memory`'s value.
fn memory_size(text: &str) -> Result<u64, String> {
    radiosity::memory::parse_size(text).map_err(|m| format!("--max-memory: {m}"))
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

/// A switch given as `on` or `off`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum OnOff {
    On,
    Off,
}

impl RenderArgs {
    /// The validated job (second stage after clap's raw values).
    fn job(&self) -> Result<Job> {
        let mut settings = self.preset.settings();
        if let Some(shooting) = self.shooting {
            settings.shooting = shooting;
        }
        if let Some(t) = self.tolerance {
            settings.tolerance = t;
        }
        if let Some(switch) = self.merge_coplanar {
            settings.merge_coplanar = switch == OnOff::On;
        }
        if let Some(form_factor) = self.form_factor {
            settings.form_factor = form_factor;
        }
        if let Some(accel) = self.accel {
            settings.accel = accel;
        }
        if let Some(visibility) = self.visibility {
            settings.visibility = visibility;
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
        if let Some(seconds) = self.time_limit {
            if !(seconds.is_finite() && seconds > 0.0 && seconds <= 1e9) {
                return Err(anyhow!(
                    "--time-limit must be a positive number of seconds, not {seconds}"
                ));
            }
            settings.time_limit = Some(Duration::from_secs_f64(seconds));
        }
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
            load: self.load.options(limits),
            bake: self.bake.clone().map(|path| BakeJob {
                path,
                mode: self.bake_mode,
            }),
            ply: self.ply.clone(),
            sensors: match (&self.sensors, &self.sensors_out) {
                (Some(points), Some(out)) => Some(SensorJob {
                    points: points.clone(),
                    out: out.clone(),
                    max_points: self.max_sensors.unwrap_or(sensors::DEFAULT_MAX_SENSORS),
                }),
                _ => None,
            },
            max_memory: self.max_memory,
        })
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // An option's value checked by one of the parsers above: one line
        // in the words of that parser, like every other bad input.
        Err(e) if e.kind() == ErrorKind::ValueValidation => {
            // Our own checks name their option; other parsers' words (an
            // address, a number) go with clap's line, which names it.
            match std::error::Error::source(&e).map(|s| s.to_string()) {
                Some(source) if source.contains("--") => eprintln!("error: {source}"),
                _ => eprintln!(
                    "{}",
                    e.render().to_string().lines().next().unwrap_or("error")
                ),
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
        Some(Command::Serve(args)) => serve(&args),
        Some(Command::ExportScene(args)) => {
            for path in app::export_scene(
                &args.scene,
                &args.out,
                &args.load.options(Limits::default()),
            )? {
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Some(Command::View(args)) => view(&args),
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
        scenes: args.scenes.clone(),
        embree_python: args.embree_python.clone(),
        reference: args.reference.clone(),
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
    let interrupted = interrupt_handler()?;
    let mut display = ProgressDisplay::new(args.quiet, interrupted);
    let outcome = pool.install(|| app::run(&job, &mut display));
    display.finish();
    let outcome = outcome?;
    for warning in &outcome.warnings {
        eprintln!("warning: {warning}");
    }
    if !args.quiet {
        print_summary(&outcome);
    }
    Ok(())
}

/// Ctrl-C once asks the solve to stop after the current shot and write its
/// outputs from the state reached; a second Ctrl-C aborts at once, writing
/// nothing. Returns the flag the first one raises.
fn interrupt_handler() -> Result<Arc<AtomicBool>> {
    let interrupted = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&interrupted);
    ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            eprintln!("\naborted: no output written");
            std::process::exit(130);
        }
        eprintln!(
            "\nstopping and writing the outputs from the state reached (Ctrl-C again aborts \
             without writing)"
        );
    })
    .context("cannot install the Ctrl-C handler")?;
    Ok(interrupted)
}

/// How often a progress line is printed when standard error is not a
/// terminal (a log).
const PROGRESS_LINE_INTERVAL: Duration = Duration::from_secs(10);

/// Shows a solve's progress: a bar on a terminal, a line every
/// [`PROGRESS_LINE_INTERVAL`] in a log, nothing with `--quiet`; stops the
/// solve after a Ctrl-C.
struct ProgressDisplay {
    bar: Option<ProgressBar>,
    lines: bool,
    meter: app::ProgressMeter,
    last_line: Instant,
    /// What is being solved, until it has been said.
    header: Option<String>,
    interrupted: Arc<AtomicBool>,
}

impl ProgressDisplay {
    fn new(quiet: bool, interrupted: Arc<AtomicBool>) -> ProgressDisplay {
        let terminal = std::io::stderr().is_terminal();
        let bar = (!quiet && terminal).then(|| {
            let bar = ProgressBar::new(1000);
            bar.set_style(
                ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {msg}")
                    .expect("static template"),
            );
            bar
        });
        ProgressDisplay {
            bar,
            lines: !quiet && !terminal,
            meter: app::ProgressMeter::new(),
            last_line: Instant::now(),
            header: None,
            interrupted,
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

/// `1:02:03` or `2:03`.
fn clock(d: Duration) -> String {
    let s = d.as_secs();
    if s >= 3600 {
        format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
    } else {
        format!("{}:{:02}", s / 60, s % 60)
    }
}

impl app::Observer for ProgressDisplay {
    fn started(&mut self, scene: &Scene, mesh: &Mesh) {
        self.meter = app::ProgressMeter::new();
        self.last_line = Instant::now();
        // Said with the first progress line, so a short run's log holds
        // only its summary.
        self.header = Some(format!(
            "solving {}: {} surfaces, {} elements, {} vertices",
            scene.name,
            scene.surfaces.len(),
            mesh.elements.len(),
            mesh.vertices.len()
        ));
    }

    fn shot(&mut self, solver: &Solver<'_>) -> Flow {
        let p = self.meter.update(solver);
        let left = p.remaining.map_or_else(
            || "estimating time left".to_string(),
            |r| format!("about {} left", clock(r)),
        );
        let message = format!(
            "{} shots, unshot {:.2}% (stop at {:.2}%), {:.2}M rays/s, {}",
            p.shots,
            100.0 * p.unshot_fraction,
            100.0 * solver.settings().converge,
            p.rays_per_second / 1e6,
            left
        );
        if let Some(bar) = &self.bar {
            bar.set_position((p.completion * 1000.0) as u64);
            bar.set_message(message);
        } else if self.lines && self.last_line.elapsed() >= PROGRESS_LINE_INTERVAL {
            self.last_line = Instant::now();
            if let Some(header) = self.header.take() {
                eprintln!("{header}");
            }
            eprintln!("progress: {}, {} elapsed", message, clock(p.elapsed));
        }
        if self.interrupted.load(Ordering::SeqCst) {
            Flow::Stop
        } else {
            Flow::Continue
        }
    }

    fn interrupt(&self) -> Option<Arc<AtomicBool>> {
        Some(Arc::clone(&self.interrupted))
    }
}

fn view(args: &ViewArgs) -> Result<()> {
    let server = viewer::Server::bind(&args.file, args.port)?;
    println!("serving {} at {}", args.file.display(), server.url());
    println!("open that address in a browser; Ctrl-C stops");
    server.run()?;
    Ok(())
}

fn print_summary(o: &Outcome) {
    let c = o.counts;
    println!(
        "{}: {} surfaces ({} surface ids), {} shooters, {} elements, {} vertices",
        o.scene, c.surfaces, c.surface_ids, c.patches, c.elements, c.vertices
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
    if let Some(peak) = o.peak_memory_bytes {
        println!(
            "memory: peak {} resident (estimated {})",
            radiosity::memory::bytes(peak),
            radiosity::memory::bytes(o.memory_estimate.total())
        );
    }
    for path in &o.written {
        println!("wrote {}", path.display());
    }
}

fn serve(args: &ServeArgs) -> Result<()> {
    let job = args.render.job()?;
    app::validate(&job)?;
    let pool = pool(args.render.threads)?;
    let server = serve::Server::start(
        SocketAddr::new(args.host, args.port),
        serve::Display {
            camera: job.image.as_ref().and_then(|i| i.camera),
            ambient: !args.render.no_ambient,
            exposure: args.render.exposure,
        },
    )?;
    // The first Ctrl-C stops the solve and writes the outputs; a second
    // one gives up at once.
    let handle = server.handle();
    let interrupts = std::sync::atomic::AtomicUsize::new(0);
    ctrlc::set_handler(move || {
        if interrupts.fetch_add(1, std::sync::atomic::Ordering::SeqCst) == 0 {
            handle.shutdown();
        } else {
            std::process::exit(130);
        }
    })
    .context("cannot install the Ctrl-C handler")?;
    println!("serving {}", server.url());
    if !args.render.quiet {
        eprintln!("open it in a browser; Ctrl-C stops the solve, writes the outputs and quits");
    }

    let outcome = pool.install(|| app::run(&job, &mut server.observer()));
    let outcome = match outcome {
        Ok(outcome) => outcome,
        Err(error) => {
            server.close();
            return Err(error.into());
        }
    };
    for warning in &outcome.warnings {
        eprintln!("warning: {warning}");
    }
    if !args.render.quiet {
        print_summary(&outcome);
    }
    server.finished(&outcome);
    if !server.shutdown_requested() && !args.render.quiet {
        eprintln!(
            "still serving the final state at {}; Ctrl-C quits",
            server.url()
        );
    }
    server.wait();
    Ok(())
}
