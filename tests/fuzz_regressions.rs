//! Inputs the fuzzers in `fuzz/` found crashing, replayed through the same
//! path as their target (an input is OBJ bytes, a NUL, then the MTL every
//! `mtllib` resolves to; then meshing with the scene's own sizes) and
//! checked to give the error a user should see. RELIABILITY.md lists the
//! findings.

use std::path::{Path, PathBuf};

use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::{Limits, obj};

/// Loads and meshes a fuzz input as the `load_mesh` target does; the error
/// message if any step fails.
fn replay(name: &str) -> Result<usize, String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions")
        .join(name);
    let data = std::fs::read(&path).unwrap();
    let split = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let (obj_bytes, mtl_bytes) = (&data[..split], data.get(split + 1..).unwrap_or(&[]));
    let scene = obj::parse_bytes(
        "fuzz",
        Path::new("fuzz.obj"),
        obj_bytes,
        &Limits::default(),
        &mut |lib: &str| Ok((PathBuf::from(lib), mtl_bytes.to_vec())),
    )
    .map_err(|e| e.to_string())?;
    let sizes = scene.default_mesh_sizes();
    let mesh = Mesh::build(
        &scene,
        &MeshSettings {
            patch_size: sizes.patch_size,
            element_size: sizes.element_size,
            max_elements: 20_000,
            bisect_triangles: true,
        },
    )
    .map_err(|e| e.to_string())?;
    Ok(mesh.elements.len())
}

/// Crash load_mesh-7996e258 (a mangled Cornell box), cut down to its face:
/// a bow-tie 0.08 mm out of plane. Newell's normal lay along the face, the
/// face looked simple seen along it, and choosing the flatter diagonal
/// panicked ("a simple quad has an interior diagonal").
#[test]
fn slightly_non_planar_bow_tie() {
    assert_eq!(
        replay("load_mesh-7996e258-minimized"),
        Err(
            "fuzz.obj:7: the face's outline crosses itself (its edge from corner 1 to 2 meets \
             its edge from corner 3 to 4): a face must be a simple polygon, so split it into \
             faces that are"
                .into()
        )
    );
}
