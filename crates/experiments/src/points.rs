//! Points the experiments score beyond the paper's vertices (Wong & Tsang
//! 1993 compare vertex radiosities only): points drawn uniformly by area
//! over a scene's surfaces, a fixed sequence so their Radiance reference is
//! cached, and the vertices CSV rows the reference harness scores.

use std::path::Path;

use glam::DVec3;

use super::{Error, write_file};
use radiosity::export;
use radiosity::scene::Scene;
use radiosity::sensors::SensorPoint;

/// Uniform numbers in [0, 1) by SplitMix64 from `seed`: the same sequence
/// on every machine.
pub fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Sensor points `validate` scores per scene.
pub const SENSOR_POINTS: usize = 300;

/// `n` points drawn uniformly by area over `scene`'s surfaces (a fixed
/// sequence for a given scene), each with its surface's normal and index.
#[must_use]
pub fn random_points(scene: &Scene, n: usize) -> Vec<(SensorPoint, usize)> {
    // A fixed seed: the same points, so the same cached reference, on
    // every run.
    let mut unit = uniform(0x5EED);
    let mut triangles = Vec::new();
    for (index, surface) in scene.surfaces.iter().enumerate() {
        let v0 = surface.polygon[0];
        for pair in surface.polygon[1..].windows(2) {
            let area = (pair[0] - v0).cross(pair[1] - v0).length() / 2.0;
            triangles.push(([v0, pair[0], pair[1]], area, index));
        }
    }
    let total: f64 = triangles.iter().map(|t| t.1).sum();
    (0..n)
        .map(|_| {
            let mut pick = unit() * total;
            let &(corners, _, surface) = triangles
                .iter()
                .find(|t| {
                    pick -= t.1;
                    pick < 0.0
                })
                .unwrap_or_else(|| triangles.last().expect("a scene has surfaces"));
            let (mut a, mut b) = (unit(), unit());
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            let position =
                corners[0] + (corners[1] - corners[0]) * a + (corners[2] - corners[0]) * b;
            (
                SensorPoint {
                    position,
                    normal: scene.surfaces[surface].normal,
                    line: 0,
                },
                surface,
            )
        })
        .collect()
}

/// Writes rows of a vertices CSV (`export::VERTEX_CSV_HEADER`): position,
/// normal, input face and `B`.
pub fn write_rows(path: &Path, rows: &[(DVec3, DVec3, u32, DVec3)]) -> Result<(), Error> {
    let mut text = String::from(export::VERTEX_CSV_HEADER);
    text.push('\n');
    for (p, n, face, b) in rows {
        text.push_str(&format!(
            "{},{},{},{},{},{},{face},{},{},{}\n",
            p.x, p.y, p.z, n.x, n.y, n.z, b.x, b.y, b.z
        ));
    }
    write_file(path, text.as_bytes())
}
