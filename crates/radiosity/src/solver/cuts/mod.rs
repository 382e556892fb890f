//! Whole-scene passes through cuts of the tree of all unshot power, beyond
//! the paper: Lightcuts (Walter et al. 2005) applied to progressive
//! radiosity, so a pass costs what the light needs, not what the scene's
//! shooters number.
//!
//! Progressive shooting (Wallace et al. 1989, the paper's and adaptive
//! shooting) sends one shooter's light to every receiver per shot, so a
//! scene of a thousand shooters needs thousands of shots each reaching every
//! vertex. Here every shot is a *pass* of the whole scene: every element
//! shoots its unshot radiosity at once (a Jacobi step of the radiosity
//! equation; Gortler, Cohen & Slusallek 1993 call it the full sweep), and
//! every receiver gathers it through its own cut of the element tree
//! (`cut`): elements nearby at their exact factor, larger nodes far off as
//! corrected point sources, each refined until its possible error is below
//! the tolerance times what the receiver gathers in the pass. A receiver
//! keeps its cut, with the factors and visibilities it found, from pass to
//! pass and only refines it where the light has moved, so the shadow rays
//! of a solve are spent mostly in its first passes and later passes cost
//! little more than arithmetic.
//!
//! The passes needed follow the scene's reflectance, not its size (the
//! unshot power falls by about the mean reflectance a pass); the cost of a
//! pass follows the size of the cuts, which grows with the log of the
//! element count. Book-keeping is the elements' own, as in adaptive
//! shooting, and exact: the power shot, received, absorbed and reflected
//! balance to round-off.

mod cut;

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use self::cut::{CutScratch, Entry, Refiner, Work};
use super::hierarchy::Hierarchy;
use super::hierarchy::sources::Sources;
use super::hierarchy::transfer::Transfer;
use super::method::{
    self, Counter, Emission, Kind, Method, MethodError, Parameter, Received, SetError, Shooter,
    Shot, ShotInputs, Stats, Value,
};
use super::{Receiver, Settings};
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::costs;

/// The method's own parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct CutSettings {
    /// A node of a receiver's cut is refined while its possible error is
    /// above this fraction of what the receiver gathers in the pass (or of
    /// the pass's mean irradiance, if more).
    pub error: f64,
}

/// Default `--cut-error`.
pub const DEFAULT_ERROR: f64 = 0.02;

impl Default for CutSettings {
    fn default() -> Self {
        CutSettings {
            error: DEFAULT_ERROR,
        }
    }
}

/// `--cut-error`.
const ERROR: Parameter = Parameter {
    name: "cut_error",
    value_name: "FRACTION",
    help: "Cut shooting's accuracy: a part of the light is one source for a receiver while what \
           it may be off by is below this fraction of what the receiver gathers in the pass \
           (default 0.02)",
    kind: Kind::Number,
};

/// A pass's floor for a receiver's threshold, as a fraction of the pass's
/// mean irradiance: a receiver that gathers less than this refines no more
/// than one that gathers this much.
const FLOOR: f64 = 0.1;

/// Settings cut shooting cannot run with.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CutSettingsError {
    /// Error outside (0, 1].
    #[error("--cut-error must be a fraction in (0, 1], not {0}")]
    Error(f64),
}

impl Method for CutSettings {
    fn parameters(&self) -> &'static [Parameter] {
        &[ERROR]
    }

    fn set(&mut self, name: &str, value: &Value) -> Result<(), SetError> {
        match name {
            "cut_error" => self.error = value.number(name)?,
            _ => return Err(SetError::NotMine),
        }
        Ok(())
    }

    fn values(&self) -> Vec<(&'static str, serde_json::Value)> {
        vec![("cut_error", self.error.into())]
    }

    fn validate(&self) -> Result<(), MethodError> {
        if !(self.error.is_finite() && self.error > 0.0 && self.error <= 1.0) {
            return Err(MethodError::new(CutSettingsError::Error(self.error)));
        }
        Ok(())
    }

    fn zero_counters(&self) -> Vec<(&'static str, Counter)> {
        Counters::default().list()
    }

    fn memory(&self) -> costs::SolverCosts {
        costs::SolverCosts {
            vertex: 104.0 + 8.0 * 400.0,
            element: 270.0,
            surface: 400.0,
            parts: Vec::new(),
        }
    }

    fn start<'a>(
        &self,
        scene: &'a Scene,
        mesh: &'a Mesh,
        settings: &Settings,
        receivers: &[Receiver],
    ) -> Box<dyn Shooter + 'a> {
        Box::new(CutShooting::new(
            scene, mesh, settings, self.error, receivers,
        ))
    }
}

/// What the passes did.
#[derive(Clone, Copy, Debug, Default)]
struct Counters {
    /// Entries of all cuts after the last pass.
    kept: u64,
    /// Entries evaluated.
    evaluations: u64,
    /// Nodes of cuts replaced by their children.
    splits: u64,
    /// Nodes whose visibility was sampled by four rays.
    sampled: u64,
}

impl Counters {
    fn list(&self) -> Vec<(&'static str, Counter)> {
        vec![
            ("cut_entries", Counter::Count(self.kept)),
            ("cut_evaluations", Counter::Count(self.evaluations)),
            ("cut_splits", Counter::Count(self.splits)),
            ("cut_samples", Counter::Count(self.sampled)),
        ]
    }
}

/// The state of cut shooting.
struct CutShooting {
    hierarchy: Hierarchy,
    /// Unshot radiosity of each element.
    unshot: Vec<DVec3>,
    /// The elements whose emission is still unshot.
    emission: Emission,
    /// Each receiver's cut.
    cuts: Vec<Vec<Entry>>,
    /// The pass's sources.
    sources: Sources,
    /// The elements' total area.
    area: f64,
    error: f64,
    counters: Counters,
}

impl CutShooting {
    fn new(
        scene: &Scene,
        mesh: &Mesh,
        settings: &Settings,
        error: f64,
        receivers: &[Receiver],
    ) -> CutShooting {
        let hierarchy = Hierarchy::build(scene, mesh, settings.mesh.patch_size);
        let root = if hierarchy.tree.nodes.is_empty() {
            Vec::new()
        } else {
            vec![Entry::new(0)]
        };
        CutShooting {
            cuts: vec![root; receivers.len()],
            emission: Emission::new(scene, mesh.elements.len(), |i| mesh.elements[i].surface),
            hierarchy,
            unshot: mesh
                .elements
                .iter()
                .map(|e| scene.surfaces[e.surface as usize].emission)
                .collect(),
            sources: Sources::default(),
            area: mesh.total_area(),
            error,
            counters: Counters::default(),
        }
    }
}

impl Shooter for CutShooting {
    /// One: the whole scene shoots at once.
    fn shooters(&self) -> usize {
        1
    }

    fn unshot_power(&self, mesh: &Mesh) -> DVec3 {
        mesh.elements
            .iter()
            .zip(&self.unshot)
            .map(|(e, u)| *u * e.area)
            .sum()
    }

    /// One pass: every element shoots its unshot radiosity through every
    /// receiver's cut; every element's unshot radiosity is zeroed.
    fn shoot(&mut self, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Option<Shot> {
        let start = Instant::now();
        let (scene, mesh) = (inputs.scene, inputs.mesh);
        let power = self.unshot_power(mesh);
        self.sources
            .prepare(scene, mesh, &self.hierarchy, &self.unshot, 0);
        let shooting = self.unshot.iter().filter(|u| **u != DVec3::ZERO).count() as u64;
        let refiner = Refiner {
            transfer: Transfer {
                scene,
                mesh,
                hierarchy: &self.hierarchy,
                unshot: &self.unshot,
                sources: &self.sources,
                root: 0,
                origin: self
                    .hierarchy
                    .tree
                    .nodes
                    .first()
                    .map_or(DVec3::ZERO, |n| n.centre),
                occluder: inputs.occluder,
                form_factor: inputs.settings.form_factor,
            },
            tolerance: self.error,
            floor: FLOOR * luminance(power) / self.area.max(f64::MIN_POSITIVE),
        };
        let gather_start = Instant::now();
        let abort = inputs.abort;
        let (irradiance, work): (Vec<DVec3>, Vec<Work>) = self
            .cuts
            .par_iter_mut()
            .zip(inputs.receivers.par_iter())
            .with_min_len(16)
            .map_init(CutScratch::default, |scratch, (cut, r)| {
                let mut work = Work::default();
                if abort.fired() {
                    return (DVec3::ZERO, work);
                }
                let e = refiner.gather(r, cut, scratch, &mut work);
                (e, work)
            })
            .unzip();
        if abort.fired() {
            return None;
        }
        let gather_end = Instant::now();
        let mut total = Work::default();
        for w in work {
            total += w;
        }
        let cost = total.cost;
        self.counters.evaluations += total.evaluations;
        self.counters.splits += total.splits;
        self.counters.sampled += total.sampled;
        self.counters.kept = self.cuts.iter().map(|c| c.len() as u64).sum();
        stats.book_gathering(&cost, gather_end - gather_start, shooting);
        self.unshot.fill(DVec3::ZERO);
        let emitted = self.emission.take(
            inputs.scene,
            inputs
                .mesh
                .elements
                .iter()
                .enumerate()
                .map(|(i, e)| (i, e.surface, e.area)),
        );
        Some(Shot::single(
            irradiance,
            power,
            emitted,
            gather_start - start,
        ))
    }

    fn receive(
        &mut self,
        scene: &Scene,
        mesh: &Mesh,
        irradiance: &[DVec3],
        element_means: Option<&[DVec3]>,
    ) -> Received {
        let unshot = &mut self.unshot;
        method::receive_at_elements(scene, mesh, irradiance, element_means, |e, radiosity| {
            unshot[e] += radiosity;
        })
    }

    fn counters(&self) -> Vec<(&'static str, Counter)> {
        self.counters.list()
    }
}
