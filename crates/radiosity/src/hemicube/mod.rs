//! The hemicube visibility pre-test of Wong & Tsang (1993), section 2
//! (design.md section 3, "Hemicube pre-test").
//!
//! Before a subsource casts its shadow rays, a hemicube is placed at its
//! centre along the source normal and every other surface is rasterised onto
//! the five faces with a depth buffer, keeping the nearest surface's index in
//! each pixel (an *item buffer*). A receiving point on surface `s` is then
//! decided without a ray when its own pixel holds `s` ([`Pretest::Visible`])
//! or when none of the 3 x 3 pixels around it does ([`Pretest::Hidden`]);
//! anything else is [`Pretest::Uncertain`] and the caller casts the ray. The
//! paper rasterised on the SGI's graphics hardware; this is the software
//! version, which its Figure 2.1 also timed.
//!
//! # Geometry
//!
//! The hemicube frame is `(u, v, n)` with `n` the source normal. The top face
//! looks along `n` and covers `|x/z|, |y/z| <= 1`; each side face looks along
//! `+-u` or `+-v` and covers the upper half of its 90-degree frustum only
//! (`0 <= z/w <= 1` with `w` the distance along the face's axis), so it is
//! `resolution x resolution / 2` pixels and all pixels subtend the same
//! tangent-plane step `2 / resolution`. A point's face is the axis among
//! `z, |x|, |y|` with the largest coordinate, and its pixel is found by the
//! same screen mapping ([`Face`], `screen_position`) that the rasteriser
//! snaps polygon corners with, so the two agree exactly.
//!
//! # Rasterisation
//!
//! Each surface (front- or back-facing: both occlude) is clipped in every
//! face's own coordinates to that face's frustum: the near plane
//! `w >= near` (with `near` = [`NEAR_FRACTION`] of the scene's bounding-box
//! diagonal), the two side planes, the far edge and the base plane `z >= 0`.
//! Clipped corners are interpolated from the end of each edge nearer the
//! plane, whichever way the edge is walked ([`crate::geometry::clip`]), so
//! two surfaces sharing an edge get bit-identical clipped corners. Corners are
//! snapped to 1/256 pixel and covered pixel centres are found with exact
//! integer edge functions and a top-left fill rule: a pixel centre on an edge
//! two polygons share belongs to exactly one of them, so a far surface can
//! never show through a crack. Depth is `1/w`, which is affine in screen
//! space; it is evaluated from the surface's own plane (exact for planar
//! polygons) and kept in `f32`, larger meaning nearer.
//!
//! # Deciding
//!
//! The 3 x 3 neighbourhood crosses face borders: a neighbour beyond a face's
//! edge is the pixel that the neighbour's pixel-centre direction (on the
//! face's extended plane) projects to on the adjacent face; one beyond the
//! base plane is unknown and makes the answer [`Pretest::Uncertain`].
//! Two safeguards go beyond the paper, both only turning `Hidden` into
//! `Uncertain`: every one of the nine pixels must hold a surface that lies
//! in front of the receiver's plane along that pixel's ray (a receiver too
//! thin to cover any pixel centre would otherwise always be called hidden),
//! and no pixel may be empty. On the built-in room the first cuts the
//! wrong answers from 4% of the pairs to 0.34% at resolution 128:
//! thin furniture edges seen nearly edge-on are exactly such receivers.
//! Surfaces cut from one input face (same [`Surface::face`], hence coplanar
//! and contiguous) count as one item.
//!
//! What remains wrong is inherent to sampling pixel centres: a point within
//! half a pixel diagonal of a shadow's edge can be called visible because
//! its pixel's centre sees its surface, and a point seen only through a gap
//! narrower than a pixel can be called hidden. Both shrink with the pixel.
//! The answers are about the segment from the hemicube's origin: a caller
//! that shoots from elsewhere (a subsource clipped by the receiver's plane)
//! must cast the ray.

use glam::DVec3;

use crate::geometry::clip;
use crate::scene::Surface;

/// Default pixels across the top face.
///
/// Measured on the built-in room (patch 2.5 m, element 0.2 m; the 36
/// subsources (3 x 3) of its emitting patches against the 106,773
/// vertex-subsource pairs in front of them; best render time on one core):
///
/// | resolution | visible | hidden | uncertain | wrong | render |
/// |-----------:|--------:|-------:|----------:|------:|-------:|
/// |         32 |   52.5% |  14.8% |     32.8% | 1.51% | 0.08 ms |
/// |         64 |   53.8% |  19.7% |     26.5% | 0.63% | 0.11 ms |
/// |        128 |   54.8% |  23.3% |     21.9% | 0.34% | 0.20 ms |
/// |        256 |   55.4% |  25.2% |     19.4% | 0.18% | 0.48 ms |
/// |        512 |   55.8% |  26.2% |     18.0% | 0.15% | 1.90 ms |
///
/// ("wrong": a decision the brute-force ray contradicts.) Past 128 the
/// uncertain share barely falls: nine in ten uncertain pairs are vertices on
/// their surface's own edge, whose pixel straddles it at any resolution.
///
/// The wrong answers are not symmetric, though: almost all are "visible"
/// for vertices on a line where furniture meets the floor or a wall, whose
/// pixel centre peeks past the contact edge. They bias the solution upwards.
/// Solving the room to 72 subsources with the analytic factor, the mean
/// reflected radiosity moves against ray-only visibility by 0.66% at 128,
/// 0.29% at 256, 0.18% at 512 and 0.12% at 1024, while the whole solve
/// takes the same time at 128 and 256 (the extra raster time buys back the
/// rays it saves) and 1.6x and 4x longer at 512 and 1024. 256 is the
/// smallest resolution that keeps the picture within 0.5% of ray-only
/// visibility at no cost (tests/configurations.rs checks it).
pub const DEFAULT_RESOLUTION: u32 = 256;

/// Largest accepted resolution (the buffers then take 400 MB); larger
/// requests are clamped.
pub const MAX_RESOLUTION: u32 = 4096;

/// The near plane sits at this fraction of the scene's bounding-box diagonal
/// from the subsource centre (1 mm in a 10 m scene). The projection divides
/// by the distance `w` along a face's axis, so geometry must be clipped
/// before `w` reaches 0; what lies closer than this (in practice only
/// surfaces that touch the source's rim, seen edge-on) would cover whole
/// faces at a depth `f32` cannot resolve. Points that close are uncertain.
pub const NEAR_FRACTION: f64 = 1e-4;

/// Fractional bits of the fixed-point screen coordinates.
const SUBPIXEL_BITS: u32 = 8;
const SUBPIXEL: i64 = 1 << SUBPIXEL_BITS;
const HALF_SUBPIXEL: i64 = SUBPIXEL / 2;

/// A pixel no surface covers.
const EMPTY: u32 = u32::MAX;

/// A receiver's plane must lie this much (relatively, in `1/w`) behind the
/// surface held by a pixel for that pixel to count as hiding it.
const HIDDEN_DEPTH_MARGIN: f32 = 1e-3;

/// A point within this fraction of its distance of the base plane is
/// treated as lying on it.
const BASE_PLANE_TOLERANCE: f64 = 1e-9;

/// The outcome of the pre-test for one point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pretest {
    /// The point's pixel holds its surface: visible, no ray needed.
    Visible,
    /// None of the 3 x 3 pixels around the point holds its surface and each
    /// holds something in front of it: hidden, no ray needed.
    Hidden,
    /// Marginal: the caller casts a shadow ray.
    Uncertain,
}

/// Tally of pre-test outcomes, for statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PretestCounts {
    /// Pairs decided visible.
    pub visible: u64,
    /// Pairs decided hidden.
    pub hidden: u64,
    /// Pairs left to a ray.
    pub uncertain: u64,
}

impl PretestCounts {
    /// Counts one outcome.
    pub fn record(&mut self, outcome: Pretest) {
        match outcome {
            Pretest::Visible => self.visible += 1,
            Pretest::Hidden => self.hidden += 1,
            Pretest::Uncertain => self.uncertain += 1,
        }
    }

    /// All pairs counted.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.visible + self.hidden + self.uncertain
    }

    /// Pairs decided without a ray.
    #[must_use]
    pub fn decided(&self) -> u64 {
        self.visible + self.hidden
    }
}

impl std::ops::AddAssign for PretestCounts {
    fn add_assign(&mut self, other: PretestCounts) {
        self.visible += other.visible;
        self.hidden += other.hidden;
        self.uncertain += other.uncertain;
    }
}

/// One of the hemicube's five faces. Hemicube-local coordinates are
/// `(x, y, z)` along `(u, v, n)`; each face has its own coordinates
/// `(a, b, w)`: `w` along the face's axis and screen position
/// `(a / w, b / w)`. The top face has `(a, b, w) = (x, y, z)`; the `+-u`
/// faces `(y, z, +-x)` and the `+-v` faces `(x, z, +-y)`, so `b` runs
/// along `n` on every side face.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Face {
    /// Looks along `n`; `resolution x resolution` pixels.
    Top,
    /// Looks along `+u`; `resolution x resolution / 2` pixels.
    PlusU,
    /// Looks along `-u`.
    MinusU,
    /// Looks along `+v`.
    PlusV,
    /// Looks along `-v`.
    MinusV,
}

impl Face {
    /// The five faces, in buffer order.
    pub const ALL: [Face; 5] = [
        Face::Top,
        Face::PlusU,
        Face::MinusU,
        Face::PlusV,
        Face::MinusV,
    ];

    /// Face coordinates `(a, b, w)` of a hemicube-local vector. A signed
    /// permutation, so dot products are preserved.
    #[must_use]
    fn face_coordinates(self, l: DVec3) -> DVec3 {
        match self {
            Face::Top => l,
            Face::PlusU => DVec3::new(l.y, l.z, l.x),
            Face::MinusU => DVec3::new(l.y, l.z, -l.x),
            Face::PlusV => DVec3::new(l.x, l.z, l.y),
            Face::MinusV => DVec3::new(l.x, l.z, -l.y),
        }
    }

    /// Inverse of [`Face::face_coordinates`].
    #[must_use]
    fn local_coordinates(self, f: DVec3) -> DVec3 {
        match self {
            Face::Top => f,
            Face::PlusU => DVec3::new(f.z, f.x, f.y),
            Face::MinusU => DVec3::new(-f.z, f.x, f.y),
            Face::PlusV => DVec3::new(f.x, f.z, f.y),
            Face::MinusV => DVec3::new(f.x, -f.z, f.y),
        }
    }

    /// Lowest screen `b / w` the face covers: the top face spans
    /// `[-1, 1]`, a side face only the half above the base plane, `[0, 1]`.
    #[must_use]
    fn b_min(self) -> f64 {
        if self == Face::Top { -1.0 } else { 0.0 }
    }

    /// The face a hemicube-local direction with `z > 0` projects to: the
    /// axis with the largest coordinate (ties go to the top face, then in
    /// [`Face::ALL`] order).
    #[must_use]
    fn of_local(l: DVec3) -> Face {
        let (ax, ay) = (l.x.abs(), l.y.abs());
        if l.z >= ax && l.z >= ay {
            Face::Top
        } else if ax >= ay {
            if l.x > 0.0 { Face::PlusU } else { Face::MinusU }
        } else if l.y > 0.0 {
            Face::PlusV
        } else {
            Face::MinusV
        }
    }
}

/// One pixel of the item buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Pixel {
    /// Which face.
    pub face: Face,
    /// Column, `0..resolution`, increasing with `a / w`.
    pub col: u32,
    /// Row, `0..resolution` on the top face and `0..resolution / 2` on a
    /// side face (row 0 touching the base plane), increasing with `b / w`.
    pub row: u32,
}

/// Counters of the last [`ItemBuffer::render`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Surfaces that reached at least one face after clipping.
    pub surfaces_drawn: u32,
    /// (Surface, face) pairs rasterised.
    pub polygons_rasterised: u32,
    /// Pixel-centre samples depth-tested (overdraw included).
    pub samples_tested: u64,
}

/// A plane in hemicube-local coordinates: `normal . l = offset`.
#[derive(Clone, Copy, Debug)]
struct LocalPlane {
    normal: DVec3,
    offset: f64,
}

/// A software hemicube item buffer: for each pixel of the five faces, the
/// index of the nearest surface and its `1/w` depth. Buffers are allocated
/// once and reused by every [`ItemBuffer::render`].
#[derive(Clone, Debug)]
pub struct ItemBuffer {
    resolution: u32,
    /// `resolution / 2`: pixels per unit of screen tangent.
    half: f64,
    /// Surface index per pixel: the top face, then the four side faces.
    items: Vec<u32>,
    /// `1/w` per pixel, 0 where empty.
    depth: Vec<f32>,
    origin: DVec3,
    /// The hemicube frame `(u, v, n)`.
    frame: [DVec3; 3],
    near: f64,
    skip: u32,
    rendered: bool,
    /// Per surface of the last render: its plane in local coordinates, and
    /// its input face (for the same-item test).
    planes: Vec<LocalPlane>,
    groups: Vec<u32>,
    stats: RenderStats,
    // Scratch, reused across polygons.
    local: Vec<DVec3>,
    clip_in: Vec<DVec3>,
    clip_out: Vec<DVec3>,
    fixed: Vec<[i64; 2]>,
    edges: Vec<EdgeWalker>,
}

impl ItemBuffer {
    /// An empty item buffer with `resolution` pixels across the top face
    /// (rounded up to even, clamped to `2..=`[`MAX_RESOLUTION`]).
    #[must_use]
    pub fn new(resolution: u32) -> ItemBuffer {
        let resolution = resolution.clamp(2, MAX_RESOLUTION).next_multiple_of(2);
        let pixels = 3 * resolution as usize * resolution as usize;
        ItemBuffer {
            resolution,
            half: f64::from(resolution / 2),
            items: vec![EMPTY; pixels],
            depth: vec![0.0; pixels],
            origin: DVec3::ZERO,
            frame: [DVec3::X, DVec3::Y, DVec3::Z],
            near: 0.0,
            skip: EMPTY,
            rendered: false,
            planes: Vec::new(),
            groups: Vec::new(),
            stats: RenderStats::default(),
            local: Vec::new(),
            clip_in: Vec::new(),
            clip_out: Vec::new(),
            fixed: Vec::new(),
            edges: Vec::new(),
        }
    }

    /// Pixels across the top face.
    #[must_use]
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// Pixels on all five faces: `resolution^2 + 4 resolution^2 / 2`.
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        self.items.len()
    }

    /// Pixels of the last render that hold a surface.
    #[must_use]
    pub fn covered_pixel_count(&self) -> usize {
        self.items.iter().filter(|&&i| i != EMPTY).count()
    }

    /// The near-plane distance of the last render.
    #[must_use]
    pub fn near(&self) -> f64 {
        self.near
    }

    /// Counters of the last render.
    #[must_use]
    pub fn stats(&self) -> RenderStats {
        self.stats
    }

    /// Rasterises every surface except `skip` (the shooting surface) as seen
    /// from `origin`, the hemicube's axis along `normal`, keeping the
    /// nearest surface's index in each pixel. Surfaces behind the base plane
    /// or in a plane through `origin` are skipped. A zero `normal` leaves the
    /// buffer empty and every later [`ItemBuffer::classify`] uncertain.
    pub fn render(&mut self, surfaces: &[Surface], origin: DVec3, normal: DVec3, skip: u32) {
        self.items.fill(EMPTY);
        self.depth.fill(0.0);
        self.stats = RenderStats::default();
        self.planes.clear();
        self.groups.clear();
        self.origin = origin;
        self.skip = skip;
        let Some(n) = normal.try_normalize() else {
            self.rendered = false;
            return;
        };
        let (u, v) = n.any_orthonormal_pair();
        self.frame = [u, v, n];
        self.near = NEAR_FRACTION * scene_diagonal(surfaces).max(f64::MIN_POSITIVE);
        self.rendered = true;

        for (index, surface) in surfaces.iter().enumerate() {
            let normal = self.to_local_vector(surface.normal);
            let offset = surface.offset - surface.normal.dot(origin);
            self.planes.push(LocalPlane { normal, offset });
            self.groups.push(surface.group);
            let index = index as u32;
            // A plane through the origin is seen edge-on and covers no
            // pixel centre; `1/w` would be unbounded on it.
            if index == skip || offset.abs() <= 1e-2 * self.near {
                continue;
            }
            self.local.clear();
            let mut above = false;
            for &p in &surface.polygon {
                let l = self.to_local_vector(p - origin);
                above |= l.z > 0.0;
                self.local.push(l);
            }
            if !above {
                continue;
            }
            let mut drawn = false;
            for face in Face::ALL {
                drawn |= self.rasterise(face, index, LocalPlane { normal, offset });
            }
            self.stats.surfaces_drawn += u32::from(drawn);
        }
    }

    /// The pre-test of paper section 2 for a point lying on surface
    /// `surface` (see the module documentation for the rule and its
    /// safeguards). Points behind the base plane or (nearly) on it, closer
    /// than the near plane, on the skipped surface, or on a surface seen
    /// edge-on are uncertain.
    #[must_use]
    pub fn classify(&self, point: DVec3, surface: u32) -> Pretest {
        if !self.rendered || surface == self.skip {
            return Pretest::Uncertain;
        }
        let Some(plane) = self.planes.get(surface as usize) else {
            return Pretest::Uncertain;
        };
        if plane.offset.abs() <= 1e-2 * self.near {
            return Pretest::Uncertain;
        }
        let local = self.to_local_vector(point - self.origin);
        let Some(centre) = self.locate_local(local) else {
            return Pretest::Uncertain;
        };
        let face_w = centre.face.face_coordinates(local).z;
        if face_w < self.near {
            return Pretest::Uncertain;
        }
        let group = self.groups[surface as usize];
        let same = |item: u32| item != EMPTY && self.groups[item as usize] == group;
        if same(self.items[self.index(centre)]) {
            return Pretest::Visible;
        }
        // First the cheap integer tests on all nine pixels, then the depth
        // safeguard, which costs a division a pixel, only if they all pass.
        let mut neighbours = [(centre, 0usize); 9];
        for (slot, (dr, dc)) in neighbours
            .iter_mut()
            .zip((-1..=1).flat_map(|dr| (-1..=1).map(move |dc| (dr, dc))))
        {
            let Some(p) = self.neighbour(centre, dc, dr) else {
                return Pretest::Uncertain;
            };
            let k = self.index(p);
            let item = self.items[k];
            if item == EMPTY || same(item) {
                return Pretest::Uncertain;
            }
            *slot = (p, k);
        }
        let hidden = neighbours
            .iter()
            .all(|&(p, k)| self.depth[k] > self.plane_depth(plane, p));
        if hidden {
            Pretest::Hidden
        } else {
            Pretest::Uncertain
        }
    }

    /// The pixel a point projects to, `None` if it is behind the base plane,
    /// (nearly) on it, or the buffer has not been rendered.
    #[must_use]
    pub fn locate(&self, point: DVec3) -> Option<Pixel> {
        if !self.rendered {
            return None;
        }
        self.locate_local(self.to_local_vector(point - self.origin))
    }

    /// The world-space unit direction from the hemicube's origin through the
    /// centre of `pixel`.
    #[must_use]
    pub fn pixel_direction(&self, pixel: Pixel) -> DVec3 {
        let f = self.pixel_centre_face(pixel.face, f64::from(pixel.col), f64::from(pixel.row));
        let l = pixel.face.local_coordinates(f);
        (self.frame[0] * l.x + self.frame[1] * l.y + self.frame[2] * l.z).normalize()
    }

    /// The surface a pixel holds, `None` if empty or out of range.
    #[must_use]
    pub fn item(&self, pixel: Pixel) -> Option<u32> {
        if pixel.col >= self.resolution || pixel.row >= self.rows(pixel.face) {
            return None;
        }
        let item = self.items[self.index(pixel)];
        (item != EMPTY).then_some(item)
    }

    /// Rows of a face.
    fn rows(&self, face: Face) -> u32 {
        if face == Face::Top {
            self.resolution
        } else {
            self.resolution / 2
        }
    }

    /// Index of a pixel in the buffers.
    fn index(&self, p: Pixel) -> usize {
        let r = self.resolution as usize;
        let start = match p.face {
            Face::Top => 0,
            Face::PlusU => r * r,
            Face::MinusU => r * r + r * r / 2,
            Face::PlusV => r * r + r * r,
            Face::MinusV => r * r + 3 * r * r / 2,
        };
        start + p.row as usize * r + p.col as usize
    }

    fn to_local_vector(&self, d: DVec3) -> DVec3 {
        DVec3::new(
            self.frame[0].dot(d),
            self.frame[1].dot(d),
            self.frame[2].dot(d),
        )
    }

    /// Continuous pixel coordinates `(col, row)` of face coordinates
    /// `(a, b, w)`, `w > 0`: the one projection shared by the rasteriser and
    /// [`ItemBuffer::classify`]. Pixel `(i, j)` covers `[i, i + 1) x [j, j + 1)`
    /// and is sampled at its centre.
    fn screen_position(&self, face: Face, f: DVec3) -> (f64, f64) {
        (
            (f.x / f.z + 1.0) * self.half,
            (f.y / f.z - face.b_min()) * self.half,
        )
    }

    /// Face coordinates (with `w = 1`) of the point at continuous pixel
    /// coordinates `(col + 0.5, row + 0.5)`, on the face's extended plane.
    fn pixel_centre_face(&self, face: Face, col: f64, row: f64) -> DVec3 {
        DVec3::new(
            (col + 0.5) / self.half - 1.0,
            (row + 0.5) / self.half + face.b_min(),
            1.0,
        )
    }

    fn locate_local(&self, l: DVec3) -> Option<Pixel> {
        // Written so that NaN coordinates also give `None`.
        if l.z.partial_cmp(&(BASE_PLANE_TOLERANCE * l.length()))
            != Some(std::cmp::Ordering::Greater)
        {
            return None;
        }
        let face = Face::of_local(l);
        let (x, y) = self.screen_position(face, face.face_coordinates(l));
        let max_col = f64::from(self.resolution - 1);
        let max_row = f64::from(self.rows(face) - 1);
        Some(Pixel {
            face,
            col: x.floor().clamp(0.0, max_col) as u32,
            row: y.floor().clamp(0.0, max_row) as u32,
        })
    }

    /// The pixel one step `(dc, dr)` from `p`, across a face border if need
    /// be; `None` below the base plane.
    fn neighbour(&self, p: Pixel, dc: i32, dr: i32) -> Option<Pixel> {
        let col = i64::from(p.col) + i64::from(dc);
        let row = i64::from(p.row) + i64::from(dr);
        if (0..i64::from(self.resolution)).contains(&col)
            && (0..i64::from(self.rows(p.face))).contains(&row)
        {
            return Some(Pixel {
                face: p.face,
                col: col as u32,
                row: row as u32,
            });
        }
        let f = self.pixel_centre_face(p.face, col as f64, row as f64);
        self.locate_local(p.face.local_coordinates(f))
    }

    /// `1/w` of a surface's plane along the centre ray of pixel `p`
    /// (negative or zero if the ray does not meet the plane in front).
    fn plane_depth(&self, plane: &LocalPlane, p: Pixel) -> f32 {
        let f = self.pixel_centre_face(p.face, f64::from(p.col), f64::from(p.row));
        let m = p.face.face_coordinates(plane.normal);
        let inverse_w = m.dot(f) / plane.offset;
        (inverse_w * (1.0 + f64::from(HIDDEN_DEPTH_MARGIN))) as f32
    }

    /// Clips the surface (in `self.local`) to one face's frustum and
    /// rasterises it with a depth test. Returns whether anything was left
    /// after clipping.
    fn rasterise(&mut self, face: Face, index: u32, plane: LocalPlane) -> bool {
        let b_min = face.b_min();
        // Frustum planes as linear forms in (a, b, w), inside when >= 0.
        let planes = [
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(-1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(0.0, -1.0, 1.0),
            DVec3::new(0.0, 1.0, -b_min),
        ];
        let offsets = [self.near, 0.0, 0.0, 0.0, 0.0];
        self.clip_in.clear();
        self.clip_in
            .extend(self.local.iter().map(|&l| face.face_coordinates(l)));
        // Most surfaces miss most faces: reject on one plane with every
        // corner outside, and skip planes with every corner inside (exact:
        // clipping would return the polygon unchanged).
        let mut needed = [false; 5];
        for (k, (form, offset)) in planes.iter().zip(offsets).enumerate() {
            let (mut any_in, mut any_out) = (false, false);
            for f in &self.clip_in {
                let inside = form.dot(*f) >= offset;
                any_in |= inside;
                any_out |= !inside;
            }
            if !any_in {
                return false;
            }
            needed[k] = any_out;
        }
        for ((form, offset), _) in planes
            .iter()
            .zip(offsets)
            .zip(needed)
            .filter(|(_, needed)| *needed)
        {
            clip::clip_into(&self.clip_in, |f| form.dot(f) - offset, &mut self.clip_out);
            std::mem::swap(&mut self.clip_in, &mut self.clip_out);
            if self.clip_in.len() < 3 {
                return false;
            }
        }

        self.fixed.clear();
        for &f in &self.clip_in {
            let (x, y) = self.screen_position(face, f);
            let p = [to_fixed(x), to_fixed(y)];
            if self.fixed.last() != Some(&p) {
                self.fixed.push(p);
            }
        }
        while self.fixed.len() > 1 && self.fixed.first() == self.fixed.last() {
            self.fixed.pop();
        }
        if self.fixed.len() < 3 {
            return true;
        }
        let twice_area: i64 = (0..self.fixed.len())
            .map(|i| {
                let a = self.fixed[i];
                let b = self.fixed[(i + 1) % self.fixed.len()];
                a[0] * b[1] - a[1] * b[0]
            })
            .sum();
        if twice_area == 0 {
            return true;
        }
        if twice_area < 0 {
            self.fixed.reverse();
        }
        self.stats.polygons_rasterised += 1;

        // 1/w = m . (a/w, b/w, 1) / offset, affine in pixel coordinates.
        let m = face.face_coordinates(plane.normal) / plane.offset;
        let ddx = m.x / self.half;
        let ddy = m.y / self.half;
        let d0 = m.z - m.x + m.y * b_min;

        let r = self.resolution as usize;
        let start = self.index(Pixel {
            face,
            col: 0,
            row: 0,
        });
        let rows = self.rows(face) as i64;
        let (y_lo, y_hi) = self.fixed.iter().fold((i64::MAX, i64::MIN), |(lo, hi), p| {
            (lo.min(p[1]), hi.max(p[1]))
        });
        let first_row = ceil_div(y_lo - HALF_SUBPIXEL, SUBPIXEL).max(0);
        let last_row = (y_hi - HALF_SUBPIXEL).div_euclid(SUBPIXEL).min(rows - 1);
        self.edges.clear();
        let py0 = first_row * SUBPIXEL + HALF_SUBPIXEL;
        for (i, &a) in self.fixed.iter().enumerate() {
            let b = self.fixed[(i + 1) % self.fixed.len()];
            self.edges.push(EdgeWalker::new(a, b, py0));
        }
        for row in first_row..=last_row {
            let mut lo: i64 = 0;
            let mut hi: i64 = r as i64 - 1;
            for e in &mut self.edges {
                e.clamp(&mut lo, &mut hi);
                e.next_row();
            }
            if lo > hi {
                continue;
            }
            let (lo, hi) = (lo as usize, hi as usize);
            let row_start = start + row as usize * r;
            let z0 = d0 + ddy * (row as f64 + 0.5) + ddx * (lo as f64 + 0.5);
            depth_test_span(
                &mut self.depth[row_start + lo..=row_start + hi],
                &mut self.items[row_start + lo..=row_start + hi],
                z0,
                ddx,
                index,
            );
            self.stats.samples_tested += (hi - lo + 1) as u64;
        }
        true
    }
}

/// Writes `index` into the pixels of one span where `1/w`, starting at `z0`
/// and growing by `dz` a pixel, is nearer than the stored depth. Branch-free
/// lanes of eight so the compiler vectorises it.
fn depth_test_span(depths: &mut [f32], items: &mut [u32], z0: f64, dz: f64, index: u32) {
    const LANES: usize = 8;
    const RAMP: [f32; LANES] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
    let done = depths.len() / LANES * LANES;
    let mut depth_chunks = depths.chunks_exact_mut(LANES);
    let mut item_chunks = items.chunks_exact_mut(LANES);
    let dz32 = dz as f32;
    for (c, (d, it)) in (&mut depth_chunks).zip(&mut item_chunks).enumerate() {
        let base = (z0 + dz * (c * LANES) as f64) as f32;
        for l in 0..LANES {
            let z = base + dz32 * RAMP[l];
            let nearer = z > d[l];
            d[l] = if nearer { z } else { d[l] };
            it[l] = if nearer { index } else { it[l] };
        }
    }
    let base = (z0 + dz * done as f64) as f32;
    for (l, (d, it)) in depth_chunks
        .into_remainder()
        .iter_mut()
        .zip(item_chunks.into_remainder())
        .enumerate()
    {
        let z = base + dz32 * l as f32;
        let nearer = z > *d;
        *d = if nearer { z } else { *d };
        *it = if nearer { index } else { *it };
    }
}

/// One edge of a convex screen polygon (counter-clockwise, fixed point),
/// giving for each row of pixel centres the first or last column on its
/// inside, stepped from row to row exactly in integers with no division.
///
/// The edge function at pixel centre `(px, py)` is
/// `E = dx (py - ay) - dy (px - ax)`, positive inside. Top-left fill rule: a
/// centre exactly on the edge (`E = 0`) is inside only for an edge going
/// down (`dy < 0`) or horizontally right, so the shared edge of two
/// polygons, walked in opposite directions, gives it to exactly one of them.
/// At column `c` of a row, `E - bias = k + s c` with `s = -dy * SUBPIXEL`;
/// with `D = |s|` and `q = floor(k / D)`, the inside columns are `c >= -q`
/// for `s > 0` and `c <= q` for `s < 0`.
#[derive(Clone, Copy, Debug)]
struct EdgeWalker {
    /// `1`: bounds the span on the left; `-1`: on the right; `0`:
    /// horizontal, the whole row is inside when `remainder >= 0`.
    side: i8,
    quotient: i64,
    remainder: i64,
    divisor: i64,
    step_quotient: i64,
    step_remainder: i64,
}

impl EdgeWalker {
    /// The edge `a -> b` at the row of pixel centres `py`.
    fn new(a: [i64; 2], b: [i64; 2], py: i64) -> EdgeWalker {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let bias = i64::from(!(dy < 0 || (dy == 0 && dx > 0)));
        let k = dx * (py - a[1]) - dy * (HALF_SUBPIXEL - a[0]) - bias;
        let step = dx * SUBPIXEL;
        if dy == 0 {
            return EdgeWalker {
                side: 0,
                quotient: 0,
                remainder: k,
                divisor: 1,
                step_quotient: 0,
                step_remainder: step,
            };
        }
        let divisor = dy.abs() * SUBPIXEL;
        EdgeWalker {
            side: if dy < 0 { 1 } else { -1 },
            quotient: k.div_euclid(divisor),
            remainder: k.rem_euclid(divisor),
            divisor,
            step_quotient: step.div_euclid(divisor),
            step_remainder: step.rem_euclid(divisor),
        }
    }

    /// Narrows the span `[lo, hi]` of the current row to this edge's inside.
    fn clamp(&self, lo: &mut i64, hi: &mut i64) {
        match self.side {
            1 => *lo = (*lo).max(-self.quotient),
            -1 => *hi = (*hi).min(self.quotient),
            _ => {
                if self.remainder < 0 {
                    *hi = -1;
                }
            }
        }
    }

    /// Moves to the next row of pixel centres.
    fn next_row(&mut self) {
        self.quotient += self.step_quotient;
        self.remainder += self.step_remainder;
        if self.side != 0 && self.remainder >= self.divisor {
            self.remainder -= self.divisor;
            self.quotient += 1;
        }
    }
}

/// Snaps a continuous pixel coordinate to the nearest 1/256 pixel. Clipped
/// corners lie within the face (up to round-off), so the clamp only guards
/// the conversion; rounding is `floor(v + 0.5)` done by truncating a
/// positive number, which needs no library call.
fn to_fixed(x: f64) -> i64 {
    const BIAS: f64 = (4 * MAX_RESOLUTION as i64 * SUBPIXEL) as f64;
    let shifted = (x * SUBPIXEL as f64 + 0.5 + BIAS).clamp(0.0, 2.0 * BIAS);
    shifted as i64 - BIAS as i64
}

fn ceil_div(a: i64, b: i64) -> i64 {
    -(-a).div_euclid(b)
}

/// Bounding-box diagonal of all surfaces: the distance scale of the scene.
fn scene_diagonal(surfaces: &[Surface]) -> f64 {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in surfaces.iter().flat_map(|s| &s.polygon) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if lo.x <= hi.x {
        (hi - lo).length()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator, so the tests need no crate.
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> u64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            self.0 >> 33
        }

        fn range(&mut self, lo: i64, hi: i64) -> i64 {
            lo + (self.next() % (hi - lo) as u64) as i64
        }
    }

    #[test]
    fn face_coordinates_round_trip_and_pick_the_dominant_axis() {
        let l = DVec3::new(0.3, -0.7, 0.2);
        for face in Face::ALL {
            assert_eq!(face.local_coordinates(face.face_coordinates(l)), l);
            // The face's axis maps to w.
            let axis = face.local_coordinates(DVec3::Z);
            assert_eq!(Face::of_local(axis + DVec3::Z * 1e-3), face);
        }
        assert_eq!(Face::of_local(DVec3::new(0.5, 0.5, 1.0)), Face::Top);
        assert_eq!(Face::of_local(DVec3::new(-2.0, 0.5, 1.0)), Face::MinusU);
        assert_eq!(Face::of_local(DVec3::new(0.1, -2.0, 1.0)), Face::MinusV);
    }

    #[test]
    fn edge_walker_matches_the_edge_function_row_by_row() {
        let mut rng = Lcg(7);
        for _ in 0..2_000 {
            let a = [rng.range(-600, 3000), rng.range(-600, 3000)];
            let b = [rng.range(-600, 3000), rng.range(-600, 3000)];
            if a == b {
                continue;
            }
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let top_left = dy < 0 || (dy == 0 && dx > 0);
            let first_row = rng.range(-3, 4);
            let mut walker = EdgeWalker::new(a, b, first_row * SUBPIXEL + HALF_SUBPIXEL);
            for row in first_row..first_row + 12 {
                let py = row * SUBPIXEL + HALF_SUBPIXEL;
                let (mut lo, mut hi) = (-20, 30);
                walker.clamp(&mut lo, &mut hi);
                for col in -20..=30 {
                    let px = col * SUBPIXEL + HALF_SUBPIXEL;
                    let e = dx * (py - a[1]) - dy * (px - a[0]);
                    let inside = e > 0 || (e == 0 && top_left);
                    assert_eq!(
                        (lo..=hi).contains(&col),
                        inside,
                        "{a:?} {b:?} ({col}, {row})"
                    );
                }
                walker.next_row();
            }
        }
    }

    #[test]
    fn vectorised_span_matches_a_plain_depth_test() {
        let mut rng = Lcg(11);
        for len in 0..40 {
            let depths: Vec<f32> = (0..len).map(|_| rng.range(0, 100) as f32 / 50.0).collect();
            let items: Vec<u32> = (0..len).map(|i| i as u32).collect();
            let (z0, dz) = (1.0, 0.013 * (len as f64 - 20.0));
            let (mut d, mut it) = (depths.clone(), items.clone());
            depth_test_span(&mut d, &mut it, z0, dz, 99);
            for k in 0..len {
                let z = (z0 + dz * k as f64) as f32;
                if (z - depths[k]).abs() > 1e-5 {
                    let nearer = z > depths[k];
                    assert_eq!(it[k] == 99, nearer, "{len} {k}");
                    if nearer {
                        assert!((d[k] - z).abs() < 1e-5);
                    } else {
                        assert_eq!(d[k], depths[k]);
                    }
                }
            }
        }
    }

    #[test]
    fn resolution_is_clamped_to_an_even_size() {
        assert_eq!(ItemBuffer::new(0).resolution(), 2);
        assert_eq!(ItemBuffer::new(101).resolution(), 102);
        assert_eq!(ItemBuffer::new(u32::MAX).resolution(), MAX_RESOLUTION);
        assert_eq!(ItemBuffer::new(10).pixel_count(), 300);
    }

    #[test]
    fn a_zero_normal_leaves_everything_uncertain() {
        let square = Surface::new(
            vec![
                DVec3::new(-1.0, -1.0, 1.0),
                DVec3::new(1.0, -1.0, 1.0),
                DVec3::new(1.0, 1.0, 1.0),
                DVec3::new(-1.0, 1.0, 1.0),
            ],
            DVec3::splat(0.5),
            DVec3::ZERO,
            0,
        )
        .expect("square");
        let mut buffer = ItemBuffer::new(16);
        buffer.render(std::slice::from_ref(&square), DVec3::ZERO, DVec3::Z, 1);
        assert_eq!(
            buffer.classify(DVec3::new(0.1, 0.2, 1.0), 0),
            Pretest::Visible
        );
        buffer.render(&[square], DVec3::ZERO, DVec3::ZERO, 1);
        assert_eq!(buffer.covered_pixel_count(), 0);
        assert_eq!(
            buffer.classify(DVec3::new(0.1, 0.2, 1.0), 0),
            Pretest::Uncertain
        );
        assert_eq!(buffer.locate(DVec3::new(0.1, 0.2, 1.0)), None);
    }
}
