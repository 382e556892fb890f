//! Receiver refinement inside one solve, beyond the paper: the two-pass
//! scheme of Cohen, Greenberg, Immel & Brock (1986) splits the elements
//! where a first solution's radiosity varies and solves again from the
//! start. Here the first solve goes on, on the refined mesh, from where it
//! stood:
//!
//! * **Old vertices** keep what they gathered (a split keeps every vertex
//!   at its index, [`crate::mesh::Mesh::refine`]).
//! * **New vertices** (and the final solve's sensors) get each shot made
//!   so far replayed to them, in order: a light's shot is gathered at them
//!   ([`lights::gather`]); a method's kept shot is sent again as it was
//!   ([`super::Shooter::replay`]), each receiver refining the source
//!   against the threshold it would have had then. So no shot is made
//!   twice, and a new vertex holds what it would have had if it had been
//!   there from the start.
//! * **A split element's pieces** take its unshot radiosity plus the
//!   reflected difference between what they received and what it did:
//!   `dB_c = dB_p + rho (E_c - E_p)`, `E` an element's mean irradiance over
//!   every shot (its corners' mean, or a light's integral across a
//!   shadow's edge, [`lights::element_means_of`]). The pieces send what
//!   their parent sent, so what they have left is what they reflected less
//!   that.
//! * **The ledger** books the same differences: the power the pieces
//!   received less what the parent did is received (from a sun or sky,
//!   whose power is what arrives, also emitted; from anything else, no
//!   longer escaped), `1 - rho` of it absorbed. It balances to round-off.
//!
//! Everything is computed receiver by receiver in a fixed order, so the
//! result does not depend on the number of threads.

use glam::DVec3;

use super::method::{ElementState, ShotInputs};
use super::{Abort, Energy, Receiver, Settings, Solver, Stats, lights, vertex_receivers};
use crate::accel::Occluder;
use crate::mesh::{Element, Mesh};
use crate::scene::Scene;

/// A shot a solve has made, as kept for its replay.
pub(super) enum Step {
    /// A light's shot.
    Light {
        /// The light.
        index: usize,
        /// Its irradiance at each vertex.
        vertex: Vec<DVec3>,
        /// Each element's mean irradiance from it, where the shot knew it
        /// better than the corners ([`lights::element_means`]).
        means: Option<Vec<DVec3>>,
    },
    /// One of the method's rounds (the method keeps what it sent).
    Method,
}

/// A solve's state carried onto a refined mesh ([`Solver::go_on`]), from
/// which [`Solver::resume`] goes on.
pub struct Start {
    sensors: Vec<Receiver>,
    irradiance: Vec<DVec3>,
    direct: Vec<DVec3>,
    sky: Vec<DVec3>,
    direct_partial: bool,
    method: ElementState,
    energy: Energy,
    stats: Stats,
    lights_pending: Vec<usize>,
    light_power: Vec<DVec3>,
    device_shots: u64,
    /// Receivers the shots so far were replayed to: the new vertices and
    /// the sensors.
    pub replayed_receivers: usize,
    /// Shots replayed to them.
    pub replayed_shots: usize,
}

/// What the kept shots gave the receivers they were replayed to
/// ([`Solver::replay`]).
struct Replayed {
    /// Irradiance at each receiver: the new vertices, then the sensors.
    gathered: Vec<DVec3>,
    /// Its part straight from a source.
    direct: Vec<DVec3>,
    /// Its part from skies.
    sky: Vec<DVec3>,
    /// The part of each refined-mesh vertex's irradiance that the method's
    /// shots gave.
    method_vertex: Vec<DVec3>,
    /// Each kept light's irradiance at every refined-mesh vertex.
    light_vertex: Vec<Vec<DVec3>>,
}

/// The split elements of a refinement.
struct Split {
    /// The base element each refined element was cut from.
    of: Vec<u32>,
    /// Base elements that were split.
    parents: Vec<usize>,
    /// Refined elements that are pieces of a split element, and the pieces.
    pieces: Vec<usize>,
    elements: Vec<Element>,
}

impl Split {
    /// The split elements of `base` refined as `refined`, element `c`
    /// cut from `parents[c]`: those whose pieces differ from themselves.
    fn new(base: &Mesh, refined: &Mesh, parents: &[u32]) -> Split {
        let mut split = vec![false; base.elements.len()];
        for (e, &p) in refined.elements.iter().zip(parents) {
            split[p as usize] |= e.vertices() != base.elements[p as usize].vertices();
        }
        let pieces: Vec<usize> = (0..parents.len())
            .filter(|&c| split[parents[c] as usize])
            .collect();
        Split {
            of: parents.to_vec(),
            parents: (0..split.len()).filter(|&p| split[p]).collect(),
            elements: pieces.iter().map(|&c| refined.elements[c]).collect(),
            pieces,
        }
    }
}

/// The kept lights' mean irradiance over a refinement's pieces and split
/// parents ([`Solver::light_means`]).
struct LightMeans {
    /// Per piece, summed over the lights.
    piece: Vec<DVec3>,
    /// Per base element (zero unless split), summed over the lights.
    parent: Vec<DVec3>,
    /// Each light's power received by the pieces less their parents'.
    delta: Vec<(usize, DVec3)>,
}

/// The mean of `values` over `element`'s corners.
fn corner_mean(values: &[DVec3], element: &Element) -> DVec3 {
    let corners = element.vertices();
    corners.iter().map(|&c| values[c as usize]).sum::<DVec3>() / corners.len() as f64
}

impl<'a> Solver<'a> {
    /// Keeps `step` when shots are recorded.
    pub(super) fn keep(&mut self, step: Step) {
        if let Some(record) = self.record.as_mut() {
            record.push(step);
        }
    }

    /// Keeps every shot from now on, so the solve can go on on a refined
    /// mesh ([`Solver::go_on`]); call it before the first shot. False
    /// when the method cannot replay its shots (the paper's patches): such
    /// a solve is refined by solving again.
    pub fn record_shots(&mut self) -> bool {
        if self.stats.shots > 0 || !self.shooter.record_shots() {
            return false;
        }
        self.record = Some(Vec::new());
        true
    }

    /// The state this solve (which kept its shots, [`Solver::record_shots`])
    /// goes on from on `refined`, this mesh refined ([`Mesh::refine`]:
    /// `parents[c]` is the element of this mesh that element `c` was cut
    /// from), gathering also at `sensors`. `None` when the shots were not
    /// kept (or a device's failure made some again), when the method keeps
    /// no state per element, or when the replay is interrupted.
    #[must_use]
    pub fn go_on(
        &mut self,
        refined: &Mesh,
        parents: &[u32],
        sensors: Vec<Receiver>,
    ) -> Option<Start> {
        let record = self.record.take()?;
        let state = self.shooter.element_state()?;
        let old = self.mesh.vertices.len();
        if parents.len() != refined.elements.len() || refined.vertices.len() < old {
            return None;
        }
        let mut receivers = vertex_receivers(self.scene, refined).split_off(old);
        receivers.extend(sensors.iter().copied());
        let mut stats = self.stats.clone();
        let replayed = self.replay(&record, refined, &receivers, &mut stats)?;
        let split = Split::new(self.mesh, refined, parents);
        let lights = self.light_means(&record, &replayed, refined, &split, &mut stats)?;
        let (method, energy, light_power) =
            self.pieces(state, &replayed.method_vertex, &lights, &split);
        let join = |here: &[DVec3], there: &[DVec3]| [&here[..old], there].concat();
        Some(Start {
            irradiance: join(&self.irradiance, &replayed.gathered),
            direct: join(&self.direct, &replayed.direct),
            sky: join(&self.sky, &replayed.sky),
            sensors,
            direct_partial: self.direct_partial,
            method,
            energy,
            stats,
            lights_pending: self.lights_pending.clone(),
            light_power,
            device_shots: self.device_report().device_shots,
            replayed_receivers: receivers.len(),
            replayed_shots: record.len(),
        })
    }

    /// The kept shots `record` replayed, in order, to `receivers` (the
    /// vertices `refined` adds, then sensors); `None` when interrupted.
    fn replay(
        &mut self,
        record: &[Step],
        refined: &Mesh,
        receivers: &[Receiver],
        stats: &mut Stats,
    ) -> Option<Replayed> {
        let (scene, base) = (self.scene, self.mesh);
        let (old, new) = (
            base.vertices.len(),
            refined.vertices.len() - base.vertices.len(),
        );
        let abort = Abort {
            deadline: None,
            flag: self.interrupt.clone(),
        };
        let mut gathered = vec![DVec3::ZERO; receivers.len()];
        let mut direct = vec![DVec3::ZERO; receivers.len()];
        let mut sky = vec![DVec3::ZERO; receivers.len()];
        // The old vertices' part from the method's shots: all they
        // gathered less the lights' (which all shot before it).
        let mut method_vertex = self.irradiance[..old].to_vec();
        method_vertex.resize(old + new, DVec3::ZERO);
        let mut light_vertex = Vec::new();
        let mut method_shots = 0;
        for step in record {
            let inputs = |mesh| ShotInputs {
                scene,
                mesh,
                settings: &self.settings,
                occluder: self.occluder.as_ref(),
                receivers,
                irradiance: &gathered,
                direct: &[],
                abort: &abort,
            };
            let (e, d) = match step {
                Step::Light { index, vertex, .. } => {
                    let light = &scene.lights[*index];
                    let e = lights::gather(light, &inputs(refined), None, stats).ok()??;
                    for (m, l) in method_vertex.iter_mut().zip(vertex) {
                        *m -= *l;
                    }
                    if light.sky().is_some() {
                        for (s, e) in sky.iter_mut().zip(&e) {
                            *s += *e;
                        }
                    }
                    light_vertex.push([vertex, &e[..new]].concat());
                    (e.clone(), e)
                }
                Step::Method => {
                    let r = self.shooter.replay(&inputs(base), method_shots)?;
                    method_shots += 1;
                    for (m, e) in method_vertex[old..].iter_mut().zip(&r.irradiance) {
                        *m += *e;
                    }
                    (r.irradiance, r.direct)
                }
            };
            for (g, e) in gathered.iter_mut().zip(&e) {
                *g += *e;
            }
            for (t, e) in direct.iter_mut().zip(&d) {
                *t += *e;
            }
        }
        Some(Replayed {
            gathered,
            direct,
            sky,
            method_vertex,
            light_vertex,
        })
    }

    /// Each kept light's mean irradiance over the pieces and over their
    /// split parents (its element means where it had them, else the
    /// corners'), summed over the lights, and each light's difference in
    /// power received; `None` when interrupted.
    fn light_means(
        &self,
        record: &[Step],
        replayed: &Replayed,
        refined: &Mesh,
        split: &Split,
        stats: &mut Stats,
    ) -> Option<LightMeans> {
        let abort = Abort {
            deadline: None,
            flag: self.interrupt.clone(),
        };
        let inputs = ShotInputs {
            scene: self.scene,
            mesh: refined,
            settings: &self.settings,
            occluder: self.occluder.as_ref(),
            receivers: &[],
            irradiance: &[],
            direct: &[],
            abort: &abort,
        };
        let mut out = LightMeans {
            piece: vec![DVec3::ZERO; split.pieces.len()],
            parent: vec![DVec3::ZERO; self.mesh.elements.len()],
            delta: Vec::new(),
        };
        let kept = record.iter().filter_map(|s| match s {
            Step::Light {
                index,
                vertex,
                means,
            } => Some((*index, vertex, means)),
            Step::Method => None,
        });
        for ((index, vertex, means), all) in kept.zip(&replayed.light_vertex) {
            let light = &self.scene.lights[index];
            let piece_means =
                lights::element_means_of(light, &inputs, &split.elements, all, None, stats)
                    .ok()??;
            let mut delta = DVec3::ZERO;
            for (k, e) in split.elements.iter().enumerate() {
                let m = piece_means
                    .as_ref()
                    .map_or_else(|| corner_mean(all, e), |m| m[k]);
                out.piece[k] += m;
                delta += m * e.area;
            }
            for &p in &split.parents {
                let e = &self.mesh.elements[p];
                let m = means
                    .as_ref()
                    .map_or_else(|| corner_mean(vertex, e), |m| m[p]);
                out.parent[p] += m;
                delta -= m * e.area;
            }
            out.delta.push((index, delta));
        }
        Some(out)
    }

    /// The method's state on the refined mesh and the ledger: a piece
    /// takes its parent's unshot radiosity plus `rho (E_c - E_p)`, the
    /// ledger books the pieces' difference from their parents.
    fn pieces(
        &self,
        state: ElementState,
        method_vertex: &[DVec3],
        lights: &LightMeans,
        split: &Split,
    ) -> (ElementState, Energy, Vec<DVec3>) {
        let (scene, base) = (self.scene, self.mesh);
        let mut unshot: Vec<DVec3> = split.of.iter().map(|&p| state.unshot[p as usize]).collect();
        let emission_pending = split
            .of
            .iter()
            .map(|&p| state.emission_pending[p as usize])
            .collect();
        let parent_mean =
            |p: usize| corner_mean(method_vertex, &base.elements[p]) + lights.parent[p];
        let (mut method_delta, mut absorbed_delta) = (DVec3::ZERO, DVec3::ZERO);
        for (k, (&c, e)) in split.pieces.iter().zip(&split.elements).enumerate() {
            let rho = scene.surfaces[e.surface as usize].rho;
            let method_mean = corner_mean(method_vertex, e);
            let mean = method_mean + lights.piece[k];
            unshot[c] += rho * (mean - parent_mean(split.of[c] as usize));
            method_delta += method_mean * e.area;
            absorbed_delta += (DVec3::ONE - rho) * mean * e.area;
        }
        for &p in &split.parents {
            let e = &base.elements[p];
            let rho = scene.surfaces[e.surface as usize].rho;
            method_delta -= corner_mean(method_vertex, e) * e.area;
            absorbed_delta -= (DVec3::ONE - rho) * parent_mean(p) * e.area;
        }
        let mut energy = self.energy;
        let mut light_power = self.light_power.clone();
        let mut power = state.power;
        energy.received += method_delta;
        energy.escaped -= method_delta;
        energy.absorbed += absorbed_delta;
        for &(index, delta) in &lights.delta {
            energy.received += delta;
            power += crate::luminance(delta);
            if scene.lights[index].position().is_none() {
                // A sun's or sky's power is what arrives.
                energy.emitted += delta;
                light_power[index] += delta;
            } else {
                energy.escaped -= delta;
            }
        }
        let state = ElementState {
            unshot,
            emission_pending,
            power,
        };
        (state, energy, light_power)
    }

    /// The final solve on a refined mesh ([`super::refine::Refined`]):
    /// the coarse pass going on from `start` ([`Solver::resume`], with the
    /// sensors it was made with) when there is one, else a fresh solve
    /// gathering at `sensors`; visibility answered by `occluder`.
    #[must_use]
    pub fn resume_or_new(
        scene: &'a Scene,
        mesh: &'a Mesh,
        settings: Settings,
        start: Option<Start>,
        sensors: Vec<Receiver>,
        occluder: Box<dyn Occluder + 'a>,
    ) -> Solver<'a> {
        match start {
            Some(start) => Solver::resume(scene, mesh, settings, start, occluder),
            None => Solver::with_sensors_and_occluder(scene, mesh, settings, sensors, occluder),
        }
    }

    /// A solve of `scene` on `mesh` that goes on from `start` (made by
    /// [`Solver::go_on`] for this mesh), gathering at the sensors `start`
    /// was made with, its visibility answered by `occluder`.
    ///
    /// # Panics
    ///
    /// When `start` was made for another mesh.
    #[must_use]
    pub fn resume(
        scene: &'a Scene,
        mesh: &'a Mesh,
        settings: Settings,
        start: Start,
        occluder: Box<dyn Occluder + 'a>,
    ) -> Solver<'a> {
        let mut solver =
            Solver::with_sensors_and_occluder(scene, mesh, settings, start.sensors, occluder);
        assert_eq!(
            (solver.irradiance.len(), start.method.unshot.len()),
            (start.irradiance.len(), mesh.elements.len()),
            "a start made for another mesh"
        );
        solver.shooter.resume(mesh, start.method);
        for (i, v) in mesh.vertices.iter().enumerate() {
            let s = &scene.surfaces[v.surface as usize];
            solver.radiosity[i] = s.emission + s.rho * start.irradiance[i];
        }
        solver.irradiance = start.irradiance;
        solver.direct = start.direct;
        solver.sky = start.sky;
        solver.direct_partial = start.direct_partial;
        solver.energy = start.energy;
        solver.stats = start.stats;
        solver.lights_pending = start.lights_pending;
        solver.light_power = start.light_power;
        solver.other_device_shots = start.device_shots;
        solver.saved = (solver.energy, solver.stats.clone());
        solver
    }
}
