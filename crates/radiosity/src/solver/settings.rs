//! The settings of a solve (apart from run state): what every method shares
//! (the mesh's sizes, the form factor of the paper's section 4, the
//! shadow-ray accelerator of its section 3, the stopping rules of
//! design.md section 2) and the method with its own ([`MethodSettings`]).
//! The presets are named constructors: the paper's two (Wallace et al.
//! 1989; Wong & Tsang 1993) and the default, which goes beyond it.

use std::time::Duration;

use super::adaptive::AdaptiveSettings;
use super::device::Device;
use super::method::{self, MethodError, SetError, Value, Visibility};
use super::patches::PatchSettings;
use super::registry::{MethodSettings, Shooting};
use crate::accel::Accel;
use crate::form_factor::FormFactor;
use crate::mesh::{MeshSettings, RefineSettings};

/// Every setting of a solve, apart from run state. Presets are named
/// constructors; each field can be overridden on its own. Serialised as
/// the `--stats` file's `settings` object: one flat object, the mesh's
/// sizes and the method's parameters among the others, the time limit in
/// seconds.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Settings {
    /// Patch and element sizes.
    #[serde(flatten)]
    pub mesh: MeshSettings,
    /// The way of solving, with its own parameters.
    #[serde(flatten)]
    pub method: MethodSettings,
    /// Give adjacent coplanar faces of one material one surface id
    /// ([`crate::scene::merge`]).
    pub merge_coplanar: bool,
    /// Point-to-polygon formula.
    pub form_factor: FormFactor,
    /// Shadow-segment accelerator.
    pub accel: Accel,
    /// Stop when the unshot power falls below this fraction of the emitted
    /// power.
    pub converge: f64,
    /// Stop after this many shots.
    pub max_shots: Option<u64>,
    /// Stop once this many of the method's finest sources (subsources)
    /// have been shot.
    pub max_subsources: Option<u64>,
    /// Stop before a shot once the solve has run this long.
    #[serde(serialize_with = "optional_seconds")]
    pub time_limit: Option<Duration>,
    /// Where the transfers run (`--device`): the CPU unless a back end is
    /// given. Reported beside the settings, not among them.
    #[serde(skip)]
    pub device: Device,
}

/// A duration as a number of seconds, `null` for none.
fn optional_seconds<S: serde::Serializer>(
    time: &Option<Duration>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&time.map(|t| t.as_secs_f64()), serializer)
}

/// The default preset's `--refine-levels`.
pub const DEFAULT_REFINE_LEVELS: u32 = 2;

/// Default `--converge` of the paper's presets.
pub const DEFAULT_CONVERGE: f64 = 0.01;

/// Default `--converge` of the default preset: at 0.01 the light not yet
/// shot leaves the answer about 1% dark in a closed room (measured against
/// Radiance on the built-in Cornell box: bias -1.0% at 0.01, -0.3% at
/// 0.003).
pub const ADAPTIVE_CONVERGE: f64 = 0.003;

impl Settings {
    /// Wallace, Elmquist & Haines (1989): patch shooting, a shadow ray for
    /// every pair against every surface, the disk form factor of equation
    /// (1), 3 x 3 subsources, every input face its own surface.
    #[must_use]
    pub fn wallace89() -> Settings {
        Settings {
            mesh: MeshSettings::default(),
            method: MethodSettings::Patches(PatchSettings::default()),
            merge_coplanar: false,
            form_factor: FormFactor::Wallace,
            accel: Accel::Brute,
            converge: DEFAULT_CONVERGE,
            max_shots: None,
            max_subsources: None,
            time_limit: None,
            device: Device::cpu(),
        }
    }

    /// Wong & Tsang (1993), all three improvements: the hemicube pre-test
    /// (section 2), BSP-ordered shadow rays (section 3) and the analytic
    /// form factor of Baum et al. (section 4, equation 2).
    #[must_use]
    pub fn wong_tsang93() -> Settings {
        Settings {
            method: MethodSettings::Patches(PatchSettings {
                visibility: Visibility::HemicubePretest,
                ..PatchSettings::default()
            }),
            form_factor: FormFactor::Analytic,
            accel: Accel::Bsp,
            ..Settings::wallace89()
        }
    }

    /// The default: adaptive element-resolution shooting from clusters
    /// ([`super::adaptive`]), the analytic factor at the elements, shadow
    /// rays through the BVH, coplanar faces merged into surfaces.
    #[must_use]
    pub fn adaptive() -> Settings {
        Settings {
            mesh: MeshSettings {
                bisect_triangles: true,
                refine: RefineSettings {
                    refine_levels: DEFAULT_REFINE_LEVELS,
                    ..RefineSettings::default()
                },
                conform: true,
                ..MeshSettings::default()
            },
            method: MethodSettings::Adaptive(AdaptiveSettings::default()),
            merge_coplanar: true,
            form_factor: FormFactor::Analytic,
            accel: Accel::Bvh,
            converge: ADAPTIVE_CONVERGE,
            ..Settings::wallace89()
        }
    }

    /// Switches to the method `shooting` with its default settings, keeping
    /// the values of the parameters it shares with the method it replaces
    /// (a preset's `visibility`, say): a value the new method refuses is an
    /// error, as if given to it.
    pub fn switch_method(&mut self, shooting: Shooting) -> Result<(), SettingsError> {
        if shooting == self.method.shooting() {
            return Ok(());
        }
        let mut method = MethodSettings::default_for(shooting);
        let taken = method.method().parameters();
        for (name, value) in self.method.method().values() {
            if taken.iter().any(|p| p.name == name) {
                method
                    .method_mut()
                    .set(name, &Value::from_json(&value))
                    .map_err(|e| match e {
                        SetError::Refused(e) => SettingsError::Method(e),
                        SetError::NotMine => unreachable!("{name} is among its parameters"),
                    })?;
            }
        }
        self.method = method;
        Ok(())
    }

    /// Sets the method's parameters from a front end (a command line's
    /// flags), by [`super::method::Parameter::name`]. A parameter the method takes is set;
    /// one it does not take is checked by the methods that do take it (so
    /// a value out of range is an error whichever method runs) and then
    /// ignored, with a warning naming those methods. Returns the warnings.
    pub fn set_parameters(
        &mut self,
        given: &[(&str, Value)],
    ) -> Result<Vec<String>, SettingsError> {
        let mut warnings = Vec::new();
        let mut others: Vec<MethodSettings> = Vec::new();
        for (name, value) in given {
            match self.method.method_mut().set(name, value) {
                Ok(()) => continue,
                Err(SetError::Refused(e)) => return Err(e.into()),
                Err(SetError::NotMine) => {}
            }
            let owners = MethodSettings::taking(name);
            if owners.is_empty() {
                return Err(MethodError::new(UnknownParameter(name.to_string())).into());
            }
            for owner in &owners {
                let slot = match others.iter().position(|m| m.shooting() == *owner) {
                    Some(i) => i,
                    None => {
                        others.push(MethodSettings::default_for(*owner));
                        others.len() - 1
                    }
                };
                if let Err(SetError::Refused(e)) = others[slot].method_mut().set(name, value) {
                    return Err(e.into());
                }
            }
            let owners: Vec<&str> = owners.iter().map(|o| o.name()).collect();
            warnings.push(format!(
                "--{} is a setting of --shooting {}; {} shooting does not use it",
                method::flag(name),
                owners.join(" or "),
                self.method.shooting()
            ));
        }
        for other in &others {
            other.method().validate()?;
        }
        Ok(warnings)
    }

    /// Checks the settings a user can get wrong: the method's, then the
    /// stopping rules.
    pub fn validate(&self) -> Result<(), SettingsError> {
        self.method.method().validate()?;
        if !(self.converge.is_finite() && (0.0..1.0).contains(&self.converge)) {
            return Err(SettingsError::Converge(self.converge));
        }
        if self.converge == 0.0
            && self.max_shots.is_none()
            && self.max_subsources.is_none()
            && self.time_limit.is_none()
        {
            return Err(SettingsError::NeverStops);
        }
        if let Some((backend, setting)) = self
            .device
            .get()
            .and_then(|b| b.refuses(self).map(|setting| (b, setting)))
        {
            return Err(SettingsError::Device {
                device: backend.name(),
                setting,
            });
        }
        Ok(())
    }
}

/// A parameter no method takes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("no way of shooting takes a parameter called {0}")]
pub struct UnknownParameter(pub String);

/// Settings a solve cannot run with ([`Settings::validate`]); each message
/// names the flag to change.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// One of the method's parameters.
    #[error(transparent)]
    Method(#[from] MethodError),
    /// Convergence threshold outside [0, 1).
    #[error("--converge must be a fraction in [0, 1), not {0}")]
    Converge(f64),
    /// No stopping rule at all.
    #[error(
        "--converge 0 never stops by itself: give --max-shots, --max-subsources or --time-limit"
    )]
    NeverStops,
    /// A setting the device does not run.
    #[error(
        "the GPU ({device}) runs the default method (adaptive shooting, the BVH, the analytic \
         factor), not {setting}: use --device cpu (the paper's presets run on the CPU, in f64)"
    )]
    Device {
        /// The device.
        device: String,
        /// The setting it refuses, as a flag.
        setting: String,
    },
}

crate::choice::named_choice! {
    /// The named settings ([`Settings::adaptive`], [`Settings::wong_tsang93`],
    /// [`Settings::wallace89`]), in the order the command line lists them.
    pub enum Preset: "preset" {
        /// [`Settings::adaptive`], the default.
        Adaptive = "adaptive",
        /// [`Settings::wong_tsang93`], the paper's method.
        WongTsang93 = "wong-tsang93",
        /// [`Settings::wallace89`], the 1989 baseline.
        Wallace89 = "wallace89",
    }
}

impl Preset {
    /// The preset's settings.
    #[must_use]
    pub fn settings(self) -> Settings {
        match self {
            Preset::Adaptive => Settings::adaptive(),
            Preset::WongTsang93 => Settings::wong_tsang93(),
            Preset::Wallace89 => Settings::wallace89(),
        }
    }
}
