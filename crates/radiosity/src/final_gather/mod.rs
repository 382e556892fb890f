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
//! [`crate::form_factor::analytic()`], clipped to the receiver's front) is its
//! point factor's share of theirs, so a pixel sums the whole factor and a
//! penumbra is smooth noise, not copies of a shadow. A pixel's samples are
//! shaded together, in groups of pixels along a row. First a shaft
//! (Haines & Wallace 1991, [`crate::accel::shaft`]) from the ball holding
//! the group's samples, then each pixel's, to the surface: where no other
//! surface meets it, nothing can block any of their rays and none is cast.
//! Otherwise each sample probes the surface with one ray; where every probe
//! lets the same through (wholly hidden, or behind the same glass), that
//! is what passes, and only where they disagree (a penumbra) do the
//! samples cast their rays. Where nothing blocks, the exact factor
//! stands, with no noise: one for the pixel, at its samples' centroid,
//! where they lie on one surface close together beside their distance to
//! the emitter ([`PIXEL_SHARE`]; the pixel's mean is then exact
//! to the second order of their spread), else one a sample. A vertex,
//! texel or sensor casts [`EMITTER_SIDE`]` x `[`EMITTER_SIDE`] rays, one to each
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

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::accel::Occluder;
use crate::mesh::locator::{Locator, RELATIVE_TOLERANCE};

use crate::mesh::Mesh;
use crate::scene::{Scene, glass};
use crate::solver::{Receiver, Solver, lights, surface_receivers};

mod direct;
mod pixel;
pub mod tree;

use self::direct::{Emitter, Source, emitters, sources};
pub use self::pixel::PIXEL_SHARE;
use self::tree::LightTree;

use crate::solver::Preset;

crate::choice::named_choice! {
    /// What pictures, lightmap texels and sensors show (`--final-gather`):
    /// a setting of the job, not of the solve, whose results it only reads.
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

impl FinalGather {
    /// What `preset` shows when `--final-gather` is not given: the paper's
    /// presets their mesh's values (`off`, their figures as the paper drew
    /// them), the default the direct light at each point (`direct`).
    #[must_use]
    pub fn of_preset(preset: Preset) -> FinalGather {
        match preset {
            Preset::Adaptive => FinalGather::Direct,
            Preset::WongTsang93 | Preset::Wallace89 => FinalGather::Off,
        }
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
            pass.locator = Some(Locator::new(mesh, RELATIVE_TOLERANCE * (hi - lo).length()));
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
