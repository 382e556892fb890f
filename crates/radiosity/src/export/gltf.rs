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

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io;
use std::path::{Path, PathBuf};

use glam::{DMat3, DQuat, DVec3};
use gltf_json as json;
use json::validation::{Checked, USize64};

use crate::mesh::Mesh;
use crate::scene::gltf::{Appearance, NGON_EXTENSION, interpolate_on_fan};
use crate::scene::{Camera, Scene};

crate::choice::named_choice! {
    /// What `COLOR_0` of a bake holds.
    pub enum BakeMode: "bake mode" {
        /// Displayed radiance under an unlit material.
        Lit = "lit",
        /// Irradiance / pi, with the original materials.
        Irradiance = "irradiance",
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

/// A glTF document being built: JSON plus one binary buffer.
struct Builder {
    root: json::Root,
    bin: Vec<u8>,
}

impl Builder {
    fn new() -> Builder {
        let root = json::Root {
            asset: json::Asset {
                generator: Some(format!("radiosity {}", env!("CARGO_PKG_VERSION"))),
                version: "2.0".into(),
                ..Default::default()
            },
            ..Default::default()
        };
        Builder {
            root,
            bin: Vec::new(),
        }
    }

    /// Appends bytes as a buffer view, 4-byte aligned.
    fn view(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: None,
            extras: Default::default(),
            name: None,
            target: target.map(Checked::Valid),
        })
    }

    fn accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        component: json::accessor::ComponentType,
        kind: json::accessor::Type,
        target: json::buffer::Target,
        bounds: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        let view = self.view(bytes, Some(target));
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(USize64(0)),
            count: USize64::from(count),
            component_type: Checked::Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Checked::Valid(kind),
            min: bounds.as_ref().map(|(lo, _)| serde_json::json!(lo)),
            max: bounds.as_ref().map(|(_, hi)| serde_json::json!(hi)),
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A float VEC3 (or VEC2) attribute; `with_bounds` adds min and max
    /// (required for `POSITION`).
    fn floats<const N: usize>(
        &mut self,
        values: &[[f32; N]],
        with_bounds: bool,
    ) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = values
            .iter()
            .flat_map(|v| v.iter().flat_map(|c| c.to_le_bytes()))
            .collect();
        let bounds = with_bounds.then(|| {
            let mut lo = vec![f32::INFINITY; N];
            let mut hi = vec![f32::NEG_INFINITY; N];
            for v in values {
                for k in 0..N {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
            (lo, hi)
        });
        let kind = match N {
            2 => json::accessor::Type::Vec2,
            3 => json::accessor::Type::Vec3,
            _ => json::accessor::Type::Vec4,
        };
        self.accessor(
            &bytes,
            values.len(),
            json::accessor::ComponentType::F32,
            kind,
            json::buffer::Target::ArrayBuffer,
            bounds,
        )
    }

    fn indices(&mut self, indices: &[u32]) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        self.accessor(
            &bytes,
            indices.len(),
            json::accessor::ComponentType::U32,
            json::accessor::Type::Scalar,
            json::buffer::Target::ElementArrayBuffer,
            None,
        )
    }

    fn camera(
        &mut self,
        camera: &Camera,
        aspect_ratio: f64,
        znear: f64,
    ) -> json::Index<json::Node> {
        let forward = (camera.target - camera.eye).normalize();
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        // A glTF camera looks down its -Z with +Y up.
        let rotation = DQuat::from_mat3(&DMat3::from_cols(right, up, -forward)).normalize();
        let c = camera;
        let index = self.root.push(json::Camera {
            name: Some("radiosity view".into()),
            orthographic: None,
            perspective: Some(json::camera::Perspective {
                aspect_ratio: Some(aspect_ratio as f32),
                yfov: c.fov_degrees.to_radians() as f32,
                zfar: None,
                znear: znear as f32,
                extensions: None,
                extras: Default::default(),
            }),
            type_: Checked::Valid(json::camera::Type::Perspective),
            extensions: None,
            extras: raw_extras(&serde_json::json!({ "radiosity": { "camera": [
                c.eye.x, c.eye.y, c.eye.z, c.target.x, c.target.y, c.target.z,
                c.up.x, c.up.y, c.up.z, c.fov_degrees
            ] } })),
        });
        self.root.push(json::Node {
            camera: Some(index),
            name: Some("camera".into()),
            rotation: Some(json::scene::UnitQuaternion(
                rotation.to_array().map(|v| v as f32),
            )),
            translation: Some(camera.eye.to_array().map(|v| v as f32)),
            ..Default::default()
        })
    }

    /// The finished files: one `.glb`, or a `.gltf` and its `.bin`.
    fn finish(mut self, path: &Path) -> io::Result<Vec<(PathBuf, Vec<u8>)>> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let glb = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
        let bin_path = path.with_extension("bin");
        let uri = if glb {
            None
        } else {
            let name = bin_path
                .file_name()
                .and_then(|n| n.to_str())
                .ok_or_else(|| io::Error::other("the output name is not UTF-8"))?;
            Some(percent_encode(name))
        };
        if !self.bin.is_empty() {
            self.root.buffers.push(json::Buffer {
                byte_length: USize64::from(self.bin.len()),
                name: None,
                uri,
                extensions: None,
                extras: Default::default(),
            });
        }
        let text = serde_json::to_vec(&self.root).map_err(io::Error::other)?;
        if glb {
            let file = ::gltf::binary::Glb {
                header: ::gltf::binary::Header {
                    magic: *b"glTF",
                    version: 2,
                    length: 0,
                },
                json: text.into(),
                bin: (!self.bin.is_empty()).then(|| self.bin.into()),
            };
            let bytes = file.to_vec().map_err(io::Error::other)?;
            Ok(vec![(path.to_path_buf(), bytes)])
        } else {
            let mut files = vec![(path.to_path_buf(), text)];
            if !self.bin.is_empty() {
                files.push((bin_path, self.bin));
            }
            Ok(files)
        }
    }
}

/// Escapes what a URI reference may not hold literally.
fn percent_encode(name: &str) -> String {
    let mut out = String::new();
    for b in name.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// `extras` holding a JSON value.
fn raw_extras(value: &serde_json::Value) -> json::Extras {
    serde_json::value::to_raw_value(value).ok()
}

/// Extension names used anywhere in a JSON value (keys of every
/// `extensions` object).
fn extensions_in(value: &serde_json::Value, out: &mut BTreeSet<String>) {
    match value {
        serde_json::Value::Object(map) => {
            for (key, v) in map {
                if key == "extensions"
                    && let Some(e) = v.as_object()
                {
                    out.extend(e.keys().cloned());
                }
                extensions_in(v, out);
            }
        }
        serde_json::Value::Array(items) => items.iter().for_each(|v| extensions_in(v, out)),
        _ => {}
    }
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
/// point light of the same flux (glTF has no intensity tables) and a sky is
/// left out (glTF has no skies). Returns the nodes.
fn lights(root: &mut json::Root, lights: &[crate::scene::Light]) -> Vec<json::Index<json::Node>> {
    use crate::scene::LightKind;
    use json::extensions::scene::khr_lights_punctual::{Light, Spot, Type};
    let mut out = Vec::new();
    for light in lights {
        let (type_, position, direction, spot, intensity) = match &light.kind {
            LightKind::Point { position } => (Type::Point, *position, None, None, light.intensity),
            LightKind::Spot {
                position,
                direction,
                inner,
                outer,
            } => (
                Type::Spot,
                *position,
                Some(*direction),
                Some(Spot {
                    inner_cone_angle: *inner as f32,
                    outer_cone_angle: *outer as f32,
                }),
                light.intensity,
            ),
            LightKind::Sun { direction } => (
                Type::Directional,
                DVec3::ZERO,
                Some(*direction),
                None,
                light.intensity,
            ),
            LightKind::Luminaire {
                position, profile, ..
            } => (
                Type::Point,
                *position,
                None,
                None,
                light.intensity * profile.flux() / (4.0 * std::f64::consts::PI),
            ),
            LightKind::Sky { .. } => continue,
        };
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

fn extension_name_list(root: &json::Root) -> Vec<String> {
    let value = serde_json::to_value(root).unwrap_or_default();
    let mut used = BTreeSet::new();
    extensions_in(&value, &mut used);
    used.into_iter().collect()
}

fn primitive(
    attributes: &BTreeMap<Checked<json::mesh::Semantic>, json::Index<json::Accessor>>,
    indices: json::Index<json::Accessor>,
    material: Option<json::Index<json::Material>>,
    extensions: Option<json::extensions::mesh::Primitive>,
) -> json::mesh::Primitive {
    json::mesh::Primitive {
        attributes: attributes.clone(),
        extensions,
        extras: Default::default(),
        indices: Some(indices),
        material,
        mode: Checked::Valid(json::mesh::Mode::Triangles),
        targets: None,
    }
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
            b.root.materials.push(json::Material {
                name: Some("baked (unlit)".into()),
                pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                    metallic_factor: json::material::StrengthFactor(0.0),
                    roughness_factor: json::material::StrengthFactor(1.0),
                    ..Default::default()
                },
                extensions: Some(json::extensions::material::Material {
                    unlit: Some(json::extensions::material::Unlit {}),
                    ..Default::default()
                }),
                ..Default::default()
            });
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
    fn uri_escaping() {
        assert_eq!(percent_encode("out bake.bin"), "out%20bake.bin");
        assert_eq!(percent_encode("a-b_c.d~e.bin"), "a-b_c.d~e.bin");
    }

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
