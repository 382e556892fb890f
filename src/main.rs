//! The `radiosity` command: parses flags into a validated [`Job`] and calls
//! [`radiosity::app::run`]. All logic lives in the library.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, anyhow};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use radiosity::accel::Accel;
use radiosity::app::{self, BakeJob, ImageJob, Job, Outcome};
use radiosity::experiments;
use radiosity::export::gltf::BakeMode;
use radiosity::form_factor::FormFactor;
use radiosity::render::Exposure;
use radiosity::scene::{Camera, DEFAULT_REFLECTANCE_CAP, LoadOptions, builtin};
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
    /// Write a built-in or file scene as glTF 2.0 (.glb, or .gltf with a
    /// .bin): reflectance as baseColorFactor, exitance as emissive (the
    /// inverse of the glTF reader's mapping), one polygon per surface.
    ExportScene(ExportSceneArgs),
    /// Show a baked .glb/.gltf in the browser: serves the viewer page on
    /// 127.0.0.1 and prints its address (Ctrl-C to stop).
    View(ViewArgs),
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
    fn options(&self) -> LoadOptions {
        LoadOptions {
            reflectance_cap: self.reflectance_cap,
            emission_scale: self.emission_scale,
        }
    }
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
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
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
    #[arg(long, value_name = "MODE", default_value = "lit", value_parser = names(&BakeMode::ALL.map(BakeMode::name)))]
    bake_mode: String,

    /// Write the element mesh as binary PLY: positions, normals, the
    /// picture's 8-bit sRGB colours and float radiosity (W/m^2).
    #[arg(long, value_name = "FILE.ply")]
    ply: Option<PathBuf>,

    #[command(flatten)]
    load: LoadArgs,

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
    #[arg(long, value_name = "N")]
    hemicube_resolution: Option<u32>,

    /// A shooting patch is split into N x N subsources.
    #[arg(long, value_name = "N")]
    subsources: Option<u32>,

    /// Longest patch edge, metres (default: the scene's #@mesh suggestion,
    /// else a third of the scene's bounding-box diagonal).
    #[arg(long, value_name = "METRES")]
    patch_size: Option<f64>,

    /// Longest element edge, metres (default: the scene's #@mesh
    /// suggestion, else 1/40 of the scene's bounding-box diagonal).
    #[arg(long, value_name = "METRES")]
    element_size: Option<f64>,

    /// Stop when unshot power falls below this fraction of emitted power.
    #[arg(long, value_name = "FRACTION", default_value_t = DEFAULT_CONVERGE)]
    converge: f64,

    /// Stop after N patches have shot.
    #[arg(long, value_name = "N")]
    max_shots: Option<u64>,

    /// Stop once N subsources have shot.
    #[arg(long, value_name = "N")]
    max_subsources: Option<u64>,

    /// Worker threads (default: every core).
    #[arg(long, value_name = "N")]
    threads: Option<usize>,

    /// Picture width in pixels.
    #[arg(long, default_value_t = 800)]
    width: u32,

    /// Picture height in pixels.
    #[arg(long, default_value_t = 600)]
    height: u32,

    /// The view as eye,target,up,fov: ten numbers, e.g.
    /// 0,1.6,4,0,1,0,0,1,0,60 (default: the scene's camera, or one framing
    /// the scene).
    #[arg(long, value_name = "EYE,TARGET,UP,FOV", allow_hyphen_values = true)]
    camera: Option<String>,

    /// Anti-aliasing: N x N samples a pixel.
    #[arg(long, value_name = "N", default_value_t = 3)]
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
            load: self.load.options(),
            bake: self
                .bake
                .clone()
                .map(|path| -> Result<BakeJob> {
                    Ok(BakeJob {
                        path,
                        mode: BakeMode::from_name(&self.bake_mode).context("bake mode")?,
                    })
                })
                .transpose()?,
            ply: self.ply.clone(),
        })
    }
}

fn main() -> ExitCode {
    match real_main() {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn real_main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Scenes) => {
            for (name, description) in builtin::list() {
                println!("{name:10} {description}");
            }
            Ok(())
        }
        Some(Command::Render(args)) => render(&args),
        Some(Command::Experiment(args)) => experiment(&args),
        Some(Command::ExportScene(args)) => {
            for path in app::export_scene(&args.scene, &args.out, &args.load.options())? {
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

fn view(args: &ViewArgs) -> Result<()> {
    let server = radiosity::viewer::Server::bind(&args.file, args.port)?;
    println!("serving {} at {}", args.file.display(), server.url());
    println!("open that address in a browser; Ctrl-C stops");
    server.run()?;
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
