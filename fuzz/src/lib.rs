//! Shared pieces of the fuzz targets: how an input is split into files, the
//! limits a fuzzed load runs under, and the invariants every loaded scene
//! must satisfy. A new loader's target is a few lines on top of these (see
//! fuzz_targets/obj.rs).

use std::path::{Path, PathBuf};

use radiosity::scene::{Limits, LoadOptions, Scene, SceneError, gltf, obj};
use radiosity::{geometry, sensors};

/// Limits small enough that one input runs in milliseconds.
pub const LIMITS: Limits = Limits {
    max_file_bytes: 1 << 20,
    max_line_bytes: 1 << 16,
    max_corners: 2_000,
    max_faces: 2_000,
    max_vertices: 10_000,
};

/// An input as an OBJ file and the MTL library it may name: the bytes
/// before the first NUL are the OBJ, the rest the MTL (a NUL is never valid
/// OBJ text, so nothing is lost).
#[must_use]
pub fn split(data: &[u8]) -> (&[u8], &[u8]) {
    match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, b"newmtl m\nKd 0.5\nKe 1\n"),
    }
}

/// Loads an input through the OBJ loader: every `mtllib` name resolves to
/// the MTL part.
pub fn load_obj(data: &[u8]) -> Result<Scene, SceneError> {
    let (obj_bytes, mtl_bytes) = split(data);
    obj::parse_bytes(
        "fuzz",
        Path::new("fuzz.obj"),
        obj_bytes,
        &LIMITS,
        &mut |name: &str| Ok((PathBuf::from(name), mtl_bytes.to_vec())),
    )
}

/// What every loaded scene guarantees to the stages after it: finite,
/// planar, convex, counter-clockwise surfaces with area, unit normals and
/// materials in range, and messages that are short enough to read.
pub fn check_scene(scene: &Scene) {
    assert!(!scene.surfaces.is_empty());
    for pane in &scene.panes {
        assert!(pane.polygon.len() >= 3 && pane.polygon.iter().all(|p| p.is_finite()));
        let t = pane.transmittance;
        assert!(t.min_element() >= 0.0 && t.max_element() <= 1.0, "{}", pane.material);
    }
    for portal in &scene.portals {
        assert!(portal.polygon.len() >= 3 && portal.polygon.iter().all(|p| p.is_finite()));
    }
    for light in &scene.lights {
        assert_eq!(light.validate(), Ok(()), "{}", light.name);
        if let Some(flux) = light.flux() {
            assert!(
                flux.is_finite() && flux.min_element() >= 0.0,
                "{}",
                light.name
            );
        }
    }
    for s in &scene.surfaces {
        assert!(s.polygon.len() >= 3);
        assert!(s.polygon.iter().all(|p| p.is_finite()));
        assert!(s.area > 0.0 && s.area.is_finite(), "area {}", s.area);
        assert!((s.normal.length() - 1.0).abs() < 1e-9);
        let size = s
            .polygon
            .iter()
            .map(|p| p.distance(s.polygon[0]))
            .fold(0.0, f64::max);
        for p in &s.polygon {
            let off = (s.normal.dot(*p) - s.offset).abs();
            assert!(
                off <= 1e-6 * size.max(1e-300),
                "off-plane corner: {off} of {size}"
            );
        }
        assert!(geometry::is_convex(
            &s.polygon,
            s.normal,
            1e-6 * size * size
        ));
        assert!(s.rho.min_element() >= 0.0 && s.rho.max_element() < 1.0);
        assert!(s.emission.min_element() >= 0.0 && s.emission.is_finite());
    }
    for w in &scene.warnings {
        assert!(w.len() < 2_000, "a warning of {} bytes", w.len());
    }
}

/// Error messages name a place and are short enough to read.
pub fn check_error(error: &SceneError) {
    let text = error.to_string();
    assert!(text.len() < 2_000, "a message of {} bytes", text.len());
    assert!(!text.is_empty());
}

/// An input as a glTF file and the one external file every URI resolves
/// to: a GLB (starting with the `glTF` magic) is the whole input and has no
/// external file; otherwise the bytes before the first NUL are the JSON
/// document and the rest the external file (a buffer or an image), as for
/// the OBJ targets.
#[must_use]
pub fn split_gltf(data: &[u8]) -> (&[u8], Option<&[u8]>) {
    if data.starts_with(b"glTF") {
        return (data, None);
    }
    match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], Some(&data[i + 1..])),
        None => (data, None),
    }
}

/// Loads an input through the glTF loader's from-bytes entry
/// (`gltf::load_slice`) under [`LIMITS`]; every URI that is not a `data:`
/// URI resolves to the external part, or is missing.
pub fn load_gltf(data: &[u8]) -> Result<(Scene, gltf::Appearance), SceneError> {
    let (document, external) = split_gltf(data);
    let options = LoadOptions {
        limits: LIMITS,
        ..LoadOptions::default()
    };
    gltf::load_slice(
        "fuzz",
        Path::new("fuzz.gltf"),
        document,
        &mut |_uri: &str| match external {
            Some(bytes) => Ok(bytes.to_vec()),
            None => Err(std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "no such file",
            )),
        },
        &options,
    )
}

/// What a glTF load guarantees beyond [`check_scene`]: the appearance kept
/// for the bake has one material and one set of texture coordinates per
/// surface, each with one entry per corner, and one image per image of the
/// document.
pub fn check_appearance(scene: &Scene, appearance: &gltf::Appearance) {
    assert_eq!(appearance.material.len(), scene.surfaces.len());
    assert_eq!(appearance.uvs.len(), scene.surfaces.len());
    for (surface, sets) in scene.surfaces.iter().zip(&appearance.uvs) {
        assert!(sets.len() <= appearance.texcoord_sets);
        for set in sets {
            assert_eq!(set.len(), surface.polygon.len());
            assert!(set.iter().all(|uv| uv[0].is_finite() && uv[1].is_finite()));
        }
    }
    for m in appearance.material.iter().flatten() {
        assert!(*m < appearance.json.materials.len());
    }
    assert_eq!(appearance.images.len(), appearance.json.images.len());
}

/// Most points a fuzzed points file may hold: each is placed in the scene.
pub const MAX_SENSORS: usize = 1_000;

/// Parses an input as a points file (`sensors::parse`, under [`LIMITS`]
/// and [`MAX_SENSORS`]) and places the points in the built-in Cornell box
/// (`sensors::receivers`).
pub fn check_sensors(data: &[u8]) {
    use std::sync::OnceLock;
    static CORNELL: OnceLock<Scene> = OnceLock::new();
    let scene = CORNELL.get_or_init(|| {
        // `receivers` places points on rayon's pool: one worker, so the
        // fuzzer stays on one core.
        // SAFETY: set once, before any thread of this process reads the
        // environment (rayon's pool starts on first use, after this).
        unsafe { std::env::set_var("RAYON_NUM_THREADS", "1") };
        radiosity::scene::builtin::load("cornell")
            .expect("a built-in scene")
            .expect("it loads")
    });
    let path = Path::new("fuzz.pts");
    let points = match sensors::parse(path, data, &LIMITS, MAX_SENSORS) {
        Ok(points) => points,
        Err(error) => {
            check_error(&error);
            assert!(error.to_string().starts_with("fuzz.pts"));
            return;
        }
    };
    assert!(!points.is_empty() && points.len() <= MAX_SENSORS);
    for pair in points.windows(2) {
        assert!(pair[0].line < pair[1].line);
    }
    for p in &points {
        assert!(p.line >= 1);
        assert!(p.position.is_finite());
        assert!(
            (p.normal.length() - 1.0).abs() < 1e-12,
            "normal {}",
            p.normal
        );
    }
    match sensors::receivers(scene, &points, path) {
        Ok(receivers) => {
            assert_eq!(receivers.len(), points.len());
            let index = sensors::SurfaceIndex::new(&scene.surfaces);
            for (point, r) in points.iter().zip(&receivers) {
                let surface = &scene.surfaces[r.surface as usize];
                assert_eq!(r.normal, surface.normal);
                assert!(surface.normal.dot(point.normal) > sensors::NORMAL_AGREEMENT);
                assert!(r.point.is_finite());
                let off = (surface.normal.dot(r.point) - surface.offset).abs();
                assert!(off <= 1e-9, "receiver {off} off its surface");
                assert!(
                    sensors::closest_point(surface, point.position).distance(point.position)
                        <= index.tolerance()
                );
            }
        }
        Err(error) => {
            check_error(&error);
            assert!(error.to_string().starts_with("fuzz.pts:"));
        }
    }
}

/// The IES LM-63 reader (`ies::parse`): any bytes give a profile whose
/// candela values and flux are finite and not negative in every
/// direction, or an error naming a line of the input.
pub fn check_ies(data: &[u8]) {
    // Lines end in LF, CR LF or CR alone, as the reader takes them.
    let lines = 1 + data
        .iter()
        .enumerate()
        .filter(|&(i, &b)| b == b'\n' || (b == b'\r' && data.get(i + 1) != Some(&b'\n')))
        .count();
    match radiosity::scene::ies::parse(data) {
        Ok(profile) => {
            assert!(profile.flux().is_finite() && profile.flux() >= 0.0);
            for gamma in [-1.0, 0.0, 12.5, 45.0, 90.0, 133.0, 180.0, 181.0] {
                for c in [-90.0, 0.0, 30.0, 90.0, 180.0, 270.0, 359.9, 725.0] {
                    let candela = profile.candela(gamma, c);
                    assert!(
                        candela.is_finite() && candela >= 0.0,
                        "{gamma} {c}: {candela}"
                    );
                    // Interpolation stays within the table (up to round-off).
                    assert!(
                        candela <= profile.peak() * (1.0 + 1e-12),
                        "{gamma} {c}: {candela}"
                    );
                }
            }
        }
        Err(error) => {
            assert!(error.line >= 1 && error.line <= lines, "{error}");
            assert!(!error.message.is_empty());
        }
    }
}

/// Lightmap settings for fuzzed inputs: small, so a hostile input's size
/// cannot make a large lightmap.
pub const LIGHTMAP: radiosity::export::lightmap::AtlasSettings =
    radiosity::export::lightmap::AtlasSettings {
        density: 8.0,
        max_size: 256,
        padding: 2,
    };

/// Rewrites a loaded glTF for a lightmap ([`LIGHTMAP`]); when that
/// succeeds, the document written must read back with as many placed
/// primitives, `TEXCOORD_1` inside [0, 1] on every one that has triangles.
pub fn check_lightmap(appearance: &gltf::Appearance) {
    use radiosity::export::lightmap;
    let Ok((layout, glb)) = lightmap::rewrite_blank(appearance, &LIGHTMAP) else {
        return;
    };
    assert!(layout.width <= LIGHTMAP.max_size && layout.height <= LIGHTMAP.max_size);
    let options = LoadOptions {
        limits: LIMITS,
        ..LoadOptions::default()
    };
    let back = gltf::load_slice(
        "fuzz",
        Path::new("blank.glb"),
        &glb,
        &mut |_| Err(std::io::Error::other("no external files")),
        &options,
    );
    // The written document holds the input's lights and emitters, so it
    // reads back whenever the input did (limits permitting).
    if let Ok((_, written)) = back {
        assert_eq!(written.primitives.len(), appearance.primitives.len());
        // A primitive with no triangle (fewer than three indices) draws
        // nothing and is left as it was.
        for p in written.primitives.iter().filter(|p| !p.triangles.is_empty()) {
            let uv = p.uv1.as_ref().expect("every placed primitive with triangles has TEXCOORD_1");
            assert!(uv.iter().flatten().all(|c| (0.0..=1.0).contains(c)));
        }
    }
}
