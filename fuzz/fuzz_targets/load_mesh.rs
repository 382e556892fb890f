//! Load, then mesh with the scene's own sizes under a small element limit:
//! small inputs (the size cap keeps each run in milliseconds) either mesh
//! into elements that tile every surface or give an error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use radiosity::mesh::{Mesh, MeshSettings};

/// Inputs larger than this are skipped: the whole path runs per input.
const MAX_INPUT: usize = 16 * 1024;

fuzz_target!(|data: &[u8]| {
    if data.len() > MAX_INPUT {
        return;
    }
    let scene = match radiosity_fuzz::load_obj(data) {
        Ok(scene) => scene,
        Err(error) => return radiosity_fuzz::check_error(&error),
    };
    radiosity_fuzz::check_scene(&scene);
    let settings = MeshSettings {
        max_elements: 20_000,
        bisect_triangles: true,
        ..MeshSettings::default()
    }
    .sized_for(&scene);
    let Ok(mesh) = Mesh::build(&scene, &settings) else {
        return;
    };
    assert!(mesh.elements.len() <= settings.max_elements);
    let surfaces: f64 = scene.surfaces.iter().map(|s| s.area).sum();
    let patches = mesh.total_area();
    assert!(
        (patches - surfaces).abs() <= 1e-6 * surfaces,
        "patches cover {patches} of {surfaces}"
    );
    for e in &mesh.elements {
        assert!(e.area.is_finite() && e.area >= 0.0);
    }
});
