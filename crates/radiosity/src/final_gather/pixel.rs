//! A picture's pixel in the final pass: its samples shaded together when
//! every source is traced. For each emitting surface, a shaft
//! (Haines & Wallace 1991) from a row of pixels, then from a pixel, to
//! the surface: where nothing meets it, no ray is cast; otherwise one
//! probe ray a sample, and the samples' own rays only where the probes
//! disagree (a penumbra; Wallace, Elmquist & Haines 1989's ray-traced
//! final display, its shadow rays spent where visibility is partial). The
//! exact factor is one for the pixel where its samples lie close together.

use std::cell::RefCell;
use std::sync::atomic::Ordering;

use glam::DVec3;
use rayon::prelude::*;

use super::direct::{Emitter, Shares, Source, cells_side, point_in, sample_side};
use super::{FinalPass, Point, unit};
use crate::accel::ShadowCache;
use crate::accel::shaft::Shaft;
use crate::solver::{Receiver, lights};

impl FinalPass<'_> {
    /// [`FinalPass::direct_light`] of picture samples when every source is
    /// traced, a pixel's samples together (consecutive points with one
    /// seed), pixels in groups of [`PIXEL_GROUP`]. For each emitting
    /// surface, a shaft from the group's samples to it, then from each
    /// pixel's where the group's is not clear ([`FinalPass::clear_view`]):
    /// where it is clear, the surface is wholly in view and no ray is
    /// cast. Otherwise each sample probes it with one ray, the pixel's
    /// samples taking the cells of an `s x s` grid over it; if every probe
    /// lets the same through (the surface wholly hidden, or behind the
    /// same glass), each sample takes the surface's exact factor times
    /// that (no noise); otherwise (a penumbra) each sample takes its
    /// [`SAMPLE_SPLIT`](super::SAMPLE_SPLIT)` x `[`SAMPLE_SPLIT`](super::SAMPLE_SPLIT) rays as alone. A surface
    /// partly hidden from a pixel by something that meets the shaft but
    /// no probe is taken as wholly in view (or hidden): the probes are a
    /// grid of `s^2` cells over it, a point drawn in each. The exact
    /// factor is the pixel's ([`PIXEL_SHARE`]) where its samples allow.
    pub(super) fn pixels_light(
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
        // Pixels in groups of [`PIXEL_GROUP`] (a stretch of a row): one
        // shaft for the group first, then one for each pixel where that
        // one is not clear.
        let bounds: Vec<(usize, usize)> = starts.windows(2).map(|w| (w[0], w[1])).collect();
        let light: Vec<Vec<DVec3>> = bounds
            .par_chunks(PIXEL_GROUP)
            .map_init(
                || RefCell::new(ShadowCache::default()),
                |cache, pixels| {
                    let (start, end) = (pixels[0].0, pixels[pixels.len() - 1].1);
                    let (rs, ps) = (&receivers[start..end], &points[start..end]);
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
                    let group = (pixels.len() > 1).then(|| Pixel::of(rs, ps));
                    let each: Vec<Pixel> = pixels
                        .iter()
                        .map(|&(a, b)| Pixel::of(&receivers[a..b], &points[a..b]))
                        .collect();
                    let mut probes = Vec::new();
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
                        cache.borrow_mut().from_origin(k);
                        let group_clear = group
                            .as_ref()
                            .is_some_and(|g| g.all_face(e, rs) && self.clear_view(e, g, cache));
                        for (&(a, b), pixel) in pixels.iter().zip(&each) {
                            let at = a - start..b - start;
                            self.pixel_light(
                                k,
                                e,
                                (&rs[at.clone()], &ps[at.clone()], pixel),
                                group_clear,
                                &mut out[at],
                                &mut probes,
                                cache,
                            );
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

    /// What emitter `e` (source `k`) sends to a pixel's samples `rs`
    /// (points `ps`, seen together as `pixel`), added to `out`
    /// ([`FinalPass::pixels_light`]); `clear` where a shaft around more
    /// than the pixel was found clear of `e` already.
    #[allow(clippy::too_many_arguments)]
    fn pixel_light(
        &self,
        k: u32,
        e: &Emitter,
        (rs, ps, pixel): (&[Receiver], &[Point], &Pixel),
        clear: bool,
        out: &mut [DVec3],
        probes: &mut Vec<Option<DVec3>>,
        cache: &RefCell<ShadowCache>,
    ) {
        probes.clear();
        let mut seen = Seen::Nothing;
        let all_face = pixel.all_face(e, rs);
        cache.borrow_mut().from_origin(k);
        if all_face && (clear || self.clear_view(e, pixel, cache)) {
            // Nothing stands between the pixel and the surface: no probe
            // needed.
            seen = Seen::All(DVec3::ONE);
        } else {
            for (r, p) in rs.iter().zip(ps) {
                cache.borrow_mut().from_origin(k);
                let probe = self.probe(e, r, p.sample, p.seed, cache);
                if let Some(passed) = probe {
                    seen = seen.and(passed);
                }
                probes.push(probe);
            }
            // A lone sample's probe says nothing of the rest of the
            // surface: it takes its own rays.
            if rs.len() < 2 && seen != Seen::Nothing {
                seen = Seen::Mixed;
            }
        }
        match seen {
            // Nothing in front, or wholly hidden.
            Seen::Nothing => {}
            Seen::All(passed) if passed == DVec3::ZERO => {}
            // Wholly in view (or behind the same glass): the exact factor
            // times what passes, one for the pixel where its samples are
            // close enough together.
            Seen::All(passed) => {
                let shared = pixel_factor(e, pixel, all_face);
                for (o, r) in out.iter_mut().zip(rs) {
                    if e.faces(r) {
                        let whole =
                            shared.unwrap_or_else(|| e.factor(r.point, r.normal, &e.polygon));
                        *o += e.emission * passed * whole.max(0.0);
                    }
                }
            }
            Seen::Mixed => {
                let shared = pixel_shares(e, pixel, all_face, ps);
                for ((o, r), p) in out.iter_mut().zip(rs).zip(ps) {
                    cache.borrow_mut().from_origin(k);
                    *o += self.emitter_light_shared(e, r, p.sample, p.seed, cache, shared.as_ref());
                }
            }
        }
    }

    /// Whether nothing stands between `pixel`'s samples (all facing
    /// emitter `e`) and `e`: no surface but theirs and its meets the shaft
    /// between the ball holding them and `e` ([`Shaft`]), and no glass
    /// could dim the light. One walk of the tree for what would be a
    /// probe ray a sample.
    fn clear_view(&self, e: &Emitter, pixel: &Pixel, cache: &RefCell<ShadowCache>) -> bool {
        let Some(group) = pixel.group else {
            return false;
        };
        if !self.scene.panes.is_empty() {
            return false;
        }
        Shaft::around(pixel.centre, pixel.radius, &e.polygon, e.normal, e.centre)
            .map(|shaft| match pixel.normal {
                Some(normal) => shaft.on_plane(normal, &e.polygon),
                None => shaft,
            })
            .is_some_and(|shaft| {
                self.occluder
                    .shaft_clear(&shaft, [e.group, group], &mut cache.borrow_mut())
            })
    }

    /// A picture's sample's probe of emitter `e`: what passes along one
    /// shadow ray from a point drawn in the sample's cell of an `s x s`
    /// grid over it (`s^2 >= n`, the pixel's samples taking the cells in
    /// turn from a place of the pixel's own); `None` where nothing of it
    /// lies before `r`. The rays are those of
    /// [`FinalPass::emitter_light_split`] with one ray a sample.
    fn probe(
        &self,
        e: &Emitter,
        r: &Receiver,
        sample: Option<(u32, u32)>,
        seed: u64,
        cache: &RefCell<ShadowCache>,
    ) -> Option<DVec3> {
        let (k, n) = sample?;
        if !e.faces(r) {
            return None;
        }
        let pieces = e.grid(cells_side(n));
        let count = pieces.len() as u64;
        if count == 0 {
            return None;
        }
        let index = (u64::from(k) + seed % count) % count;
        let piece = &pieces[index as usize];
        let stream = u64::from(k) * 2 + 2;
        let at = point_in(&piece.polygon, unit(seed, stream), unit(seed, stream + 1));
        self.passed_from(e, r, &piece.polygon, Some(at), cache)
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
}

/// Pixels of a picture whose shafts to an emitter are tested together
/// first ([`FinalPass::pixels_light`]).
const PIXEL_GROUP: usize = 4;

/// A pixel's samples share one exact factor of an emitter when they lie
/// within this fraction of their distance to it of their centroid.
///
/// The mean of the factor over the samples is its value at their centroid
/// plus a term of the second order in their spread: for a factor falling
/// as a power of the distance, within `10 (spread / distance)^2` of it,
/// 0.1% here, where the picture shows the mean.
pub const PIXEL_SHARE: f64 = 0.01;

/// A pixel's samples seen together: the ball holding them, and what they
/// have in common.
struct Pixel {
    centre: DVec3,
    /// Every sample lies within this of the centre (and a hair more).
    radius: f64,
    /// Their normal, where they lie on one surface.
    normal: Option<DVec3>,
    /// Their surface's id, where they share one.
    group: Option<u32>,
}

impl Pixel {
    fn of(rs: &[Receiver], ps: &[Point]) -> Pixel {
        let centre = rs.iter().map(|r| r.point).sum::<DVec3>() / rs.len().max(1) as f64;
        let radius = rs
            .iter()
            .map(|r| r.point.distance(centre))
            .fold(0.0, f64::max)
            * (1.0 + 1e-9);
        let first = rs.first();
        let one_surface = !rs.is_empty()
            && ps.iter().all(|p| p.surface == ps[0].surface)
            && rs.iter().all(|r| Some(r.normal) == first.map(|f| f.normal));
        Pixel {
            centre,
            radius,
            normal: first.filter(|_| one_surface).map(|r| r.normal),
            group: first
                .filter(|f| rs.iter().all(|r| r.group == f.group))
                .map(|r| r.group),
        }
    }

    /// Whether every sample `rs` faces `e` ([`Emitter::faces`]): for the
    /// whole ball at once where the samples share a surface, else one by
    /// one.
    fn all_face(&self, e: &Emitter, rs: &[Receiver]) -> bool {
        if let (Some(normal), Some(group)) = (self.normal, self.group) {
            let ahead = e.normal.dot(self.centre) - e.offset > self.radius;
            let seen = e
                .polygon
                .iter()
                .any(|c| normal.dot(*c - self.centre) > self.radius);
            if group != e.group && ahead && seen {
                return true;
            }
        }
        !rs.is_empty() && rs.iter().all(|r| e.faces(r))
    }
}

/// Where a pixel's samples may share what they see of `e` (its exact
/// factor, its pieces' shares): their centroid and normal, where they lie
/// on one surface and face `e` together (`all_face`), within
/// [`PIXEL_SHARE`] of their distance to it of the centroid; `None`
/// otherwise (each sample takes its own).
fn pixel_centre(e: &Emitter, pixel: &Pixel, all_face: bool) -> Option<(DVec3, DVec3)> {
    let normal = pixel.normal.filter(|_| all_face)?;
    let distance = pixel.centre.distance(e.centre) - e.radius;
    (pixel.radius <= PIXEL_SHARE * distance).then_some((pixel.centre, normal))
}

/// The exact factor of `e` a pixel's samples share ([`pixel_centre`]).
fn pixel_factor(e: &Emitter, pixel: &Pixel, all_face: bool) -> Option<f64> {
    let (centre, normal) = pixel_centre(e, pixel, all_face)?;
    Some(e.factor(centre, normal, &e.polygon))
}

/// The exact factor and pieces' shares of `e` a pixel's samples share
/// ([`pixel_centre`]), for samples that cast their own rays.
fn pixel_shares(e: &Emitter, pixel: &Pixel, all_face: bool, ps: &[Point]) -> Option<Shares> {
    let (centre, normal) = pixel_centre(e, pixel, all_face)?;
    let (_, n) = ps[0].sample?;
    Shares::listed(e, centre, normal, &e.grid(sample_side(n)))
}
