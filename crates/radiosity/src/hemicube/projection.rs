//! The hemicube's projection: its five faces, the mapping of a direction
//! to a face and a pixel (shared by the rasteriser and the pre-test, so the
//! two agree exactly), and the neighbours of a pixel across face borders.

use super::*;

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
    pub(super) fn face_coordinates(self, l: DVec3) -> DVec3 {
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
    pub(super) fn local_coordinates(self, f: DVec3) -> DVec3 {
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
    pub(super) fn b_min(self) -> f64 {
        if self == Face::Top { -1.0 } else { 0.0 }
    }

    /// The face a hemicube-local direction with `z > 0` projects to: the
    /// axis with the largest coordinate (ties go to the top face, then in
    /// [`Face::ALL`] order).
    #[must_use]
    pub(super) fn of_local(l: DVec3) -> Face {
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

impl ItemBuffer {
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

    /// Rows of a face.
    pub(super) fn rows(&self, face: Face) -> u32 {
        if face == Face::Top {
            self.resolution
        } else {
            self.resolution / 2
        }
    }

    /// Index of a pixel in the buffers.
    pub(super) fn index(&self, p: Pixel) -> usize {
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

    pub(super) fn to_local_vector(&self, d: DVec3) -> DVec3 {
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
    pub(super) fn screen_position(&self, face: Face, f: DVec3) -> (f64, f64) {
        (
            (f.x / f.z + 1.0) * self.half,
            (f.y / f.z - face.b_min()) * self.half,
        )
    }

    /// Face coordinates (with `w = 1`) of the point at continuous pixel
    /// coordinates `(col + 0.5, row + 0.5)`, on the face's extended plane.
    pub(super) fn pixel_centre_face(&self, face: Face, col: f64, row: f64) -> DVec3 {
        DVec3::new(
            (col + 0.5) / self.half - 1.0,
            (row + 0.5) / self.half + face.b_min(),
            1.0,
        )
    }

    pub(super) fn locate_local(&self, l: DVec3) -> Option<Pixel> {
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
    pub(super) fn neighbour(&self, p: Pixel, dc: i32, dr: i32) -> Option<Pixel> {
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
}
