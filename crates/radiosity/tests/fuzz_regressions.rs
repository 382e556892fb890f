//! Inputs the fuzzers in `fuzz/` found crashing (or hanging), replayed
//! through the same path as their target (an OBJ input is OBJ bytes, a NUL,
//! then the MTL every `mtllib` resolves to; then meshing with the scene's
//! own sizes; a glTF input is loaded from bytes) and checked to give the
//! error a user should see. RELIABILITY.md lists the findings.

use std::path::{Path, PathBuf};

use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::{Limits, LoadOptions, gltf, obj};

/// The bytes of a stored input.
fn input(name: &str) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions")
        .join(name);
    std::fs::read(&path).unwrap()
}

/// Loads and meshes a fuzz input as the `load_mesh` target does; the error
/// message if any step fails.
fn replay(name: &str) -> Result<usize, String> {
    let data = input(name);
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
    let mesh = Mesh::build(
        &scene,
        &MeshSettings {
            max_elements: 20_000,
            bisect_triangles: true,
            ..MeshSettings::default()
        }
        .sized_for(&scene),
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

/// Loads a glTF input as the `gltf` target does (under its limits: at most
/// 2,000 faces); the error message if it fails.
fn replay_gltf(name: &str, max_faces: usize) -> Result<usize, String> {
    let options = LoadOptions {
        limits: Limits {
            max_faces,
            ..Limits::default()
        },
        ..LoadOptions::default()
    };
    gltf::load_slice(
        "fuzz",
        Path::new("fuzz.gltf"),
        &input(name),
        &mut |_: &str| Err(std::io::Error::other("no external files")),
        &options,
    )
    .map(|(scene, _)| scene.surfaces.len())
    .map_err(|e| e.to_string())
}

/// A 436-byte glTF hung the `gltf` target (over 10 s an input): an accessor
/// with no buffer view may declare 4 million zero vertices (1.4 million
/// triangles, no bytes in the file behind them), and twenty nodes instance
/// its mesh, each costing about a second. Found by a hand-made input while
/// the target was written (the fuzzer itself did not reach it). The loader
/// now counts every instance's triangles against `--max-faces`.
#[test]
fn instanced_viewless_mesh_is_bounded_by_the_face_limit() {
    assert_eq!(
        replay_gltf("gltf-instanced-viewless-mesh.gltf", 2_000),
        Err(
            "fuzz.gltf: mesh 0, primitive 0: more than 2000 triangles in the scene, the limit \
             (raise it with --max-faces)"
                .into()
        )
    );
}
