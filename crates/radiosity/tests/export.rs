//! What a run writes, read back independently (the `gltf` crate's own
//! importer, the `exr` crate, PLY by hand): glTF bakes, lit and irradiance,
//! hold what `--vertices` holds; PLY holds the positions, colours and
//! radiosities; EXR the linear picture that PFM holds; output names are
//! checked before any work.

mod common;

use std::f64::consts::PI;
use std::path::Path;

use approx::{abs_diff_eq, relative_eq};
use common::test_data;
use glam::DVec3;
use radiosity::app::{self, BakeJob, ImageJob, Job};
use radiosity::export::gltf::BakeMode;
use radiosity::final_gather::FinalGather;
use radiosity::render::Exposure;
use radiosity::scene::{self, LoadOptions};
use radiosity::solver::Settings;
use serde_json::Value;

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
        final_gather: FinalGather::Off,
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
        bake: bake.map(|(name, mode)| BakeJob::vertices(dir.join(name), mode)),
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
    let hierarchy = test_data("hierarchy.gltf");
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
