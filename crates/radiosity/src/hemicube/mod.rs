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
//! and no pixel may be empty. Thin furniture edges seen nearly edge-on are
//! exactly such receivers; EXPERIMENTS.md ("The pre-test's resolution")
//! gives the measured effect.
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
//!
//! # Files
//!
//! `projection` (faces, pixels and neighbours), `raster` (clipping,
//! scan conversion, depth test) and `pretest` (the decision); the buffer
//! itself and its public accessors are here.

use glam::DVec3;

use crate::geometry::clip;
use crate::scene::{self, Surface};

mod pretest;
mod projection;
mod raster;

pub use pretest::{Pretest, PretestCounts};
pub use projection::Face;
use raster::*;

/// Default pixels across the top face: the smallest resolution that keeps
/// the solution within 0.5% of ray-only visibility at no cost in solve time
/// (tests/configurations.rs checks the 0.5%). The wrong answers a coarser
/// buffer gives are biased (vertices where furniture meets the floor seen
/// past the contact edge), and past 128 the uncertain share barely falls:
/// most uncertain pairs are vertices on their own surface's edge. The
/// measurements behind the choice are in EXPERIMENTS.md ("The pre-test's
/// resolution", under Figure 2.1).
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
    /// The scene's bounding-box diagonal, when the owner gave it
    /// ([`ItemBuffer::for_scene`]); `None`: measured on each render.
    scene_diagonal: Option<f64>,
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
            scene_diagonal: None,
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

    /// An empty item buffer (as [`ItemBuffer::new`]) for rendering the
    /// surfaces of a scene whose bounding box is `bounds` (as
    /// [`Scene::bounds`](crate::scene::Scene::bounds) gives it): the near
    /// plane is set from it once, where a buffer from `new` measures the
    /// surfaces it is given on every render.
    #[must_use]
    pub fn for_scene(resolution: u32, bounds: (DVec3, DVec3)) -> ItemBuffer {
        ItemBuffer {
            scene_diagonal: Some(diagonal(bounds)),
            ..ItemBuffer::new(resolution)
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

    /// The surface a pixel holds, `None` if empty or out of range.
    #[must_use]
    pub fn item(&self, pixel: Pixel) -> Option<u32> {
        if pixel.col >= self.resolution || pixel.row >= self.rows(pixel.face) {
            return None;
        }
        let item = self.items[self.index(pixel)];
        (item != EMPTY).then_some(item)
    }
}

/// Bounding-box diagonal: the distance scale of the scene (0 for an empty
/// box).
fn diagonal((lo, hi): (DVec3, DVec3)) -> f64 {
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
