//! Receiver refinement beyond the paper: elements split where the light
//! changes across them, as in the adaptive subdivision of Cohen, Greenberg,
//! Immel & Brock (1986), who refine the element mesh where a first, coarse
//! solution varies, and the error-driven refinement of Hanrahan, Salzman &
//! Aupperle (1991).
//!
//! [`Mesh::refine`] splits chosen elements into four (a quad at its edge
//! midpoints and centre, a triangle at its edge midpoints), each as many
//! times as asked. Edge midpoints are [`edge_point`]s, so two elements that
//! split a shared edge share its midpoint; an element next to a finer one
//! keeps its corners, and the finer one's midpoints hang on its edge (a
//! T-vertex), which [`Mesh::triangles`](super::Mesh::triangles) closes for
//! everything shown.
//!
//! [`split_depths`] says how many times to split each element from a solved
//! coarse mesh: the element's radiosity `B` at its corners and at its centre
//! (gathered there as a sensor) against the bilinear interpolation of its
//! corners, measured in units of the larger of the element's own mean `B`
//! and the scene's mean `B` (the adaptive tolerance's rule: relative where
//! it is bright, absolute where it is dark).

use std::collections::HashMap;

use glam::DVec3;

use super::{Element, Mesh, MeshError, Vertex, edge_point};
use crate::geometry;

/// How the element mesh refines: how many times an element may be halved
/// and at what variation of the light. Part of [`MeshSettings`](super::MeshSettings).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RefineSettings {
    /// At most this many halvings of an element's edges (0: the fixed
    /// grid, as in the paper).
    pub refine_levels: u32,
    /// An element splits once its light varies by more than this fraction
    /// of the larger of its own mean radiosity and the scene's; once more
    /// for each doubling beyond.
    pub refine_tolerance: f64,
}

/// The most `--refine-levels` accepted: each level can multiply an
/// element by four.
pub const MAX_REFINE_LEVELS: u32 = 8;

/// Default `--refine-tolerance`.
pub const DEFAULT_REFINE_TOLERANCE: f64 = 0.25;

impl Default for RefineSettings {
    fn default() -> Self {
        RefineSettings {
            refine_levels: 0,
            refine_tolerance: DEFAULT_REFINE_TOLERANCE,
        }
    }
}

/// The centre of an element (the mean of its corners: the bilinear centre
/// of a quad, the centroid of a triangle).
#[must_use]
pub fn element_centre(mesh: &Mesh, element: &Element) -> DVec3 {
    let corners = element.vertices();
    corners
        .iter()
        .map(|&c| mesh.vertices[c as usize].position)
        .sum::<DVec3>()
        / corners.len() as f64
}

/// How many times to split each element: `radiosity` per vertex and
/// `centre_radiosity` per element (at [`element_centre`]), each element's
/// variation `max(|B(centre) - mean B(corners)|, (max - min of B(corners)) / 2)`
/// (channel means) against `tolerance` times the larger of the element's
/// mean and the scene's area-weighted mean; an element varying by `v > 1`
/// times that splits `max(1, ceil(log2 v))` times (once per halving of the
/// error a discontinuity leaves), at most `levels`.
#[must_use]
pub fn split_depths(
    mesh: &Mesh,
    radiosity: &[DVec3],
    centre_radiosity: &[DVec3],
    tolerance: f64,
    levels: u32,
) -> Vec<u8> {
    let level = |b: DVec3| (b.x + b.y + b.z) / 3.0;
    let (mut weighted, mut area) = (0.0, 0.0);
    for (e, c) in mesh.elements.iter().zip(centre_radiosity) {
        weighted += level(*c) * e.area;
        area += e.area;
    }
    let scene_mean = if area > 0.0 { weighted / area } else { 0.0 };
    let levels = levels.min(u32::from(u8::MAX)) as f64;
    mesh.elements
        .iter()
        .zip(centre_radiosity)
        .map(|(e, centre)| {
            let corners: Vec<f64> = e
                .vertices()
                .iter()
                .map(|&v| level(radiosity[v as usize]))
                .collect();
            let mean = corners.iter().sum::<f64>() / corners.len() as f64;
            let (lo, hi) = corners
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &b| {
                    (lo.min(b), hi.max(b))
                });
            let centre = level(*centre);
            let variation = (centre - mean).abs().max((hi - lo) / 2.0);
            let unit = tolerance * mean.max(centre).max(scene_mean);
            if unit.is_nan() || variation.is_nan() || unit <= 0.0 || variation <= unit {
                return 0;
            }
            (variation / unit)
                .log2()
                .ceil()
                .clamp(1.0, levels.max(1.0))
                .min(levels) as u8
        })
        .collect()
}

/// Elements `count` elements make when element `e` is split `depth[e]`
/// times (0 where `depth` has no entry), saturating.
#[must_use]
pub fn refined_count(count: usize, depth: &[u8]) -> u128 {
    (0..count).fold(0u128, |sum, e| {
        let d = depth.get(e).copied().unwrap_or(0).min(60);
        sum.saturating_add(1u128 << (2 * u32::from(d)))
    })
}

impl Mesh {
    /// This mesh with element `e` split `depth[e]` times into four (see
    /// the module's text); patches keep their polygons and take their
    /// elements' pieces in place, old vertices keep their indices and new
    /// ones follow.
    ///
    /// # Errors
    ///
    /// [`MeshError::TooManyElements`] when the pieces would exceed
    /// `max_elements`.
    pub fn refine(
        &self,
        depth: &[u8],
        max_elements: usize,
        element_size: f64,
    ) -> Result<Mesh, MeshError> {
        self.refine_with_parents(depth, max_elements, element_size)
            .map(|(mesh, _)| mesh)
    }

    /// [`Mesh::refine`], and for each element of the refined mesh the
    /// element of this one it was cut from (its parent, or itself unsplit).
    ///
    /// # Errors
    ///
    /// As [`Mesh::refine`].
    pub fn refine_with_parents(
        &self,
        depth: &[u8],
        max_elements: usize,
        element_size: f64,
    ) -> Result<(Mesh, Vec<u32>), MeshError> {
        let total = refined_count(self.elements.len(), depth);
        if total > max_elements as u128 {
            return Err(MeshError::TooManyElements {
                elements: total,
                patches: self.patches.len() as u128,
                limit: max_elements,
                element_size,
            });
        }
        let mut out = Mesh {
            patches: self.patches.clone(),
            elements: Vec::with_capacity(total as usize),
            vertices: self.vertices.clone(),
        };
        let mut lookup = self.vertex_lookup();
        let mut parents = Vec::with_capacity(total as usize);
        for (p, patch) in self.patches.iter().enumerate() {
            let start = out.elements.len();
            for e in patch.elements.clone() {
                let element = self.elements[e];
                // The element's own surface: its first corner may belong
                // to a neighbouring face of the same surface id.
                let template = Vertex {
                    surface: element.surface,
                    ..self.vertices[element.corners[0] as usize]
                };
                let mut splitter = Splitter {
                    out: &mut out,
                    lookup: &mut lookup,
                    template,
                };
                splitter.split(element, depth.get(e).copied().unwrap_or(0));
                parents.resize(out.elements.len(), e as u32);
            }
            out.patches[p].elements = start..out.elements.len();
        }
        Ok((out, parents))
    }
}

/// Splits elements of one surface into [`Mesh::refine`]'s output.
struct Splitter<'a> {
    out: &'a mut Mesh,
    lookup: &'a mut HashMap<(u32, [u64; 3]), u32>,
    /// A vertex of the element's surface: its normal, surface and id for
    /// the new vertices.
    template: Vertex,
}

impl Splitter<'_> {
    fn vertex(&mut self, p: DVec3) -> u32 {
        let vertex = Vertex {
            position: p,
            ..self.template
        };
        self.out.shared_vertex(self.lookup, vertex)
    }

    fn midpoint(&mut self, a: u32, b: u32) -> u32 {
        let (pa, pb) = (
            self.out.vertices[a as usize].position,
            self.out.vertices[b as usize].position,
        );
        self.vertex(edge_point(pa, pb, 1, 2))
    }

    fn split(&mut self, element: Element, depth: u8) {
        if depth == 0 {
            self.out.elements.push(element);
            return;
        }
        let c = element.corners;
        let children: Vec<(u8, [u32; 4])> = if element.corner_count == 4 {
            let [m01, m12, m23, m30] = [
                self.midpoint(c[0], c[1]),
                self.midpoint(c[1], c[2]),
                self.midpoint(c[2], c[3]),
                self.midpoint(c[3], c[0]),
            ];
            let centre = c
                .iter()
                .map(|&v| self.out.vertices[v as usize].position)
                .sum::<DVec3>()
                * 0.25;
            let m = self.vertex(centre);
            vec![
                (4, [c[0], m01, m, m30]),
                (4, [m01, c[1], m12, m]),
                (4, [m, m12, c[2], m23]),
                (4, [m30, m, m23, c[3]]),
            ]
        } else {
            let [m01, m12, m20] = [
                self.midpoint(c[0], c[1]),
                self.midpoint(c[1], c[2]),
                self.midpoint(c[2], c[0]),
            ];
            vec![
                (3, [c[0], m01, m20, 0]),
                (3, [m01, c[1], m12, 0]),
                (3, [m20, m12, c[2], 0]),
                (3, [m01, m12, m20, 0]),
            ]
        };
        for (count, corners) in children {
            let polygon: Vec<DVec3> = corners[..count as usize]
                .iter()
                .map(|&v| self.out.vertices[v as usize].position)
                .collect();
            let child = Element {
                corners,
                corner_count: count,
                area: geometry::area(&polygon),
                ..element
            };
            self.split(child, depth - 1);
        }
    }
}
