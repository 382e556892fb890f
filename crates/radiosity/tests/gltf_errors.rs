//! Bad glTF 2.0 input: the smallest valid document (one emissive
//! triangle) loads, and broken one piece at a time, each break gets its one
//! error naming the file and the object; truncated and broken `.glb` files
//! and a missing buffer get theirs; mutated copies of real files never
//! panic the loader.

mod common;

use std::f64::consts::PI;
use std::path::Path;

use common::test_data;
use glam::DVec3;
use radiosity::app;
use radiosity::scene::LightKind;
use radiosity::scene::{self, LoadOptions, gltf};
use serde_json::{Value, json};

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

#[test]
fn lights_take_their_nodes_transforms_and_light_a_scene_alone() {
    let (mut doc, bin) = triangle();
    // No emitter: the lights alone light the scene.
    doc["materials"][0]["emissiveFactor"] = json!([0, 0, 0]);
    doc["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    doc["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"name": "spot", "type": "spot", "color": [1, 0.5, 0.25], "intensity": 40,
         "spot": {"innerConeAngle": 0.25, "outerConeAngle": 0.5}},
        {"name": "sun", "type": "directional", "intensity": 80000},
        {"name": "bulb", "type": "point"},
        {"name": "downlight", "type": "point", "intensity": 5,
         "extras": {"ies": "lamp.ies", "ies_multiplier": 3}}
    ]}});
    // A quarter turn about x takes -z to -y: the spot and the sun point
    // down; the spot's node sits 2 m up inside a parent moved 1 m along x.
    let quarter = [-(0.5f64.sqrt()), 0.0, 0.0, 0.5f64.sqrt()];
    doc["scenes"][0]["nodes"] = json!([0, 1, 3, 4]);
    doc["nodes"] = json!([
        {"name": "tri", "mesh": 0},
        {"name": "rig", "translation": [1, 0, 0], "children": [2]},
        {"name": "spot node", "translation": [0, 2, 0], "rotation": quarter,
         "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"name": "sun node", "rotation": quarter,
         "extensions": {"KHR_lights_punctual": {"light": 1}}},
        {"name": "downlight node", "translation": [0, 3, 0], "rotation": quarter,
         "extensions": {"KHR_lights_punctual": {"light": 3}}},
    ]);
    let ies = "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 90\n0\n100 0\n";
    let bytes = serde_json::to_vec(&doc).unwrap();
    let (scene, _) = gltf::load_slice(
        "lit",
        Path::new("lit.gltf"),
        &bytes,
        &mut |uri: &str| {
            Ok(if uri == "lamp.ies" {
                ies.as_bytes().to_vec()
            } else {
                bin.clone()
            })
        },
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(
        scene.lights.len(),
        3,
        "the unused point light is not placed"
    );
    let near = |a: DVec3, b: DVec3| (a - b).length() < 1e-6;
    // The profiled light: its nadir the node's -z, C0 its +x, the
    // multiplier from the extras (the glTF intensity is not used).
    let LightKind::Luminaire(radiosity::scene::light::Luminaire {
        position,
        nadir,
        c0,
        ref profile,
    }) = scene.lights[2].kind
    else {
        panic!("{:?}", scene.lights[2].kind)
    };
    assert!(near(position, DVec3::new(0.0, 3.0, 0.0)) && near(nadir, -DVec3::Y));
    assert!(near(c0, DVec3::X), "{c0}");
    assert_eq!(profile.candela(0.0, 0.0), 100.0);
    assert_eq!(scene.lights[2].intensity, 3.0);
    let spot = &scene.lights[0];
    assert_eq!(spot.name, "light 0 ('spot')");
    assert_eq!(spot.intensity, 40.0);
    assert_eq!(spot.colour, DVec3::new(1.0, 0.5, 0.25));
    let LightKind::Spot(radiosity::scene::light::Spot {
        position,
        direction,
        inner,
        outer,
    }) = spot.kind
    else {
        panic!("{:?}", spot.kind)
    };
    assert!(near(position, DVec3::new(1.0, 2.0, 0.0)), "{position}");
    assert!(near(direction, -DVec3::Y), "{direction}");
    assert!((inner - 0.25).abs() < 1e-7 && (outer - 0.5).abs() < 1e-7);
    let LightKind::Sun(radiosity::scene::light::Sun { direction }) = scene.lights[1].kind else {
        panic!("{:?}", scene.lights[1].kind)
    };
    assert!(near(direction, -DVec3::Y), "{direction}");
    assert_eq!(scene.lights[1].intensity, 80000.0);
}

#[test]
fn a_gltf_scene_with_no_emitter_and_no_light_is_refused_when_loaded() {
    let (mut doc, bin) = triangle();
    doc["materials"][0]["emissiveFactor"] = json!([0, 0, 0]);
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tri.bin"), &bin).unwrap();
    let path = dir.path().join("dark.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let error = scene::load(path.to_str().unwrap()).unwrap_err().to_string();
    assert_eq!(
        error,
        format!(
            "{}: the scene has no emitter: no material has an emissiveFactor > 0 and no node \
             has a KHR_lights_punctual light; give it an emitting surface, a light, or daylight \
             (--sun, --sky)",
            path.display()
        )
    );
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
                d["extensions"] = json!({"KHR_lights_punctual": {"lights": [
                    {"name": "bulb", "type": "point", "intensity": -5}]}});
                d["nodes"][0]["extensions"] = json!({"KHR_lights_punctual": {"light": 0}});
            }),
            bin.clone(),
            "light 0 ('bulb') (on node 0 ('tri')): its intensity -5 is not a finite number at \
             least 0",
        ),
        (
            with(&|d| {
                d["extensions"] = json!({"KHR_lights_punctual": {"lights": [
                    {"type": "spot", "spot": {"innerConeAngle": 0.6, "outerConeAngle": 0.5}}]}});
                d["nodes"][0]["extensions"] = json!({"KHR_lights_punctual": {"light": 0}});
            }),
            bin.clone(),
            "light 0 (on node 0 ('tri')): its cone angles are wrong: inner 34.37746770784939 and \
             outer 28.64788975654116 degrees must satisfy 0 <= inner <= outer <= 90 and outer > 0",
        ),
        (
            with(&|d| {
                d["extensions"] = json!({"KHR_lights_punctual": {"lights": []}});
                d["nodes"][0]["extensions"] = json!({"KHR_lights_punctual": {"light": 2}});
            }),
            bin.clone(),
            "node 0 ('tri') uses KHR_lights_punctual light 2, which the file does not have",
        ),
        (
            with(&|d| {
                d["extensions"] = json!({"KHR_lights_punctual": {"lights": [
                    {"type": "point", "extras": {"ies": "tri.bin"}}]}});
                d["nodes"][0]["extensions"] = json!({"KHR_lights_punctual": {"light": 0}});
            }),
            bin.clone(),
            "light 0 (on node 0 ('tri')): tri.bin:1: no TILT= line: this is not an IES LM-63 \
             photometric file",
        ),
        (
            with(&|d| {
                d["extensions"] = json!({"KHR_lights_punctual": {"lights": [
                    {"type": "point", "extras": {"ies": 7}}]}});
                d["nodes"][0]["extensions"] = json!({"KHR_lights_punctual": {"light": 0}});
            }),
            bin.clone(),
            "light 0 (on node 0 ('tri')): its extras' \"ies\" is 7, not a file name",
        ),
        (
            with(&|d| {
                d["extensions"] = json!({"KHR_lights_punctual": {"lights": [
                    {"type": "area"}]}});
                d["nodes"][0]["extensions"] = json!({"KHR_lights_punctual": {"light": 0}});
            }),
            bin.clone(),
            "light 0 (on node 0 ('tri')): its type is not one of directional, point, spot",
        ),
        (
            with(&|d| d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])),
            bin.clone(),
            "the file requires extension KHR_draco_mesh_compression, which radiosity does not \
             support (supported: KHR_materials_emissive_strength, KHR_materials_transmission, \
             KHR_mesh_quantization, KHR_texture_transform, KHR_materials_unlit, \
             KHR_lights_punctual)",
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
    let text = std::fs::read(test_data("hierarchy.gltf")).unwrap();
    let side = std::fs::read(test_data("hierarchy.bin")).unwrap();
    let png = std::fs::read(test_data("checker.png")).unwrap();
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

#[test]
fn transmission_makes_glass_and_alpha_blending_is_named() {
    let (mut doc, bin) = triangle();
    doc["nodes"] = json!([{"mesh": 0}, {"mesh": 1}, {"mesh": 2}]);
    doc["scenes"] = json!([{"nodes": [0, 1, 2]}]);
    doc["meshes"] = json!([
        {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
        {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 1}]},
        {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 2}]},
    ]);
    doc["materials"] = json!([
        {"name": "glow", "emissiveFactor": [1, 1, 1]},
        {"name": "window", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.9, 1.0, 1.0]},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.9}}},
        {"name": "veil", "alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 0.4]}},
    ]);
    doc["extensionsUsed"] = json!(["KHR_materials_transmission"]);
    let bytes = serde_json::to_vec(&doc).unwrap();
    let (scene, _) = gltf::load_slice(
        "glass",
        Path::new("glass.gltf"),
        &bytes,
        &mut |_: &str| Ok(bin.clone()),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(
        scene.surfaces.len(),
        2,
        "the glow and the veil are surfaces"
    );
    assert_eq!(scene.panes.len(), 1);
    let t = scene.panes[0].transmittance;
    assert!(
        (t - DVec3::new(0.72, 0.81, 0.9)).abs().max_element() < 1e-6,
        "{t}"
    );
    assert!(
        scene.panes[0].material.contains("window"),
        "{}",
        scene.panes[0].material
    );
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("'veil'") && w.contains("transparent by its alpha")),
        "{:?}",
        scene.warnings
    );
    // A factor outside [0, 1] is an error naming the material.
    doc["materials"][1]["extensions"]["KHR_materials_transmission"]["transmissionFactor"] =
        json!(1.5);
    let error = load_error(&doc, &bin);
    assert!(
        error.contains("transmissionFactor 1.5 is not from 0 to 1"),
        "{error}"
    );
}

#[test]
fn a_material_marked_as_a_portal_gives_portals_not_surfaces() {
    let (mut doc, bin) = triangle();
    doc["nodes"] = json!([{"mesh": 0}, {"mesh": 1}]);
    doc["scenes"] = json!([{"nodes": [0, 1]}]);
    doc["meshes"] = json!([
        {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
        {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 1}]},
    ]);
    doc["materials"] = json!([
        {"name": "glow", "emissiveFactor": [1, 1, 1]},
        {"name": "opening", "extras": {"radiosity": {"portal": true}}},
    ]);
    let bytes = serde_json::to_vec(&doc).unwrap();
    let (scene, _) = gltf::load_slice(
        "portal",
        Path::new("portal.gltf"),
        &bytes,
        &mut |_: &str| Ok(bin.clone()),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(scene.surfaces.len(), 1);
    assert_eq!(scene.portals.len(), 1);
    assert!(scene.portals[0].material.contains("opening"));
    // Anything but true or false is an error naming the material.
    doc["materials"][1]["extras"]["radiosity"]["portal"] = json!("yes");
    let error = load_error(&doc, &bin);
    assert!(
        error.contains("'opening'")
            && error.contains("extras radiosity.portal must be true or false"),
        "{error}"
    );
}
