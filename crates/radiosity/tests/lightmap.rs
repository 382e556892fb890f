//! Lightmap bakes (`--bake-target lightmap`), read back from the bytes
//! written as an engine would read them (the `gltf` crate's reader, the
//! EXR decoded by the `exr` crate): no light leaking under a thin wall, a
//! mesh drawn twice getting its own texels, the input's own `TEXCOORD_1`
//! kept, points and lines left alone. Accuracy against sensor points is
//! the `lightmap` experiment's, tested in `crates/experiments`.

mod common;

use std::io::Cursor;
use std::path::Path;

use common::{quad, scene_of};
use glam::{DVec2, DVec3};
use radiosity::export::gltf::BakeMode;
use radiosity::export::lightmap::{self, AtlasSettings, LightmapBake, LightmapReport};
use radiosity::final_gather::{FinalGather, FinalPass, Point};
use radiosity::scene::gltf::{Appearance, load_slice};
use radiosity::scene::{Camera, LoadOptions, Scene};
use radiosity::solver::refine::refined_mesh;
use radiosity::solver::{Flow, Settings, Solver};

/// Solves `scene` and bakes a lit lightmap of `appearance` at `density`;
/// returns the written files and the report.
fn bake(
    scene: &Scene,
    appearance: &Appearance,
    density: f64,
    mode: BakeMode,
) -> (Vec<(std::path::PathBuf, Vec<u8>)>, LightmapReport) {
    bake_with(scene, appearance, density, mode, FinalGather::Off, 1e-3)
}

/// [`bake`] under a final pass (lit values in radiosity units: the mesh's
/// part at the vertices, the pass's at each texel), stopping at
/// `converge`.
fn bake_with(
    scene: &Scene,
    appearance: &Appearance,
    density: f64,
    mode: BakeMode,
    final_gather: FinalGather,
    converge: f64,
) -> (Vec<(std::path::PathBuf, Vec<u8>)>, LightmapReport) {
    let mut settings = Settings::adaptive();
    settings.mesh = settings.mesh.sized_for(scene);
    settings.converge = converge;
    let refined = refined_mesh(scene, &settings, None).unwrap();
    let mut solver = Solver::new(scene, &refined.mesh, settings);
    solver.run(|_| Flow::Continue);
    let pass = FinalPass::new(&solver, final_gather);
    let values = pass.vertex_display(solver.radiosity(), DVec3::ZERO);
    let shade = |points: &[Point]| pass.shade(points);
    let bake = LightmapBake {
        scene,
        mesh: &refined.mesh,
        appearance,
        values: &values,
        shade: (final_gather != FinalGather::Off).then_some(&shade as radiosity::render::Shade<'_>),
        mode,
        settings: AtlasSettings {
            density,
            ..AtlasSettings::default()
        },
        camera: Camera {
            eye: DVec3::new(1.0, 1.0, -3.0),
            target: DVec3::new(1.0, 0.5, 1.0),
            up: DVec3::Y,
            fov_degrees: 50.0,
        },
        aspect_ratio: 1.0,
        metadata: serde_json::json!({}),
    };
    lightmap::bake(&bake, Path::new("out.glb")).unwrap()
}

/// A `.glb`'s scene and appearance, as the loader reads it.
fn load(glb: &[u8]) -> (Scene, Appearance) {
    load_slice(
        "test",
        Path::new("test.glb"),
        glb,
        &mut |_| Err(std::io::Error::other("no external files")),
        &LoadOptions::default(),
    )
    .unwrap()
}

/// An OBJ-like scene through `export-scene`, as a lightmap bake of a
/// scene with no glTF input does.
fn exported(scene: &Scene) -> (Scene, Appearance) {
    let files = radiosity::export::gltf::export_scene(scene, Path::new("scene.glb")).unwrap();
    load(&files[0].1)
}

/// A written primitive: world positions, `TEXCOORD_1`, triangle indices.
type Written = (Vec<DVec3>, Vec<[f32; 2]>, Vec<u32>);

/// Every lightmapped primitive of a written `.glb`, in node order: world
/// positions (the nodes' transforms are translations here), `TEXCOORD_1`
/// and triangle indices.
fn primitives(glb: &[u8]) -> Vec<Written> {
    let gltf = gltf::Gltf::from_slice(glb).unwrap();
    let blob = gltf.blob.clone().unwrap();
    let mut out = Vec::new();
    for node in gltf
        .default_scene()
        .unwrap()
        .nodes()
        .flat_map(|n| std::iter::once(n.clone()).chain(n.children()))
    {
        let Some(mesh) = node.mesh() else { continue };
        let offset = DVec3::from(node.transform().decomposed().0.map(f64::from));
        for p in mesh.primitives() {
            let reader = p.reader(|_| Some(&blob));
            let Some(uv) = reader.read_tex_coords(1) else {
                continue;
            };
            let positions = reader
                .read_positions()
                .unwrap()
                .map(|q| DVec3::from(q.map(f64::from)) + offset)
                .collect();
            out.push((
                positions,
                uv.into_f32().collect(),
                reader.read_indices().unwrap().into_u32().collect(),
            ));
        }
    }
    out
}

/// The EXR's pixels, width and height.
fn exr_pixels(bytes: &[u8]) -> (Vec<[f32; 3]>, usize, usize) {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |size, _| (size.0, vec![[0f32; 3]; size.0 * size.1]),
            |(w, pixels): &mut (usize, Vec<[f32; 3]>), at, (r, g, b, _): (f32, f32, f32, f32)| {
                pixels[at.1 * *w + at.0] = [r, g, b];
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .unwrap();
    let size = image.layer_data.size;
    (image.layer_data.channel_data.pixels.1, size.0, size.1)
}

/// Bilinear lookup at `uv` (glTF's convention), clamped at the edges.
fn sample(pixels: &[[f32; 3]], width: usize, height: usize, uv: DVec2) -> DVec3 {
    let x = (uv.x * width as f64 - 0.5).clamp(0.0, (width - 1) as f64);
    let y = (uv.y * height as f64 - 0.5).clamp(0.0, (height - 1) as f64);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let at = |x: usize, y: usize| DVec3::from(pixels[y * width + x].map(f64::from));
    (at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx) * (1.0 - fy)
        + (at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx) * fy
}

/// Texel centres strictly inside two or more `TEXCOORD_1` triangles.
fn overlaps(primitives: &[Written], width: usize, height: usize) -> usize {
    let mut count = vec![0u8; width * height];
    for (_, uv, indices) in primitives {
        for t in indices.chunks_exact(3) {
            let c = [0, 1, 2].map(|k| {
                let p = uv[t[k] as usize];
                DVec2::new(
                    f64::from(p[0]) * width as f64,
                    f64::from(p[1]) * height as f64,
                )
            });
            let area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
            for y in 0..height {
                for x in 0..width {
                    let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                    let w = [
                        (c[2] - c[1]).perp_dot(p - c[1]) / area,
                        (c[0] - c[2]).perp_dot(p - c[2]) / area,
                        (c[1] - c[0]).perp_dot(p - c[0]) / area,
                    ];
                    if area.abs() > 1e-12 && w.iter().all(|&w| w > 1e-6) {
                        count[y * width + x] += 1;
                    }
                }
            }
        }
    }
    count.iter().filter(|&&c| c > 1).count()
}

/// A lit room (x in [0, 2]) and a dark one (x in [2.02, 4.02]) on either
/// side of a 2 cm wall as high as the lamp: no light reaches the dark room.
fn two_rooms() -> Scene {
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    scene_of(vec![
        quad(DVec3::ZERO, 2.0 * z, 2.0 * x, 0.8, 0.0, 0), // lit floor
        quad(DVec3::new(2.02, 0.0, 0.0), 2.0 * z, 2.0 * x, 0.8, 0.0, 1), // dark floor
        quad(DVec3::new(2.0, 0.0, 0.0), 2.0 * z, 2.0 * y, 0.8, 0.0, 2), // wall, lit side (faces -x)
        quad(DVec3::new(2.02, 0.0, 0.0), 2.0 * y, 2.0 * z, 0.8, 0.0, 3), // wall, dark side (faces +x)
        quad(DVec3::new(0.5, 2.0, 0.5), x, z, 0.0, 50.0, 4),             // lamp, facing down
    ])
}

/// A 1 x 1 m black board 1 m above a 6 x 6 m floor in a parallel sun 60
/// degrees high, baked at the default 32 texels per metre: under the
/// default final pass the shadow's edge is at most 2 texels wide (texels
/// between 10% and 90% of the lit level, over the shadow's 4 m outline in
/// texels), where the mesh alone smears it over its elements.
#[test]
fn a_sun_shadow_edge_in_a_lightmap_is_at_most_two_texels_wide() {
    let (scene, appearance) = exported(&common::board_in_the_sun());
    let density = AtlasSettings::default().density;
    let width = |final_gather| {
        let (files, _) = bake_with(
            &scene,
            &appearance,
            density,
            BakeMode::Lit,
            final_gather,
            Settings::adaptive().converge,
        );
        let exr = files
            .iter()
            .find(|(p, _)| p.to_string_lossy().ends_with(".exr"));
        let (pixels, _, _) = exr_pixels(&exr.unwrap().1);
        let lit = pixels.iter().map(|p| p[1]).fold(0.0f32, f32::max);
        let between = pixels
            .iter()
            .filter(|p| p[1] > 0.1 * lit && p[1] < 0.9 * lit)
            .count();
        between as f64 / (4.0 * density)
    };
    let sharp = width(FinalGather::Direct);
    let mesh_only = width(FinalGather::Off);
    println!("edge: {sharp:.2} texels (the mesh alone: {mesh_only:.2})");
    assert!(sharp <= 2.0, "{sharp} texels");
    assert!(mesh_only > sharp, "{mesh_only} against {sharp}");
}

#[test]
fn no_light_leaks_under_a_thin_wall() {
    let scene = two_rooms();
    assert_eq!(scene.surfaces[2].normal, -DVec3::X);
    assert_eq!(scene.surfaces[3].normal, DVec3::X);
    assert_eq!(scene.surfaces[4].normal, -DVec3::Y);
    let (scene, appearance) = exported(&scene);
    // Texels of 5 cm: wider than the wall, so a texel of the dark floor
    // by the wall has its centre on the lit side.
    let (files, report) = bake(&scene, &appearance, 20.0, BakeMode::Lit);
    assert!(report.generated);
    let (pixels, width, height) = exr_pixels(&files.last().unwrap().1);
    let (mut dark, mut lit) = (0, 0);
    for (positions, uv, indices) in primitives(&files[0].1) {
        for t in indices.chunks_exact(3) {
            let corners = [0, 1, 2].map(|k| (positions[t[k] as usize], uv[t[k] as usize]));
            if corners.iter().any(|c| c.0.y.abs() > 1e-6) {
                continue; // not a floor
            }
            for i in 0..=20 {
                for j in 0..=(20 - i) {
                    let w = [i as f64 / 20.0, j as f64 / 20.0, (20 - i - j) as f64 / 20.0];
                    let p: DVec3 = corners.iter().zip(w).map(|(c, w)| c.0 * w).sum();
                    let at: DVec2 = corners
                        .iter()
                        .zip(w)
                        .map(|(c, w)| DVec2::from(c.1.map(f64::from)) * w)
                        .sum();
                    let value = sample(&pixels, width, height, at);
                    if p.x > 2.01 && p.x < 2.05 {
                        dark += 1;
                        assert!(value.max_element() < 1e-9, "dark floor at {p}: {value}");
                    } else if p.x > 1.9 && p.x <= 2.0 {
                        lit += 1;
                        assert!(value.min_element() > 0.1, "lit floor at {p}: {value}");
                    }
                }
            }
        }
    }
    assert!(
        dark > 20 && lit > 20,
        "{dark} dark and {lit} lit points by the wall"
    );
}

#[test]
fn a_mesh_drawn_twice_gets_a_copy_with_its_own_texels() {
    let lamp_room = lamp_room(DVec3::ZERO);
    let files = radiosity::export::gltf::export_scene(&lamp_room, Path::new("one.glb")).unwrap();
    // A second node drawing mesh 0 five metres away.
    let glb = gltf::binary::Glb::from_slice(&files[0].1).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&glb.json).unwrap();
    let node = json["nodes"].as_array().unwrap().len();
    json["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "mesh": 0, "translation": [5.0, 0.0, 0.0] }));
    json["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!(node));
    let text = serde_json::to_vec(&json).unwrap();
    let twice = gltf::binary::Glb {
        header: glb.header,
        json: text.into(),
        bin: glb.bin.clone(),
    }
    .to_vec()
    .unwrap();
    let (scene, appearance) = load(&twice);
    assert_eq!(appearance.primitives.len(), 4, "two primitives drawn twice");
    let (out, report) = bake(&scene, &appearance, 32.0, BakeMode::Lit);
    let written = gltf::Gltf::from_slice(&out[0].1).unwrap();
    let meshes: Vec<usize> = written.meshes().map(|m| m.primitives().len()).collect();
    assert_eq!(
        meshes,
        vec![2, 2],
        "the mesh and one copy, with the same primitives"
    );
    let copy = written.nodes().nth(node).unwrap();
    assert_eq!(copy.mesh().map(|m| m.index()), Some(1));
    let placed = primitives(&out[0].1);
    assert_eq!(placed.len(), 4);
    assert_eq!(
        overlaps(&placed, report.width as usize, report.height as usize),
        0
    );
    // Both copies are lit alike (each lamp over its own floor).
    let (pixels, width, height) = exr_pixels(&out.last().unwrap().1);
    let mean = |k: usize| {
        let (_, uv, indices) = &placed[k];
        let c: DVec2 = indices[..3]
            .iter()
            .map(|&i| DVec2::from(uv[i as usize].map(f64::from)))
            .sum::<DVec2>()
            / 3.0;
        sample(&pixels, width, height, c)
    };
    let (a, b) = (mean(0), mean(2));
    assert!(
        a.x > 0.1 && ((a - b).abs().max_element() / a.x) < 0.05,
        "{a} {b}"
    );
}

#[test]
fn the_inputs_own_second_uv_set_is_kept() {
    let lamp_room = lamp_room(DVec3::ZERO);
    let (scene, appearance) = exported(&lamp_room);
    // An irradiance bake keeps the materials, so it can be read and baked again.
    let (first, _) = bake(&scene, &appearance, 32.0, BakeMode::Irradiance);
    let (scene, appearance) = load(&first[0].1);
    assert!(appearance.primitives.iter().all(|p| p.uv1.is_some()));
    let (second, report) = bake(&scene, &appearance, 32.0, BakeMode::Lit);
    assert!(!report.generated, "the input's TEXCOORD_1 is used");
    let before = primitives(&first[0].1);
    let after = primitives(&second[0].1);
    assert_eq!(before.len(), after.len());
    for (b, a) in before.iter().zip(&after) {
        assert_eq!(b.1, a.1, "TEXCOORD_1 unchanged");
        assert_eq!(b.2, a.2, "triangles unchanged");
    }
}

#[test]
fn points_and_lines_are_kept_and_every_triangle_primitive_gets_uvs() {
    let path = common::test_data("hierarchy.gltf");
    let options = LoadOptions::default();
    let (scene, appearance) = radiosity::scene::gltf::load_file(&path, &options).unwrap();
    let (files, _) = bake(&scene, &appearance, 64.0, BakeMode::Lit);
    let input = gltf::Gltf::open(&path).unwrap();
    let output = gltf::Gltf::from_slice(&files[0].1).unwrap();
    let modes = |g: &gltf::Gltf| -> Vec<Vec<gltf::mesh::Mode>> {
        g.meshes()
            .map(|m| m.primitives().map(|p| p.mode()).collect())
            .collect()
    };
    let out_modes = modes(&output);
    assert_eq!(out_modes.len(), input.meshes().len());
    for (i, o) in modes(&input).iter().zip(&out_modes) {
        assert_eq!(i.len(), o.len(), "same primitives");
    }
    assert_eq!(
        output.nodes().count(),
        input.nodes().count() + 1,
        "the input's nodes and the bake's camera"
    );
    for (mesh, modes) in output.meshes().zip(&out_modes) {
        for (p, mode) in mesh.primitives().zip(modes) {
            let has_uv1 = p
                .attributes()
                .any(|(s, _)| s == gltf::Semantic::TexCoords(1));
            assert_eq!(
                has_uv1,
                *mode == gltf::mesh::Mode::Triangles,
                "{:?}: {mode:?}",
                mesh.name()
            );
        }
    }
}

/// A 2 m floor at `offset` under a lamp a metre up.
fn lamp_room(offset: DVec3) -> Scene {
    scene_of(vec![
        quad(offset, 2.0 * DVec3::Z, 2.0 * DVec3::X, 0.8, 0.0, 0),
        quad(
            offset + DVec3::new(0.5, 1.0, 0.5),
            DVec3::X,
            DVec3::Z,
            0.0,
            20.0,
            1,
        ),
    ])
}

/// The lamp room's `.glb` with `edit` applied to its JSON.
fn edited_lamp_room(offset: DVec3, edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
    let files =
        radiosity::export::gltf::export_scene(&lamp_room(offset), Path::new("one.glb")).unwrap();
    let glb = gltf::binary::Glb::from_slice(&files[0].1).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&glb.json).unwrap();
    edit(&mut json);
    gltf::binary::Glb {
        header: glb.header,
        json: serde_json::to_vec(&json).unwrap().into(),
        bin: glb.bin.clone(),
    }
    .to_vec()
    .unwrap()
}

#[test]
fn a_scene_far_from_the_origin_finds_every_texel() {
    // 100 km away: single-precision world positions would be centimetres
    // off; the texels' surface points are found in double precision.
    let glb = edited_lamp_room(DVec3::new(1e5, 0.0, -1e5), |_| {});
    let (scene, appearance) = load(&glb);
    let (files, report) = bake(&scene, &appearance, 32.0, BakeMode::Lit);
    assert_eq!(report.missing, 0, "{report:?}");
    let (pixels, width, height) = exr_pixels(&files.last().unwrap().1);
    let placed = primitives(&files[0].1);
    let (_, uv, indices) = &placed[0];
    let centre: DVec2 = indices[..3]
        .iter()
        .map(|&i| DVec2::from(uv[i as usize].map(f64::from)))
        .sum::<DVec2>()
        / 3.0;
    assert!(sample(&pixels, width, height, centre).x > 0.1);
}

#[test]
fn an_attribute_the_loader_does_not_read_is_carried_over_without_trusting_its_count() {
    // A custom attribute with no data and a count of 10^11: zeros, of
    // which only the vertices drawn are read.
    let glb = edited_lamp_room(DVec3::ZERO, |json| {
        let accessors = json["accessors"].as_array_mut().unwrap();
        accessors.push(serde_json::json!({ "componentType": 5126, "count": 100_000_000_000u64, "type": "SCALAR" }));
        let index = accessors.len() - 1;
        json["meshes"][0]["primitives"][0]["attributes"]["_WEIGHT"] = serde_json::json!(index);
    });
    let (scene, appearance) = load(&glb);
    let (files, _) = bake(&scene, &appearance, 32.0, BakeMode::Irradiance);
    let written = gltf::Gltf::from_slice(&files[0].1).unwrap();
    let primitive = written
        .meshes()
        .next()
        .unwrap()
        .primitives()
        .next()
        .unwrap();
    let custom = primitive
        .attributes()
        .find(|(s, _)| *s == gltf::Semantic::Extras("WEIGHT".into()))
        .map(|(_, a)| a)
        .expect("the custom attribute is kept");
    let positions = primitive.get(&gltf::Semantic::Positions).unwrap();
    assert_eq!(custom.count(), positions.count());
}

#[test]
fn instancing_and_compression_extensions_are_refused_before_the_solve() {
    let glb = edited_lamp_room(DVec3::ZERO, |json| {
        json["extensionsUsed"] = serde_json::json!(["EXT_mesh_gpu_instancing"]);
    });
    let (_, appearance) = load(&glb);
    let message = lightmap::check_input(&appearance).unwrap_err();
    assert!(message.contains("EXT_mesh_gpu_instancing"), "{message}");
}

#[test]
fn an_unknown_extension_keeps_the_accessors_it_may_point_at() {
    // An extension radiosity does not know, pointing at accessor 0 (the
    // positions): every accessor and buffer view keeps its index.
    let glb = edited_lamp_room(DVec3::ZERO, |json| {
        json["extensionsUsed"] = serde_json::json!(["EXT_example"]);
        json["nodes"][0]["extensions"] = serde_json::json!({ "EXT_example": { "accessor": 0 } });
    });
    let input = gltf::Gltf::from_slice(&glb).unwrap();
    let (scene, appearance) = load(&glb);
    let (files, _) = bake(&scene, &appearance, 32.0, BakeMode::Lit);
    let output = gltf::Gltf::from_slice(&files[0].1).unwrap();
    assert!(output.accessors().count() > input.accessors().count());
    for (a, b) in input.accessors().zip(output.accessors()) {
        assert_eq!(
            (a.count(), a.data_type(), a.dimensions(), a.min(), a.max()),
            (b.count(), b.data_type(), b.dimensions(), b.min(), b.max())
        );
    }
    let read = |g: &gltf::Gltf, bytes: &[u8]| -> Vec<[f32; 3]> {
        let blob = gltf::binary::Glb::from_slice(bytes)
            .unwrap()
            .bin
            .unwrap()
            .into_owned();
        let accessor = g.accessors().next().unwrap();
        let view = accessor.view().unwrap();
        let start = view.offset() + accessor.offset();
        blob[start..start + 12 * accessor.count()]
            .chunks_exact(12)
            .map(|c| [0, 4, 8].map(|k| f32::from_le_bytes(c[k..k + 4].try_into().unwrap())))
            .collect()
    };
    assert_eq!(
        read(&input, &glb),
        read(&output, &files[0].1),
        "the same data at accessor 0"
    );
}
