//! The hemicube's software rasteriser: each surface clipped to every
//! face's frustum ([`crate::geometry::clip`]), snapped to fixed point and
//! scan-converted with exact integer edge functions, a top-left fill rule
//! and a `1/w` depth test (see the parent module).

use super::*;

impl ItemBuffer {
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
        let diagonal = self
            .scene_diagonal
            .unwrap_or_else(|| diagonal(scene::bounds_of(surfaces)));
        self.near = NEAR_FRACTION * diagonal.max(f64::MIN_POSITIVE);
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

    /// Clips the surface (in `self.local`) to one face's frustum and
    /// rasterises it with a depth test. Returns whether anything was left
    /// after clipping.
    pub(super) fn rasterise(&mut self, face: Face, index: u32, plane: LocalPlane) -> bool {
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
pub(super) fn depth_test_span(depths: &mut [f32], items: &mut [u32], z0: f64, dz: f64, index: u32) {
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
pub(super) struct EdgeWalker {
    /// `1`: bounds the span on the left; `-1`: on the right; `0`:
    /// horizontal, the whole row is inside when `remainder >= 0`.
    pub(super) side: i8,
    pub(super) quotient: i64,
    pub(super) remainder: i64,
    pub(super) divisor: i64,
    pub(super) step_quotient: i64,
    pub(super) step_remainder: i64,
}

impl EdgeWalker {
    /// The edge `a -> b` at the row of pixel centres `py`.
    pub(super) fn new(a: [i64; 2], b: [i64; 2], py: i64) -> EdgeWalker {
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
    pub(super) fn clamp(&self, lo: &mut i64, hi: &mut i64) {
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
    pub(super) fn next_row(&mut self) {
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
pub(super) fn to_fixed(x: f64) -> i64 {
    const BIAS: f64 = (4 * MAX_RESOLUTION as i64 * SUBPIXEL) as f64;
    let shifted = (x * SUBPIXEL as f64 + 0.5 + BIAS).clamp(0.0, 2.0 * BIAS);
    shifted as i64 - BIAS as i64
}

pub(super) fn ceil_div(a: i64, b: i64) -> i64 {
    -(-a).div_euclid(b)
}
