//! glTF 2.0 in and out: the hand-written scene (tests/data/hierarchy.gltf,
//! tools/gen_gltf_tests.py) and the Blender export (tests/data/
//! blender-cornell.glb, tools/blender_cornell.py) load with the transforms,
//! materials and camera worked out by hand; bakes, PLY and EXR hold what
//! `--vertices` and the picture hold; the built-in scenes survive an
//! `export-scene` round trip bit for bit; every bad input gets its one
//! error. No Node or browser here: the Khronos validator and the viewer run
//! in web/test/.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use approx::{abs_diff_eq, assert_abs_diff_eq, relative_eq};
use glam::DVec3;
use radiosity::app::{self, BakeJob, ImageJob, Job};
use radiosity::export::gltf::BakeMode;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::render::Exposure;
use radiosity::scene::{self, LoadOptions, Scene, gltf};
use radiosity::solver::patches::PatchSettings;
use radiosity::solver::{Flow, Settings, Solver, Visibility};
use serde_json::{Value, json};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("data")
        .join(name)
}

fn load(path: &Path) -> Scene {
    scene::load_with(path.to_str().unwrap(), &LoadOptions::default())
        .unwrap()
        .scene
}

/// sRGB decoding, written out independently of the loader's.
fn srgb_decode(v: u8) -> f64 {
    let c = f64::from(v) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn bounds(polygon: &[DVec3]) -> (DVec3, DVec3) {
    let lo = polygon.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
    let hi = polygon.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(*p));
    (lo, hi)
}

#[test]
fn hierarchy_transforms_materials_camera_and_warnings() {
    let path = data("hierarchy.gltf");
    let scene = load(&path);
    // floor 2 + rug 2 + lamp 2 + panel 2 x 2 (double-sided); POINTS skipped.
    assert_eq!(scene.surfaces.len(), 10);
    let faces: Vec<u32> = scene.surfaces.iter().map(|s| s.face).collect();
    assert_eq!(faces, [0, 1, 2, 3, 4, 5, 6, 6, 7, 7]);

    // Floor: room scale 2 x floor matrix (90 degrees about y): 2 x 2 m at
    // y = 0, facing up, textured: 0.8 x mean of the linear texels.
    let texel_mean = (srgb_decode(255) + 2.0 * srgb_decode(0) + srgb_decode(128)) / 4.0;
    let floor_rho = DVec3::splat(0.8 * texel_mean);
    for s in &scene.surfaces[0..2] {
        assert!(
            abs_diff_eq!(s.normal, DVec3::Y, epsilon = 1e-12),
            "{}",
            s.normal
        );
        assert!(abs_diff_eq!(s.area, 2.0, epsilon = 1e-12), "{}", s.area);
        let (lo, hi) = bounds(&s.polygon);
        assert!(
            abs_diff_eq!(lo, DVec3::new(-1.0, 0.0, -1.0), epsilon = 1e-12),
            "{lo}"
        );
        assert!(
            abs_diff_eq!(hi, DVec3::new(1.0, 0.0, 1.0), epsilon = 1e-12),
            "{hi}"
        );
        assert!(
            abs_diff_eq!(s.rho, floor_rho, epsilon = 1e-12),
            "{} vs {floor_rho}",
            s.rho
        );
        assert_eq!(s.emission, DVec3::ZERO);
    }
    // Rug: a mirrored node (scale -0.5 in x) under the floor: the winding
    // flips with the determinant, so it still faces up; 1 x 1 m at y = 0.01.
    for s in &scene.surfaces[2..4] {
        assert!(
            abs_diff_eq!(s.normal, DVec3::Y, epsilon = 1e-12),
            "{}",
            s.normal
        );
        assert_abs_diff_eq!(s.area, 0.5, epsilon = 1e-12);
        let (lo, hi) = bounds(&s.polygon);
        assert!(
            abs_diff_eq!(lo, DVec3::new(-0.5, 0.01, -0.5), epsilon = 1e-12),
            "{lo}"
        );
        assert!(
            abs_diff_eq!(hi, DVec3::new(0.5, 0.01, 0.5), epsilon = 1e-12),
            "{hi}"
        );
        assert_eq!(s.rho, DVec3::new(0.5, 0.25, 0.125));
    }
    // Lamp: rotated 180 degrees about x (faces down), 0.5 x 0.5 m at
    // y = 2.4; exitance pi x emissive (1, 0.5, 0.25) x strength 8; its white
    // base colour is capped at 0.9.
    for s in &scene.surfaces[4..6] {
        assert!(
            abs_diff_eq!(s.normal, -DVec3::Y, epsilon = 1e-12),
            "{}",
            s.normal
        );
        assert_abs_diff_eq!(s.area, 0.125, epsilon = 1e-12);
        let (lo, hi) = bounds(&s.polygon);
        assert!(
            abs_diff_eq!(lo, DVec3::new(-0.25, 2.4, -0.25), epsilon = 1e-12),
            "{lo}"
        );
        assert!(
            abs_diff_eq!(hi, DVec3::new(0.25, 2.4, 0.25), epsilon = 1e-12),
            "{hi}"
        );
        assert_eq!(s.emission, PI * 8.0 * DVec3::new(1.0, 0.5, 0.25));
        assert_eq!(s.rho, DVec3::splat(0.9));
    }
    // Panel: a matrix (rotation -90 degrees about z, translation) under the
    // room's scale: x = -1.2, y in [0, 2], z in [-1, 1], facing +x; double
    // sided, so each triangle is followed by its reversed twin facing -x.
    for pair in scene.surfaces[6..10].chunks(2) {
        let (front, back) = (&pair[0], &pair[1]);
        assert!(
            abs_diff_eq!(front.normal, DVec3::X, epsilon = 1e-12),
            "{}",
            front.normal
        );
        assert!(
            abs_diff_eq!(back.normal, -DVec3::X, epsilon = 1e-12),
            "{}",
            back.normal
        );
        let mut reversed = back.polygon.clone();
        reversed.reverse();
        assert_eq!(front.polygon, reversed);
        assert_eq!(
            (front.rho, back.rho),
            (pair[0].rho, DVec3::new(0.2, 0.4, 0.6))
        );
        let (lo, hi) = bounds(&front.polygon);
        assert_abs_diff_eq!(lo.x, -1.2, epsilon = 1e-12);
        assert_abs_diff_eq!(hi.x, -1.2, epsilon = 1e-12);
        assert_abs_diff_eq!(lo.y, 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(hi.y, 2.0, epsilon = 1e-12);
        assert_abs_diff_eq!(hi.z, 1.0, epsilon = 1e-12);
    }
    // Camera node: translation (0, 0.5, 1.5) under the room's scale 2.
    let camera = scene.camera.expect("the file has a camera");
    assert!(
        abs_diff_eq!(camera.eye, DVec3::new(0.0, 1.0, 3.0), epsilon = 1e-12),
        "{}",
        camera.eye
    );
    assert!(abs_diff_eq!(
        (camera.target - camera.eye).normalize(),
        -DVec3::Z,
        epsilon = 1e-12
    ));
    assert_abs_diff_eq!(camera.fov_degrees, 0.8f64.to_degrees(), epsilon = 1e-9);
    // One warning each: the POINTS primitive, the punctual light, the cap.
    let warnings = scene.warnings.join("\n");
    assert_eq!(scene.warnings.len(), 3, "{warnings}");
    let file = path.display();
    assert!(warnings.contains(&format!(
        "{file}: mesh 4 ('markers'), primitive 0 has mode POINTS: ignored"
    )));
    assert!(warnings.contains(&format!(
        "{file}: ignored 1 KHR_lights_punctual light(s): light 0 ('sun lamp')"
    )));
    assert!(warnings.contains(&format!(
        "{file}: reflectance above 0.9 clamped (--reflectance-cap) for material 2 ('lamp')"
    )));
}

#[test]
fn emission_scale_and_reflectance_cap_apply() {
    let path = data("hierarchy.gltf");
    let options = LoadOptions {
        limits: Default::default(),
        reflectance_cap: 0.5,
        emission_scale: 0.25,
    };
    let scene = scene::load_with(path.to_str().unwrap(), &options)
        .unwrap()
        .scene;
    assert_eq!(
        scene.surfaces[4].emission,
        PI * 2.0 * DVec3::new(1.0, 0.5, 0.25)
    );
    assert_eq!(scene.surfaces[4].rho, DVec3::splat(0.5));
    // The rug (0.5, 0.25, 0.125) is at the cap, not above it: unchanged.
    assert_eq!(scene.surfaces[2].rho, DVec3::new(0.5, 0.25, 0.125));
    for bad in [1.0, 0.0, f64::NAN] {
        let options = LoadOptions {
            reflectance_cap: bad,
            ..LoadOptions::default()
        };
        assert!(options.validate().is_err(), "{bad}");
    }
}

/// The Blender export of the Cornell box (Blender 3.4's own OBJ importer
/// and glTF exporter, tools/blender_cornell.py) reads back as the Cornell
/// box: same camera, reflectances, exitance and area; Blender writes
/// materials double-sided unless "Backface Culling" is ticked, so every
/// triangle arrives twice, back to back. Solved, its walls match the
/// built-in box's within the difference of their meshes.
#[test]
fn blender_export_renders_like_the_builtin_box() {
    let blender = load(&data("blender-cornell.glb"));
    let cornell = scene::load("cornell").unwrap();
    let camera = blender.camera.expect("Blender exported the camera");
    let reference = cornell.camera.unwrap();
    assert!(
        abs_diff_eq!(camera.eye, reference.eye, epsilon = 1e-5),
        "{}",
        camera.eye
    );
    let forward = (camera.target - camera.eye).normalize();
    assert!(abs_diff_eq!(forward, DVec3::Z, epsilon = 1e-5), "{forward}");
    assert_abs_diff_eq!(camera.fov_degrees, reference.fov_degrees, epsilon = 1e-3);
    let fronts: Vec<_> = blender.surfaces.iter().step_by(2).collect();
    assert_eq!(fronts.len() * 2, blender.surfaces.len());
    let area = |surfaces: &mut dyn Iterator<Item = &radiosity::scene::Surface>| {
        surfaces.map(|s| s.area).sum::<f64>()
    };
    let (a, b) = (
        area(&mut fronts.iter().copied()),
        area(&mut cornell.surfaces.iter()),
    );
    assert!(
        relative_eq!(a, b, epsilon = 0.0, max_relative = 1e-5),
        "{a} vs {b}"
    );
    let exitance = PI * DVec3::new(17.0, 12.0, 4.0);
    for s in &blender.surfaces {
        let known = cornell.surfaces.iter().any(|c| {
            abs_diff_eq!(c.rho, s.rho, epsilon = 1e-6)
                && abs_diff_eq!(c.emission, s.emission, epsilon = 1e-4)
        });
        assert!(known, "rho {} emission {}", s.rho, s.emission);
        if s.is_emitter() {
            assert!(
                abs_diff_eq!(s.emission, exitance, epsilon = 1e-4),
                "{}",
                s.emission
            );
        }
    }

    // Area-weighted mean radiosity of the red and green walls after the
    // same coarse solve of both.
    let wall_means = |scene: &Scene| {
        let settings = Settings {
            mesh: MeshSettings {
                patch_size: 0.3,
                element_size: 0.1,
                max_elements: 100_000,
                bisect_triangles: false,
            },
            converge: 0.01,
            method: PatchSettings {
                visibility: Visibility::HemicubePretest,
                subsources: 2,
                hemicube_resolution: 96,
            }
            .into(),
            ..Settings::wong_tsang93()
        };
        let mesh = Mesh::build(scene, &settings.mesh).unwrap();
        let mut solver = Solver::new(scene, &mesh, settings);
        solver.run(|_| Flow::Continue);
        let mut sums = [DVec3::ZERO; 2];
        let mut areas = [0.0; 2];
        for element in &mesh.elements {
            let corners = element.vertices();
            let surface = &scene.surfaces[mesh.vertices[corners[0] as usize].surface as usize];
            // Red wall (rho.x > 0.5 > rho.y) and green wall (rho.y > 0.4 > rho.x), fronts only.
            let wall = if surface.rho.x > 0.5 && surface.rho.y < 0.1 {
                0
            } else if surface.rho.y > 0.4 && surface.rho.x < 0.2 {
                1
            } else {
                continue;
            };
            if surface
                .normal
                .dot(DVec3::new(0.278, 0.27, 0.28) - surface.polygon[0])
                <= 0.0
            {
                continue;
            }
            let b: DVec3 = corners
                .iter()
                .map(|c| solver.radiosity()[*c as usize])
                .sum::<DVec3>()
                / corners.len() as f64;
            sums[wall] += b * element.area;
            areas[wall] += element.area;
        }
        [sums[0] / areas[0], sums[1] / areas[1]]
    };
    let (ours, theirs) = (wall_means(&cornell), wall_means(&blender));
    for (o, t) in ours.iter().zip(&theirs) {
        let relative = ((*o - *t).abs() / *o).max_element();
        assert!(relative < 0.03, "built-in {o} vs Blender {t}");
    }
}

/// A double-sided panel between two lamps (red on its +x side, blue on its
/// -x side): each side receives its own lamp's light only, and the
/// hemicube pre-test decides every pair as ray casting does, although the
/// two faces lie in one plane.
#[test]
fn double_sided_faces_receive_on_both_sides_without_leaks() {
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0},
            {"mesh": 1, "translation": [1, 0, 0]},
            {"mesh": 2, "translation": [-1, 0, 0]},
        ],
        "meshes": [
            {"name": "panel", "primitives": [{"attributes": {"POSITION": 0}, "indices": 3, "material": 0}]},
            {"name": "red lamp", "primitives": [{"attributes": {"POSITION": 1}, "indices": 3, "material": 1}]},
            {"name": "blue lamp", "primitives": [{"attributes": {"POSITION": 2}, "indices": 3, "material": 2}]},
        ],
        "materials": [
            {"name": "panel", "doubleSided": true, "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}},
            {"name": "red", "emissiveFactor": [1, 0, 0], "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]}},
            {"name": "blue", "emissiveFactor": [0, 0, 1], "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]}},
        ],
    });
    // Panel in the plane x = 0 facing +x; the red lamp at x = 1 facing -x,
    // the blue lamp at x = -1 facing +x.
    let panel = [
        [0.0, -0.5, -0.5],
        [0.0, 0.5, -0.5],
        [0.0, 0.5, 0.5],
        [0.0, -0.5, 0.5],
    ];
    let facing_minus_x = [
        [0.0, -0.5, -0.5],
        [0.0, -0.5, 0.5],
        [0.0, 0.5, 0.5],
        [0.0, 0.5, -0.5],
    ];
    let (bytes, bin) = with_buffers(doc, &[&panel, &facing_minus_x, &panel], &[0, 1, 2, 0, 2, 3]);
    let (scene, _) = gltf::load_slice(
        "panel",
        Path::new("panel.gltf"),
        &bytes,
        &mut |_: &str| Ok(bin.clone()),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(scene.surfaces.len(), 2 * 2 + 2 + 2);
    let solve = |visibility: Visibility| {
        let settings = Settings {
            mesh: MeshSettings {
                patch_size: 1.0,
                element_size: 0.125,
                max_elements: 100_000,
                bisect_triangles: false,
            },
            method: PatchSettings {
                visibility,
                ..PatchSettings::default()
            }
            .into(),
            max_shots: Some(40),
            ..Settings::wong_tsang93()
        };
        let mesh = Mesh::build(&scene, &settings.mesh).unwrap();
        let radiosity = {
            let mut solver = Solver::new(&scene, &mesh, settings);
            solver.run(|_| Flow::Continue);
            solver.radiosity().to_vec()
        };
        (mesh, radiosity)
    };
    let (mesh, pretest) = solve(Visibility::HemicubePretest);
    let (_, rays) = solve(Visibility::Ray);
    let mut sides = [DVec3::ZERO; 2];
    for (v, (p, r)) in mesh.vertices.iter().zip(pretest.iter().zip(&rays)) {
        assert!(
            abs_diff_eq!(*p, *r, epsilon = 1e-12 * (1.0 + r.length())),
            "{p} vs {r}"
        );
        if scene.surfaces[v.surface as usize].rho.x == 0.5 {
            let side = usize::from(v.normal.x < 0.0);
            sides[side] += *p;
        }
    }
    // Front (+x) sees only red, back (-x) only blue, in equal amounts.
    assert!(sides[0].x > 0.0 && sides[0].z == 0.0, "{}", sides[0]);
    assert!(sides[1].z > 0.0 && sides[1].x == 0.0, "{}", sides[1]);
    assert_abs_diff_eq!(sides[0].x, sides[1].z, epsilon = 1e-9 * sides[0].x);
}

/// A glTF JSON document with one external buffer holding `quads`
/// (positions, `[f32; 3]` each) followed by `indices` (u16): accessor k < n
/// is quad k's positions, accessor n the indices. Returns the JSON bytes
/// and the buffer.
fn with_buffers(mut doc: Value, quads: &[&[[f32; 3]; 4]], indices: &[u16]) -> (Vec<u8>, Vec<u8>) {
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    for (k, quad) in quads.iter().enumerate() {
        let offset = bin.len();
        for p in quad.iter() {
            for c in p {
                bin.extend(c.to_le_bytes());
            }
        }
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": 48}));
        let lo: Vec<f32> = (0..3)
            .map(|i| quad.iter().map(|p| p[i]).fold(f32::INFINITY, f32::min))
            .collect();
        let hi: Vec<f32> = (0..3)
            .map(|i| quad.iter().map(|p| p[i]).fold(f32::NEG_INFINITY, f32::max))
            .collect();
        accessors.push(json!({"bufferView": k, "componentType": 5126, "count": 4, "type": "VEC3", "min": lo, "max": hi}));
    }
    let offset = bin.len();
    for i in indices {
        bin.extend(i.to_le_bytes());
    }
    views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": 2 * indices.len()}));
    accessors.push(json!({"bufferView": quads.len(), "componentType": 5123, "count": indices.len(), "type": "SCALAR"}));
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    doc["buffers"] = json!([{"uri": "scene.bin", "byteLength": bin.len()}]);
    doc["bufferViews"] = Value::Array(views);
    doc["accessors"] = Value::Array(accessors);
    (serde_json::to_vec(&doc).unwrap(), bin)
}

/// One emissive triangle: the smallest valid input, which the bad-input
/// tests break one piece at a time. Buffer: 3 positions (36 bytes), then
/// indices 0 1 2 as u16 (6 bytes + 2 padding).
fn triangle() -> (Value, Vec<u8>) {
    let positions: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mut bin: Vec<u8> = positions
        .iter()
        .flat_map(|p| p.iter().flat_map(|c| c.to_le_bytes()))
        .collect();
    bin.extend([0u16, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
    bin.extend([0, 0]);
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "tri", "mesh": 0}],
        "meshes": [{"name": "shape", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"name": "glow", "emissiveFactor": [1, 1, 1]}],
        "buffers": [{"uri": "tri.bin", "byteLength": 44}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
        ],
    });
    (doc, bin)
}

/// Loads a document whose buffer `tri.bin` is `bin`; returns the error
/// message.
fn load_error(doc: &Value, bin: &[u8]) -> String {
    let bytes = serde_json::to_vec(doc).unwrap();
    load_bytes_error(&bytes, bin)
}

fn load_bytes_error(bytes: &[u8], bin: &[u8]) -> String {
    let result = gltf::load_slice(
        "bad",
        Path::new("bad.gltf"),
        bytes,
        &mut |uri: &str| {
            if uri == "tri.bin" {
                Ok(bin.to_vec())
            } else {
                Err(std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "no such file",
                ))
            }
        },
        &LoadOptions::default(),
    );
    match result {
        Ok(_) => panic!("loaded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn the_valid_triangle_loads() {
    let (doc, bin) = triangle();
    let bytes = serde_json::to_vec(&doc).unwrap();
    let (scene, appearance) = gltf::load_slice(
        "tri",
        Path::new("tri.gltf"),
        &bytes,
        &mut |_: &str| Ok(bin.clone()),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(scene.surfaces.len(), 1);
    assert_eq!(scene.surfaces[0].emission, DVec3::splat(PI));
    assert_eq!(scene.surfaces[0].rho, DVec3::splat(0.9));
    assert_eq!(appearance.material, [Some(0)]);
}

/// `n` nested nodes each scaling by 1e38, the last holding mesh 0.
fn scaled_chain(n: usize) -> Value {
    Value::Array(
        (0..n)
            .map(|i| {
                let mut node = json!({"scale": [1e38, 1e38, 1e38]});
                if i + 1 < n {
                    node["children"] = json!([i + 1]);
                } else {
                    node["mesh"] = json!(0);
                }
                node
            })
            .collect(),
    )
}

#[test]
fn every_bad_input_gets_its_error() {
    let (base, bin) = triangle();
    let with = |edit: &dyn Fn(&mut Value)| {
        let mut doc = base.clone();
        edit(&mut doc);
        doc
    };
    let cases: Vec<(Value, Vec<u8>, &str)> = vec![
        (
            with(&|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(7)),
            bin.clone(),
            "mesh 0 ('shape'), primitive 0, POSITION refers to accessor 7, but the file has 2",
        ),
        (
            with(&|d| d["accessors"][0]["byteOffset"] = json!(24)),
            bin.clone(),
            "mesh 0 ('shape'), primitive 0, POSITION accessor 0: its 3 elements of 12 bytes from \
             byte 24 run past the end of buffer view 0 (36 bytes)",
        ),
        (
            with(&|d| d["accessors"][0]["count"] = json!(4)),
            bin.clone(),
            "mesh 0 ('shape'), primitive 0, POSITION accessor 0: its 4 elements of 12 bytes from \
             byte 0 run past the end of buffer view 0 (36 bytes)",
        ),
        (
            base.clone(),
            {
                let mut b = bin.clone();
                b[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
                b
            },
            "mesh 0 ('shape'), primitive 0, POSITION accessor 0: element 1 has a non-finite value \
             (NaN)",
        ),
        (
            base.clone(),
            {
                let mut b = bin.clone();
                b[40..42].copy_from_slice(&5u16.to_le_bytes());
                b
            },
            "mesh 0 ('shape'), primitive 0, indices accessor 1: index 5 (entry 2) is past the \
             vertex count 3",
        ),
        (
            with(&|d| d["bufferViews"][0]["byteLength"] = json!(999)),
            bin.clone(),
            "buffer view 0 (bytes 0 + 999 of buffer 0) runs past the buffer's 44 bytes",
        ),
        (
            base.clone(),
            bin[..20].to_vec(),
            "buffer 0 declares 44 bytes but has only 20 (truncated?)",
        ),
        (
            with(&|d| d["buffers"][0]["uri"] = json!("missing.bin")),
            bin.clone(),
            "buffer 0: cannot read 'missing.bin': no such file",
        ),
        (
            with(&|d| d["buffers"][0]["uri"] = json!("https://example.com/tri.bin")),
            bin.clone(),
            "buffer 0: 'https://example.com/tri.bin' is a URL; radiosity reads only files beside \
             the glTF and embedded data",
        ),
        (
            with(&|d| d["accessors"][0]["type"] = json!("VEC2")),
            bin.clone(),
            "mesh 0 ('shape'), primitive 0, POSITION accessor 0 is Vec2, expected Vec3",
        ),
        (
            with(&|d| {
                d["accessors"][0] =
                    json!({"componentType": 5126, "count": 4294967295u64, "type": "VEC3"})
            }),
            bin.clone(),
            "mesh 0 ('shape'), primitive 0, POSITION accessor 0 has no buffer view but declares \
             4294967295 elements (at most 4194304)",
        ),
        (
            with(&|d| d["accessors"][1]["componentType"] = json!(5126)),
            bin.clone(),
            "mesh 0 ('shape'), primitive 0, indices accessor 1 must hold unsigned integers",
        ),
        (
            with(&|d| {
                d["nodes"] = json!([{"name": "a", "children": [1]}, {"name": "b", "children": [0], "mesh": 0}])
            }),
            bin.clone(),
            "node 0 ('a') is reached twice: the node hierarchy must be a tree (no cycles, one \
             parent each)",
        ),
        (
            with(&|d| d["scenes"][0]["nodes"] = json!([3])),
            bin.clone(),
            "a scene or node refers to node 3, but the file has 1",
        ),
        (
            with(&|d| {
                d["materials"][0]["emissiveFactor"] = json!([0, 0, 0]);
                d["extensionsUsed"] = json!(["KHR_lights_punctual"]);
                d["extensions"] =
                    json!({"KHR_lights_punctual": {"lights": [{"name": "bulb", "type": "point"}]}});
                d["nodes"] = json!([{"name": "tri", "mesh": 0, "extensions": {"KHR_lights_punctual": {"light": 0}}}]);
            }),
            bin.clone(),
            "the scene has no emitter: no material has an emissiveFactor > 0; its \
             KHR_lights_punctual lights (light 0 ('bulb')) are not area lights and are ignored; \
             give the lamps a mesh with an emissive material",
        ),
        (
            with(&|d| d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])),
            bin.clone(),
            "the file requires extension KHR_draco_mesh_compression, which radiosity does not \
             support (supported: KHR_materials_emissive_strength, KHR_mesh_quantization, \
             KHR_texture_transform, KHR_materials_unlit, KHR_lights_punctual)",
        ),
        (
            with(&|d| d["asset"]["version"] = json!("1.0")),
            bin.clone(),
            "asset version '1.0': only glTF 2.0 is supported",
        ),
        (
            with(&|d| d["nodes"][0]["rotation"] = json!([0, 0, 0, 0])),
            bin.clone(),
            "node 0 ('tri'): rotation [0.0, 0.0, 0.0, 0.0] is not a unit quaternion",
        ),
        (
            with(&|d| d["nodes"] = scaled_chain(8)),
            {
                let mut b = bin.clone();
                b[12..16].copy_from_slice(&3e38f32.to_le_bytes());
                b
            },
            "mesh 0 ('shape'), primitive 0: a transformed position is not finite",
        ),
        (
            with(&|d| d["nodes"] = scaled_chain(9)),
            bin.clone(),
            "node 8: its world transform is not finite",
        ),
        (
            with(&|d| {
                d["materials"][0]["pbrMetallicRoughness"] =
                    json!({"baseColorTexture": {"index": 0}});
                d["textures"] = json!([{"source": 0}]);
                d["images"] =
                    json!([{"name": "broken", "uri": "data:image/png;base64,iVBORw0KGgo="}]);
            }),
            bin.clone(),
            "material 0 ('glow'): image 0 ('broken'): cannot decode:",
        ),
        (
            with(&|d| d["meshes"][0]["primitives"][0]["mode"] = json!(0)),
            bin.clone(),
            "the scene has no triangles",
        ),
        (
            with(&|d| {
                d["bufferViews"][0]["byteStride"] = json!(4);
            }),
            bin.clone(),
            "mesh 0 ('shape'), primitive 0, POSITION accessor 0: its byte stride 4 is smaller than \
             an element (12 bytes)",
        ),
    ];
    for (doc, bin, expected) in cases {
        let message = load_error(&doc, &bin);
        let expected = format!("bad.gltf: {expected}");
        assert!(
            message == expected || (expected.ends_with(':') && message.starts_with(&expected)),
            "\n got: {message}\nwant: {expected}"
        );
    }
    // Not glTF at all, and an empty file.
    let message = load_bytes_error(b"{\"asset\": 3", &bin);
    assert!(
        message.starts_with("bad.gltf: not a valid glTF 2.0 file:"),
        "{message}"
    );
    assert_eq!(load_bytes_error(b"", &bin), "bad.gltf: the file is empty");
}

/// A real `.glb` from the exporter, cut short or with its header broken.
#[test]
fn truncated_and_broken_glb_files_get_their_error() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("cornell.glb");
    app::export_scene("cornell", &glb, &LoadOptions::default()).unwrap();
    let bytes = std::fs::read(&glb).unwrap();
    let n = bytes.len();
    let cut = dir.path().join("cut.glb");
    std::fs::write(&cut, &bytes[..n / 2]).unwrap();
    let message = scene::load(cut.to_str().unwrap()).unwrap_err().to_string();
    assert_eq!(
        message,
        format!(
            "{}: truncated GLB: the header gives {n} bytes, the file has {}",
            cut.display(),
            n / 2
        )
    );
    for (edit, expected) in [
        ((8, 100u32), "GLB: the first chunk is not JSON"),
        ((4, 1u32), "GLB version 1: only glTF 2.0 is supported"),
        (
            (12, 0xFFFF_FF00u32),
            "truncated GLB: chunk 0 needs 4294967040 bytes",
        ),
    ] {
        let mut broken = bytes.clone();
        let (at, value) = edit;
        if at == 8 {
            // Header length kept, first chunk type changed.
            broken[16..20].copy_from_slice(b"BIN\0");
        } else {
            broken[at..at + 4].copy_from_slice(&value.to_le_bytes());
        }
        let path = dir.path().join("broken.glb");
        std::fs::write(&path, &broken).unwrap();
        let message = scene::load(path.to_str().unwrap()).unwrap_err().to_string();
        assert!(
            message.starts_with(&format!("{}: {expected}", path.display())),
            "{message}"
        );
    }
    // A missing buffer file next to a real .gltf.
    let gltf_path = dir.path().join("scene.gltf");
    app::export_scene("cornell", &gltf_path, &LoadOptions::default()).unwrap();
    std::fs::remove_file(dir.path().join("scene.bin")).unwrap();
    let message = scene::load(gltf_path.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert_eq!(
        message,
        format!(
            "{}: buffer 0: cannot read 'scene.bin': No such file or directory (os error 2)",
            gltf_path.display()
        )
    );
}

/// Mutated and truncated copies of real files never panic the loader
/// (the gltf crate and the image decoder are given only checked input).
#[test]
fn mutated_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("room.glb");
    app::export_scene("room", &glb, &LoadOptions::default()).unwrap();
    let original = std::fs::read(&glb).unwrap();
    let text = std::fs::read(data("hierarchy.gltf")).unwrap();
    let side = std::fs::read(data("hierarchy.bin")).unwrap();
    let png = std::fs::read(data("checker.png")).unwrap();
    let mut state: u64 = 0x2545_F491_4F6C_DD1D;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for round in 0..600 {
        let (source, is_text) = match round % 3 {
            0 => (&original, false),
            1 => (&text, true),
            _ => (&side, false),
        };
        let mut bytes = source.clone();
        for _ in 0..1 + next() % 8 {
            let at = (next() % bytes.len() as u64) as usize;
            bytes[at] = if is_text && next() % 2 == 0 {
                b"0123456789-e.,[]{}\""[(next() % 19) as usize]
            } else {
                next() as u8
            };
        }
        if next() % 4 == 0 {
            bytes.truncate((next() % bytes.len() as u64) as usize);
        }
        let (main, buffer) = if round % 3 == 2 {
            (text.clone(), bytes)
        } else {
            (bytes, side.clone())
        };
        let png = png.clone();
        let result = std::panic::catch_unwind(|| {
            let _ = gltf::load_slice(
                "fuzz",
                Path::new("fuzz.gltf"),
                &main,
                &mut |uri: &str| match uri {
                    "hierarchy.bin" => Ok(buffer.clone()),
                    "checker.png" => Ok(png.clone()),
                    _ => Err(std::io::Error::other("no such file")),
                },
                &LoadOptions::default(),
            );
        });
        assert!(result.is_ok(), "round {round} panicked");
    }
}

/// The built-in scenes written by `export-scene` (both containers) read
/// back as the same surfaces, bit for bit, and solve to the same vertex
/// radiosities.
#[test]
fn export_scene_round_trip_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["room", "cornell"] {
        let original = scene::load(name).unwrap();
        for extension in ["glb", "gltf"] {
            let path = dir.path().join(format!("{name}.{extension}"));
            app::export_scene(name, &path, &LoadOptions::default()).unwrap();
            let back = load(&path);
            assert_eq!(back.surfaces.len(), original.surfaces.len());
            for (a, b) in original.surfaces.iter().zip(&back.surfaces) {
                assert_eq!(a.polygon, b.polygon, "{name}");
                assert_eq!(
                    (a.rho, a.emission, a.face, a.group),
                    (b.rho, b.emission, b.face, b.group)
                );
                assert_eq!((a.normal, a.offset, a.area), (b.normal, b.offset, b.area));
            }
            let sizes = |s: &Scene| s.mesh_hint.as_ref().map(|h| (h.patch_size, h.element_size));
            assert_eq!(sizes(&back), sizes(&original), "{name}");
            assert_eq!(back.camera, original.camera, "{name}");
            let solve = |scene: &Scene| {
                let mut settings = Settings {
                    max_shots: Some(25),
                    ..Settings::wong_tsang93()
                };
                let sizes = scene.default_mesh_sizes();
                settings.mesh.patch_size = sizes.patch_size;
                settings.mesh.element_size = 2.0 * sizes.element_size;
                let mesh = Mesh::build(scene, &settings.mesh).unwrap();
                let mut solver = Solver::new(scene, &mesh, settings);
                solver.run(|_| Flow::Continue);
                solver.radiosity().to_vec()
            };
            if extension == "glb" {
                assert_eq!(solve(&original), solve(&back), "{name}");
            }
        }
    }
}

/// Reads the bake: positions, normals, COLOR_0 of the (shared) vertex
/// attributes, the scene's extras, and the document.
struct ReadBake {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colours: Vec<[f32; 3]>,
    uvs: Option<Vec<[f32; 2]>>,
    extras: Value,
    document: ::gltf::Document,
    images: usize,
}

fn read_bake(path: &Path) -> ReadBake {
    let (document, buffers, images) = ::gltf::import(path).unwrap_or_else(|e| panic!("{e}"));
    let mesh = document.meshes().next().unwrap();
    let primitive = mesh.primitives().next().unwrap();
    let reader = primitive.reader(|b| Some(&buffers[b.index()]));
    let extras: Value = serde_json::from_str(
        document
            .default_scene()
            .unwrap()
            .extras()
            .as_ref()
            .unwrap()
            .get(),
    )
    .unwrap();
    ReadBake {
        positions: reader.read_positions().unwrap().collect(),
        normals: reader.read_normals().unwrap().collect(),
        colours: reader.read_colors(0).unwrap().into_rgb_f32().collect(),
        uvs: reader.read_tex_coords(0).map(|t| t.into_f32().collect()),
        extras: extras["radiosity"].clone(),
        images: images.len(),
        document,
    }
}

/// Rows of `--vertices`: position, normal, face, B.
fn read_csv(path: &Path) -> Vec<(DVec3, DVec3, u32, DVec3)> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|line| {
            let v: Vec<f64> = line.split(',').map(|t| t.parse().unwrap()).collect();
            (
                DVec3::new(v[0], v[1], v[2]),
                DVec3::new(v[3], v[4], v[5]),
                v[6] as u32,
                DVec3::new(v[7], v[8], v[9]),
            )
        })
        .collect()
}

fn job(scene: &str, dir: &Path, bake: Option<(&str, BakeMode)>, image: &str) -> Job {
    Job {
        scene: scene.into(),
        settings: Settings {
            converge: 0.05,
            ..Settings::wong_tsang93()
        },
        patch_size: None,
        element_size: None,
        image: Some(ImageJob {
            path: dir.join(image),
            width: 120,
            height: 90,
            camera: None,
            supersampling: 1,
            exposure: Exposure::Auto { ev: 0.0 },
            ambient: true,
        }),
        vertices_csv: Some(dir.join("vertices.csv")),
        stats_json: None,
        load: LoadOptions::default(),
        bake: bake.map(|(name, mode)| BakeJob {
            path: dir.join(name),
            mode,
        }),
        ply: Some(dir.join("mesh.ply")),
        sensors: None,
        max_memory: None,
    }
}

/// Equal to f32 precision: within 2e-7 absolutely or relatively.
fn f32_close(a: f64, b: f64) -> bool {
    relative_eq!(a, b, epsilon = 2e-7, max_relative = 2e-7)
}

/// Lit bakes hold `min(1, color_scale x (B + rho ambient) / pi)` per vertex
/// of `--vertices`, in the same order; irradiance bakes hold
/// `color_scale x (E + ambient) / pi` with `B = emission + rho E`, keep the
/// input's materials, texture and texture coordinates (interpolated onto
/// the element vertices), and write every material single-sided.
#[test]
fn bakes_match_the_vertex_csv() {
    let hierarchy = data("hierarchy.gltf");
    for (scene_name, file) in [
        ("cornell", "lit.glb"),
        ("cornell", "irradiance.gltf"),
        (hierarchy.to_str().unwrap(), "lit.gltf"),
        (hierarchy.to_str().unwrap(), "irradiance.glb"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let mode = if file.starts_with("lit") {
            BakeMode::Lit
        } else {
            BakeMode::Irradiance
        };
        let outcome = app::run(
            &job(scene_name, dir.path(), Some((file, mode)), "p.png"),
            &mut (),
        )
        .unwrap();
        assert_eq!(
            outcome.written.len(),
            4 + usize::from(file.ends_with(".gltf"))
        );
        let scene = scene::load_with(scene_name, &LoadOptions::default())
            .unwrap()
            .scene;
        let rows = read_csv(&dir.path().join("vertices.csv"));
        let bake = read_bake(&dir.path().join(file));
        assert_eq!(bake.positions.len(), rows.len());
        assert_eq!(bake.extras["bake_mode"], mode.name());
        let scale = bake.extras["color_scale"].as_f64().unwrap();
        let ambient: Vec<f64> = serde_json::from_value(bake.extras["ambient"].clone()).unwrap();
        let ambient = DVec3::from_slice(&ambient);
        assert!(ambient.min_element() > 0.0 && scale > 0.0);
        // Reflectance and emission of the vertex's surface: the CSV gives
        // the face, and a face's surfaces share them.
        let material_of = |face: u32| {
            let s = scene.surfaces.iter().find(|s| s.face == face).unwrap();
            (s.rho, s.emission)
        };
        for (k, (p, n, face, b)) in rows.iter().enumerate() {
            let bp = bake.positions[k].map(f64::from);
            let bn = bake.normals[k].map(f64::from);
            for i in 0..3 {
                assert!(
                    f32_close(bp[i], p[i]) && f32_close(bn[i], n[i]),
                    "vertex {k}"
                );
            }
            let colour = DVec3::from_array(bake.colours[k].map(f64::from));
            let (rho, emission) = material_of(*face);
            match mode {
                BakeMode::Lit => {
                    let expected = ((*b + rho * ambient) / PI * scale).min(DVec3::ONE);
                    for i in 0..3 {
                        assert!(
                            f32_close(colour[i], expected[i]),
                            "vertex {k}: {colour} vs {expected}"
                        );
                    }
                }
                BakeMode::Irradiance => {
                    let e = colour * PI / scale - ambient;
                    let rebuilt = emission + rho * e;
                    for i in 0..3 {
                        assert!(
                            abs_diff_eq!(
                                rebuilt[i],
                                b[i],
                                epsilon = 1e-5 * (1.0 + b[i].abs() + (rho * ambient)[i])
                            ),
                            "vertex {k}: {rebuilt} vs {b}"
                        );
                    }
                    assert!(colour.max_element() <= 1.0);
                }
            }
        }
        let materials: Vec<_> = bake.document.materials().collect();
        assert!(bake.document.cameras().next().is_some());
        match mode {
            BakeMode::Lit => {
                assert_eq!(materials.len(), 1);
                assert!(materials[0].unlit());
                assert_eq!(
                    bake.document.meshes().next().unwrap().primitives().count(),
                    1
                );
            }
            BakeMode::Irradiance => {
                assert!(materials.iter().all(|m| !m.double_sided() && !m.unlit()));
            }
        }
        if scene_name.ends_with("hierarchy.gltf") && mode == BakeMode::Irradiance {
            let names: Vec<_> = materials.iter().map(|m| m.name().unwrap()).collect();
            assert_eq!(names, ["checker", "rug", "lamp", "panel"]);
            assert_eq!(bake.images, 1);
            let texture = materials[0]
                .pbr_metallic_roughness()
                .base_color_texture()
                .unwrap();
            assert_eq!(texture.texture().source().index(), 0);
            // Floor vertices (y = 0, facing up): the floor node maps world
            // (x, z) to texture (0.5 - z/2, 0.5 + x/2).
            let uvs = bake.uvs.as_ref().expect("TEXCOORD_0 kept");
            let mut floor = 0;
            for (k, (p, n, _, _)) in rows.iter().enumerate() {
                if p.y.abs() < 1e-9 && n.y > 0.5 {
                    floor += 1;
                    let expected = [0.5 - p.z / 2.0, 0.5 + p.x / 2.0];
                    for i in 0..2 {
                        assert!(
                            abs_diff_eq!(f64::from(uvs[k][i]), expected[i], epsilon = 1e-6),
                            "{p}: {:?}",
                            uvs[k]
                        );
                    }
                }
            }
            assert!(floor > 100, "{floor}");
        }
    }
}

/// PLY: binary little-endian, one vertex per `--vertices` row with its
/// position, normal, the picture's 8-bit sRGB colour and B; triangles.
#[test]
fn ply_holds_positions_colours_and_radiosity() {
    let dir = tempfile::tempdir().unwrap();
    app::run(
        &job(
            "cornell",
            dir.path(),
            Some(("lit.glb", BakeMode::Lit)),
            "p.png",
        ),
        &mut (),
    )
    .unwrap();
    let rows = read_csv(&dir.path().join("vertices.csv"));
    let bake = read_bake(&dir.path().join("lit.glb"));
    let exposure = bake.extras["picture_exposure"].as_f64().unwrap();
    let ambient: Vec<f64> = serde_json::from_value(bake.extras["ambient"].clone()).unwrap();
    let ambient = DVec3::from_slice(&ambient);
    let scene = scene::load("cornell").unwrap();
    let bytes = std::fs::read(dir.path().join("mesh.ply")).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    let count = |element: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .unwrap()
            .parse()
            .unwrap()
    };
    assert_eq!(count("vertex"), rows.len());
    let properties: Vec<&str> = header
        .lines()
        .filter(|l| l.starts_with("property"))
        .collect();
    assert_eq!(properties.len(), 13);
    let record = 6 * 4 + 3 + 3 * 4;
    let faces = count("face");
    assert_eq!(bytes.len(), end + rows.len() * record + faces * 13);
    let f = |at: usize| f64::from(f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()));
    let encode = |linear: f64| {
        let v = linear.clamp(0.0, 1.0);
        let e = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (e * 255.0).round()
    };
    for (k, (p, _, face, b)) in rows.iter().enumerate() {
        let at = end + k * record;
        for i in 0..3 {
            assert!(f32_close(f(at + 4 * i), p[i]));
            assert!(f32_close(f(at + 27 + 4 * i), b[i]), "vertex {k}");
        }
        let rho = scene.surfaces.iter().find(|s| s.face == *face).unwrap().rho;
        let shown = (*b + rho * ambient) * exposure;
        for i in 0..3 {
            let expected = encode(shown[i]);
            assert!(
                abs_diff_eq!(f64::from(bytes[at + 24 + i]), expected, epsilon = 1.0),
                "vertex {k}"
            );
        }
    }
    let mut at = end + rows.len() * record;
    for _ in 0..faces {
        assert_eq!(bytes[at], 3);
        for i in 0..3 {
            let v = u32::from_le_bytes(bytes[at + 1 + 4 * i..at + 5 + 4 * i].try_into().unwrap());
            assert!((v as usize) < rows.len());
        }
        at += 13;
    }
}

/// EXR holds the linear picture, the same numbers as PFM (which is stored
/// bottom row first).
#[test]
fn exr_holds_the_linear_picture() {
    let dir = tempfile::tempdir().unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let picture = |name: &str| {
        let mut j = job("cornell", dir.path(), None, name);
        j.ply = None;
        pool.install(|| app::run(&j, &mut ())).unwrap();
    };
    picture("p.exr");
    picture("p.pfm");
    let image = exr::prelude::read_first_rgba_layer_from_file(
        dir.path().join("p.exr"),
        |size, _| vec![[0f32; 3]; size.width() * size.height()],
        |pixels, position, (r, g, b, _): (f32, f32, f32, f32)| {
            pixels[position.y() * 120 + position.x()] = [r, g, b];
        },
    )
    .unwrap();
    let size = image.layer_data.size;
    assert_eq!((size.width(), size.height()), (120, 90));
    let exr = image.layer_data.channel_data.pixels;
    let pfm = std::fs::read(dir.path().join("p.pfm")).unwrap();
    let header = b"PF\n120 90\n-1.0\n".len();
    let mut lit = 0;
    for y in 0..90 {
        for x in 0..120 {
            let row = 89 - y;
            for (c, value) in exr[y * 120 + x].iter().enumerate() {
                let at = header + 4 * (3 * (row * 120 + x) + c);
                let v = f32::from_le_bytes(pfm[at..at + 4].try_into().unwrap());
                assert_eq!(*value, v, "pixel {x},{y}");
            }
            lit += usize::from(exr[y * 120 + x][0] > 0.0);
        }
    }
    assert!(lit > 120 * 90 / 2);
}

/// A run that fails on bad input writes none of its outputs, and the
/// command exits non-zero with the loader's message.
#[test]
fn a_bad_gltf_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.glb");
    std::fs::write(&bad, b"glTF\x02\0\0\0\xff\xff\0\0").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .arg("render")
        .arg(&bad)
        .arg("--output")
        .arg(dir.path().join("p.png"))
        .arg("--bake")
        .arg(dir.path().join("b.glb"))
        .arg("--ply")
        .arg(dir.path().join("m.ply"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        stderr.trim(),
        format!(
            "error: {}: truncated GLB: the header gives 65535 bytes, the file has 12",
            bad.display()
        )
    );
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, [std::ffi::OsString::from("bad.glb")]);
}

/// `export-scene` and `--bake` refuse file names they cannot write.
#[test]
fn output_names_are_checked_before_work() {
    let dir = tempfile::tempdir().unwrap();
    let message = app::export_scene(
        "room",
        &dir.path().join("room.obj"),
        &LoadOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        message.ends_with("the file name must end in .glb or .gltf"),
        "{message}"
    );
    let mut j = job(
        "cornell",
        dir.path(),
        Some(("bake.png", BakeMode::Lit)),
        "p.png",
    );
    j.ply = None;
    let message = app::run(&j, &mut ()).unwrap_err().to_string();
    assert!(message.starts_with("--bake "), "{message}");
    assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none());
}
