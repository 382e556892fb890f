//! The command line's flags (clap's derive), first stage of the two of
//! ripgrep's design: raw values here, checked and turned into a
//! [`radiosity::app::Job`] in [`super::job`]. The solving methods' own
//! parameters are not listed here: each method declares them
//! ([`radiosity::solver::Method::parameters`]) and [`MethodArgs`] offers
//! every registered method's.

use std::net::IpAddr;
use std::path::PathBuf;

use clap::builder::PossibleValuesParser;
use clap::{Arg, ArgAction, ArgMatches, Parser, Subcommand};

use super::values::{fraction, memory_size, metres, positive, positive_real, whole};
use crate::serve;
use radiosity::accel::Accel;
use radiosity::app;
use radiosity::export::gltf::{BakeMode, BakeTarget};
use radiosity::export::lightmap;
use radiosity::final_gather::FinalGather;
use radiosity::form_factor::FormFactor;
use radiosity::scene::{DEFAULT_REFLECTANCE_CAP, Limits, LoadOptions};
use radiosity::solver::method::{Kind, Value};
use radiosity::solver::{MethodSettings, Preset, Shooting};

/// Diffuse global illumination by progressive radiosity with ray-traced
/// visibility (Wallace et al. 1989; Wong & Tsang 1993).
///
/// With no arguments, renders the built-in room to room.png.
#[derive(Parser, Debug)]
#[command(name = "radiosity", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
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
pub struct ServeArgs {
    #[command(flatten)]
    pub render: RenderArgs,

    /// Port to listen on; 0 takes any free port.
    #[arg(long, value_name = "N", default_value_t = serve::DEFAULT_PORT)]
    pub port: u16,

    /// Address to listen on. The default takes connections from this
    /// machine only; 0.0.0.0 (or ::) opens the page to every network the
    /// machine is on.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1")]
    pub host: IpAddr,

    /// Pause the solve by itself once it has made this many shots (0:
    /// before the first), as the pause button does, at the end of the
    /// round that reaches it (`--round`); a list (10,100,1000) pauses at
    /// each. Resume goes on to the next.
    #[arg(long, value_name = "SHOTS", value_delimiter = ',')]
    pub pause_at: Vec<u64>,
}

#[derive(Parser, Debug)]
pub struct ExportSceneArgs {
    /// A built-in scene (see `radiosity scenes`) or an .obj/.gltf/.glb file.
    pub scene: String,

    /// The glTF file to write: .glb or .gltf.
    #[arg(value_name = "OUT")]
    pub out: PathBuf,

    #[command(flatten)]
    pub load: LoadArgs,
}

#[derive(Parser, Debug)]
pub struct ViewArgs {
    /// The baked file (.glb or .gltf).
    pub file: PathBuf,

    /// Port on 127.0.0.1 (0: any free port).
    #[arg(long, default_value_t = 8417)]
    pub port: u16,
}

/// How glTF materials become reflectance and exitance.
#[derive(clap::Args, Debug)]
pub struct LoadArgs {
    /// glTF input: largest reflectance per channel; brighter base colours
    /// (white is common) are clamped to it with a warning, since a closed
    /// scene with reflectance 1 never converges. Must be below 1.
    #[arg(help_heading = "Scene and lights", long, value_name = "RHO", default_value_t = DEFAULT_REFLECTANCE_CAP)]
    pub reflectance_cap: f64,

    /// glTF input: exitance (W/m^2) = pi x SCALE x emissiveFactor x
    /// KHR_materials_emissive_strength. glTF emissive is read as radiance in
    /// W/(m^2 sr): a Blender Emission strength S (colour C) gives exitance
    /// pi S C W/m^2 at scale 1. To make a lamp of area A emit P watts, set
    /// its strength to P / (pi A), or scale all emitters with this flag.
    #[arg(
        help_heading = "Scene and lights",
        long,
        value_name = "SCALE",
        default_value_t = 1.0
    )]
    pub emission_scale: f64,

    /// Add the sun: ALTITUDE degrees above the horizon, AZIMUTH degrees
    /// from north (-z) towards east (+x), LUX on a plane facing it. Its
    /// light reaches every surface facing it that nothing shades.
    #[arg(help_heading = "Daylight", long, num_args = 3, value_names = ["ALTITUDE", "AZIMUTH", "LUX"], allow_negative_numbers = true)]
    pub sun: Option<Vec<f64>>,

    /// Add a sky: uniform, overcast (CIE standard overcast, zenith three
    /// times the horizon) or clear (CIE clear sky around the --sun
    /// position). Its light arrives from above the horizon wherever
    /// nothing blocks it: through windows, skylights, open courtyards.
    #[arg(help_heading = "Daylight", long, value_name = "MODEL", value_parser = ["uniform", "overcast", "clear"], requires = "sky_illuminance")]
    pub sky: Option<String>,

    /// The sky's unobstructed horizontal illuminance (the sky alone,
    /// without the sun), lux: about 10,000 on an overcast day, 20,000 on a
    /// clear one.
    #[arg(help_heading = "Daylight", long, value_name = "LUX", requires = "sky")]
    pub sky_illuminance: Option<f64>,

    /// Sky patches: Tregenza's 145 divided N x N each (Reinhart's scheme):
    /// 1 gives 145 directions per receiver, 2 gives 580, 4 gives 2320.
    /// One direction is drawn in each patch per receiver, apart from the
    /// directions through the scene's openings, which are sampled where
    /// they are.
    #[arg(help_heading = "Daylight", long, value_name = "N", default_value_t = radiosity::scene::sky::DEFAULT_SUBDIVISION)]
    pub sky_subdivision: usize,

    /// Reflectance of the ground below the sky's horizon, from 0 to below
    /// 1: lit by the sky and the sun, it lights what sees below the
    /// horizon (through a window, from a roof), as Radiance's gensky does.
    #[arg(help_heading = "Daylight", long, value_name = "RHO", default_value_t = radiosity::scene::sky::DEFAULT_GROUND_REFLECTANCE, requires = "sky")]
    pub ground_reflectance: f64,
}

impl LoadArgs {
    pub fn options(&self, limits: Limits) -> LoadOptions {
        use radiosity::scene::sky::{Daylight, SkyModel, SkySpec, SunSpec};
        LoadOptions {
            limits,
            reflectance_cap: self.reflectance_cap,
            emission_scale: self.emission_scale,
            daylight: Daylight {
                sun: self.sun.as_ref().map(|v| SunSpec {
                    altitude: v[0],
                    azimuth: v[1],
                    illuminance: v[2],
                }),
                // clap accepts only the three names.
                sky: self.sky.as_ref().map(|model| SkySpec {
                    model: model.parse().unwrap_or(SkyModel::Uniform),
                    illuminance: self.sky_illuminance.unwrap_or(f64::NAN),
                    subdivision: self.sky_subdivision,
                    ground_reflectance: self.ground_reflectance,
                }),
            },
        }
    }
}

#[derive(Parser, Debug)]
pub struct ExperimentArgs {
    /// Experiments to run, or `all` (the paper's): fig2-1, fig4-2, fig4-3,
    /// formula-timing, fig5-1, fig5-2; and, by name only, rays (the shared
    /// real scenes), validate (against the Radiance reference harness),
    /// accuracy-curve (L1 against time, ours and Radiance's), lightmap
    /// (lightmap bakes read back and checked against sensors) and scale (a
    /// whole render job on scenes up to the shared conference room).
    #[arg(required = true, value_name = "NAME")]
    pub names: Vec<String>,

    /// Output folder.
    #[arg(long, value_name = "DIR", default_value = "experiments-out")]
    pub out: PathBuf,

    /// Smaller grids and one repetition: checks the experiments run, the
    /// numbers are not for quoting.
    #[arg(long)]
    pub quick: bool,

    /// Worker threads (default: every core).
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = positive::<usize>())]
    pub threads: Option<usize>,

    /// Folder holding the shared real scenes, for `rays` and `scale`
    /// (default: ../shared/scenes).
    #[arg(long, value_name = "DIR")]
    pub scenes: Option<PathBuf>,

    /// A Python interpreter with the embreex package: `rays` then times
    /// Embree too (tools/embree_rays.py).
    #[arg(long, value_name = "PYTHON")]
    pub embree_python: Option<PathBuf>,

    /// The Radiance reference harness's folder, for `validate` and
    /// `accuracy-curve` (default: ../shared/reference). Its Python
    /// environment is installed by its setup.sh.
    #[arg(long, value_name = "DIR")]
    pub reference: Option<PathBuf>,

    /// The device beside the CPU: `rays` also traces its segments on the
    /// GPU. auto: a real GPU, if there is one; gpu: any adapter, software
    /// ones (lavapipe) included, an error without one; cpu: none.
    #[arg(long, value_enum, default_value_t = DeviceArg::Auto)]
    pub device: DeviceArg,
}

/// `--device`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DeviceArg {
    /// A real GPU if there is one, else the CPU.
    Auto,
    /// The CPU only.
    Cpu,
    /// A GPU adapter, software ones included.
    Gpu,
}

impl From<DeviceArg> for radiosity_gpu::DeviceChoice {
    fn from(arg: DeviceArg) -> Self {
        match arg {
            DeviceArg::Auto => radiosity_gpu::DeviceChoice::Auto,
            DeviceArg::Cpu => radiosity_gpu::DeviceChoice::Cpu,
            DeviceArg::Gpu => radiosity_gpu::DeviceChoice::Gpu,
        }
    }
}

#[derive(Parser, Debug)]
pub struct RenderArgs {
    /// A built-in scene (see `radiosity scenes`), an .obj file with its
    /// .mtl, or a glTF 2.0 file (.gltf with its buffers, or .glb).
    #[arg(default_value = "room")]
    pub scene: String,

    /// The picture: .png (tone-mapped sRGB), .pfm or .exr (linear
    /// radiosity). Default: SCENE-NAME.png in the current folder.
    #[arg(help_heading = "Outputs", short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,

    /// Write one CSV row per vertex: x,y,z,nx,ny,nz,surface,r,g,b.
    #[arg(help_heading = "Outputs", long, value_name = "FILE.csv")]
    pub vertices: Option<PathBuf>,

    /// Write the run's counters and settings as JSON.
    #[arg(help_heading = "Outputs", long, value_name = "FILE.json")]
    pub stats: Option<PathBuf>,

    /// Write the element mesh as glTF 2.0 (.glb, or .gltf with a .bin) with
    /// per-vertex baked colours (COLOR_0), normals and the view's camera.
    #[arg(help_heading = "Outputs", long, value_name = "FILE.glb")]
    pub bake: Option<PathBuf>,

    /// What the bake's COLOR_0 holds: lit (the picture's radiance, exposure
    /// and ambient term included, under an unlit material: opens lit in any
    /// viewer) or irradiance (E/pi, scaled, with the input's materials and
    /// UVs kept, for engines that multiply it with their own base colour).
    #[arg(help_heading = "Outputs", long, value_name = "MODE", default_value_t = BakeMode::Lit)]
    pub bake_mode: BakeMode,

    /// Where the bake puts the light: vertices (the element mesh with
    /// COLOR_0) or lightmap (the input's own nodes, meshes and materials,
    /// a second UV set TEXCOORD_1, the input's or generated, and a lightmap
    /// texture inside the file, plus NAME.lightmap.exr beside it).
    #[arg(help_heading = "Outputs", long, value_name = "TARGET", default_value_t = BakeTarget::Vertices)]
    pub bake_target: BakeTarget,

    /// Lightmap texels per metre of surface (lowered, with a note, when the
    /// lightmap would exceed --lightmap-max-size).
    #[arg(help_heading = "Outputs", long, value_name = "TEXELS_PER_METRE", default_value_t = lightmap::DEFAULT_DENSITY)]
    pub lightmap_density: f64,

    /// Largest lightmap width or height, texels.
    #[arg(help_heading = "Outputs", long, value_name = "TEXELS", default_value_t = lightmap::DEFAULT_MAX_SIZE)]
    pub lightmap_max_size: u32,

    /// Write the element mesh as binary PLY: positions, normals, the
    /// picture's 8-bit sRGB colours and float radiosity (W/m^2).
    #[arg(help_heading = "Outputs", long, value_name = "FILE.ply")]
    pub ply: Option<PathBuf>,

    /// Sensor points, in Radiance's `rtrace -I` input format: one point a
    /// line, `x y z nx ny nz` (metres; the normal says which side of the
    /// surface to measure), `#` comments. Each point must lie on a surface
    /// (within 1e-4 of the scene's size). Needs --sensors-out.
    #[arg(
        help_heading = "Outputs",
        long,
        value_name = "POINTS.txt",
        requires = "sensors_out"
    )]
    pub sensors: Option<PathBuf>,

    /// Write the values at the --sensors points as CSV, one row a point in
    /// input order: x,y,z,nx,ny,nz (as given, normal normalised),
    /// er,eg,eb (irradiance E, W/m^2), br,bg,bb (radiosity B = Ke + Kd E
    /// of the surface, W/m^2), lux (Radiance's 179 x (0.265 R + 0.670 G +
    /// 0.065 B) of E); under an overcast sky alone, a last column
    /// daylight_factor (lux over the sky's unobstructed horizontal
    /// illuminance, percent).
    #[arg(
        help_heading = "Outputs",
        long,
        value_name = "FILE.csv",
        requires = "sensors"
    )]
    pub sensors_out: Option<PathBuf>,

    /// Require the daylight_factor column of --sensors-out: an error unless
    /// the scene is lit by an overcast sky alone (no sun, no lights, no
    /// emitting faces), where the daylight factor is defined.
    #[arg(help_heading = "Outputs", long, requires = "sensors_out")]
    pub daylight_factor: bool,

    #[command(flatten)]
    pub load: LoadArgs,

    /// Where the solve's transfers run. auto: a real GPU (discrete or
    /// integrated) when there is one and the settings run on it, else the
    /// CPU; gpu: any GPU adapter, software ones (Mesa's lavapipe) included,
    /// an error without one; cpu: the CPU. The GPU runs the default method
    /// only: the paper's presets, --shooting cuts|patches, --accel bsp|brute
    /// and the other form factors stay on the CPU
    #[arg(help_heading = "Device", long, value_enum, default_value_t = DeviceArg::Auto, env = "RADIOSITY_DEVICE",
          hide_possible_values = true)]
    pub device: DeviceArg,

    /// Named settings. adaptive (the default, the most accurate and
    /// fastest): unshot radiosity per element, clusters of elements as
    /// shooters refined per receiver, analytic factor, BVH shadow rays,
    /// coplanar faces merged. wong-tsang93: the paper's method (patches,
    /// hemicube pre-test, BSP shadow rays, analytic factor). wallace89: the
    /// 1989 baseline (patches, a ray per pair against every surface,
    /// Wallace's disk formula, eq. 1).
    #[arg(help_heading = "Solver", long, default_value_t = Preset::Adaptive)]
    pub preset: Preset,

    /// How shooters send their unshot radiosity (each method's summary).
    /// Overrides the preset.
    #[arg(help_heading = "Solver", long, value_name = "NAME", help = shooting_help())]
    pub shooting: Option<Shooting>,

    /// The methods' own parameters (`--tolerance`, `--subsources`, ...).
    #[command(flatten)]
    pub method: MethodArgs,

    /// Give adjacent coplanar faces of one material one surface id (on in
    /// the adaptive preset, off in the paper's). Overrides the preset.
    #[arg(help_heading = "Scene and lights", long, value_name = "on|off")]
    pub merge_coplanar: Option<OnOff>,

    /// Point-to-polygon form factor: wallace (eq. 1), disk (eq. 3) or
    /// analytic (eq. 2). Overrides the preset.
    #[arg(help_heading = "Solver", long, value_name = "NAME")]
    pub form_factor: Option<FormFactor>,

    /// Shadow-ray accelerator. Overrides the preset.
    #[arg(help_heading = "Solver", long, value_name = "NAME")]
    pub accel: Option<Accel>,

    /// What pictures, lightmap texels and sensors show: off, the mesh's
    /// values; direct, the direct light evaluated at each point shown
    /// (shadow rays per picture sample and texel) plus the mesh's indirect
    /// light; full, also the indirect light gathered over each point's
    /// hemisphere from the mesh. Vertex bakes, --vertices and the PLY keep
    /// the mesh's values (default: the preset's; adaptive direct, the
    /// paper's presets off)
    #[arg(help_heading = "Solver", long, value_name = "MODE")]
    pub final_gather: Option<FinalGather>,

    /// Longest patch edge, metres (default: the scene's #@mesh suggestion,
    /// else a third of the scene's bounding-box diagonal).
    #[arg(help_heading = "Solver", long, value_name = "METRES", allow_negative_numbers = true,
          value_parser = metres())]
    pub patch_size: Option<f64>,

    /// Longest element edge, metres (default: the scene's #@mesh
    /// suggestion, else 1/40 of the scene's bounding-box diagonal).
    #[arg(help_heading = "Solver", long, value_name = "METRES", allow_negative_numbers = true,
          value_parser = metres())]
    pub element_size: Option<f64>,

    /// Receiver refinement: at most N halvings of an element where a
    /// first, coarse solve finds the light varying across it (shadow
    /// edges, contacts, hot spots); 0 keeps the fixed grid. Overrides the
    /// preset (adaptive: 2; the paper's presets: 0). At most 8
    #[arg(help_heading = "Solver", long, value_name = "N", allow_negative_numbers = true,
          value_parser = whole::<u32>())]
    pub refine_levels: Option<u32>,

    /// Receiver refinement's threshold: an element splits once its
    /// radiosity varies by more than this fraction of the larger of its
    /// own mean and the scene's, once more per doubling beyond (default
    /// 0.25)
    #[arg(help_heading = "Solver", long, value_name = "FRACTION", allow_negative_numbers = true,
          value_parser = positive_real())]
    pub refine_tolerance: Option<f64>,

    /// Stop when unshot power falls below this fraction of emitted power
    /// (default: the preset's; adaptive 0.003, the paper's presets 0.01).
    #[arg(help_heading = "Solver", long, value_name = "FRACTION", allow_negative_numbers = true,
          value_parser = fraction())]
    pub converge: Option<f64>,

    /// Stop after N patches have shot.
    #[arg(help_heading = "Solver", long, value_name = "N", allow_negative_numbers = true,
          value_parser = whole::<u64>())]
    pub max_shots: Option<u64>,

    /// Stop once N subsources have shot.
    #[arg(help_heading = "Solver", long, value_name = "N", allow_negative_numbers = true,
          value_parser = whole::<u64>())]
    pub max_subsources: Option<u64>,

    /// Stop the solve after this many seconds and write every output from
    /// the state reached (pictures with the ambient term for the rest).
    #[arg(help_heading = "Solver", long, value_name = "SECONDS")]
    pub time_limit: Option<f64>,

    /// Worker threads (default: every core).
    #[arg(help_heading = "Solver", long, value_name = "N", allow_negative_numbers = true,
          value_parser = positive::<usize>())]
    pub threads: Option<usize>,

    /// Picture width in pixels.
    #[arg(help_heading = "Picture", long, default_value_t = app::DEFAULT_PICTURE[0], allow_negative_numbers = true,
          value_parser = positive::<u32>())]
    pub width: u32,

    /// Picture height in pixels.
    #[arg(help_heading = "Picture", long, default_value_t = app::DEFAULT_PICTURE[1], allow_negative_numbers = true,
          value_parser = positive::<u32>())]
    pub height: u32,

    /// The view as eye,target,up,fov: ten numbers, e.g.
    /// 0,1.6,4,0,1,0,0,1,0,60 (default: the scene's camera, or one framing
    /// the scene).
    #[arg(
        help_heading = "Picture",
        long,
        value_name = "EYE,TARGET,UP,FOV",
        allow_hyphen_values = true
    )]
    pub camera: Option<String>,

    /// Anti-aliasing: N x N samples a pixel.
    #[arg(help_heading = "Picture", long, value_name = "N", default_value_t = 3, allow_negative_numbers = true,
          value_parser = positive::<u32>())]
    pub supersampling: u32,

    /// Exposure adjustment in stops, on top of automatic exposure.
    #[arg(
        help_heading = "Picture",
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub exposure: f64,

    /// Show the solution without the ambient term.
    #[arg(help_heading = "Picture", long)]
    pub no_ambient: bool,

    /// No progress bar and no summary.
    #[arg(help_heading = "Progress and stopping", short, long)]
    pub quiet: bool,

    /// Machine-readable progress: one JSON object a line (`stage`,
    /// `progress`, `done` or `error` events, see the README's "Progress for
    /// other programs"), written to FILE as the run goes, or to standard
    /// output for `-` (then with no summary). For front ends such as the
    /// Blender add-on; independent of --quiet.
    #[arg(help_heading = "Progress and stopping", long, value_name = "FILE")]
    pub progress_json: Option<PathBuf>,

    /// Stop the solve, and write the outputs from the state reached, once
    /// FILE exists (checked ten times a second), as a first Ctrl-C does: a
    /// way to stop that works on every system. FILE must not exist when
    /// the run starts.
    #[arg(help_heading = "Progress and stopping", long, value_name = "FILE")]
    pub stop_file: Option<PathBuf>,

    /// Largest scene file (OBJ or MTL) read, MiB [default: 1024].
    #[arg(long, value_name = "MIB", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<u64>())]
    pub max_file_size: Option<u64>,

    /// Longest line of a scene file, bytes [default: 4194304].
    #[arg(long, value_name = "BYTES", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>())]
    pub max_line_length: Option<usize>,

    /// Most corners of one face [default: 100000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>())]
    pub max_corners: Option<usize>,

    /// Most faces in a scene [default: 5000000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>())]
    pub max_faces: Option<usize>,

    /// Most vertices (`v` lines) in a scene [default: 10000000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>())]
    pub max_vertices: Option<usize>,

    /// Most elements in the mesh [default: 4000000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>())]
    pub max_elements: Option<usize>,

    /// Most points in a --sensors file [default: 1000000].
    #[arg(long, value_name = "N", help_heading = LIMITS, allow_negative_numbers = true,
          value_parser = positive::<usize>())]
    pub max_sensors: Option<usize>,
    /// Memory the run may use, e.g. 8G, 1.5GiB or 512M (a bare number is
    /// MiB). A run whose estimated peak exceeds it is refused before its
    /// solve, naming the setting to change [default: the machine's
    /// available memory].
    #[arg(long, value_name = "SIZE", help_heading = LIMITS, allow_hyphen_values = true,
          value_parser = memory_size)]
    pub max_memory: Option<u64>,
    /// GPU memory a solve may take on the device, like --max-memory: a
    /// solve whose estimate exceeds it runs on the CPU under --device auto
    /// (with a note) and is refused under --device gpu [default: the
    /// adapter's own limits]
    #[arg(long, value_name = "SIZE", help_heading = LIMITS, allow_hyphen_values = true,
          value_parser = memory_size)]
    pub max_gpu_memory: Option<u64>,
}

/// `--shooting`'s help: every registered method with its summary.
fn shooting_help() -> String {
    let methods: Vec<String> = Shooting::ALL
        .iter()
        .map(|m| format!("{m} ({})", m.summary()))
        .collect();
    let list = match methods.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    };
    format!("How shooters send their unshot radiosity: {list}. Overrides the preset")
}

/// Help heading of the options that bound a load.
const LIMITS: &str = "Limits (each error says which to raise)";

/// A switch given as `on` or `off`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

/// The solving methods' parameters, as their flags: every registered
/// method's ([`MethodSettings::all_parameters`]), each with the help, value
/// name and kind of value its method declares. What was given goes to the
/// chosen method ([`radiosity::solver::Settings::set_parameters`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MethodArgs {
    /// The parameters given, by name, in the order the methods list them.
    pub given: Vec<(&'static str, Value)>,
}

impl clap::Args for MethodArgs {
    fn augment_args(mut cmd: clap::Command) -> clap::Command {
        for p in MethodSettings::all_parameters() {
            let arg = Arg::new(p.name)
                .long(p.flag())
                .value_name(p.value_name)
                .help(p.help)
                .help_heading("Solver")
                .action(ArgAction::Set);
            cmd = cmd.arg(match p.kind {
                Kind::Count => arg
                    .allow_negative_numbers(true)
                    .value_parser(positive::<u64>()),
                Kind::Number => arg.value_parser(clap::value_parser!(f64)),
                Kind::Choice(names) => arg.value_parser(PossibleValuesParser::new(names)),
            });
        }
        cmd
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        MethodArgs::augment_args(cmd)
    }
}

impl clap::FromArgMatches for MethodArgs {
    fn from_arg_matches(matches: &ArgMatches) -> Result<MethodArgs, clap::Error> {
        let mut args = MethodArgs::default();
        args.update_from_arg_matches(matches)?;
        Ok(args)
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        for p in MethodSettings::all_parameters() {
            let value = match p.kind {
                Kind::Count => matches.get_one::<u64>(p.name).copied().map(Value::Count),
                Kind::Number => matches.get_one::<f64>(p.name).copied().map(Value::Number),
                Kind::Choice(_) => matches
                    .get_one::<String>(p.name)
                    .map(|s| Value::Choice(s.clone())),
            };
            if let Some(value) = value {
                self.given.retain(|(name, _)| *name != p.name);
                self.given.push((p.name, value));
            }
        }
        Ok(())
    }
}
