//! The sky in the solver, in one module: the openings its light comes
//! through ([`portals`]: found, or marked by the file and checked), the
//! plan of the directions drawn at a receiver (here) and its shot over a
//! chunk of receivers (`shot`). Its model, luminance and the light kind
//! are the scene's ([`crate::scene::sky`]).
//!
//! The sky's irradiance at a receiver: what a sky sends through openings
//! ([`portals`]) and over the rest of
//! its dome and the ground, as unblocked irradiances each with the far end
//! of its shadow segment. Beyond the paper, whose sources are surfaces.
//!
//! One estimator for every receiver (vertices, sensors, texels): the
//! directions are split between the *active* portals (the openings in
//! front of the receiver that pass the most light, at most
//! [`MAX_ACTIVE`]) and the rest of the sky. Each active portal is sampled
//! uniformly in the solid angle it subtends (stratified, Arvo 1995),
//! counting only the directions for which it is the nearest active portal
//! crossed; the rest is sampled as before, one direction in each of the
//! sky's patches (and the ground's), counting only directions that cross no
//! active portal. Every direction is counted by exactly one of the two, so
//! the estimate is unbiased whatever the portals; where daylight comes in
//! through openings (a window, a skylight, a slit, a courtyard) it is
//! sampled where it is, not found by a handful of patches that happen to
//! see it.
//!
//! A portal's light unblocked is integrated without rays (a midpoint rule
//! over each spherical triangle, split at the receiver's horizon where the
//! luminance jumps to the ground's); its rays, one in each cell of a grid
//! over each triangle, only measure the share blocked (a ratio estimator:
//! exact where nothing blocks). Where something does, the cells whose
//! neighbours disagree, or on the outline of a portal found partly blocked,
//! are drawn again in a second round ([`SkyPlan::refine`]), chosen without
//! looking at their own rays. Random numbers come from a generator seeded
//! by the receiver's index: the same answer on any number of threads.

use glam::DVec3;

pub mod portals;
mod shot;

pub(super) use self::shot::gather;

use self::portals::Portal;
use crate::accel::Occluder;
use crate::geometry::{self, spherical};
use crate::scene::sky::{self, Patch, SkyLight};
use crate::scene::{Light, Scene};

/// Most portals sampled at one receiver: those that pass it the most.
pub const MAX_ACTIVE: usize = 16;

/// Directions drawn through a receiver's active portals, shared among them
/// by the light each passes (at least [`MIN_PORTAL_RAYS`] each).
pub const PORTAL_RAYS: usize = 64;

/// Most points per side of the midpoint rule that integrates a portal's
/// unblocked light over each of its spherical triangles (twice the side of
/// the triangle's grid of rays, at least 2).
const QUADRATURE: usize = 16;

/// A refined portal cell's rays per side.
pub const REFINE: usize = 4;

/// Most portal cells refined at one receiver.
pub const MAX_REFINED_CELLS: usize = 48;

/// Fewest directions drawn through an active portal.
pub const MIN_PORTAL_RAYS: usize = 4;

/// A portal's convex piece, with what the crossing test needs.
struct Piece {
    corners: Vec<DVec3>,
    normal: DVec3,
}

/// A portal prepared for many receivers.
struct Prepared {
    pieces: Vec<Piece>,
    centre: DVec3,
    radius: f64,
}

/// What a sky needs at every receiver: its patches, the ground's, and the
/// scene's openings.
pub struct SkyPlan {
    patches: Vec<Patch>,
    ground: Vec<Patch>,
    portals: Vec<Prepared>,
}

/// A portal as one receiver sees it: the spherical triangles of its pieces
/// clipped to the receiver's front, their cumulative solid angles, and the
/// pieces for the nearest-portal test.
struct Active {
    triangles: Vec<spherical::Triangle>,
    cumulative: Vec<f64>,
    pieces: Vec<Piece>,
    power: f64,
    /// A cone holding every direction through it: its axis and the cosine
    /// of its half-angle (-1: the whole sphere).
    axis: DVec3,
    cos_half: f64,
    /// The other active portals some direction through this one may cross.
    others: Vec<usize>,
}

impl Active {
    /// Whether `towards` may cross the portal: inside its cone.
    fn may_cross(&self, towards: DVec3) -> bool {
        towards.dot(self.axis) >= self.cos_half
    }

    /// Where the ray from `point` along `towards` crosses it, if it does.
    fn crossing(&self, point: DVec3, towards: DVec3) -> Option<f64> {
        if self.may_cross(towards) {
            crossing(&self.pieces, point, towards)
        } else {
            None
        }
    }

    /// Whether some direction may cross both this portal and `other`.
    fn overlaps(&self, other: &Active) -> bool {
        if self.cos_half <= 0.0 || other.cos_half <= 0.0 {
            return true;
        }
        let between = self.axis.dot(other.axis).clamp(-1.0, 1.0).acos();
        between <= self.cos_half.acos() + other.cos_half.acos()
    }
}

impl SkyPlan {
    /// The plan for `light` if it is a sky: its patches and the openings of
    /// `scene` (found with `occluder`); `None` for any other light.
    #[must_use]
    pub fn new(light: &Light, scene: &Scene, occluder: &dyn Occluder) -> Option<SkyPlan> {
        let SkyLight { sky, subdivision } = light.sky()?;
        let ground = if sky.ground() > 0.0 {
            sky::ground_patches((*subdivision / 2).max(1))
        } else {
            Vec::new()
        };
        // The openings, those marked, and the glass (a pane in an opening
        // found from the geometry overlaps it: each direction is counted by
        // the nearer, or the first listed).
        let mut portals: Vec<Prepared> = portals::openings(&scene.surfaces, occluder)
            .iter()
            .map(prepare)
            .collect();
        portals.extend(
            scene
                .portals
                .iter()
                .filter_map(|m| m.portal())
                .map(|p| prepare(&p)),
        );
        portals.extend(scene.panes.iter().map(|pane| {
            prepare(&Portal {
                pieces: vec![pane.polygon.clone()],
                normal: pane.normal,
                area: geometry::area(&pane.polygon),
            })
        }));
        Some(SkyPlan {
            patches: sky::patches(*subdivision),
            ground,
            portals,
        })
    }

    /// The openings found.
    #[must_use]
    pub fn portal_count(&self) -> usize {
        self.portals.len()
    }

    /// The receiver's first round of rays ([`SkyDraw::rays`]): one in each
    /// of the sky's and the ground's patches that crosses no active portal,
    /// and a stratified grid of cells over each active portal. `index`
    /// seeds the receiver's random numbers; the rays reach `reach` metres
    /// out.
    #[must_use]
    pub fn pilot(
        &self,
        light: &Light,
        index: u64,
        point: DVec3,
        normal: DVec3,
        reach: f64,
    ) -> SkyDraw {
        let mut draw = SkyDraw {
            rays: Vec::new(),
            refined: Vec::new(),
            patch_rays: 0,
            portals: Vec::new(),
            active: Vec::new(),
            index,
            point,
            normal,
            reach,
        };
        let Some(SkyLight { sky, .. }) = light.sky() else {
            return draw;
        };
        let radiometric = light.radiometric();
        let mut random = Stream::new(index);
        draw.active = self.active(sky, point, normal);
        let active = &draw.active;
        for patch in self.patches.iter().chain(&self.ground) {
            let uv = (random.next(), random.next());
            let towards = patch.direction(uv.0, uv.1);
            let cos = normal.dot(towards);
            if cos <= 0.0 || active.iter().any(|a| a.crossing(point, towards).is_some()) {
                continue;
            }
            let weight = sky.relative_luminance(towards) * cos * patch.solid_angle();
            if weight > 0.0 {
                draw.rays
                    .push((radiometric * weight, point + towards * reach));
            }
        }
        draw.patch_rays = draw.rays.len();
        let total: f64 = active.iter().map(|a| a.power).sum();
        for k in 0..active.len() {
            let a = &active[k];
            let share = (PORTAL_RAYS as f64 * a.power / total).round() as usize;
            let n = share.max(MIN_PORTAL_RAYS);
            let value = |towards: DVec3| value(sky, active, k, point, normal, towards);
            let omega = *a.cumulative.last().unwrap_or(&0.0);
            let mut grids = Vec::with_capacity(a.triangles.len());
            let mut unblocked = 0.0;
            let mut before = 0.0;
            for (t, &cumulative) in a.cumulative.iter().enumerate() {
                let size = cumulative - before;
                before = cumulative;
                // Each spherical triangle its own grid of cells, one ray in
                // each: its outline, where a frame or a reveal cuts the
                // light, is the grid's border.
                let rays = ((n as f64 * size / omega).round() as usize).max(1);
                let columns = (rays as f64).sqrt().ceil() as usize;
                let rows = rays.div_ceil(columns);
                let mut cells = Vec::with_capacity(columns * rows);
                for i in 0..columns {
                    for j in 0..rows {
                        let u = (i as f64 + random.next()) / columns as f64;
                        let v = (j as f64 + random.next()) / rows as f64;
                        let towards = a.in_triangle(t, u, v);
                        let f = value(towards);
                        let ray = (f > 0.0).then(|| {
                            draw.rays.push((radiometric * f, point + towards * reach));
                            draw.rays.len() - 1
                        });
                        cells.push(Cell {
                            ray,
                            f,
                            refined: None,
                        });
                    }
                }
                // The triangle's unblocked light, found without rays by the
                // midpoint rule on a grid of directions over it (twice its
                // rays' points a side, 2 to QUADRATURE): the rays then
                // estimate only the fraction blocked, which is exact where
                // nothing is (a ratio estimator).
                let m = ((2.0 * (rays as f64).sqrt()).ceil() as usize).clamp(2, QUADRATURE);
                let mut sum = 0.0;
                for i in 0..m {
                    for j in 0..m {
                        let u = (i as f64 + 0.5) / m as f64;
                        let v = (j as f64 + 0.5) / m as f64;
                        sum += value(a.in_triangle(t, u, v));
                    }
                }
                unblocked += sum / (m * m) as f64 * size;
                grids.push(Grid {
                    columns,
                    rows,
                    cells,
                    weight: size / (columns * rows) as f64,
                });
            }
            draw.portals.push(PortalDraw { grids, unblocked });
        }
        draw
    }

    /// The second round ([`SkyDraw::refined`]), from what passed along each
    /// first-round ray (`passed`, per channel, 0 where blocked): a portal's
    /// cell whose neighbours disagree (some see the sky through it, some do
    /// not: a reveal's, a frame's or an obstruction's edge crosses it), or
    /// on the border of a portal that other rays found partly blocked, is
    /// drawn again, [`REFINE`] x [`REFINE`] rays stratified in it, its first
    /// ray set aside. The choice never looks at the cell's own ray, so the
    /// estimate stays unbiased.
    pub fn refine(&self, light: &Light, draw: &mut SkyDraw, passed: &[DVec3]) {
        let Some(SkyLight { sky, .. }) = light.sky() else {
            return;
        };
        let radiometric = light.radiometric();
        let mut random = Stream::new(draw.index ^ 0x5DEE_CE66_D1CE_4E5B);
        let (point, normal, reach) = (draw.point, draw.normal, draw.reach);
        // The cells to refine, in order, at most MAX_REFINED_CELLS.
        let mut chosen = Vec::new();
        'portals: for (k, portal) in draw.portals.iter().enumerate() {
            let seen = |grid: &Grid, i: usize, j: usize| -> Option<bool> {
                let ray = grid.cells[i * grid.rows + j].ray?;
                Some(passed[ray] != DVec3::ZERO)
            };
            // How many first rays through this portal passed and how many
            // were blocked.
            let (mut open, mut shut) = (0usize, 0usize);
            for grid in &portal.grids {
                for cell in &grid.cells {
                    if let Some(ray) = cell.ray {
                        if passed[ray] != DVec3::ZERO {
                            open += 1;
                        } else {
                            shut += 1;
                        }
                    }
                }
            }
            for (g, grid) in portal.grids.iter().enumerate() {
                let (columns, rows) = (grid.columns, grid.rows);
                for i in 0..columns {
                    for j in 0..rows {
                        // Partly blocked without this cell's own ray: the
                        // opening's frame, a reveal or an obstruction cuts
                        // it, most often along its outline, the border of a
                        // triangle's grid.
                        let own = seen(grid, i, j);
                        let others_open = open - usize::from(own == Some(true));
                        let others_shut = shut - usize::from(own == Some(false));
                        let border = i == 0 || j == 0 || i + 1 == columns || j + 1 == rows;
                        let partly = others_open > 0 && others_shut > 0;
                        let mut neighbours = [
                            (i > 0).then(|| seen(grid, i - 1, j)).flatten(),
                            (i + 1 < columns).then(|| seen(grid, i + 1, j)).flatten(),
                            (j > 0).then(|| seen(grid, i, j - 1)).flatten(),
                            (j + 1 < rows).then(|| seen(grid, i, j + 1)).flatten(),
                        ]
                        .into_iter()
                        .flatten();
                        let disagree = neighbours
                            .next()
                            .is_some_and(|first| !neighbours.all(|n| n == first));
                        if !(disagree || (border && partly)) {
                            continue;
                        }
                        if chosen.len() == MAX_REFINED_CELLS {
                            break 'portals;
                        }
                        chosen.push((k, g, i, j));
                    }
                }
            }
        }
        for (k, g, i, j) in chosen {
            let (columns, rows) = (
                draw.portals[k].grids[g].columns,
                draw.portals[k].grids[g].rows,
            );
            let start = draw.refined.len();
            let a = &draw.active[k];
            let mut f_sum = 0.0;
            for p in 0..REFINE {
                for q in 0..REFINE {
                    let u =
                        (i as f64 + (p as f64 + random.next()) / REFINE as f64) / columns as f64;
                    let v = (j as f64 + (q as f64 + random.next()) / REFINE as f64) / rows as f64;
                    let towards = a.in_triangle(g, u, v);
                    let f = value(sky, &draw.active, k, point, normal, towards);
                    if f > 0.0 {
                        f_sum += f;
                        draw.refined
                            .push((radiometric * f, point + towards * reach));
                    }
                }
            }
            let count = draw.refined.len() - start;
            draw.portals[k].grids[g].cells[i * rows + j].refined = Some((start, count, f_sum));
        }
    }

    /// The receiver's irradiance (W/m^2 per channel) from what passed along
    /// each ray of both rounds.
    #[must_use]
    pub fn finish(&self, draw: &SkyDraw, passed: &[DVec3], passed_refined: &[DVec3]) -> DVec3 {
        let mut sum = DVec3::ZERO;
        for (ray, through) in draw.rays[..draw.patch_rays].iter().zip(passed) {
            if *through != DVec3::ZERO {
                sum += ray.0 * *through;
            }
        }
        let per_cell = (REFINE * REFINE) as f64;
        for portal in &draw.portals {
            // What passes and what comes, over the cells (each of its
            // triangle's solid angle over its cell count).
            let (mut through, mut all) = (DVec3::ZERO, 0.0);
            for grid in &portal.grids {
                for cell in &grid.cells {
                    match cell.refined {
                        Some((start, count, f_sum)) => {
                            let passing: DVec3 = draw.refined[start..start + count]
                                .iter()
                                .zip(&passed_refined[start..start + count])
                                .map(|(ray, through)| ray.0 * *through)
                                .sum();
                            through += passing * (grid.weight / per_cell);
                            all += f_sum * grid.weight / per_cell;
                        }
                        None => {
                            if let Some(r) = cell.ray {
                                through += draw.rays[r].0 * passed[r] * grid.weight;
                            }
                            all += cell.f * grid.weight;
                        }
                    }
                }
            }
            if all > 0.0 {
                sum += through * (portal.unblocked / all);
            }
        }
        sum
    }

    /// The portals in front of the receiver, the most light first, at most
    /// [`MAX_ACTIVE`].
    fn active(&self, sky: &sky::Sky, point: DVec3, normal: DVec3) -> Vec<Active> {
        let mut out: Vec<Active> = Vec::new();
        let mut clipped = Vec::new();
        let mut half = Vec::new();
        for p in &self.portals {
            // Wholly behind the receiver's plane.
            if normal.dot(p.centre - point) < -p.radius {
                continue;
            }
            let scale = 1.0 + point.abs().max_element() + p.radius;
            let front = point + normal * (1e-9 * scale);
            let mut a = Active {
                triangles: Vec::new(),
                cumulative: Vec::new(),
                pieces: Vec::new(),
                power: 0.0,
                axis: DVec3::ZERO,
                cos_half: -1.0,
                others: Vec::new(),
            };
            let mut omega = 0.0;
            for piece in &p.pieces {
                geometry::clip_to_half_space(&piece.corners, front, normal, 0.0, &mut clipped);
                if clipped.len() < 3 {
                    continue;
                }
                // Above and below the receiver's horizon apart: the
                // luminance jumps there from the sky's to the ground's, and
                // each part's integrand is smooth.
                for up in [DVec3::Y, -DVec3::Y] {
                    geometry::clip_to_half_space(&clipped, point, up, 0.0, &mut half);
                    if half.len() < 3 {
                        continue;
                    }
                    let unit: Vec<DVec3> = half.iter().map(|&c| (c - point).normalize()).collect();
                    for i in 1..unit.len() - 1 {
                        let t = [unit[0], unit[i], unit[i + 1]];
                        let w = spherical::solid_angle(t[0], t[1], t[2]);
                        if w.is_nan() || w <= 0.0 {
                            continue;
                        }
                        let middle = (t[0] + t[1] + t[2]).normalize();
                        a.power += w * sky.relative_luminance(middle) * normal.dot(middle).max(0.0);
                        let before = omega;
                        omega += w;
                        // Its solid angle as the cumulative sums give it.
                        a.triangles.push(spherical::Triangle::new(
                            t[0],
                            t[1],
                            t[2],
                            omega - before,
                        ));
                        a.cumulative.push(omega);
                    }
                }
                a.pieces.push(Piece {
                    corners: clipped.clone(),
                    normal: piece.normal,
                });
            }
            if a.power > 0.0 {
                // The cone: about the corners' mean direction, out to the
                // farthest corner (a cap holding the corners holds their
                // spherical hull, the pieces, when under a hemisphere), a
                // little wider for round-off.
                let corners = a.pieces.iter().flat_map(|p| &p.corners);
                let sum: DVec3 = corners.clone().map(|&c| (c - point).normalize()).sum();
                let axis = sum.normalize_or_zero();
                if axis != DVec3::ZERO {
                    let cos = corners
                        .map(|&c| (c - point).normalize().dot(axis))
                        .fold(1.0, f64::min);
                    a.axis = axis;
                    a.cos_half = if cos > 0.0 { cos - 1e-9 } else { -1.0 };
                }
                out.push(a);
            }
        }
        out.sort_by(|a, b| b.power.total_cmp(&a.power));
        out.truncate(MAX_ACTIVE);
        for k in 0..out.len() {
            let others = (0..out.len())
                .filter(|&m| m != k && out[k].overlaps(&out[m]))
                .collect();
            out[k].others = others;
        }
        out
    }
}

/// What the direction `towards` through active portal `k` brings per
/// steradian, per lux of the sky: its luminance times the receiver's
/// cosine, or 0 where a nearer active portal (or one as near and listed
/// first: a pane in an opening) counts it.
fn value(
    sky: &sky::Sky,
    active: &[Active],
    k: usize,
    point: DVec3,
    normal: DVec3,
    towards: DVec3,
) -> f64 {
    let cos = normal.dot(towards);
    if cos <= 0.0 {
        return 0.0;
    }
    let a = &active[k];
    let mut here = None;
    for &m in &a.others {
        let Some(s) = active[m].crossing(point, towards) else {
            continue;
        };
        let here = *here
            .get_or_insert_with(|| crossing(&a.pieces, point, towards).unwrap_or(f64::INFINITY));
        if s < here - 1e-9 * here || (s <= here + 1e-9 * here && m < k) {
            return 0.0;
        }
    }
    sky.relative_luminance(towards) * cos
}

/// One receiver's rays and how they combine ([`SkyPlan::pilot`],
/// [`SkyPlan::refine`], [`SkyPlan::finish`]).
pub struct SkyDraw {
    /// The first round: each ray's value if it passes (W/m^2 per channel)
    /// and the far end of its shadow segment.
    pub rays: Vec<(DVec3, DVec3)>,
    /// The second round, the same way.
    pub refined: Vec<(DVec3, DVec3)>,
    patch_rays: usize,
    portals: Vec<PortalDraw>,
    active: Vec<Active>,
    index: u64,
    point: DVec3,
    normal: DVec3,
    reach: f64,
}

/// A portal at one receiver: a grid of cells over each of its spherical
/// triangles, and its unblocked light.
struct PortalDraw {
    grids: Vec<Grid>,
    unblocked: f64,
}

/// A spherical triangle's cells, `columns` x `rows`, each of solid angle
/// `weight`.
struct Grid {
    columns: usize,
    rows: usize,
    cells: Vec<Cell>,
    weight: f64,
}

/// A cell of a portal's grid: its first ray (none where it brings
/// nothing) and what it brings, and where refined, its second-round rays
/// (first, count) and the sum of what they bring.
struct Cell {
    ray: Option<usize>,
    f: f64,
    refined: Option<(usize, usize, f64)>,
}

impl Active {
    /// The direction at `(u, v)` in `[0, 1)^2` of spherical triangle `t`,
    /// uniform in solid angle.
    fn in_triangle(&self, t: usize, u: f64, v: f64) -> DVec3 {
        self.triangles[t].sample(u, v)
    }
}

/// A portal's pieces with their normals, centre and bounding radius.
fn prepare(portal: &Portal) -> Prepared {
    let pieces: Vec<Piece> = portal
        .pieces
        .iter()
        .map(|corners| Piece {
            normal: geometry::normal(corners).unwrap_or(portal.normal),
            corners: corners.clone(),
        })
        .collect();
    let corners = portal.pieces.iter().flatten();
    let count = corners.clone().count().max(1);
    let centre = corners.clone().sum::<DVec3>() / count as f64;
    let radius = corners.map(|c| c.distance(centre)).fold(0.0, f64::max);
    Prepared {
        pieces,
        centre,
        radius,
    }
}

/// Where the ray from `point` along `towards` crosses one of `pieces`
/// (its distance), if it does.
fn crossing(pieces: &[Piece], point: DVec3, towards: DVec3) -> Option<f64> {
    pieces.iter().find_map(|piece| {
        let denominator = piece.normal.dot(towards);
        if denominator == 0.0 {
            return None;
        }
        let s = piece.normal.dot(piece.corners[0] - point) / denominator;
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        let hit = point + towards * s;
        geometry::convex_contains(&piece.corners, piece.normal, hit, 0.0).then_some(s)
    })
}

/// A stream of numbers in `[0, 1)` seeded by a receiver's index
/// (SplitMix64, Steele et al. 2014): each receiver draws its own, so the
/// sky's samples do not depend on the number of threads.
struct Stream(u64);

impl Stream {
    fn new(seed: u64) -> Stream {
        Stream(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03)
    }

    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        // The top 53 bits, as a fraction.
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}
