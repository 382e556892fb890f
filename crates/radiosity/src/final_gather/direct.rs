//! The final pass's direct light at a point: the emitting surfaces in
//! pieces (the paper's subsources) and the lights with a position, every
//! one traced or, beyond a point's budget, a cut of the light tree
//! ([`super::tree`]: Conty Estevez & Kulla 2018, Yuksel 2019), each
//! surface's light as the exact factor times what passes along shadow
//! rays to points of its pieces (Wallace, Elmquist & Haines 1989's
//! ray-traced final display). A picture's pixel shading its samples
//! together is `super::pixel`'s.

use std::borrow::Cow;
use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::tree::{Bounds, Pick};
use super::{EMITTER_SIDE, FinalPass, Point, SAMPLE_SOURCES, SAMPLE_SPLIT, unit};
use crate::accel::{self, ShadowCache};
use crate::form_factor;
use crate::geometry;
use crate::mesh;
use crate::scene::light::AtPoints;
use crate::scene::{Scene, glass};
use crate::solver::{Receiver, lights};

/// An emitting surface, set up for points.
pub(super) struct Emitter {
    pub(super) polygon: Vec<DVec3>,
    pub(super) normal: DVec3,
    pub(super) offset: f64,
    pub(super) emission: DVec3,
    pub(super) group: u32,
    /// The centre and radius of a sphere holding it.
    pub(super) centre: DVec3,
    pub(super) radius: f64,
    /// Its pieces at 1 to [`PRESPLIT`] per side (index `side - 1`).
    pieces: Vec<Vec<Piece>>,
}

impl Emitter {
    /// Its pieces at `side` per side: set up beforehand up to
    /// [`PRESPLIT`], made here beyond.
    pub(super) fn grid(&self, side: u32) -> Cow<'_, [Piece]> {
        match self.pieces.get(side as usize - 1) {
            Some(pieces) => Cow::Borrowed(pieces),
            None => Cow::Owned(pieces(&self.polygon, side)),
        }
    }

    /// The exact factor (equation (2), [`form_factor::analytic::analytic_facing_fast`])
    /// from a point (normal `normal`) to `polygon`, the emitter or a
    /// piece of it, clipped to the point's front.
    pub(super) fn factor(&self, point: DVec3, normal: DVec3, polygon: &[DVec3]) -> f64 {
        form_factor::analytic::analytic_facing_fast(point, normal, polygon, self.normal)
    }

    /// Whether it can send light to `r`: another surface, `r` before its
    /// front, some of it before `r`'s.
    pub(super) fn faces(&self, r: &Receiver) -> bool {
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
pub(super) enum Source {
    /// An emitting surface (index into the emitters).
    Emitter(usize),
    /// A light with a position (index into the scene's lights).
    Light(usize),
}

/// The first stream of a point's random numbers that draw in the light
/// tree (below it, the emitters' pieces draw theirs).
const TREE_STREAM: u64 = 1 << 40;

/// A piece of an emitting surface.
#[derive(Clone)]
pub(super) struct Piece {
    pub(super) polygon: Vec<DVec3>,
    centroid: DVec3,
    area: f64,
}

/// Grids of pieces set up beforehand per emitter: up to this many per side.
const PRESPLIT: u32 = 6;

impl FinalPass<'_> {
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
    pub(super) fn direct_light(
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

    /// What source `k` sends to `r` (its shadow rays through `cache`).
    pub(super) fn source_light(
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
                crate::luminance(e.emission) * e.factor(r.point, r.normal, &e.polygon)
            }
            Source::Light(l) => crate::luminance(
                self.scene.lights[l]
                    .irradiance(r.point, r.normal, self.reach)
                    .0,
            ),
        }
    }

    /// What passes from `at` (a point of `piece`, or its centroid when
    /// `None`) to `r`; a piece crossing `r`'s tangent plane is seen from
    /// its clipped part's centroid when `at` lies behind. `None` where
    /// nothing of the piece lies before `r`.
    pub(super) fn passed_from(
        &self,
        e: &Emitter,
        r: &Receiver,
        piece: &[DVec3],
        at: Option<DVec3>,
        cache: &RefCell<ShadowCache>,
    ) -> Option<DVec3> {
        let front = |c: DVec3| r.normal.dot(c - r.point) > 0.0;
        let c = match at {
            Some(c) if front(c) => c,
            _ if piece.iter().all(|c| front(*c)) => geometry::centroid(piece),
            _ => {
                let clipped = clip_front(piece, r);
                if clipped.len() < 3 {
                    return None;
                }
                geometry::centroid(&clipped)
            }
        };
        Some(self.passed(e, r, c, cache))
    }

    /// What emitter `e` sends to `r`: a picture's sample casts
    /// [`SAMPLE_SPLIT`]` x `[`SAMPLE_SPLIT`] rays (`shared`: the exact
    /// factor and the pieces' shares its pixel's samples share, from
    /// [`pixel_shares`]); any other point [`EMITTER_SIDE`]` x
    /// `[`EMITTER_SIDE`], one to each piece's centroid.
    fn emitter_light(
        &self,
        e: &Emitter,
        r: &Receiver,
        sample: Option<(u32, u32)>,
        seed: u64,
        cache: &RefCell<ShadowCache>,
    ) -> DVec3 {
        self.emitter_light_shared(e, r, sample, seed, cache, None)
    }

    pub(super) fn emitter_light_shared(
        &self,
        e: &Emitter,
        r: &Receiver,
        sample: Option<(u32, u32)>,
        seed: u64,
        cache: &RefCell<ShadowCache>,
        shared: Option<&Shares>,
    ) -> DVec3 {
        if !e.faces(r) {
            return DVec3::ZERO;
        }
        let seen_from = |piece: &[DVec3], at: Option<DVec3>| -> DVec3 {
            self.passed_from(e, r, piece, at, cache)
                .unwrap_or(DVec3::ZERO)
        };
        let passed = match sample {
            // One piece of an `s x s` grid (`s^2 >= n`) a sample, the
            // pixel's samples taking them in turn from a place of the
            // pixel's own, seen from a point drawn uniformly in it.
            Some((k, n)) => {
                let pieces = e.grid(sample_side(n));
                let count = pieces.len() as u64;
                if count == 0 {
                    return DVec3::ZERO;
                }
                // `SAMPLE_SPLIT^2` pieces a sample, `n` apart: the pixel's
                // samples take every piece of the grid once (when there are
                // no more than that: a triangle or a quad), from a place of
                // the pixel's own. Each piece's share of the surface's
                // exact factor is its point factor's share of theirs (the
                // surface's factor is then exact where nothing blocks; one
                // exact factor a sample, not one a piece).
                let own_shares;
                let shares = match shared {
                    Some(shares) => shares,
                    None => {
                        let Some(shares) = Shares::at(e, r.point, r.normal, &pieces) else {
                            return DVec3::ZERO;
                        };
                        own_shares = shares;
                        &own_shares
                    }
                };
                let rays = u64::from(SAMPLE_SPLIT * SAMPLE_SPLIT);
                let mut sum = DVec3::ZERO;
                for j in 0..rays {
                    let index = (u64::from(k) + j * u64::from(n) + seed % count) % count;
                    let piece = &pieces[index as usize];
                    let share = shares.share(index as usize, piece, r.point, r.normal, e);
                    if share <= 0.0 {
                        continue;
                    }
                    let stream = (u64::from(k) * rays + j) * 2 + 2;
                    let at = point_in(&piece.polygon, unit(seed, stream), unit(seed, stream + 1));
                    sum += seen_from(&piece.polygon, Some(at)) * share;
                }
                // Each piece drawn stands for `count / rays` of them.
                sum * (shares.whole * count as f64 / rays as f64)
            }
            // A piece's exact factor (equation (2), clipped to the
            // receiver's front) times what passes from its centroid.
            None => e.pieces[EMITTER_SIDE as usize - 1]
                .iter()
                .map(|piece| {
                    let factor = e.factor(r.point, r.normal, &piece.polygon);
                    if factor <= 0.0 {
                        return DVec3::ZERO;
                    }
                    seen_from(&piece.polygon, None) * factor
                })
                .sum(),
        };
        e.emission * passed
    }
}

/// Side of the grid of cells a pixel's `n` samples take one each of
/// (`side^2 >= n`): their probes' grid.
pub(super) fn cells_side(n: u32) -> u32 {
    (f64::from(n.max(1)).sqrt().ceil() as u32).max(1)
}

/// Side of the grid of pieces a picture's samples (`n` to a pixel) take
/// [`SAMPLE_SPLIT`]` x `[`SAMPLE_SPLIT`] each of.
pub(super) fn sample_side(n: u32) -> u32 {
    cells_side(n) * SAMPLE_SPLIT
}

/// An emitter's exact factor at a point and its pieces' shares of it
/// (each piece's point factor over their sum), at one sample or for a
/// whole pixel.
pub(super) struct Shares {
    whole: f64,
    /// Each piece's share; empty when each is worked out as asked for.
    shares: Vec<f64>,
    /// The sum of the pieces' point factors.
    total: f64,
}

impl Shares {
    /// At `point` (normal `normal`); `None` where nothing of `e` is in
    /// front.
    fn at(e: &Emitter, point: DVec3, normal: DVec3, pieces: &[Piece]) -> Option<Shares> {
        let whole = e.factor(point, normal, &e.polygon);
        if whole <= 0.0 {
            return None;
        }
        let total: f64 = pieces
            .iter()
            .map(|p| point_factor(p, point, normal, e))
            .sum();
        (total > 0.0).then_some(Shares {
            whole,
            shares: Vec::new(),
            total,
        })
    }

    /// [`Shares::at`] with every piece's share worked out at once.
    pub(super) fn listed(
        e: &Emitter,
        point: DVec3,
        normal: DVec3,
        pieces: &[Piece],
    ) -> Option<Shares> {
        let whole = e.factor(point, normal, &e.polygon);
        if whole <= 0.0 {
            return None;
        }
        let mut shares: Vec<f64> = pieces
            .iter()
            .map(|p| point_factor(p, point, normal, e))
            .collect();
        let total: f64 = shares.iter().sum();
        if total <= 0.0 {
            return None;
        }
        shares.iter_mut().for_each(|s| *s /= total);
        Some(Shares {
            whole,
            shares,
            total,
        })
    }

    /// Piece `index`'s share.
    fn share(&self, index: usize, piece: &Piece, point: DVec3, normal: DVec3, e: &Emitter) -> f64 {
        match self.shares.get(index) {
            Some(share) => *share,
            None => point_factor(piece, point, normal, e) / self.total,
        }
    }
}

/// A piece's point factor at `point` (normal `normal`), but for `pi`:
/// its area times the cosines over the squared distance.
fn point_factor(piece: &Piece, point: DVec3, normal: DVec3, e: &Emitter) -> f64 {
    let d = piece.centroid - point;
    let d2 = d.length_squared();
    let cosines = (normal.dot(d) * -e.normal.dot(d)).max(0.0);
    piece.area * cosines / (d2 * d2)
}

/// The scene's emitting surfaces.
pub(super) fn emitters(scene: &Scene) -> Vec<Emitter> {
    scene
        .surfaces
        .iter()
        .filter(|s| s.is_emitter())
        .map(|s| Emitter {
            centre: geometry::centroid(&s.polygon),
            radius: {
                let c = geometry::centroid(&s.polygon);
                s.polygon.iter().map(|p| p.distance(c)).fold(0.0, f64::max)
            },
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
pub(super) fn sources(
    scene: &Scene,
    emitters: &[Emitter],
) -> (Vec<Source>, Vec<Bounds>, Vec<usize>) {
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
        let orientation = match light.model().at_points(light.radiometric()) {
            AtPoints::FromMesh => continue,
            AtPoints::Distant => {
                suns.push(i);
                continue;
            }
            AtPoints::Located(orientation) => orientation,
        };
        let Some(position) = light.position() else {
            continue;
        };
        sources.push(Source::Light(i));
        bounds.push(Bounds {
            lo: position,
            hi: position,
            power: orientation.power,
            axis: orientation.axis,
            theta_o: orientation.theta_o,
            theta_e: orientation.theta_e,
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
pub(super) fn point_in(piece: &[DVec3], u: f64, v: f64) -> DVec3 {
    if piece.len() == 4 {
        let bottom = piece[0].lerp(piece[1], u);
        let top = piece[3].lerp(piece[2], u);
        bottom.lerp(top, v)
    } else {
        let r = u.sqrt();
        piece[0] * (1.0 - r) + piece[1] * (r * (1.0 - v)) + piece[2] * (r * v)
    }
}
