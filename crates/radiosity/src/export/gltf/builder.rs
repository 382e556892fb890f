//! The glTF document writer shared by the bakes and `export-scene`: JSON
//! built with `gltf-json` plus one binary buffer, written as `.glb` or as
//! `.gltf` with a `.bin` beside it (Khronos glTF 2.0 specification, *GLB
//! File Format* and *Buffers and Buffer Views*).

use std::collections::{BTreeMap, BTreeSet};
use std::io;
use std::path::{Path, PathBuf};

use glam::{DMat3, DQuat};
use gltf_json as json;
use json::validation::{Checked, USize64};

use crate::scene::Camera;

/// A glTF document being built: JSON plus one binary buffer.
pub(crate) struct Builder {
    /// The document's JSON.
    pub(crate) root: json::Root,
    /// The binary buffer's bytes so far.
    pub(crate) bin: Vec<u8>,
}

impl Builder {
    pub(crate) fn new() -> Builder {
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
    pub(crate) fn view(
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

    pub(crate) fn accessor(
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
    pub(crate) fn floats<const N: usize>(
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

    pub(crate) fn indices(&mut self, indices: &[u32]) -> json::Index<json::Accessor> {
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

    pub(crate) fn camera(
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
    pub(crate) fn finish(mut self, path: &Path) -> io::Result<Vec<(PathBuf, Vec<u8>)>> {
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
pub(crate) fn raw_extras(value: &serde_json::Value) -> json::Extras {
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

/// An unlit material (`KHR_materials_unlit`): the base colour shown as
/// it is, from `texture` when given.
pub(crate) fn unlit_material(
    name: Option<String>,
    texture: Option<json::texture::Info>,
    double_sided: bool,
) -> json::Material {
    json::Material {
        name,
        double_sided,
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_texture: texture,
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(1.0),
            ..Default::default()
        },
        extensions: Some(json::extensions::material::Material {
            unlit: Some(json::extensions::material::Unlit {}),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// `extras` read as a JSON object (empty when absent or not an object).
pub(crate) fn extras_object(extras: &json::Extras) -> serde_json::Value {
    extras
        .as_ref()
        .and_then(|raw| serde_json::from_str(raw.get()).ok())
        .filter(serde_json::Value::is_object)
        .unwrap_or_else(|| serde_json::json!({}))
}

/// Every extension the document uses, for `extensionsUsed`.
pub(crate) fn extension_name_list(root: &json::Root) -> Vec<String> {
    let value = serde_json::to_value(root).unwrap_or_default();
    let mut used = BTreeSet::new();
    extensions_in(&value, &mut used);
    used.into_iter().collect()
}

/// A triangle-list primitive.
pub(crate) fn primitive(
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uri_escaping() {
        assert_eq!(percent_encode("out bake.bin"), "out%20bake.bin");
        assert_eq!(percent_encode("a-b_c.d~e.bin"), "a-b_c.d~e.bin");
    }
}
