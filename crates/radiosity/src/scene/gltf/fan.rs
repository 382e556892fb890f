//! Triangles from index lists and polygons from triangle fans: the
//! `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` topologies of the glTF
//! 2.0 specification (*Meshes*, primitive modes) assembled into
//! counter-clockwise vertex triples; the vendor extension
//! `FB_ngon_encoding`, which stores each polygon as a fan of consecutive
//! triangles, read back into polygons (what `export-scene` writes); and the
//! interpolation of per-corner values on such a polygon as a renderer
//! interpolates its fan.

use glam::DVec3;
use gltf_json as json;

/// The name of the vendor extension that encodes polygons as triangle fans.
pub const NGON_EXTENSION: &str = "FB_ngon_encoding";

/// Vertex triples of a triangle list, strip or fan, counter-clockwise.
pub(super) fn assemble(mode: json::mesh::Mode, indices: &[usize]) -> Vec<[usize; 3]> {
    use json::mesh::Mode;
    let n = indices.len();
    match mode {
        Mode::TriangleStrip if n >= 3 => (0..n - 2)
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i], indices[i + 1], indices[i + 2]]
                } else {
                    [indices[i + 1], indices[i], indices[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan if n >= 3 => (1..n - 1)
            .map(|i| [indices[i], indices[i + 1], indices[0]])
            .collect(),
        Mode::Triangles => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
        _ => Vec::new(),
    }
}

/// Groups triangles into the polygons `FB_ngon_encoding` encodes: a run of
/// consecutive triangles sharing their first vertex, each starting where the
/// last ended, is one fan.
pub(super) fn fans(triangles: &[[usize; 3]]) -> Vec<Vec<usize>> {
    let mut polygons: Vec<Vec<usize>> = Vec::new();
    let mut previous: Option<[usize; 3]> = None;
    for t in triangles {
        match (previous, polygons.last_mut()) {
            (Some(p), Some(polygon)) if p[0] == t[0] && p[2] == t[1] => polygon.push(t[2]),
            _ => polygons.push(t.to_vec()),
        }
        previous = Some(*t);
    }
    polygons
}

/// Interpolates per-corner `values` at `p` on a planar polygon, linearly
/// inside the fan triangle (corner 0, i, i + 1) that holds `p`, as a
/// renderer interpolates a triangulated polygon.
#[must_use]
pub fn interpolate_on_fan(corners: &[DVec3], values: &[[f64; 2]], p: DVec3) -> [f64; 2] {
    let n = corners.len().min(values.len());
    if n == 0 {
        return [0.0, 0.0];
    }
    if n < 3 {
        return values[0];
    }
    let mut best = (f64::NEG_INFINITY, [0.0, 0.0]);
    for i in 1..n - 1 {
        let (a, b, c) = (corners[0], corners[i], corners[i + 1]);
        let normal = (b - a).cross(c - a);
        let area2 = normal.length_squared();
        if area2 == 0.0 {
            continue;
        }
        let wa = (c - b).cross(p - b).dot(normal) / area2;
        let wb = (a - c).cross(p - c).dot(normal) / area2;
        let wc = 1.0 - wa - wb;
        let worst = wa.min(wb).min(wc);
        if worst > best.0 {
            let (va, vb, vc) = (values[0], values[i], values[i + 1]);
            best = (
                worst,
                [
                    wa * va[0] + wb * vb[0] + wc * vc[0],
                    wa * va[1] + wb * vb[1] + wc * vc[1],
                ],
            );
        }
        if worst >= 0.0 {
            break;
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_wind_counter_clockwise() {
        use json::mesh::Mode;
        assert_eq!(
            assemble(Mode::TriangleStrip, &[0, 1, 2, 3]),
            vec![[0, 1, 2], [2, 1, 3]]
        );
        assert_eq!(
            assemble(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![[1, 2, 0], [2, 3, 0]]
        );
        assert_eq!(assemble(Mode::Triangles, &[0, 1, 2, 3]), vec![[0, 1, 2]]);
    }

    #[test]
    fn fans_regroup_polygons() {
        let triangles = [
            [0, 1, 2],
            [0, 2, 3],
            [4, 5, 6],
            [4, 6, 7],
            [4, 7, 8],
            [9, 10, 11],
        ];
        assert_eq!(
            fans(&triangles),
            vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7, 8], vec![9, 10, 11]]
        );
    }

    #[test]
    fn fan_interpolation_is_linear_per_triangle() {
        let corners = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        let uvs = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        for (p, expected) in [
            (DVec3::new(1.0, 1.0, 0.0), [0.5, 0.5]),
            (DVec3::new(1.5, 0.5, 0.0), [0.75, 0.25]),
            (DVec3::new(0.5, 1.5, 0.0), [0.25, 0.75]),
            (DVec3::new(2.0, 2.0, 0.0), [1.0, 1.0]),
        ] {
            let got = interpolate_on_fan(&corners, &uvs, p);
            assert!(
                (got[0] - expected[0]).abs() < 1e-12 && (got[1] - expected[1]).abs() < 1e-12,
                "{p}: {got:?}"
            );
        }
    }
}
