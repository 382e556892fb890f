//! glTF 2.0 out (Khronos glTF 2.0 specification): the solved element mesh
//! with baked per-vertex colours (`--bake`), and a scene's surfaces with
//! their materials (`export-scene`), written with `gltf-json`.
//!
//! A bake holds the receiving mesh of design.md section 1 (element corners
//! as shared vertices, quads as two triangles) with `POSITION`, `NORMAL`
//! and a float `COLOR_0`:
//! - [`BakeMode::Lit`]: the displayed linear radiance (radiosity with the
//!   ambient term, times the picture's exposure), clamped to [0, 1] as the
//!   picture is, under one `KHR_materials_unlit` material: any viewer shows
//!   the lit scene with no lights;
//! - [`BakeMode::Irradiance`]: irradiance `E / pi` (plus the ambient term)
//!   times a scale, for engines that multiply it with their own base colour;
//!   the input's materials, textures and texture coordinates are kept.
//!
//! The scale and the ambient term are recorded in the scene's
//! `extras.radiosity`, so absolute values can be recovered. Radiosity
//! surfaces are single-sided, so a double-sided input face arrives as two
//! faces back to back and every material is written single-sided.
//!
//! `export-scene` writes each surface as one polygon (a triangle fan marked
//! with the `FB_ngon_encoding` vendor extension, which other readers may
//! ignore and see triangles), materials as `baseColorFactor` = reflectance
//! and `emissiveFactor` x `KHR_materials_emissive_strength` = exitance / pi
//! (the inverse of the loader's mapping), with the exact values in
//! `extras.radiosity`, so reading it back gives the same surfaces.

use std::collections::{BTreeMap, HashMap};
use std::io;
use std::path::{Path, PathBuf};

use glam::DVec3;
use gltf_json as json;
use json::validation::Checked;

use crate::mesh::Mesh;

mod builder;

use crate::scene::gltf::{Appearance, NGON_EXTENSION, interpolate_on_fan};
use crate::scene::{Camera, Scene};
pub(crate) use builder::{
    Builder, extension_name_list, extras_object, primitive, raw_extras, unlit_material,
};

crate::choice::named_choice! {
    /// What `COLOR_0` of a bake holds.
    pub enum BakeMode: "bake mode" {
        /// Displayed radiance under an unlit material.
        Lit = "lit",
        /// Irradiance / pi, with the original materials.
        Irradiance = "irradiance",
    }
}

crate::choice::named_choice! {
    /// What a bake writes the light onto.
    pub enum BakeTarget: "bake target" {
        /// The element mesh, light in `COLOR_0` per vertex.
        Vertices = "vertices",
        /// The input's own meshes, light in a lightmap texture on
        /// `TEXCOORD_1` ([`crate::export::lightmap`]).
        Lightmap = "lightmap",
    }
}

/// A bake to write.
pub struct Bake<'a> {
    /// The scene solved.
    pub scene: &'a Scene,
    /// Its element mesh.
    pub mesh: &'a Mesh,
    /// Materials and texture coordinates of a glTF input.
    pub appearance: Option<&'a Appearance>,
    /// `COLOR_0` per mesh vertex, final values in [0, 1].
    pub colours: &'a [DVec3],
    /// The mode the colours were made for.
    pub mode: BakeMode,
    /// The view written as the file's camera.
    pub camera: Camera,
    /// Width over height of the picture.
    pub aspect_ratio: f64,
    /// Recorded in the scene's `extras.radiosity`.
    pub metadata: serde_json::Value,
}

/// A material with reflectance `rho` and exitance `emission` (the inverse
/// of the loader's mapping at `--emission-scale 1`), exact values in its
/// extras.
fn material_of(rho: DVec3, emission: DVec3, name: String) -> json::Material {
    let radiance = emission / std::f64::consts::PI;
    let peak = radiance.max_element();
    let (factor, strength) = if peak > 1.0 {
        (radiance / peak, Some(peak))
    } else {
        (radiance, None)
    };
    json::Material {
        name: Some(name),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([
                rho.x as f32,
                rho.y as f32,
                rho.z as f32,
                1.0,
            ]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(1.0),
            ..Default::default()
        },
        emissive_factor: json::material::EmissiveFactor(factor.to_array().map(|v| v as f32)),
        extensions: strength.map(|s| json::extensions::material::Material {
            emissive_strength: Some(json::extensions::material::EmissiveStrength {
                emissive_strength: json::extensions::material::EmissiveStrengthFactor(s as f32),
            }),
            ..Default::default()
        }),
        extras: raw_extras(&serde_json::json!({ "radiosity": {
            "reflectance": rho.to_array(),
            "exitance": emission.to_array(),
        } })),
        ..Default::default()
    }
}

/// Materials for a scene with no glTF appearance: one per distinct
/// reflectance and exitance. Returns the materials and each surface's index.
fn materials_from_surfaces(scene: &Scene) -> (Vec<json::Material>, Vec<usize>) {
    let mut keys: HashMap<[u64; 6], usize> = HashMap::new();
    let mut materials = Vec::new();
    let mut of_surface = Vec::with_capacity(scene.surfaces.len());
    for s in &scene.surfaces {
        let key = [
            s.rho.x,
            s.rho.y,
            s.rho.z,
            s.emission.x,
            s.emission.y,
            s.emission.z,
        ]
        .map(f64::to_bits);
        let index = *keys.entry(key).or_insert_with(|| {
            let name = if s.is_emitter() {
                format!("emitter {}", materials.len())
            } else {
                format!("material {}", materials.len())
            };
            materials.push(material_of(s.rho, s.emission, name));
            materials.len() - 1
        });
        of_surface.push(index);
    }
    (materials, of_surface)
}

/// The scene's lights as `KHR_lights_punctual` lights, each on a node of its
/// own at its position, its -z axis along its direction (the inverse of the
/// reader's mapping). The colour is scaled to a largest channel of 1, the
/// intensity (candela; lux for a sun) up by as much. A luminaire becomes a
/// point light of the same flux (glTF has no intensity tables); a kind
/// glTF has no form for (a sky, a Lambertian point) is left out
/// ([`crate::scene::light::LightModel::punctual`]). Returns the nodes.
fn lights(root: &mut json::Root, lights: &[crate::scene::Light]) -> Vec<json::Index<json::Node>> {
    use crate::scene::light::PunctualKind;
    use json::extensions::scene::khr_lights_punctual::{Light, Spot, Type};
    let mut out = Vec::new();
    for light in lights {
        let Some(punctual) = light.model().punctual(light.intensity) else {
            continue;
        };
        let (type_, spot) = match punctual.kind {
            PunctualKind::Point => (Type::Point, None),
            PunctualKind::Spot { inner, outer } => (
                Type::Spot,
                Some(Spot {
                    inner_cone_angle: inner as f32,
                    outer_cone_angle: outer as f32,
                }),
            ),
            PunctualKind::Directional => (Type::Directional, None),
        };
        let (position, direction, intensity) =
            (punctual.position, punctual.direction, punctual.intensity);
        let peak = light.colour.max_element();
        let (colour, intensity) = if peak > 0.0 {
            (light.colour / peak, intensity * peak)
        } else {
            (DVec3::ONE, 0.0)
        };
        let extensions = root
            .extensions
            .get_or_insert_with(Default::default)
            .khr_lights_punctual
            .get_or_insert_with(|| json::extensions::root::KhrLightsPunctual {
                lights: Vec::new(),
            });
        let index = json::Index::new(extensions.lights.len() as u32);
        extensions.lights.push(Light {
            color: colour.as_vec3().to_array(),
            extensions: None,
            extras: Default::default(),
            intensity: intensity as f32,
            name: Some(light.name.clone()),
            range: None,
            spot,
            type_: Checked::Valid(type_),
        });
        let rotation = direction.map(|d| {
            let q = glam::DQuat::from_rotation_arc(-DVec3::Z, d).as_quat();
            json::scene::UnitQuaternion([q.x, q.y, q.z, q.w])
        });
        out.push(root.push(json::Node {
            name: Some(light.name.clone()),
            translation: (position != DVec3::ZERO).then(|| position.as_vec3().to_array()),
            rotation,
            extensions: Some(json::extensions::scene::Node {
                khr_lights_punctual: Some(
                    json::extensions::scene::khr_lights_punctual::KhrLightsPunctual {
                        light: index,
                    },
                ),
                ..Default::default()
            }),
            ..Default::default()
        }));
    }
    out
}

/// Writes a bake; returns the files to stage (`.glb`, or `.gltf` + `.bin`).
pub fn bake(bake: &Bake<'_>, path: &Path) -> io::Result<Vec<(PathBuf, Vec<u8>)>> {
    use json::mesh::Semantic;
    let (scene, mesh) = (bake.scene, bake.mesh);
    let mut b = Builder::new();
    let positions: Vec<[f32; 3]> = mesh
        .vertices
        .iter()
        .map(|v| v.position.as_vec3().to_array())
        .collect();
    let normals: Vec<[f32; 3]> = mesh
        .vertices
        .iter()
        .map(|v| v.normal.as_vec3().normalize().to_array())
        .collect();
    let colours: Vec<[f32; 3]> = bake
        .colours
        .iter()
        .map(|c| c.clamp(DVec3::ZERO, DVec3::ONE).as_vec3().to_array())
        .collect();
    let mut attributes = BTreeMap::new();
    attributes.insert(
        Checked::Valid(Semantic::Positions),
        b.floats(&positions, true),
    );
    attributes.insert(Checked::Valid(Semantic::Normals), b.floats(&normals, false));
    attributes.insert(
        Checked::Valid(Semantic::Colors(0)),
        b.floats(&colours, false),
    );

    // Triangles of every element, grouped by output material.
    let surface_material: Vec<Option<usize>> = match (bake.mode, bake.appearance) {
        (BakeMode::Lit, _) => vec![Some(0); scene.surfaces.len()],
        (BakeMode::Irradiance, Some(a)) => a.material.clone(),
        (BakeMode::Irradiance, None) => {
            let (materials, of_surface) = materials_from_surfaces(scene);
            b.root.materials = materials;
            of_surface.into_iter().map(Some).collect()
        }
    };
    let mut groups: BTreeMap<Option<usize>, Vec<u32>> = BTreeMap::new();
    for t in mesh.triangles() {
        let surface = mesh.elements[t.element as usize].surface as usize;
        groups
            .entry(surface_material[surface])
            .or_default()
            .extend(t.corners);
    }

    match (bake.mode, bake.appearance) {
        (BakeMode::Lit, _) => {
            b.root
                .materials
                .push(unlit_material(Some("baked (unlit)".into()), None, false));
        }
        (BakeMode::Irradiance, Some(appearance)) => {
            copy_materials(&mut b, appearance);
            for set in 0..appearance.texcoord_sets {
                let uvs: Vec<[f32; 2]> =
                    mesh.vertices
                        .iter()
                        .map(|v| {
                            let s = v.surface as usize;
                            let polygon = &scene.surfaces[s].polygon;
                            match appearance.uvs.get(s).and_then(|sets| sets.get(set)) {
                                Some(values) => interpolate_on_fan(polygon, values, v.position)
                                    .map(|x| x as f32),
                                None => [0.0, 0.0],
                            }
                        })
                        .collect();
                attributes.insert(
                    Checked::Valid(Semantic::TexCoords(set as u32)),
                    b.floats(&uvs, false),
                );
            }
        }
        (BakeMode::Irradiance, None) => {}
    }
    let mut primitives = Vec::new();
    for (material, indices) in &groups {
        if indices.is_empty() {
            continue;
        }
        let accessor = b.indices(indices);
        primitives.push(primitive(
            &attributes,
            accessor,
            material.map(|m| json::Index::new(m as u32)),
            None,
        ));
    }
    let mesh_index = b.root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        name: Some(format!("{} ({} bake)", scene.name, bake.mode.name())),
        primitives,
        weights: None,
    });
    let mesh_node = b.root.push(json::Node {
        mesh: Some(mesh_index),
        name: Some(scene.name.clone()),
        ..Default::default()
    });
    let (lo, hi) = scene.bounds();
    let camera_node = b.camera(&bake.camera, bake.aspect_ratio, 1e-3 * (hi - lo).length());
    let scene_index = b.root.push(json::Scene {
        extensions: None,
        extras: raw_extras(&serde_json::json!({ "radiosity": bake.metadata })),
        name: Some(scene.name.clone()),
        nodes: vec![mesh_node, camera_node],
    });
    b.root.scene = Some(scene_index);
    b.root.extensions_used = extension_name_list(&b.root);
    b.finish(path)
}

/// Copies a glTF input's materials, textures, samplers and images (image
/// bytes into the output buffer), all single-sided.
fn copy_materials(b: &mut Builder, appearance: &Appearance) {
    let source = &appearance.json;
    b.root.materials = source.materials.clone();
    for m in &mut b.root.materials {
        m.double_sided = false;
    }
    b.root.samplers = source.samplers.clone();
    b.root.textures = source.textures.clone();
    for (i, image) in appearance.images.iter().enumerate() {
        let view = b.view(&image.bytes, None);
        let name = source.images.get(i).and_then(|im| im.name.clone());
        b.root.images.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType(image.mime_type.clone())),
            name,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
    }
}

/// Writes a scene's surfaces as glTF (see the module documentation);
/// returns the files to stage.
pub fn export_scene(scene: &Scene, path: &Path) -> io::Result<Vec<(PathBuf, Vec<u8>)>> {
    use json::mesh::Semantic;
    let mut b = Builder::new();
    let (materials, of_surface) = materials_from_surfaces(scene);
    b.root.materials = materials;
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut normals: Vec<[f32; 3]> = Vec::new();
    // Runs of consecutive surfaces with the same material keep the input
    // order, which the solver's results depend on.
    let mut runs: Vec<(usize, Vec<u32>)> = Vec::new();
    // Loading projects each polygon onto its plane, leaving round-off such
    // as 6e-19 where the input had 0; single precision would keep that
    // noise and reading back would start from it. Coordinates this close to
    // zero relative to the scene are written as zero.
    let (lo, hi) = scene.bounds();
    let tiny = 1e-8 * (hi - lo).length();
    let snap = |v: f64| if v.abs() < tiny { 0.0 } else { v as f32 };
    for (s, surface) in scene.surfaces.iter().enumerate() {
        let first = positions.len() as u32;
        for p in &surface.polygon {
            positions.push([snap(p.x), snap(p.y), snap(p.z)]);
            normals.push(surface.normal.as_vec3().normalize().to_array());
        }
        let material = of_surface[s];
        if runs.last().is_none_or(|(m, _)| *m != material) {
            runs.push((material, Vec::new()));
        }
        let indices = &mut runs.last_mut().expect("pushed above").1;
        for i in 1..surface.polygon.len() as u32 - 1 {
            indices.extend([first, first + i, first + i + 1]);
        }
    }
    let mut attributes = BTreeMap::new();
    attributes.insert(
        Checked::Valid(Semantic::Positions),
        b.floats(&positions, true),
    );
    attributes.insert(Checked::Valid(Semantic::Normals), b.floats(&normals, false));
    let mut primitives = Vec::new();
    for (material, indices) in &runs {
        let accessor = b.indices(indices);
        let mut extension = serde_json::Map::new();
        extension.insert(NGON_EXTENSION.into(), serde_json::json!({}));
        primitives.push(primitive(
            &attributes,
            accessor,
            Some(json::Index::new(*material as u32)),
            Some(json::extensions::mesh::Primitive { others: extension }),
        ));
    }
    let mesh_index = b.root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        name: Some(scene.name.clone()),
        primitives,
        weights: None,
    });
    let mut nodes = vec![b.root.push(json::Node {
        mesh: Some(mesh_index),
        name: Some(scene.name.clone()),
        ..Default::default()
    })];
    if let Some(camera) = &scene.camera {
        nodes.push(b.camera(camera, 4.0 / 3.0, 1e-3 * (hi - lo).length()));
    }
    nodes.extend(lights(&mut b.root, &scene.lights));
    let extras = scene.mesh_hint.as_ref().map(|h| {
        serde_json::json!({ "radiosity": {
            "patch_size": h.patch_size,
            "element_size": h.element_size,
        } })
    });
    let scene_index = b.root.push(json::Scene {
        extensions: None,
        extras: extras.as_ref().and_then(raw_extras),
        name: Some(scene.name.clone()),
        nodes,
    });
    b.root.scene = Some(scene_index);
    b.root.extensions_used = extension_name_list(&b.root);
    b.finish(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emissive_mapping_inverts() {
        let m = material_of(DVec3::splat(0.5), DVec3::new(53.4, 37.7, 12.6), "m".into());
        let f = m.emissive_factor.0;
        let s = m
            .extensions
            .and_then(|e| e.emissive_strength)
            .map_or(1.0, |s| s.emissive_strength.0);
        let back = DVec3::new(f64::from(f[0]), f64::from(f[1]), f64::from(f[2]))
            * f64::from(s)
            * std::f64::consts::PI;
        assert!((back - DVec3::new(53.4, 37.7, 12.6)).abs().max_element() < 1e-4);
        assert_eq!(f[0], 1.0);
    }
}
