//! The final pass (beyond the paper): what a picture's sample, a lightmap
//! texel or a sensor shows, evaluated at its own surface point instead of
//! read from the element mesh, so what is shown is sharper than the mesh.
//!
//! Wallace, Elmquist & Haines (1989) already ray-traced the direct light at
//! each pixel of their final display; Shirley (1990) and Reichert (1992)
//! split a solution into the direct light, evaluated per point with shadow
//! rays, and the smooth indirect light, taken from the mesh; Lischinski,
//! Tampieri & Greenberg (1993) gather the mesh's radiosity over the
//! hemisphere of each point shown (a one-bounce final gather), as every
//! lightmapper does today. [`FinalGather`] picks one:
//!
//! * `off`: the mesh's values, as the paper showed them;
//! * `direct`: the direct light evaluated at the point plus the mesh's
//!   indirect part, interpolated;
//! * `full`: the direct light at the point plus the mesh's reflected
//!   radiosity gathered over its hemisphere with stratified cosine-weighted
//!   rays (the emission of the surfaces hit is left out: it is direct).
//!
//! **The split at a vertex.** The solve books the direct part apart
//! ([`Solver::direct_irradiance`]: the lights' shots and the emitting
//! surfaces' first shots, on every method); the mesh's indirect part is
//! the vertex's total less it, interpolated between vertices, while the
//! direct part is evaluated afresh at every point shown. A device books
//! the direct part beside the total; where a device's failure left it
//! incomplete ([`Solver::direct_complete`]), the emitting surfaces' part
//! at each vertex is evaluated here by the same estimator as at any other
//! point ([`FinalPass::direct`]).
//!
//! **Direct light at a point.** The scene's lights as their shots send
//! it ([`lights::direct_at`]), but skies: a sky's light changes slowly
//! across a surface and its estimate at one point takes hundreds of rays
//! (a daylit room's picture took minutes), so its part stays with the
//! mesh's ([`Solver::sky_irradiance`]); each emitting surface in pieces
//! (the paper's subsources of each of its triangles or quads), each
//! piece's share of the light times what passes along a shadow ray from a
//! point of it, dimmed by the glass it crosses: exact where nothing
//! blocks, and as many rays for a sky opening of two hundred patches as
//! for a bulb. A picture's sample casts [`SAMPLE_SPLIT`]` x `
//! [`SAMPLE_SPLIT`] rays per emitting surface: the samples of an `s x s`
//! pixel take the pieces of a grid `s SAMPLE_SPLIT` a side in turn from a
//! place of the pixel's own, each from a point drawn uniformly in it, and
//! a piece's share of the surface's exact factor (equation (2),
//! [`form_factor::analytic()`], clipped to the receiver's front) is its
//! point factor's share of theirs, so a pixel sums the whole factor and a
//! penumbra is smooth noise, not copies of a shadow. A pixel's samples are
//! shaded together: each surface is first probed with one ray a sample,
//! and only where the probes disagree (a penumbra) do the samples take
//! those rays; elsewhere each takes the exact factor times what the probes
//! let through, with no noise ([`FinalPass::direct`]). A vertex, texel or
//! sensor casts [`EMITTER_SIDE`]` x `[`EMITTER_SIDE`] rays, one to each
//! piece's centroid, each piece with its own exact factor.
//!
//! **Many sources.** Suns are traced at every point. The emitting
//! surfaces and the lights with a position are the sources of a light
//! tree ([`tree`]: Conty Estevez & Kulla 2018's bounds, Yuksel 2019's
//! stochastic cuts): a point that sees more of them than its budget
//! ([`SAMPLE_SOURCES`] for a picture's sample, and beyond that its share
//! of [`PIXEL_SOURCES`], the pixel's samples drawing stratified; and
//! [`POINT_SOURCES`] for a vertex, texel or sensor) traces the sources of a cut of the tree, each
//! inner node of the cut standing for one of its sources drawn in
//! proportion to what it would send; below the budget every source is
//! traced, as before. The rays a point casts are bounded whatever the
//! number of emitters, and the estimate stays unbiased.

use std::cell::RefCell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::accel::{self, Occluder, ShadowCache};
use crate::export::lightmap::texels::Locator;
use crate::form_factor;
use crate::geometry;
use crate::mesh::{self, Mesh};
use crate::scene::{LightKind, Scene, glass};
use crate::solver::{Receiver, Solver, lights, surface_receivers};

pub mod tree;

use self::tree::{Bounds, LightTree, Pick};

crate::choice::named_choice! {
    /// What pictures, lightmap texels and sensors show (`--final-gather`).
    pub enum FinalGather: "final gather" {
        /// The mesh's values (the paper's display).
        Off = "off",
        /// Direct light at the point shown, the mesh's indirect part.
        Direct = "direct",
        /// Direct light at the point shown, the mesh's reflected light
        /// gathered over its hemisphere.
        Full = "full",
    }
}

/// Rays per side of the stratified grid over an emitting surface for a
/// point that casts all its rays at once (a vertex, a texel, a sensor).
pub const EMITTER_SIDE: u32 = 4;

/// Hemisphere rays of a `full` gather at a sensor or texel: at least
/// [`GATHER_MIN_RAYS`], then rounds of that many until the standard error
/// of the gathered irradiance is below [`GATHER_ERROR`] of the point's
/// total, at most this many.
pub const GATHER_MAX_RAYS: u32 = 1024;

/// The first round of a `full` gather's rays, and each further round.
pub const GATHER_MIN_RAYS: u32 = 64;

/// The relative standard error a `full` gather stops at.
pub const GATHER_ERROR: f64 = 0.01;

/// Rays a picture's pixel gathers over its samples in `full`.
pub const PIXEL_GATHER_RAYS: u32 = 64;

/// Points at `receivers` (sensors), every ray at once, seeded by their
/// order.
#[must_use]
pub fn points_at(receivers: &[Receiver]) -> Vec<Point> {
    receivers
        .iter()
        .enumerate()
        .map(|(i, r)| Point {
            surface: r.surface,
            position: r.point,
            sample: None,
            seed: i as u64,
        })
        .collect()
}

/// A point to shade.
#[derive(Clone, Copy, Debug)]
pub struct Point {
    /// The surface it lies on.
    pub surface: u32,
    /// Where.
    pub position: DVec3,
    /// `Some((k, n))` for one sample of `n` (a pixel's `k`-th):
    /// [`SAMPLE_SPLIT`]` x `[`SAMPLE_SPLIT`] rays per emitting surface and
    /// `1/n` of a pixel's gather rays. `None`: every ray at once.
    pub sample: Option<(u32, u32)>,
    /// Seeds the point's random numbers (a pixel's or texel's index).
    pub seed: u64,
}

/// An emitting surface, set up for points.
struct Emitter {
    polygon: Vec<DVec3>,
    normal: DVec3,
    offset: f64,
    emission: DVec3,
    group: u32,
    /// Its pieces at 1 to [`PRESPLIT`] per side (index `side - 1`).
    pieces: Vec<Vec<Piece>>,
}

impl Emitter {
    /// Whether it can send light to `r`: another surface, `r` before its
    /// front, some of it before `r`'s.
    fn faces(&self, r: &Receiver) -> bool {
        r.group != self.group
            && self.normal.dot(r.point) - self.offset > 0.0
            && self
                .polygon
                .iter()
                .any(|c| r.normal.dot(*c - r.point) > 0.0)
    }
}

/// A source of direct light the tree chooses among.
#[derive(Clone, Copy, Debug)]
enum Source {
    /// An emitting surface (index into the emitters).
    Emitter(usize),
    /// A light with a position (index into the scene's lights).
    Light(usize),
}

/// A picture's sample traces every source (each emitting surface with
/// [`SAMPLE_SPLIT`]` x `[`SAMPLE_SPLIT`] rays, each light with one) when
/// there are no more than this many.
pub const SAMPLE_SOURCES: usize = 16;

/// Beyond [`SAMPLE_SOURCES`], the sources a picture's pixel traces in all,
/// shared among its samples (each of `n` samples traces
/// `PIXEL_SOURCES / n`, rounded up, from a cut of the light tree).
pub const PIXEL_SOURCES: usize = 64;

/// Sources a vertex, texel or sensor traces at most (each emitting surface
/// with [`EMITTER_SIDE`]` x `[`EMITTER_SIDE`] rays, each light with one).
pub const POINT_SOURCES: usize = 64;

/// The first stream of a point's random numbers that draw in the light
/// tree (below it, the emitters' pieces draw theirs).
const TREE_STREAM: u64 = 1 << 40;

/// A piece of an emitting surface.
struct Piece {
    polygon: Vec<DVec3>,
    centroid: DVec3,
    area: f64,
}

/// Grids of pieces set up beforehand per emitter: up to this many per side.
const PRESPLIT: u32 = 6;

/// A picture's sample casts `SAMPLE_SPLIT^2` rays to each emitting surface,
/// so a pixel of `s x s` samples sees it through a grid of
/// `s SAMPLE_SPLIT` pieces a side.
pub const SAMPLE_SPLIT: u32 = 2;

/// A solved scene ready to be shown point by point.
pub struct FinalPass<'a> {
    scene: &'a Scene,
    mesh: &'a Mesh,
    occluder: &'a dyn Occluder,
    mode: FinalGather,
    emitters: Vec<Emitter>,
    /// The emitting surfaces (first) and the scene's lights with a
    /// position, as the tree's sources.
    sources: Vec<Source>,
    /// The tree over `sources`, for points that see more of them than
    /// their budget.
    tree: LightTree,
    /// The scene's distant lights but skies (suns): traced at every point.
    suns: Vec<usize>,
    /// Sources a picture's pixel (beyond [`SAMPLE_SOURCES`]) and any
    /// other point trace at most.
    budgets: (usize, usize),
    /// Once raised, points are left unshaded (zero) and the pass says so.
    stop: Option<Arc<AtomicBool>>,
    /// Points shaded so far.
    shaded: AtomicU64,
    /// Whether a point was left unshaded for the stop.
    cut_short: AtomicBool,
    /// Per vertex: the irradiance that is not direct (a sky's counts as
    /// not direct here).
    indirect: Vec<DVec3>,
    /// Per vertex: the skies' irradiance, which stays with the mesh.
    sky: Vec<DVec3>,
    /// Per vertex: the reflected radiosity `rho E` (emission left out; the
    /// display's ambient term is the point's own), what a gather ray that
    /// hits it brings back.
    reflected: Vec<DVec3>,
    locator: Option<Locator>,
    reach: f64,
}

impl<'a> FinalPass<'a> {
    /// Prepares `solver`'s solution to be shown as `mode` says.
    #[must_use]
    pub fn new(solver: &'a Solver<'a>, mode: FinalGather) -> FinalPass<'a> {
        let (scene, mesh) = (solver.scene(), solver.mesh());
        let emitters = if mode == FinalGather::Off {
            Vec::new()
        } else {
            emitters(scene)
        };
        let (sources, bounds, suns) = if mode == FinalGather::Off {
            (Vec::new(), Vec::new(), Vec::new())
        } else {
            sources(scene, &emitters)
        };
        let mut pass = FinalPass {
            scene,
            mesh,
            occluder: solver.occluder(),
            mode,
            emitters,
            sources,
            tree: LightTree::new(&bounds),
            suns,
            budgets: (PIXEL_SOURCES, POINT_SOURCES),
            stop: None,
            shaded: AtomicU64::new(0),
            cut_short: AtomicBool::new(false),
            indirect: Vec::new(),
            sky: Vec::new(),
            reflected: Vec::new(),
            locator: None,
            reach: lights::sun_reach(scene),
        };
        if mode == FinalGather::Off {
            return pass;
        }
        let vertices = mesh.vertices.len();
        // Skies' light stays with the mesh's part (see
        // `Solver::sky_irradiance`).
        let direct: Vec<DVec3> = solver.direct_irradiance()[..vertices]
            .iter()
            .zip(solver.sky_irradiance())
            .map(|(direct, sky)| *direct - *sky)
            .collect();
        pass.sky = solver.sky_irradiance()[..vertices].to_vec();
        pass.indirect = if solver.direct_complete() {
            solver
                .irradiance()
                .iter()
                .zip(&direct)
                .map(|(total, direct)| *total - *direct)
                .collect()
        } else {
            // A device's failure left the emitting surfaces' part
            // incomplete: their part at each vertex is evaluated here.
            let receivers = &solver.receivers()[..vertices];
            let from_emitters = pass.direct_light(receivers, None, true);
            solver
                .irradiance()
                .iter()
                .zip(&direct)
                .zip(&from_emitters)
                .map(|((total, light), emitted)| *total - *light - *emitted)
                .collect()
        };
        if mode == FinalGather::Full {
            pass.reflected = mesh
                .vertices
                .iter()
                .zip(solver.irradiance())
                .map(|(v, e)| scene.surfaces[v.surface as usize].rho * *e)
                .collect();
            let (lo, hi) = scene.bounds();
            pass.locator = Some(Locator::new(
                mesh,
                crate::sensors::RELATIVE_TOLERANCE * (hi - lo).length(),
            ));
        }
        pass
    }

    /// The same pass with other budgets of sources traced: at most
    /// `pixel` over a picture's pixel (beyond [`SAMPLE_SOURCES`]) and
    /// `point` at any other point ([`PIXEL_SOURCES`] and [`POINT_SOURCES`]
    /// by default). A budget at least the number of sources traces every
    /// one: the brute-force oracle the light tree is measured against.
    #[must_use]
    pub fn with_budgets(mut self, pixel: usize, point: usize) -> FinalPass<'a> {
        self.budgets = (pixel.max(1), point.max(1));
        self
    }

    /// Stops the pass once `flag` is raised: the points not yet shaded are
    /// then left at zero at once, and [`FinalPass::cut_short`] says so
    /// (a run being ended writes only the outputs that were complete).
    pub fn stop_on(&mut self, flag: Arc<AtomicBool>) {
        self.stop = Some(flag);
    }

    /// Whether the stop left points unshaded: what was drawn since is
    /// incomplete.
    #[must_use]
    pub fn cut_short(&self) -> bool {
        self.cut_short.load(Ordering::Relaxed)
    }

    /// The points shaded so far (each call's points counted as they are
    /// done, for a progress display).
    #[must_use]
    pub fn shaded(&self) -> u64 {
        self.shaded.load(Ordering::Relaxed)
    }

    /// Whether the stop has been raised (and notes that a point is left
    /// unshaded for it).
    fn stopping(&self) -> bool {
        let stop = self
            .stop
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed));
        if stop {
            self.cut_short.store(true, Ordering::Relaxed);
        }
        stop
    }

    /// The emitting surfaces and lights with a position the pass chooses
    /// among (suns and skies are not counted).
    #[must_use]
    pub fn sources(&self) -> usize {
        self.sources.len()
    }

    /// The mode in force.
    #[must_use]
    pub fn mode(&self) -> FinalGather {
        self.mode
    }

    /// Per vertex, the irradiance the mesh contributes between vertices
    /// under `direct` (the total less the direct part); empty for `off`.
    #[must_use]
    pub fn vertex_indirect(&self) -> &[DVec3] {
        &self.indirect
    }

    /// The direct irradiance at each point (W/m^2 per channel): the scene's
    /// lights' (but skies', which the mesh carries: see
    /// [`Solver::sky_irradiance`]) and the emitting surfaces'. Consecutive
    /// picture samples with one seed are one pixel's, shaded together (the
    /// renderer gives a pixel's samples in a row).
    #[must_use]
    pub fn direct(&self, points: &[Point]) -> Vec<DVec3> {
        let receivers = self.receivers(points);
        self.direct_light(&receivers, Some(points), false)
    }

    /// The indirect irradiance at each point gathered over its hemisphere
    /// from the mesh's reflected radiosity (`full`; zero otherwise). A
    /// point with every ray at once takes rounds of [`GATHER_MIN_RAYS`]
    /// until its standard error is below [`GATHER_ERROR`] of `total_hint`
    /// plus the gathered irradiance, at most [`GATHER_MAX_RAYS`].
    #[must_use]
    pub fn gather(&self, points: &[Point], total_hint: &[DVec3]) -> Vec<DVec3> {
        let Some(locator) = &self.locator else {
            return vec![DVec3::ZERO; points.len()];
        };
        points
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                let hint = total_hint.get(i).copied().unwrap_or_default();
                self.gather_one(locator, p, hint)
            })
            .collect()
    }

    fn gather_one(&self, locator: &Locator, point: &Point, hint: DVec3) -> DVec3 {
        if self.stopping() {
            return DVec3::ZERO;
        }
        let surface = &self.scene.surfaces[point.surface as usize];
        let normal = surface.normal;
        let origin = point.position;
        let (tangent, bitangent) = basis(normal);
        let shift = [unit(point.seed, 0), unit(point.seed, 1)];
        let one = |index: u32, count: u32| -> DVec3 {
            // A rank-1 lattice (Fibonacci-like, the R2 sequence) of
            // `count` points, shifted per point: stratified for any count.
            let i = f64::from(index);
            let u = (shift[0] + i * 0.754_877_666_246_692_7 + 0.5 / f64::from(count)).fract();
            let v = (shift[1] + i * 0.569_840_290_998_053_3).fract();
            let r = u.sqrt();
            let phi = std::f64::consts::TAU * v;
            let local = DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).max(0.0).sqrt());
            let direction = tangent * local.x + bitangent * local.y + normal * local.z;
            self.trace(locator, origin, direction, surface.group)
        };
        match point.sample {
            Some((k, n)) => {
                let per = PIXEL_GATHER_RAYS.div_ceil(n.max(1));
                let total = per * n.max(1);
                (0..per).map(|j| one(k * per + j, total)).sum::<DVec3>() / f64::from(per)
            }
            None => {
                let mut sum = DVec3::ZERO;
                let mut square = 0.0;
                let mut count = 0u32;
                while count < GATHER_MAX_RAYS {
                    for j in 0..GATHER_MIN_RAYS {
                        let e = one(count + j, GATHER_MAX_RAYS);
                        sum += e;
                        square += crate::luminance(e).powi(2);
                    }
                    count += GATHER_MIN_RAYS;
                    let n = f64::from(count);
                    let mean = crate::luminance(sum) / n;
                    let variance = (square / n - mean * mean).max(0.0);
                    let error = (variance / n).sqrt();
                    if error <= GATHER_ERROR * (crate::luminance(hint) + mean) {
                        break;
                    }
                }
                sum / f64::from(count)
            }
        }
    }

    /// The reflected radiosity a gather ray brings back: the mesh's value
    /// where it first hits a surface's front, zero at a back or the sky.
    fn trace(&self, locator: &Locator, origin: DVec3, direction: DVec3, group: u32) -> DVec3 {
        let Some(hit) = self
            .occluder
            .closest_hit(origin, direction, self.reach, [group, u32::MAX])
        else {
            return DVec3::ZERO;
        };
        let surface = &self.scene.surfaces[hit.surface as usize];
        if surface.normal.dot(direction) >= 0.0 {
            return DVec3::ZERO;
        }
        let q = origin + direction * hit.t;
        let q = q - surface.normal * (surface.normal.dot(q) - surface.offset);
        let value = locator
            .locate(q, surface.normal)
            .map_or(DVec3::ZERO, |(v, w)| {
                v.iter()
                    .zip(w)
                    .map(|(v, w)| self.reflected[*v as usize] * w)
                    .sum()
            });
        if self.scene.panes.is_empty() {
            value
        } else {
            value * glass::transmittance(&self.scene.panes, origin, q)
        }
    }

    fn receivers(&self, points: &[Point]) -> Vec<Receiver> {
        surface_receivers(
            self.scene,
            points.iter().map(|p| {
                let s = &self.scene.surfaces[p.surface as usize];
                // Onto the surface's plane: a point read from a picture's
                // depth buffer or a texel is only near it.
                let q = p.position - s.normal * (s.normal.dot(p.position) - s.offset);
                (p.surface, q)
            }),
        )
    }

    /// The direct irradiance at each receiver from the emitting surfaces
    /// and the lights (but skies; with `emitters_only`, the emitting
    /// surfaces alone); `points` says which sample each one is (all rays
    /// at once when `None`). A point that sees no more sources than its
    /// budget ([`SAMPLE_SOURCES`] for a picture's sample, its share of
    /// [`PIXEL_SOURCES`] beyond; [`POINT_SOURCES`] otherwise) traces every
    /// one; beyond, it traces
    /// the sources of a cut of the light tree ([`tree`]), each drawn
    /// source's light divided by the probability of its draw: unbiased,
    /// with rays bounded whatever the number of emitters.
    fn direct_light(
        &self,
        receivers: &[Receiver],
        points: Option<&[Point]>,
        emitters_only: bool,
    ) -> Vec<DVec3> {
        if self.sources.is_empty() && self.suns.is_empty() {
            self.shaded
                .fetch_add(receivers.len() as u64, Ordering::Relaxed);
            return vec![DVec3::ZERO; receivers.len()];
        }
        if let Some(points) = points
            && self.sources.len() <= SAMPLE_SOURCES
            && points.iter().any(|p| p.sample.is_some_and(|(_, n)| n > 1))
        {
            return self.pixels_light(receivers, points, emitters_only);
        }
        // Points are counted a batch at a time (a shared counter touched at
        // every point slows the pass by half), the rest once all are done.
        const COUNTED: u64 = 1024;
        let counted = AtomicU64::new(0);
        let light: Vec<DVec3> = receivers
            .par_iter()
            .enumerate()
            .map_init(
                || (RefCell::new(ShadowCache::default()), Vec::new(), 0u64),
                |(cache, picks, count), (i, r)| {
                    if self.stopping() {
                        return DVec3::ZERO;
                    }
                    *count += 1;
                    if *count == COUNTED {
                        *count = 0;
                        self.shaded.fetch_add(COUNTED, Ordering::Relaxed);
                        counted.fetch_add(COUNTED, Ordering::Relaxed);
                    }
                    let sample = points.and_then(|p| p[i].sample);
                    let seed = points.map_or(i as u64, |p| p[i].seed);
                    let mut sum = DVec3::ZERO;
                    if !emitters_only {
                        for &sun in &self.suns {
                            cache.borrow_mut().from_origin(u32::MAX);
                            sum += lights::direct_at(
                                &self.scene.lights[sun],
                                r,
                                self.scene,
                                self.occluder,
                                self.reach,
                                &mut cache.borrow_mut(),
                            );
                        }
                    }
                    let budget = match sample {
                        Some((_, n)) => {
                            let share = self.budgets.0.div_ceil(n.max(1) as usize);
                            if self.sources.len() <= SAMPLE_SOURCES {
                                SAMPLE_SOURCES
                            } else {
                                share
                            }
                        }
                        None => self.budgets.1,
                    };
                    let wanted = |k: u32| {
                        !emitters_only || matches!(self.sources[k as usize], Source::Emitter(_))
                    };
                    if self.sources.len() <= budget {
                        for k in 0..self.sources.len() as u32 {
                            if wanted(k) {
                                sum += self.source_light(k, r, sample, seed, cache);
                            }
                        }
                        return sum;
                    }
                    let importance = |k: u32| {
                        if wanted(k) {
                            self.source_importance(k, r)
                        } else {
                            0.0
                        }
                    };
                    // One uniform number a node of the cut; a pixel's
                    // samples take them stratified.
                    let draw = |j: usize| match sample {
                        Some((k, n)) => {
                            (f64::from(k) + unit(seed, TREE_STREAM + j as u64))
                                / f64::from(n.max(1))
                        }
                        None => unit(seed, TREE_STREAM + j as u64),
                    };
                    self.tree
                        .cut(r.point, r.normal, budget, &importance, &draw, picks);
                    for (j, pick) in picks.iter().enumerate() {
                        let light = match sample {
                            // A drawn source at a picture's sample: one
                            // ray, the pixel's samples drawing many.
                            Some((k, _)) => {
                                let stream =
                                    TREE_STREAM + (1 << 20) + u64::from(k) * 4096 + j as u64 * 2;
                                self.source_light_once(pick, r, seed, stream, cache)
                            }
                            None => self.source_light(pick.source, r, sample, seed, cache),
                        };
                        sum += light * pick.weight;
                    }
                    sum
                },
            )
            .collect();
        self.shaded.fetch_add(
            receivers.len() as u64 - counted.load(Ordering::Relaxed),
            Ordering::Relaxed,
        );
        light
    }

    /// [`FinalPass::direct_light`] of picture samples when every source is
    /// traced, a pixel's samples together (consecutive points with one
    /// seed): each emitting surface is first probed with one ray a sample,
    /// the pixel's samples taking the cells of an `s x s` grid over it; if
    /// every probe of the pixel lets the same through (the surface wholly
    /// in view, or wholly hidden), each sample takes the surface's exact
    /// factor times that (no noise); otherwise (a penumbra) each sample
    /// takes its [`SAMPLE_SPLIT`]` x `[`SAMPLE_SPLIT`] rays as alone. Most
    /// pixels cost one ray a sample, those in penumbrae five. A surface
    /// partly hidden from a pixel by something that no probe meets is
    /// taken as wholly in view: the probes are a grid of `s^2` cells over
    /// it, a point drawn in each.
    fn pixels_light(
        &self,
        receivers: &[Receiver],
        points: &[Point],
        emitters_only: bool,
    ) -> Vec<DVec3> {
        let mut starts = vec![0];
        for i in 1..points.len() {
            if points[i].seed != points[i - 1].seed {
                starts.push(i);
            }
        }
        starts.push(points.len());
        let light: Vec<Vec<DVec3>> = starts
            .par_windows(2)
            .map_init(
                || RefCell::new(ShadowCache::default()),
                |cache, range| {
                    let (rs, ps) = (&receivers[range[0]..range[1]], &points[range[0]..range[1]]);
                    let mut out = vec![DVec3::ZERO; rs.len()];
                    if self.stopping() {
                        return out;
                    }
                    for (o, r) in out.iter_mut().zip(rs) {
                        for &sun in self.suns.iter().filter(|_| !emitters_only) {
                            cache.borrow_mut().from_origin(u32::MAX);
                            *o += lights::direct_at(
                                &self.scene.lights[sun],
                                r,
                                self.scene,
                                self.occluder,
                                self.reach,
                                &mut cache.borrow_mut(),
                            );
                        }
                    }
                    let mut probes = Vec::with_capacity(rs.len());
                    for k in 0..self.sources.len() as u32 {
                        let Source::Emitter(e) = self.sources[k as usize] else {
                            if !emitters_only {
                                for ((o, r), p) in out.iter_mut().zip(rs).zip(ps) {
                                    *o += self.source_light(k, r, p.sample, p.seed, cache);
                                }
                            }
                            continue;
                        };
                        let e = &self.emitters[e];
                        probes.clear();
                        let mut seen = Seen::Nothing;
                        for (r, p) in rs.iter().zip(ps) {
                            cache.borrow_mut().from_origin(k);
                            let probe = self.emitter_light_split(e, r, p.sample, p.seed, cache, 1);
                            seen = seen.join(probe.1);
                            probes.push(probe.2);
                        }
                        // A lone sample's probe says nothing of the rest
                        // of the surface: it takes its own rays.
                        if rs.len() < 2 && seen != Seen::Nothing {
                            seen = Seen::Mixed;
                        }
                        match seen {
                            Seen::Nothing => {}
                            // Wholly in view (or hidden, or behind the
                            // same glass): the exact factor at each sample
                            // times what passes.
                            Seen::All(passed) => {
                                for (o, whole) in out.iter_mut().zip(&probes) {
                                    *o += e.emission * passed * *whole;
                                }
                            }
                            Seen::Mixed => {
                                for ((o, r), p) in out.iter_mut().zip(rs).zip(ps) {
                                    cache.borrow_mut().from_origin(k);
                                    *o += self.emitter_light(e, r, p.sample, p.seed, cache);
                                }
                            }
                        }
                    }
                    out
                },
            )
            .collect();
        self.shaded
            .fetch_add(receivers.len() as u64, Ordering::Relaxed);
        light.into_iter().flatten().collect()
    }

    /// What source `k` sends to `r` (its shadow rays through `cache`).
    fn source_light(
        &self,
        k: u32,
        r: &Receiver,
        sample: Option<(u32, u32)>,
        seed: u64,
        cache: &RefCell<ShadowCache>,
    ) -> DVec3 {
        cache.borrow_mut().from_origin(k);
        match self.sources[k as usize] {
            Source::Emitter(e) => self.emitter_light(&self.emitters[e], r, sample, seed, cache),
            Source::Light(l) => lights::direct_at(
                &self.scene.lights[l],
                r,
                self.scene,
                self.occluder,
                self.reach,
                &mut cache.borrow_mut(),
            ),
        }
    }

    /// What the drawn source sends to `r` estimated with one shadow ray: a light
    /// as [`FinalPass::source_light`]; an emitting surface's exact factor
    /// (clipped to `r`'s front) times what passes from one point of it
    /// drawn uniformly by area (with the random numbers of `stream` and
    /// the next), an unbiased estimate of its light.
    fn source_light_once(
        &self,
        pick: &Pick,
        r: &Receiver,
        seed: u64,
        stream: u64,
        cache: &RefCell<ShadowCache>,
    ) -> DVec3 {
        let k = pick.source;
        let Source::Emitter(e) = self.sources[k as usize] else {
            return self.source_light(k, r, None, seed, cache);
        };
        cache.borrow_mut().from_origin(k);
        let e = &self.emitters[e];
        // The importance was the exact factor times the exitance's
        // luminance ([`FinalPass::source_importance`]).
        let whole = pick.importance / crate::luminance(e.emission);
        if whole.is_nan() || whole <= 0.0 {
            return DVec3::ZERO;
        }
        let pieces = &e.pieces[0];
        let (u, v) = (unit(seed, stream), unit(seed, stream + 1));
        // A triangle of the polygon by area, then a point in it.
        let total: f64 = pieces.iter().map(|p| p.area).sum();
        let mut pick = u * total;
        let mut chosen = &pieces[pieces.len() - 1];
        let mut rest = u;
        for piece in pieces {
            if pick < piece.area {
                chosen = piece;
                rest = pick / piece.area;
                break;
            }
            pick -= piece.area;
        }
        let at = point_in(&chosen.polygon, rest.clamp(0.0, 1.0 - f64::EPSILON), v);
        if r.normal.dot(at - r.point) <= 0.0 {
            // Behind the receiver's tangent plane, where the clipped factor
            // counts none of it: seen from the front part's centroid.
            let front = clip_front(&e.polygon, r);
            if front.len() < 3 {
                return DVec3::ZERO;
            }
            return e.emission * whole * self.passed(e, r, geometry::centroid(&front), cache);
        }
        e.emission * whole * self.passed(e, r, at, cache)
    }

    /// What passes from `at` (a point of emitter `e`) to `r`: 0 where a
    /// surface blocks, else the glass's transmittance.
    fn passed(&self, e: &Emitter, r: &Receiver, at: DVec3, cache: &RefCell<ShadowCache>) -> DVec3 {
        let (a, b) = accel::shorten(at, r.point);
        if self
            .occluder
            .occluded_cached(a, b, [e.group, r.group], &mut cache.borrow_mut())
        {
            DVec3::ZERO
        } else if self.scene.panes.is_empty() {
            DVec3::ONE
        } else {
            glass::transmittance(&self.scene.panes, at, r.point)
        }
    }

    /// Source `k`'s importance at `r` for the light tree: what it would
    /// send if nothing were in the way, in luminance (an emitting
    /// surface's exact factor times its exitance).
    fn source_importance(&self, k: u32, r: &Receiver) -> f64 {
        match self.sources[k as usize] {
            Source::Emitter(e) => {
                let e = &self.emitters[e];
                if !e.faces(r) {
                    return 0.0;
                }
                crate::luminance(e.emission) * form_factor::analytic(r.point, r.normal, &e.polygon)
            }
            Source::Light(l) => crate::luminance(
                self.scene.lights[l]
                    .irradiance(r.point, r.normal, self.reach)
                    .0,
            ),
        }
    }

    fn emitter_light(
        &self,
        e: &Emitter,
        r: &Receiver,
        sample: Option<(u32, u32)>,
        seed: u64,
        cache: &RefCell<ShadowCache>,
    ) -> DVec3 {
        self.emitter_light_split(e, r, sample, seed, cache, SAMPLE_SPLIT)
            .0
    }

    /// [`FinalPass::emitter_light`] with `split^2` rays a picture's sample,
    /// what its rays saw, and the surface's exact factor at the sample
    /// (0 where none was taken).
    fn emitter_light_split(
        &self,
        e: &Emitter,
        r: &Receiver,
        sample: Option<(u32, u32)>,
        seed: u64,
        cache: &RefCell<ShadowCache>,
        split: u32,
    ) -> (DVec3, Seen, f64) {
        if !e.faces(r) {
            return (DVec3::ZERO, Seen::Nothing, 0.0);
        }
        let whole_taken = std::cell::Cell::new(0.0);
        let seen = std::cell::Cell::new(Seen::Nothing);
        // What passes from `at` (a point of `piece`, or its centroid when
        // `None`): a piece crossing the receiver's tangent plane is seen
        // from its clipped part's centroid when `at` lies behind.
        let seen_from = |piece: &[DVec3], at: Option<DVec3>| -> DVec3 {
            let front = |c: DVec3| r.normal.dot(c - r.point) > 0.0;
            let c = match at {
                Some(c) if front(c) => c,
                _ if piece.iter().all(|c| front(*c)) => geometry::centroid(piece),
                _ => {
                    let mut clipped = Vec::with_capacity(piece.len() + 2);
                    geometry::clip_to_half_space(piece, r.point, r.normal, 0.0, &mut clipped);
                    if clipped.len() < 3 {
                        return DVec3::ZERO;
                    }
                    geometry::centroid(&clipped)
                }
            };
            let (a, b) = accel::shorten(c, r.point);
            let blocked =
                self.occluder
                    .occluded_cached(a, b, [e.group, r.group], &mut cache.borrow_mut());
            let passed = if blocked {
                DVec3::ZERO
            } else if self.scene.panes.is_empty() {
                DVec3::ONE
            } else {
                glass::transmittance(&self.scene.panes, c, r.point)
            };
            seen.set(seen.get().and(passed));
            passed
        };
        // A piece's exact factor (equation (2), clipped to the receiver's
        // front) times what passes from its centroid.
        let through = |piece: &[DVec3]| -> DVec3 {
            let factor = form_factor::analytic(r.point, r.normal, piece);
            if factor <= 0.0 {
                return DVec3::ZERO;
            }
            seen_from(piece, None) * factor
        };
        let passed = match sample {
            // One piece of an `s x s` grid (`s^2 >= n`) a sample, the
            // pixel's samples taking them in turn from a place of the
            // pixel's own, seen from a point drawn uniformly in it.
            Some((k, n)) => {
                let side = (f64::from(n.max(1)).sqrt().ceil() as u32).max(1) * split;
                let own;
                let pieces = match e.pieces.get(side as usize - 1) {
                    Some(pieces) => pieces,
                    None => {
                        own = pieces(&e.polygon, side);
                        &own
                    }
                };
                let count = pieces.len() as u64;
                if count == 0 {
                    return (DVec3::ZERO, Seen::Nothing, 0.0);
                }
                // `SAMPLE_SPLIT^2` pieces a sample, `n` apart: the pixel's
                // samples take every piece of the grid once (when there are
                // no more than that: a triangle or a quad), from a place of
                // the pixel's own. Each piece's share of the surface's
                // exact factor is its point factor's share of theirs (the
                // surface's factor is then exact where nothing blocks; one
                // exact factor a sample, not one a piece).
                let whole = form_factor::analytic(r.point, r.normal, &e.polygon);
                if whole <= 0.0 {
                    return (DVec3::ZERO, Seen::Nothing, 0.0);
                }
                whole_taken.set(whole);
                let weight = |piece: &Piece| {
                    let d = piece.centroid - r.point;
                    let d2 = d.length_squared();
                    let cosines = (r.normal.dot(d) * -e.normal.dot(d)).max(0.0);
                    piece.area * cosines / (d2 * d2)
                };
                let total: f64 = pieces.iter().map(&weight).sum();
                if total <= 0.0 {
                    return (DVec3::ZERO, Seen::Nothing, 0.0);
                }
                let rays = u64::from(split * split);
                let mut sum = DVec3::ZERO;
                for j in 0..rays {
                    let index = (u64::from(k) + j * u64::from(n) + seed % count) % count;
                    let piece = &pieces[index as usize];
                    let share = weight(piece) / total;
                    if share <= 0.0 {
                        continue;
                    }
                    let stream = (u64::from(k) * rays + j) * 2 + 2;
                    let at = point_in(&piece.polygon, unit(seed, stream), unit(seed, stream + 1));
                    sum += seen_from(&piece.polygon, Some(at)) * share;
                }
                // Each piece drawn stands for `count / rays` of them.
                sum * (whole * count as f64 / rays as f64)
            }
            None => e.pieces[EMITTER_SIDE as usize - 1]
                .iter()
                .map(|piece| through(&piece.polygon))
                .sum(),
        };
        (e.emission * passed, seen.get(), whole_taken.get())
    }
}

/// What the shadow rays of one estimate saw.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Seen {
    /// No ray was cast (nothing of the source in front).
    Nothing,
    /// Every ray let the same through.
    All(DVec3),
    /// Rays let different amounts through: a penumbra.
    Mixed,
}

impl Seen {
    /// Both: one ray's `passed` after these.
    fn and(self, passed: DVec3) -> Seen {
        match self {
            Seen::Nothing => Seen::All(passed),
            Seen::All(v) if v == passed => self,
            _ => Seen::Mixed,
        }
    }

    /// Both estimates' rays together.
    fn join(self, other: Seen) -> Seen {
        match (self, other) {
            (Seen::Nothing, x) | (x, Seen::Nothing) => x,
            (Seen::All(a), Seen::All(b)) if a == b => self,
            _ => Seen::Mixed,
        }
    }
}

/// The scene's emitting surfaces.
fn emitters(scene: &Scene) -> Vec<Emitter> {
    scene
        .surfaces
        .iter()
        .filter(|s| s.is_emitter())
        .map(|s| Emitter {
            polygon: s.polygon.clone(),
            normal: s.normal,
            offset: s.offset,
            emission: s.emission,
            group: s.group,
            pieces: (1..=PRESPLIT.max(EMITTER_SIDE))
                .map(|side| pieces(&s.polygon, side))
                .collect(),
        })
        .collect()
}

/// The tree's sources: the emitting surfaces, then the lights with a
/// position, with their bounds; and the suns (traced at every point).
fn sources(scene: &Scene, emitters: &[Emitter]) -> (Vec<Source>, Vec<Bounds>, Vec<usize>) {
    let mut sources = Vec::new();
    let mut bounds = Vec::new();
    let mut suns = Vec::new();
    for (i, e) in emitters.iter().enumerate() {
        let (lo, hi) = e
            .polygon
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), c| {
                (lo.min(*c), hi.max(*c))
            });
        let area = geometry::area(&e.polygon);
        sources.push(Source::Emitter(i));
        bounds.push(Bounds {
            lo,
            hi,
            power: crate::luminance(e.emission) * area / std::f64::consts::PI,
            axis: e.normal,
            theta_o: 0.0,
            theta_e: std::f64::consts::FRAC_PI_2,
        });
    }
    for (i, light) in scene.lights.iter().enumerate() {
        let (power, axis, theta_o, theta_e) = match &light.kind {
            LightKind::Sky { .. } => continue,
            LightKind::Sun { .. } => {
                suns.push(i);
                continue;
            }
            LightKind::Point { .. } => (
                crate::luminance(light.radiometric()),
                DVec3::Y,
                std::f64::consts::PI,
                std::f64::consts::FRAC_PI_2,
            ),
            LightKind::Spot {
                direction, outer, ..
            } => (
                crate::luminance(light.radiometric()),
                *direction,
                *outer,
                0.0,
            ),
            LightKind::Luminaire { .. } => (
                light
                    .flux()
                    .map_or(0.0, |f| crate::luminance(f) / (4.0 * std::f64::consts::PI)),
                DVec3::Y,
                std::f64::consts::PI,
                std::f64::consts::FRAC_PI_2,
            ),
        };
        let Some(position) = light.position() else {
            continue;
        };
        sources.push(Source::Light(i));
        bounds.push(Bounds {
            lo: position,
            hi: position,
            power,
            axis,
            theta_o,
            theta_e,
        });
    }
    (sources, bounds, suns)
}

/// `polygon` in pieces: a triangle's or quad's `side x side` subsources
/// (the paper's), a larger polygon's triangles' each.
fn pieces(polygon: &[DVec3], side: u32) -> Vec<Piece> {
    let split = |p: &[DVec3]| -> Vec<Piece> {
        mesh::subsources(p, side)
            .into_iter()
            .map(|k| Piece {
                polygon: k.polygon,
                centroid: k.centroid,
                area: k.area,
            })
            .collect()
    };
    if polygon.len() <= 4 {
        return split(polygon);
    }
    let Some(normal) = geometry::normal(polygon) else {
        return Vec::new();
    };
    let u = (polygon[1] - polygon[0]).normalize_or_zero();
    let v = normal.cross(u);
    let flat: Vec<glam::DVec2> = polygon
        .iter()
        .map(|p| glam::DVec2::new((*p - polygon[0]).dot(u), (*p - polygon[0]).dot(v)))
        .collect();
    let triangles = geometry::triangulate::triangulate(&flat)
        .unwrap_or_else(|| (1..polygon.len() - 1).map(|i| [0, i, i + 1]).collect());
    triangles
        .iter()
        .flat_map(|t| split(&t.map(|i| polygon[i])))
        .collect()
}

/// The part of `polygon` before `r`'s tangent plane.
fn clip_front(polygon: &[DVec3], r: &Receiver) -> Vec<DVec3> {
    let mut clipped = Vec::with_capacity(polygon.len() + 2);
    geometry::clip_to_half_space(polygon, r.point, r.normal, 0.0, &mut clipped);
    clipped
}

/// The point at `(u, v)` in `[0, 1)^2` of a triangle (uniform by area) or
/// a quad (bilinear: uniform by area on a parallelogram).
fn point_in(piece: &[DVec3], u: f64, v: f64) -> DVec3 {
    if piece.len() == 4 {
        let bottom = piece[0].lerp(piece[1], u);
        let top = piece[3].lerp(piece[2], u);
        bottom.lerp(top, v)
    } else {
        let r = u.sqrt();
        piece[0] * (1.0 - r) + piece[1] * (r * (1.0 - v)) + piece[2] * (r * v)
    }
}

/// Two unit vectors completing `n` to an orthonormal basis.
fn basis(n: DVec3) -> (DVec3, DVec3) {
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = n.cross(helper).normalize();
    (t, n.cross(t))
}

/// A uniform number in `[0, 1)` from `seed` and a stream index
/// (SplitMix64).
fn unit(seed: u64, stream: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(stream.wrapping_mul(0xD1B5_4A32_D192_ED03));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

impl FinalPass<'_> {
    /// What the mesh shows at each vertex under this mode, given what it
    /// shows with every part (`display`, `B + rho ambient`): all of it for
    /// `off`; the emission, the reflected indirect part (skies' light
    /// included) and the ambient for `direct`; the emission, the skies'
    /// reflected light and the ambient for `full`.
    #[must_use]
    pub fn vertex_display(&self, display: &[DVec3], ambient: DVec3) -> Vec<DVec3> {
        self.vertex_part(ambient)
            .into_iter()
            .zip(&self.mesh.vertices)
            .zip(display)
            .map(|((part, v), shown)| match part {
                Some(e) => {
                    let s = &self.scene.surfaces[v.surface as usize];
                    s.emission + s.rho * e
                }
                None => *shown,
            })
            .collect()
    }

    /// The irradiance the mesh carries at each vertex under this mode,
    /// given the vertices' whole irradiance with the ambient (`None`: the
    /// whole, for `off`).
    #[must_use]
    pub fn vertex_part(&self, ambient: DVec3) -> Vec<Option<DVec3>> {
        match self.mode {
            FinalGather::Off => vec![None; self.mesh.vertices.len()],
            FinalGather::Direct => self.indirect.iter().map(|e| Some(*e + ambient)).collect(),
            FinalGather::Full => self.sky.iter().map(|s| Some(*s + ambient)).collect(),
        }
    }

    /// The irradiance evaluated at each point (W/m^2 per channel), what
    /// is added to the mesh's part ([`FinalPass::vertex_part`]): the direct
    /// light, and for `full` the gathered indirect light; zero for `off`.
    #[must_use]
    pub fn irradiance(&self, points: &[Point]) -> Vec<DVec3> {
        if self.mode == FinalGather::Off {
            return vec![DVec3::ZERO; points.len()];
        }
        let direct = self.direct(points);
        let gathered = self.gather(points, &direct);
        direct
            .into_iter()
            .zip(gathered)
            .map(|(d, g)| d + g)
            .collect()
    }

    /// The irradiance at `solver`'s sensors under this mode: `full`'s
    /// ([`FinalPass::irradiance`] plus the skies' part each gathered in the
    /// solve); the sensors' own for `off` and `direct` (each gathers every
    /// shot at its point, the direct light included).
    #[must_use]
    pub fn sensors(&self, solver: &Solver<'_>) -> Vec<DVec3> {
        if self.mode != FinalGather::Full {
            return solver.sensor_irradiance().to_vec();
        }
        let vertices = self.mesh.vertices.len();
        self.irradiance(&points_at(&solver.receivers()[vertices..]))
            .into_iter()
            .zip(&solver.sky_irradiance()[vertices..])
            .map(|(e, sky)| e + *sky)
            .collect()
    }

    /// The radiosity [`FinalPass::irradiance`] adds at each point: times
    /// its surface's reflectance.
    #[must_use]
    pub fn shade(&self, points: &[Point]) -> Vec<DVec3> {
        self.irradiance(points)
            .into_iter()
            .zip(points)
            .map(|(e, p)| self.scene.surfaces[p.surface as usize].rho * e)
            .collect()
    }
}
