//! The colours of a glTF bake ([`crate::export::gltf`]) from a solved
//! state: what `COLOR_0` holds in each bake mode, and the metadata written
//! beside it.

use crate::export::gltf::BakeMode;
use crate::solver::Solver;

/// The `COLOR_0` values of a bake and the metadata recorded beside them
/// (see [`crate::export::gltf`]): [`bake_values`] clamped to [0, 1].
#[must_use]
pub fn bake_colours(
    solver: &Solver<'_>,
    mode: BakeMode,
    display: &[glam::DVec3],
    exposure: f64,
    ambient: bool,
) -> (Vec<glam::DVec3>, serde_json::Value) {
    let (values, metadata) = bake_values(solver, mode, display, exposure, ambient);
    let colours: Vec<glam::DVec3> = values
        .iter()
        .map(|v| v.clamp(glam::DVec3::ZERO, glam::DVec3::ONE))
        .collect();
    (colours, metadata)
}

/// The values a bake holds per mesh vertex before clamping, and the
/// metadata recorded beside them: `color_scale x radiance`, the radiance
/// being `B_shown / pi` (lit) or `(E + ambient) / pi` (irradiance). Lit
/// uses the picture's exposure; irradiance uses it too unless that would
/// clip a vertex, then the largest scale that does not.
#[must_use]
pub fn bake_values(
    solver: &Solver<'_>,
    mode: BakeMode,
    display: &[glam::DVec3],
    exposure: f64,
    ambient: bool,
) -> (Vec<glam::DVec3>, serde_json::Value) {
    use std::f64::consts::PI;
    let ambient_term = if ambient {
        solver.ambient()
    } else {
        glam::DVec3::ZERO
    };
    let (radiance, mut scale, quantity): (Vec<glam::DVec3>, f64, &str) = match mode {
        BakeMode::Lit => (
            display.iter().map(|b| *b / PI).collect(),
            PI * exposure,
            "radiance shown by the picture, B/pi with the ambient term, W/(m^2 sr)",
        ),
        BakeMode::Irradiance => (
            solver
                .irradiance()
                .iter()
                .map(|e| (*e + ambient_term) / PI)
                .collect(),
            PI * exposure,
            "irradiance over pi, (E + ambient)/pi, W/(m^2 sr): multiply by the base colour",
        ),
    };
    if mode == BakeMode::Irradiance {
        let peak = radiance.iter().map(|r| r.max_element()).fold(0.0, f64::max);
        if peak * scale > 1.0 {
            scale = 1.0 / peak;
        }
    }
    let values: Vec<glam::DVec3> = radiance.iter().map(|r| *r * scale).collect();
    let metadata = serde_json::json!({
        "bake_mode": mode.name(),
        "color_0": quantity,
        "color_scale": scale,
        "ambient": ambient_term.to_array(),
        "picture_exposure": exposure,
    });
    (values, metadata)
}
