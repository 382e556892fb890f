//! glTF 2.0 scenes in (`.gltf` with its buffers, or `.glb`), after the
//! Khronos glTF 2.0 specification; the radiosity model is design.md
//! sections 1 and 7.
//!
//! The `gltf` crate splits the container and parses the JSON; everything the
//! loader then touches (indices, accessor byte ranges, node hierarchy,
//! cameras, images) is checked here first, so hostile input gets one error
//! naming the file and the object, never a panic or a huge allocation.
//! [`load_slice`] works from bytes and a resolver for external files, so it
//! can be fuzzed without a file system.
//!
//! The mapping to radiosity surfaces:
//! - every triangle of a `TRIANGLES`, `TRIANGLE_STRIP` or `TRIANGLE_FAN`
//!   primitive of every node of the default scene becomes a surface, with
//!   the node hierarchy's transforms applied (a transform with a negative
//!   determinant flips the winding, as the specification says); points and
//!   lines are skipped with a warning. Primitives carrying the
//!   `FB_ngon_encoding` extension have their triangle fans merged back into
//!   the planar convex polygons they encode (what `export-scene` writes);
//! - reflectance `rho` = `baseColorFactor` x mean linear colour of
//!   `baseColorTexture` (texels sRGB-decoded) x the triangle's mean
//!   `COLOR_0`, clamped to `--reflectance-cap` with a warning naming the
//!   material;
//! - emitted exitance `E` = pi x `emission_scale` x `emissiveFactor` x
//!   `KHR_materials_emissive_strength` x mean linear colour of
//!   `emissiveTexture`: glTF's emissive value is read as radiance in
//!   W/(m^2 sr) (a Blender emission strength of 1 is radiance 1), and a
//!   Lambertian surface of radiance L has exitance pi L;
//! - a `doubleSided` material gives two surfaces back to back (radiosity
//!   surfaces are single-sided), sharing the input face index;
//! - the first perspective camera met in the scene is the default view;
//!   `KHR_lights_punctual` lights are not area lights and are ignored with
//!   a warning naming them.
//!
//! glTF stores floats in single precision. Each is widened to the shortest
//! decimal that rounds to it (what the author or exporter most likely
//! wrote), so `0.1f32` reads as `0.1`, and a scene written by
//! `export-scene` from decimal input reads back with the same coordinates.
//! `export-scene` also records exact reflectance and exitance in the
//! material's `extras`, used when they agree with the standard fields.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use base64::Engine as _;
use glam::{DMat4, DQuat, DVec3};
use gltf_json as json;
use json::validation::Checked;

use super::polygon::{FaceProblem, convex_pieces};
use super::{Camera, LoadOptions, Location, MeshHint, Scene, SceneError, Surface};

/// Reads an external file named by a URI (already percent-decoded),
/// relative to the glTF file.
pub type Resolver<'a> = dyn FnMut(&str) -> std::io::Result<Vec<u8>> + 'a;

/// Most elements an accessor with no buffer view (all zeros, perhaps with
/// sparse substitutions) may declare: such an accessor costs memory without
/// any bytes in the file to back it.
pub const MAX_VIEWLESS_ELEMENTS: u64 = 1 << 22;

/// Largest texture side decoded, in texels.
pub const MAX_TEXTURE_SIDE: u32 = 16_384;

/// Most bytes a texture decode may allocate.
pub const MAX_TEXTURE_BYTES: u64 = 1 << 30;

/// The name of the vendor extension that encodes polygons as triangle fans.
pub const NGON_EXTENSION: &str = "FB_ngon_encoding";

/// Extensions a file may list as required that this loader honours (or
/// whose absence of support changes nothing for radiosity).
const SUPPORTED_REQUIRED: [&str; 5] = [
    "KHR_materials_emissive_strength",
    "KHR_mesh_quantization",
    "KHR_texture_transform",
    "KHR_materials_unlit",
    "KHR_lights_punctual",
];

/// One image of the input, kept for the irradiance bake.
#[derive(Clone, Debug)]
pub struct ImageData {
    /// The encoded bytes (PNG, JPEG, ...).
    pub bytes: Vec<u8>,
    /// Its MIME type.
    pub mime_type: String,
}

/// What a glTF input carries beyond its surfaces, for a bake that keeps the
/// original materials (`--bake-mode irradiance`): each surface's material
/// and texture coordinates, and the materials, textures and images.
#[derive(Clone, Debug)]
pub struct Appearance {
    /// For each surface, the index of its material in `json.materials`
    /// (`None`: the glTF default material).
    pub material: Vec<Option<usize>>,
    /// For each surface, its texture coordinates: one list per set
    /// (`TEXCOORD_0`, `TEXCOORD_1`, ...) with one entry per corner of the
    /// surface's polygon; empty when its primitive has none.
    pub uvs: Vec<Vec<Vec<[f64; 2]>>>,
    /// How many texture coordinate sets the widest primitive has.
    pub texcoord_sets: usize,
    /// The input document (materials, textures, samplers and images are
    /// copied from it).
    pub json: json::Root,
    /// The bytes of every image, in `json.images` order.
    pub images: Vec<ImageData>,
}

/// Loads a `.gltf` (reading its buffers and images relative to its folder)
/// or a `.glb` file.
pub fn load_file(path: &Path, options: &LoadOptions) -> Result<(Scene, Appearance), SceneError> {
    // As every input: a regular file within --max-file-size, checked
    // before it is read (a `.glb` linked to /dev/zero is refused, not read
    // until memory runs out); the buffers and images it names likewise.
    let bytes = super::read_input(path, &options.limits)?;
    let folder = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    load_slice(
        &name,
        path,
        &bytes,
        &mut |uri: &str| {
            super::read_input(&folder.join(uri), &options.limits).map_err(|e| match e {
                SceneError::Io { source, .. } => source,
                other => std::io::Error::other(other.to_string()),
            })
        },
        options,
    )
}

/// Loads a glTF document from bytes (JSON or GLB). `path` names the file in
/// messages; `resolve` reads the external files its URIs name.
pub fn load_slice(
    name: &str,
    path: &Path,
    bytes: &[u8],
    resolve: &mut Resolver<'_>,
    options: &LoadOptions,
) -> Result<(Scene, Appearance), SceneError> {
    let invalid = |message: String| SceneError::Invalid {
        location: Location::file(path),
        message,
    };
    check_container(bytes).map_err(invalid)?;
    let gltf = ::gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| invalid(format!("not a valid glTF 2.0 file: {e}")))?;
    let root = gltf.document.as_json().clone();
    let mut loader = Loader {
        path: path.to_path_buf(),
        root: &root,
        options,
        buffers: Vec::new(),
        warnings: Vec::new(),
        materials: HashMap::new(),
        texture_means: HashMap::new(),
        decoded: RefCell::new(HashMap::new()),
        surfaces: Vec::new(),
        material_of: Vec::new(),
        uvs: Vec::new(),
        texcoord_sets: 0,
        faces: 0,
        triangles: 0,
        degenerate: 0,
        camera: None,
        lights: Vec::new(),
        capped: Vec::new(),
    };
    loader.check_header()?;
    loader.load_buffers(gltf.blob.as_deref(), resolve)?;
    let images = loader.load_images(resolve)?;
    loader.load_scene(&images)?;
    let mesh_hint = loader.mesh_hint();
    let scene = loader.finish(name, mesh_hint)?;
    let appearance = Appearance {
        material: std::mem::take(&mut loader.material_of),
        uvs: std::mem::take(&mut loader.uvs),
        texcoord_sets: loader.texcoord_sets,
        json: root.clone(),
        images,
    };
    Ok((scene, appearance))
}

/// Checks a GLB container's header and chunk lengths before the `gltf`
/// crate reads it (its length arithmetic assumes sane values). JSON input
/// passes through.
fn check_container(bytes: &[u8]) -> Result<(), String> {
    if bytes.is_empty() {
        return Err("the file is empty".into());
    }
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let word = |at: usize| -> Option<u32> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (Some(version), Some(length)) = (word(4), word(8)) else {
        return Err(format!(
            "truncated GLB: {} bytes, shorter than the 12-byte header",
            bytes.len()
        ));
    };
    if version != 2 {
        return Err(format!("GLB version {version}: only glTF 2.0 is supported"));
    }
    let length = length as usize;
    if length > bytes.len() {
        return Err(format!(
            "truncated GLB: the header gives {length} bytes, the file has {}",
            bytes.len()
        ));
    }
    let mut at = 12;
    let mut chunk = 0;
    while at < length {
        let (Some(chunk_length), Some(kind)) = (word(at), word(at + 4)) else {
            return Err(format!(
                "truncated GLB: chunk {chunk} header cut off at byte {at}"
            ));
        };
        let end = (at as u64) + 8 + u64::from(chunk_length);
        if end > length as u64 {
            return Err(format!(
                "truncated GLB: chunk {chunk} needs {chunk_length} bytes, {} remain",
                length.saturating_sub(at + 8)
            ));
        }
        if chunk == 0 && kind != 0x4E4F_534A {
            return Err("GLB: the first chunk is not JSON".into());
        }
        at = end as usize;
        chunk += 1;
    }
    if chunk == 0 {
        return Err("GLB: no JSON chunk".into());
    }
    Ok(())
}

/// Reflectance and emission of one material.
#[derive(Clone, Copy, Debug)]
struct MaterialInfo {
    rho: DVec3,
    emission: DVec3,
    double_sided: bool,
}

/// A decoded accessor: `components` numbers per element, row after row.
struct Data {
    values: Vec<f64>,
    components: usize,
}

impl Data {
    fn count(&self) -> usize {
        self.values.len() / self.components.max(1)
    }

    fn get(&self, element: usize) -> &[f64] {
        &self.values[element * self.components..(element + 1) * self.components]
    }
}

/// One polygon of the input (a triangle, or an n-gon from a fan) with its
/// per-corner data.
struct SourcePolygon {
    corners: Vec<DVec3>,
    uvs: Vec<Vec<[f64; 2]>>,
    colour: DVec3,
}

/// Loading state.
struct Loader<'a> {
    path: PathBuf,
    root: &'a json::Root,
    options: &'a LoadOptions,
    buffers: Vec<Vec<u8>>,
    warnings: Vec<String>,
    materials: HashMap<Option<usize>, MaterialInfo>,
    texture_means: HashMap<usize, DVec3>,
    /// Accessors already decoded: primitives often share one vertex
    /// accessor, which is then read once, not once per primitive.
    decoded: RefCell<HashMap<usize, Rc<Data>>>,
    surfaces: Vec<Surface>,
    material_of: Vec<Option<usize>>,
    uvs: Vec<Vec<Vec<[f64; 2]>>>,
    texcoord_sets: usize,
    faces: u32,
    /// Triangles read so far, over every instance of every mesh: bounded
    /// by `limits.max_faces` (`--max-faces`), since a mesh a few bytes long
    /// may hold millions of triangles and be instanced by many nodes.
    triangles: usize,
    degenerate: usize,
    camera: Option<Camera>,
    lights: Vec<String>,
    capped: Vec<String>,
}

/// `what 3 ('name')`, or `what 3` when unnamed.
fn label(what: &str, index: usize, name: Option<&String>) -> String {
    match name {
        Some(n) if !n.is_empty() => format!("{what} {index} ('{n}')"),
        _ => format!("{what} {index}"),
    }
}

/// Widens a single-precision value to the shortest decimal that rounds to
/// it (see the module documentation).
fn widen(x: f32) -> f64 {
    // Integers (common: 0, 1) are exact either way.
    if !x.is_finite() || x.fract() == 0.0 {
        return f64::from(x);
    }
    ryu::Buffer::new()
        .format_finite(x)
        .parse()
        .unwrap_or(f64::from(x))
}

fn widen3(v: [f32; 3]) -> DVec3 {
    DVec3::new(widen(v[0]), widen(v[1]), widen(v[2]))
}

/// Decodes `%XX` escapes of a relative URI into a file name.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%'
            && i + 2 < bytes.len()
            && let Some(v) = std::str::from_utf8(&bytes[i + 1..i + 3])
                .ok()
                .and_then(|h| u8::from_str_radix(h, 16).ok())
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The MIME type of an image from its first bytes.
fn guess_mime(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else if bytes.len() >= 12 && &bytes[0..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        Some("image/webp")
    } else {
        None
    }
}

/// The standard sRGB decoding curve.
fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Parses `extras` as JSON and returns its `radiosity` member, if any.
fn radiosity_extras(extras: &json::Extras) -> Option<serde_json::Value> {
    let raw = extras.as_ref()?;
    let value: serde_json::Value = serde_json::from_str(raw.get()).ok()?;
    value.get("radiosity").cloned()
}

/// Reads `[x, y, z]` of finite numbers from JSON.
fn json_vec3(value: Option<&serde_json::Value>) -> Option<DVec3> {
    let a = value?.as_array()?;
    if a.len() != 3 {
        return None;
    }
    let v = DVec3::new(a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?);
    v.is_finite().then_some(v)
}

impl<'a> Loader<'a> {
    fn error(&self, message: String) -> SceneError {
        SceneError::Invalid {
            location: Location::file(&self.path),
            message,
        }
    }

    fn check_header(&mut self) -> Result<(), SceneError> {
        let version = &self.root.asset.version;
        if !version.starts_with("2.") {
            return Err(self.error(format!(
                "asset version '{version}': only glTF 2.0 is supported"
            )));
        }
        for extension in &self.root.extensions_required {
            if !SUPPORTED_REQUIRED.contains(&extension.as_str()) {
                return Err(self.error(format!(
                    "the file requires extension {extension}, which radiosity does not support \
                     (supported: {})",
                    SUPPORTED_REQUIRED.join(", ")
                )));
            }
        }
        Ok(())
    }

    /// Bytes of a URI: a `data:` URI decoded here, anything else read by
    /// the resolver.
    fn read_uri(
        &self,
        uri: &str,
        what: &str,
        resolve: &mut Resolver<'_>,
    ) -> Result<Vec<u8>, SceneError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((header, payload)) = rest.split_once(',') else {
                return Err(self.error(format!("{what}: malformed data URI (no comma)")));
            };
            if !header.ends_with(";base64") {
                return Err(self.error(format!("{what}: only base64 data URIs are supported")));
            }
            return base64::engine::general_purpose::STANDARD
                .decode(payload.trim())
                .map_err(|e| self.error(format!("{what}: bad base64 in data URI: {e}")));
        }
        if uri.contains("://") {
            return Err(self.error(format!(
                "{what}: '{uri}' is a URL; radiosity reads only files beside the glTF and \
                 embedded data"
            )));
        }
        let file = percent_decode(uri);
        resolve(&file).map_err(|e| self.error(format!("{what}: cannot read '{file}': {e}")))
    }

    fn load_buffers(
        &mut self,
        blob: Option<&[u8]>,
        resolve: &mut Resolver<'_>,
    ) -> Result<(), SceneError> {
        let mut buffers = Vec::with_capacity(self.root.buffers.len());
        for (i, buffer) in self.root.buffers.iter().enumerate() {
            let what = label("buffer", i, buffer.name.as_ref());
            let data = match &buffer.uri {
                None => match blob {
                    Some(b) if i == 0 => b.to_vec(),
                    _ => {
                        return Err(self.error(format!(
                            "{what} has no URI and the file has no GLB binary chunk for it"
                        )));
                    }
                },
                Some(uri) => self.read_uri(uri, &what, resolve)?,
            };
            let declared = buffer.byte_length.0;
            if (data.len() as u64) < declared {
                return Err(self.error(format!(
                    "{what} declares {declared} bytes but has only {} (truncated?)",
                    data.len()
                )));
            }
            buffers.push(data);
        }
        self.buffers = buffers;
        Ok(())
    }

    /// The bytes of buffer view `index`, bounds checked.
    fn view_bytes(&self, index: usize, what: &str) -> Result<&[u8], SceneError> {
        let views = &self.root.buffer_views;
        let view = views.get(index).ok_or_else(|| {
            self.error(format!(
                "{what} refers to buffer view {index}, but the file has {}",
                views.len()
            ))
        })?;
        let b = view.buffer.value();
        let Some(buffer) = self.buffers.get(b) else {
            return Err(self.error(format!(
                "buffer view {index} refers to buffer {b}, but the file has {}",
                self.buffers.len()
            )));
        };
        let declared = self.root.buffers[b].byte_length.0;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let end = start.checked_add(view.byte_length.0);
        match end {
            Some(end) if end <= declared && end <= buffer.len() as u64 => {
                Ok(&buffer[start as usize..end as usize])
            }
            _ => Err(self.error(format!(
                "buffer view {index} (bytes {start} + {} of buffer {b}) runs past the buffer's \
                 {declared} bytes",
                view.byte_length.0
            ))),
        }
    }

    fn load_images(&mut self, resolve: &mut Resolver<'_>) -> Result<Vec<ImageData>, SceneError> {
        let mut images = Vec::with_capacity(self.root.images.len());
        for (i, image) in self.root.images.iter().enumerate() {
            let what = label("image", i, image.name.as_ref());
            let bytes = match (&image.buffer_view, &image.uri) {
                (Some(view), _) => self.view_bytes(view.value(), &what)?.to_vec(),
                (None, Some(uri)) => self.read_uri(uri, &what, resolve)?,
                (None, None) => {
                    return Err(self.error(format!("{what} has neither a URI nor a buffer view")));
                }
            };
            let mime_type = image
                .mime_type
                .as_ref()
                .map(|m| m.0.clone())
                .or_else(|| guess_mime(&bytes).map(str::to_string))
                .unwrap_or_else(|| "application/octet-stream".into());
            images.push(ImageData { bytes, mime_type });
        }
        Ok(images)
    }

    /// Decodes accessor `index` into numbers, checking that its type is one
    /// of `allowed` and that every byte it reads lies inside its buffer.
    fn accessor(
        &self,
        index: usize,
        what: &str,
        allowed: &[json::accessor::Type],
    ) -> Result<Rc<Data>, SceneError> {
        use json::accessor::{ComponentType, Type};
        let accessors = &self.root.accessors;
        let accessor = accessors.get(index).ok_or_else(|| {
            self.error(format!(
                "{what} refers to accessor {index}, but the file has {}",
                accessors.len()
            ))
        })?;
        let what = format!("{what} accessor {index}");
        let Checked::Valid(kind) = accessor.type_ else {
            return Err(self.error(format!("{what} has an unknown type")));
        };
        if !allowed.contains(&kind) {
            return Err(self.error(format!(
                "{what} is {kind:?}, expected {}",
                allowed
                    .iter()
                    .map(|t| format!("{t:?}"))
                    .collect::<Vec<_>>()
                    .join(" or ")
            )));
        }
        let Checked::Valid(component) = accessor.component_type else {
            return Err(self.error(format!("{what} has an unknown component type")));
        };
        let component = component.0;
        let components = match kind {
            Type::Scalar => 1,
            Type::Vec2 => 2,
            Type::Vec3 => 3,
            Type::Vec4 => 4,
            Type::Mat2 | Type::Mat3 | Type::Mat4 => {
                return Err(self.error(format!("{what}: matrix accessors are not read")));
            }
        };
        if let Some(data) = self.decoded.borrow().get(&index) {
            return Ok(Rc::clone(data));
        }
        let size = component.size();
        let normalized = accessor.normalized;
        if normalized && matches!(component, ComponentType::U32 | ComponentType::F32) {
            return Err(self.error(format!(
                "{what} is normalized {component:?}, which glTF does not allow"
            )));
        }
        let decode = |b: &[u8]| -> f64 {
            match component {
                ComponentType::I8 => {
                    let v = f64::from(b[0] as i8);
                    if normalized { (v / 127.0).max(-1.0) } else { v }
                }
                ComponentType::U8 => {
                    let v = f64::from(b[0]);
                    if normalized { v / 255.0 } else { v }
                }
                ComponentType::I16 => {
                    let v = f64::from(i16::from_le_bytes([b[0], b[1]]));
                    if normalized {
                        (v / 32767.0).max(-1.0)
                    } else {
                        v
                    }
                }
                ComponentType::U16 => {
                    let v = f64::from(u16::from_le_bytes([b[0], b[1]]));
                    if normalized { v / 65535.0 } else { v }
                }
                ComponentType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                ComponentType::F32 => widen(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            }
        };
        let count = accessor.count.0;
        let element = (components * size) as u64;
        // Reads `n` elements at `offset` with `stride` from a view, checked.
        let read = |view: usize,
                    offset: u64,
                    stride: Option<u64>,
                    n: u64,
                    element: u64,
                    part: &str|
         -> Result<&[u8], SceneError> {
            let bytes = self.view_bytes(view, &what)?;
            let stride = stride.unwrap_or(element);
            if stride < element {
                return Err(self.error(format!(
                    "{what}: {part} byte stride {stride} is smaller than an element ({element} \
                     bytes)"
                )));
            }
            let end = (n.max(1) - 1)
                .checked_mul(stride)
                .and_then(|v| v.checked_add(offset))
                .and_then(|v| v.checked_add(element));
            match end {
                Some(end) if n == 0 || end <= bytes.len() as u64 => {
                    Ok(&bytes[(offset as usize).min(bytes.len())..])
                }
                _ => Err(self.error(format!(
                    "{what}: {part} {n} elements of {element} bytes from byte {offset} run past \
                     the end of buffer view {view} ({} bytes)",
                    bytes.len()
                ))),
            }
        };
        let mut values;
        if let Some(view) = &accessor.buffer_view {
            let v = view.value();
            let stride = self
                .root
                .buffer_views
                .get(v)
                .and_then(|bv| bv.byte_stride)
                .map(|s| s.0 as u64);
            let offset = accessor.byte_offset.map_or(0, |o| o.0);
            let bytes = read(v, offset, stride, count, element, "its")?;
            let stride = stride.unwrap_or(element) as usize;
            values = Vec::with_capacity(count as usize * components);
            for e in 0..count as usize {
                let base = e * stride;
                for c in 0..components {
                    values.push(decode(&bytes[base + c * size..]));
                }
            }
        } else {
            if count > MAX_VIEWLESS_ELEMENTS {
                return Err(self.error(format!(
                    "{what} has no buffer view but declares {count} elements (at most \
                     {MAX_VIEWLESS_ELEMENTS})"
                )));
            }
            values = vec![0.0; count as usize * components];
        }
        if let Some(sparse) = &accessor.sparse {
            let n = sparse.count.0;
            if n > count {
                return Err(self.error(format!(
                    "{what}: {n} sparse substitutions for {count} elements"
                )));
            }
            let Checked::Valid(index_type) = sparse.indices.component_type else {
                return Err(self.error(format!("{what}: sparse indices of unknown type")));
            };
            let index_size = index_type.0.size() as u64;
            let index_bytes = read(
                sparse.indices.buffer_view.value(),
                sparse.indices.byte_offset.0,
                None,
                n,
                index_size,
                "sparse indices:",
            )?;
            let value_bytes = read(
                sparse.values.buffer_view.value(),
                sparse.values.byte_offset.0,
                None,
                n,
                element,
                "sparse values:",
            )?;
            let mut previous: Option<u64> = None;
            for k in 0..n as usize {
                let b = &index_bytes[k * index_size as usize..];
                let target = match index_size {
                    1 => u64::from(b[0]),
                    2 => u64::from(u16::from_le_bytes([b[0], b[1]])),
                    _ => u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                };
                if target >= count || previous.is_some_and(|p| target <= p) {
                    return Err(self.error(format!(
                        "{what}: sparse index {target} (entry {k}) is out of range or not \
                         increasing"
                    )));
                }
                previous = Some(target);
                for c in 0..components {
                    values[target as usize * components + c] =
                        decode(&value_bytes[(k * element as usize) + c * size..]);
                }
            }
        }
        if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
            return Err(self.error(format!(
                "{what}: element {} has a non-finite value ({})",
                bad / components,
                values[bad]
            )));
        }
        let data = Rc::new(Data { values, components });
        self.decoded.borrow_mut().insert(index, Rc::clone(&data));
        Ok(data)
    }

    /// Mean linear colour of image `index`, cached.
    fn texture_mean(
        &mut self,
        texture: usize,
        images: &[ImageData],
        what: &str,
    ) -> Result<DVec3, SceneError> {
        let textures = &self.root.textures;
        let Some(t) = textures.get(texture) else {
            return Err(self.error(format!(
                "{what} refers to texture {texture}, but the file has {}",
                textures.len()
            )));
        };
        let image = t.source.value();
        if let Some(mean) = self.texture_means.get(&image) {
            return Ok(*mean);
        }
        let Some(data) = images.get(image) else {
            return Err(self.error(format!(
                "texture {texture} refers to image {image}, but the file has {}",
                images.len()
            )));
        };
        let image_label = label("image", image, self.root.images[image].name.as_ref());
        let mean = mean_linear_colour(&data.bytes)
            .map_err(|e| self.error(format!("{what}: {image_label}: {e}")))?;
        self.texture_means.insert(image, mean);
        Ok(mean)
    }

    /// Reflectance, emission and sidedness of a material, cached.
    fn material(
        &mut self,
        index: Option<usize>,
        images: &[ImageData],
    ) -> Result<MaterialInfo, SceneError> {
        if let Some(info) = self.materials.get(&index) {
            return Ok(*info);
        }
        let info = match index {
            None => MaterialInfo {
                // The glTF default material: white, not emissive.
                rho: DVec3::ONE,
                emission: DVec3::ZERO,
                double_sided: false,
            },
            Some(i) => {
                let Some(m) = self.root.materials.get(i) else {
                    return Err(self.error(format!(
                        "a primitive refers to material {i}, but the file has {}",
                        self.root.materials.len()
                    )));
                };
                let what = label("material", i, m.name.as_ref());
                let pbr = &m.pbr_metallic_roughness;
                let f = pbr.base_color_factor.0;
                let mut rho = DVec3::new(widen(f[0]), widen(f[1]), widen(f[2]));
                if let Some(info) = &pbr.base_color_texture {
                    rho *= self.texture_mean(info.index.value(), images, &what)?;
                }
                let strength = m
                    .extensions
                    .as_ref()
                    .and_then(|e| e.emissive_strength.as_ref())
                    .map_or(1.0, |s| widen(s.emissive_strength.0));
                let mut radiance = widen3(m.emissive_factor.0) * strength;
                if radiance.max_element() > 0.0
                    && let Some(info) = &m.emissive_texture
                {
                    radiance *= self.texture_mean(info.index.value(), images, &what)?;
                }
                if !rho.is_finite() || rho.min_element() < 0.0 {
                    return Err(self.error(format!(
                        "{what}: baseColorFactor {rho} is not a colour (each channel in [0, 1])"
                    )));
                }
                if !radiance.is_finite() || radiance.min_element() < 0.0 || strength < 0.0 {
                    return Err(self.error(format!(
                        "{what}: emissive {radiance} is negative or not finite"
                    )));
                }
                let mut emission = std::f64::consts::PI * self.options.emission_scale * radiance;
                // Exact values recorded by `export-scene`, used only where
                // they agree with what the standard fields say.
                if let Some(extra) = radiosity_extras(&m.extras) {
                    let close = |a: DVec3, b: DVec3| {
                        (a - b).abs().max_element() <= 1e-6 * (1.0 + b.abs().max_element())
                    };
                    if let Some(r) = json_vec3(extra.get("reflectance"))
                        && close(r, rho)
                    {
                        rho = r;
                    }
                    if let Some(e) = json_vec3(extra.get("exitance")) {
                        let e = e * self.options.emission_scale;
                        if close(e, emission) {
                            emission = e;
                        }
                    }
                }
                MaterialInfo {
                    rho,
                    emission,
                    double_sided: m.double_sided,
                }
            }
        };
        self.materials.insert(index, info);
        Ok(info)
    }

    /// Clamps a reflectance to the cap, remembering which material needed it.
    fn cap(&mut self, rho: DVec3, material: Option<usize>) -> DVec3 {
        let cap = self.options.reflectance_cap;
        if rho.max_element() <= cap {
            return rho;
        }
        let name = match material {
            None => "the default material (white)".to_string(),
            Some(i) => label("material", i, self.root.materials[i].name.as_ref()),
        };
        if !self.capped.contains(&name) {
            self.capped.push(name);
        }
        rho.min(DVec3::splat(cap))
    }

    /// Walks the default scene's node tree.
    fn load_scene(&mut self, images: &[ImageData]) -> Result<(), SceneError> {
        let root = self.root;
        let roots: Vec<usize> = match root.scene.map(|s| s.value()).or(if root.scenes.is_empty() {
            None
        } else {
            Some(0)
        }) {
            Some(s) => {
                let Some(scene) = root.scenes.get(s) else {
                    return Err(self.error(format!(
                        "the default scene is {s}, but the file has {} scenes",
                        root.scenes.len()
                    )));
                };
                scene.nodes.iter().map(|n| n.value()).collect()
            }
            None => {
                // No scene: every node that is nobody's child.
                let mut is_child = vec![false; root.nodes.len()];
                for node in &root.nodes {
                    for c in node.children.iter().flatten() {
                        if let Some(flag) = is_child.get_mut(c.value()) {
                            *flag = true;
                        }
                    }
                }
                (0..root.nodes.len()).filter(|i| !is_child[*i]).collect()
            }
        };
        let mut visited = vec![false; root.nodes.len()];
        let mut stack: Vec<(usize, DMat4)> =
            roots.iter().rev().map(|n| (*n, DMat4::IDENTITY)).collect();
        let mut skinned = false;
        let mut morphed = false;
        while let Some((n, parent)) = stack.pop() {
            let Some(node) = root.nodes.get(n) else {
                return Err(self.error(format!(
                    "a scene or node refers to node {n}, but the file has {}",
                    root.nodes.len()
                )));
            };
            let what = label("node", n, node.name.as_ref());
            if visited[n] {
                return Err(self.error(format!(
                    "{what} is reached twice: the node hierarchy must be a tree (no cycles, one \
                     parent each)"
                )));
            }
            visited[n] = true;
            let world = parent * self.local_transform(node, &what)?;
            if !world.is_finite() {
                return Err(self.error(format!("{what}: its world transform is not finite")));
            }
            if let Some(camera) = node.camera {
                self.take_camera(camera.value(), world, &what)?;
            }
            if let Some(light) = node
                .extensions
                .as_ref()
                .and_then(|e| e.khr_lights_punctual.as_ref())
            {
                let l = light.light.value();
                let name = root
                    .extensions
                    .as_ref()
                    .and_then(|e| e.khr_lights_punctual.as_ref())
                    .and_then(|k| k.lights.get(l))
                    .and_then(|light| light.name.clone());
                self.lights.push(label("light", l, name.as_ref()));
            }
            if let Some(mesh) = node.mesh {
                skinned |= node.skin.is_some();
                morphed |= self.load_mesh(mesh.value(), world, images)?;
            }
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), world));
            }
        }
        if skinned {
            self.warnings.push(format!(
                "{}: skinned meshes are read in their bind pose",
                self.path.display()
            ));
        }
        if morphed {
            self.warnings.push(format!(
                "{}: morph targets are ignored (base shapes are read)",
                self.path.display()
            ));
        }
        Ok(())
    }

    fn local_transform(&self, node: &json::Node, what: &str) -> Result<DMat4, SceneError> {
        let m = if let Some(m) = node.matrix {
            DMat4::from_cols_array(&m.map(widen))
        } else {
            let t = node.translation.map_or(DVec3::ZERO, widen3);
            let s = node.scale.map_or(DVec3::ONE, widen3);
            let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
            let q = DQuat::from_xyzw(widen(r[0]), widen(r[1]), widen(r[2]), widen(r[3]));
            if !q.is_finite() || q.length() < 1e-6 {
                return Err(self.error(format!("{what}: rotation {r:?} is not a unit quaternion")));
            }
            DMat4::from_scale_rotation_translation(s, q.normalize(), t)
        };
        if !m.is_finite() {
            return Err(self.error(format!("{what}: its transform is not finite")));
        }
        Ok(m)
    }

    fn take_camera(&mut self, index: usize, world: DMat4, what: &str) -> Result<(), SceneError> {
        let Some(camera) = self.root.cameras.get(index) else {
            return Err(self.error(format!(
                "{what} refers to camera {index}, but the file has {}",
                self.root.cameras.len()
            )));
        };
        let camera_label = label("camera", index, camera.name.as_ref());
        let Some(perspective) = &camera.perspective else {
            self.warnings.push(format!(
                "{}: {camera_label} is not perspective: ignored",
                self.path.display()
            ));
            return Ok(());
        };
        if self.camera.is_some() {
            return Ok(());
        }
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(DVec3::NEG_Z);
        let up = world.transform_vector3(DVec3::Y);
        let candidate = Camera {
            eye,
            target: eye + forward.normalize_or_zero(),
            up,
            fov_degrees: widen(perspective.yfov).to_degrees(),
        };
        match candidate.validate() {
            Ok(()) => {
                // An exact camera recorded by `export-scene`, if it agrees.
                let exact = radiosity_extras(&camera.extras)
                    .and_then(|e| e.get("camera").cloned())
                    .and_then(|c| serde_json::from_value::<Vec<f64>>(c).ok())
                    .filter(|v| v.len() == 10)
                    .map(|v| Camera {
                        eye: DVec3::new(v[0], v[1], v[2]),
                        target: DVec3::new(v[3], v[4], v[5]),
                        up: DVec3::new(v[6], v[7], v[8]),
                        fov_degrees: v[9],
                    })
                    .filter(|c| {
                        c.validate().is_ok()
                            && c.eye.distance(eye) <= 1e-5 * (1.0 + eye.length())
                            && (c.target - c.eye).normalize().dot(forward.normalize()) > 1.0 - 1e-6
                    });
                self.camera = Some(exact.unwrap_or(candidate));
            }
            Err(e) => self.warnings.push(format!(
                "{}: {camera_label} ignored: {e}",
                self.path.display()
            )),
        }
        Ok(())
    }

    /// Loads every primitive of mesh `index` under `world`. Returns whether
    /// the mesh has morph targets.
    fn load_mesh(
        &mut self,
        index: usize,
        world: DMat4,
        images: &[ImageData],
    ) -> Result<bool, SceneError> {
        use json::accessor::Type;
        use json::mesh::{Mode, Semantic};
        let root = self.root;
        let Some(mesh) = root.meshes.get(index) else {
            return Err(self.error(format!(
                "a node refers to mesh {index}, but the file has {}",
                root.meshes.len()
            )));
        };
        let mesh_label = label("mesh", index, mesh.name.as_ref());
        let flip = world.determinant() < 0.0;
        let mut morphed = false;
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let what = format!("{mesh_label}, primitive {p}");
            morphed |= primitive.targets.as_ref().is_some_and(|t| !t.is_empty());
            let mode = match primitive.mode {
                Checked::Valid(mode) => mode,
                Checked::Invalid => {
                    return Err(self.error(format!("{what}: unknown primitive mode")));
                }
            };
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                let name = match mode {
                    Mode::Points => "POINTS",
                    Mode::Lines => "LINES",
                    Mode::LineLoop => "LINE_LOOP",
                    _ => "LINE_STRIP",
                };
                self.warnings.push(format!(
                    "{}: {what} has mode {name}: ignored (only triangles make surfaces)",
                    self.path.display()
                ));
                continue;
            }
            let attribute = |s: Semantic| primitive.attributes.get(&Checked::Valid(s));
            let Some(position_accessor) = attribute(Semantic::Positions) else {
                self.warnings.push(format!(
                    "{}: {what} has no POSITION: ignored",
                    self.path.display()
                ));
                continue;
            };
            let positions = self.accessor(
                position_accessor.value(),
                &format!("{what}, POSITION"),
                &[Type::Vec3],
            )?;
            let vertex_count = positions.count();
            let indices: Vec<usize> = match primitive.indices {
                Some(a) => {
                    let a = a.value();
                    let what = format!("{what}, indices");
                    if let Some(acc) = root.accessors.get(a) {
                        let integer = matches!(
                            acc.component_type,
                            Checked::Valid(json::accessor::GenericComponentType(
                                json::accessor::ComponentType::U8
                                    | json::accessor::ComponentType::U16
                                    | json::accessor::ComponentType::U32
                            ))
                        );
                        if !integer || acc.normalized {
                            return Err(self.error(format!(
                                "{what} accessor {a} must hold unsigned integers"
                            )));
                        }
                    }
                    let data = self.accessor(a, &what, &[Type::Scalar])?;
                    let mut out = Vec::with_capacity(data.values.len());
                    for (k, v) in data.values.iter().enumerate() {
                        let i = *v as usize;
                        if i >= vertex_count {
                            return Err(self.error(format!(
                                "{what} accessor {a}: index {i} (entry {k}) is past the vertex \
                                 count {vertex_count}"
                            )));
                        }
                        out.push(i);
                    }
                    out
                }
                None => (0..vertex_count).collect(),
            };
            let mut uv_sets = Vec::new();
            while let Some(a) = attribute(Semantic::TexCoords(uv_sets.len() as u32)) {
                let set = uv_sets.len();
                uv_sets.push(self.accessor(
                    a.value(),
                    &format!("{what}, TEXCOORD_{set}"),
                    &[Type::Vec2],
                )?);
            }
            for (set, data) in uv_sets.iter().enumerate() {
                if data.count() < vertex_count {
                    return Err(self.error(format!(
                        "{what}: TEXCOORD_{set} has {} elements for {vertex_count} vertices",
                        data.count()
                    )));
                }
            }
            let colours = match attribute(Semantic::Colors(0)) {
                Some(a) => {
                    let data = self.accessor(
                        a.value(),
                        &format!("{what}, COLOR_0"),
                        &[Type::Vec3, Type::Vec4],
                    )?;
                    if data.count() < vertex_count {
                        return Err(self.error(format!(
                            "{what}: COLOR_0 has {} elements for {vertex_count} vertices",
                            data.count()
                        )));
                    }
                    Some(data)
                }
                None => None,
            };
            self.texcoord_sets = self.texcoord_sets.max(uv_sets.len());
            let material_index = primitive.material.map(|m| m.value());
            let material = self.material(material_index, images)?;
            let count = match mode {
                Mode::Triangles => indices.len() / 3,
                _ => indices.len().saturating_sub(2),
            };
            let limit = self.options.limits.max_faces;
            self.triangles = self.triangles.saturating_add(count);
            if self.triangles > limit {
                return Err(self.error(format!(
                    "{what}: more than {limit} triangles in the scene, the limit (raise it with \
                     --max-faces)"
                )));
            }
            let triangles = assemble(mode, &indices);
            if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
                self.warnings.push(format!(
                    "{}: {what}: {} index/vertex count is not a multiple of 3; the last {} \
                     ignored",
                    self.path.display(),
                    indices.len(),
                    indices.len() % 3
                ));
            }
            let ngon = mode == Mode::Triangles
                && primitive
                    .extensions
                    .as_ref()
                    .is_some_and(|e| e.others.contains_key(NGON_EXTENSION));
            let polygons = if ngon {
                fans(&triangles)
            } else {
                triangles.iter().map(|t| t.to_vec()).collect()
            };
            for corners_in in polygons {
                let mut corners = corners_in;
                if flip {
                    corners.reverse();
                }
                let source = SourcePolygon {
                    corners: corners
                        .iter()
                        .map(|&v| {
                            let p = positions.get(v);
                            world.transform_point3(DVec3::new(p[0], p[1], p[2]))
                        })
                        .collect(),
                    uvs: uv_sets
                        .iter()
                        .map(|d| {
                            corners
                                .iter()
                                .map(|&v| {
                                    let uv = d.get(v);
                                    [uv[0], uv[1]]
                                })
                                .collect()
                        })
                        .collect(),
                    colour: colours.as_ref().map_or(DVec3::ONE, |d| {
                        corners
                            .iter()
                            .map(|&v| {
                                let c = d.get(v);
                                DVec3::new(c[0], c[1], c[2])
                            })
                            .sum::<DVec3>()
                            / corners.len() as f64
                    }),
                };
                if source.corners.iter().any(|p| !p.is_finite()) {
                    return Err(self.error(format!("{what}: a transformed position is not finite")));
                }
                self.add_polygon(source, material, material_index, ngon, &what)?;
            }
        }
        Ok(morphed)
    }

    /// Turns one input polygon into surfaces (two back to back when the
    /// material is double-sided).
    fn add_polygon(
        &mut self,
        source: SourcePolygon,
        material: MaterialInfo,
        material_index: Option<usize>,
        ngon: bool,
        what: &str,
    ) -> Result<(), SceneError> {
        let face = self.faces;
        self.faces = self
            .faces
            .checked_add(1)
            .ok_or_else(|| self.error(format!("{what}: more than {} faces", u32::MAX)))?;
        let pieces = match convex_pieces(&source.corners) {
            Ok(pieces) => pieces.polygons,
            Err(FaceProblem::Degenerate) => {
                self.degenerate += 1;
                return Ok(());
            }
            Err(_) if ngon => {
                // Not a planar polygon after all: keep its fan triangles.
                let n = source.corners.len();
                for i in 1..n - 1 {
                    let triangle = SourcePolygon {
                        corners: vec![source.corners[0], source.corners[i], source.corners[i + 1]],
                        uvs: source
                            .uvs
                            .iter()
                            .map(|s| vec![s[0], s[i], s[i + 1]])
                            .collect(),
                        colour: source.colour,
                    };
                    self.faces -= 1;
                    self.add_polygon(triangle, material, material_index, false, what)?;
                }
                return Ok(());
            }
            Err(_) => {
                self.degenerate += 1;
                return Ok(());
            }
        };
        let rho = self.cap(material.rho * source.colour, material_index);
        for piece in pieces {
            let uvs: Vec<Vec<[f64; 2]>> = source
                .uvs
                .iter()
                .map(|set| {
                    piece
                        .iter()
                        .map(|p| interpolate_on_fan(&source.corners, set, *p))
                        .collect()
                })
                .collect();
            let Some(front) = Surface::new(piece.clone(), rho, material.emission, face) else {
                self.degenerate += 1;
                continue;
            };
            self.surfaces.push(front);
            self.material_of.push(material_index);
            self.uvs.push(uvs.clone());
            if material.double_sided {
                let mut back_polygon = piece;
                back_polygon.reverse();
                if let Some(back) = Surface::new(back_polygon, rho, material.emission, face) {
                    self.surfaces.push(back);
                    self.material_of.push(material_index);
                    self.uvs.push(
                        uvs.into_iter()
                            .map(|mut set| {
                                set.reverse();
                                set
                            })
                            .collect(),
                    );
                }
            }
        }
        Ok(())
    }

    /// The mesh sizes recorded by `export-scene` in the scene's extras.
    fn mesh_hint(&self) -> Option<MeshHint> {
        let root = self.root;
        let scene = root.scenes.get(root.scene.map_or(0, |s| s.value()))?;
        let extra = radiosity_extras(&scene.extras)?;
        let patch_size = extra.get("patch_size")?.as_f64()?;
        let element_size = extra.get("element_size")?.as_f64()?;
        (patch_size.is_finite()
            && element_size.is_finite()
            && patch_size > 0.0
            && element_size > 0.0)
            .then_some(MeshHint {
                patch_size,
                element_size,
                directive: Some(Location::file(&self.path)),
            })
    }

    fn finish(&mut self, name: &str, mesh_hint: Option<MeshHint>) -> Result<Scene, SceneError> {
        let file = self.path.display().to_string();
        if self.faces == 0 {
            return Err(self.error("the scene has no triangles".into()));
        }
        if self.surfaces.is_empty() {
            return Err(self.error(format!(
                "all {} triangles are degenerate (no area)",
                self.faces
            )));
        }
        let lights = if self.lights.is_empty() {
            String::new()
        } else {
            format!(
                "; its KHR_lights_punctual lights ({}) are not area lights and are ignored",
                self.lights.join(", ")
            )
        };
        if !self.surfaces.iter().any(Surface::is_emitter) {
            return Err(self.error(format!(
                "the scene has no emitter: no material has an emissiveFactor > 0{lights}; give \
                 the lamps a mesh with an emissive material"
            )));
        }
        let mut warnings = std::mem::take(&mut self.warnings);
        if !self.lights.is_empty() {
            warnings.push(format!(
                "{file}: ignored {} KHR_lights_punctual light(s): {} (radiosity lights only \
                 come from emissive surfaces)",
                self.lights.len(),
                self.lights.join(", ")
            ));
        }
        if !self.capped.is_empty() {
            warnings.push(format!(
                "{file}: reflectance above {} clamped (--reflectance-cap) for {}",
                self.options.reflectance_cap,
                self.capped.join(", ")
            ));
        }
        if self.degenerate > 0 {
            warnings.push(format!(
                "{file}: dropped {} degenerate triangle(s) with no area",
                self.degenerate
            ));
        }
        let mut surfaces = std::mem::take(&mut self.surfaces);
        super::merge::group_by_face(&mut surfaces);
        Ok(Scene {
            name: name.to_string(),
            surfaces,
            camera: self.camera,
            mesh_hint,
            warnings,
        })
    }
}

/// Vertex triples of a triangle list, strip or fan, counter-clockwise.
fn assemble(mode: json::mesh::Mode, indices: &[usize]) -> Vec<[usize; 3]> {
    use json::mesh::Mode;
    let n = indices.len();
    match mode {
        Mode::TriangleStrip if n >= 3 => (0..n - 2)
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i], indices[i + 1], indices[i + 2]]
                } else {
                    [indices[i + 1], indices[i], indices[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan if n >= 3 => (1..n - 1)
            .map(|i| [indices[i], indices[i + 1], indices[0]])
            .collect(),
        Mode::Triangles => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
        _ => Vec::new(),
    }
}

/// Groups triangles into the polygons `FB_ngon_encoding` encodes: a run of
/// consecutive triangles sharing their first vertex, each starting where the
/// last ended, is one fan.
fn fans(triangles: &[[usize; 3]]) -> Vec<Vec<usize>> {
    let mut polygons: Vec<Vec<usize>> = Vec::new();
    let mut previous: Option<[usize; 3]> = None;
    for t in triangles {
        match (previous, polygons.last_mut()) {
            (Some(p), Some(polygon)) if p[0] == t[0] && p[2] == t[1] => polygon.push(t[2]),
            _ => polygons.push(t.to_vec()),
        }
        previous = Some(*t);
    }
    polygons
}

/// Interpolates per-corner `values` at `p` on a planar polygon, linearly
/// inside the fan triangle (corner 0, i, i + 1) that holds `p`, as a
/// renderer interpolates a triangulated polygon.
#[must_use]
pub fn interpolate_on_fan(corners: &[DVec3], values: &[[f64; 2]], p: DVec3) -> [f64; 2] {
    let n = corners.len().min(values.len());
    if n == 0 {
        return [0.0, 0.0];
    }
    if n < 3 {
        return values[0];
    }
    let mut best = (f64::NEG_INFINITY, [0.0, 0.0]);
    for i in 1..n - 1 {
        let (a, b, c) = (corners[0], corners[i], corners[i + 1]);
        let normal = (b - a).cross(c - a);
        let area2 = normal.length_squared();
        if area2 == 0.0 {
            continue;
        }
        let wa = (c - b).cross(p - b).dot(normal) / area2;
        let wb = (a - c).cross(p - c).dot(normal) / area2;
        let wc = 1.0 - wa - wb;
        let worst = wa.min(wb).min(wc);
        if worst > best.0 {
            let (va, vb, vc) = (values[0], values[i], values[i + 1]);
            best = (
                worst,
                [
                    wa * va[0] + wb * vb[0] + wc * vc[0],
                    wa * va[1] + wb * vb[1] + wc * vc[1],
                ],
            );
        }
        if worst >= 0.0 {
            break;
        }
    }
    best.1
}

/// Why a texture has no mean colour ([`mean_linear_colour`]).
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// The bytes could not be read.
    #[error("cannot read: {0}")]
    Read(std::io::Error),
    /// The image could not be decoded.
    #[error("cannot decode: {0}")]
    Decode(image::ImageError),
    /// No pixels.
    #[error("the image is empty")]
    Empty,
}

/// Mean colour of an encoded image in linear light, texels sRGB-decoded,
/// alpha ignored.
pub fn mean_linear_colour(bytes: &[u8]) -> Result<DVec3, TextureError> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(TextureError::Read)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    limits.max_alloc = Some(MAX_TEXTURE_BYTES);
    reader.limits(limits);
    let decoded = reader.decode().map_err(TextureError::Decode)?;
    let (w, h) = (decoded.width(), decoded.height());
    if w == 0 || h == 0 {
        return Err(TextureError::Empty);
    }
    let mut sum = DVec3::ZERO;
    match decoded {
        image::DynamicImage::ImageRgb8(_)
        | image::DynamicImage::ImageRgba8(_)
        | image::DynamicImage::ImageLuma8(_)
        | image::DynamicImage::ImageLumaA8(_) => {
            let table: Vec<f64> = (0..256)
                .map(|v| srgb_to_linear(f64::from(v) / 255.0))
                .collect();
            let rgb = decoded.to_rgb8();
            for p in rgb.pixels() {
                sum += DVec3::new(
                    table[p[0] as usize],
                    table[p[1] as usize],
                    table[p[2] as usize],
                );
            }
        }
        other => {
            let rgb = other.to_rgb32f();
            for p in rgb.pixels() {
                sum += DVec3::new(
                    srgb_to_linear(f64::from(p[0]).clamp(0.0, 1.0)),
                    srgb_to_linear(f64::from(p[1]).clamp(0.0, 1.0)),
                    srgb_to_linear(f64::from(p[2]).clamp(0.0, 1.0)),
                );
            }
        }
    }
    Ok(sum / (f64::from(w) * f64::from(h)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widening_recovers_short_decimals() {
        assert_eq!(widen(0.1), 0.1);
        assert_eq!(widen(0.5528), 0.5528);
        assert_eq!(widen(-3.25), -3.25);
        assert_eq!(widen(1.0e-7), 1.0e-7);
        assert_eq!(widen(0.0), 0.0);
    }

    #[test]
    fn strips_and_fans_wind_counter_clockwise() {
        use json::mesh::Mode;
        assert_eq!(
            assemble(Mode::TriangleStrip, &[0, 1, 2, 3]),
            vec![[0, 1, 2], [2, 1, 3]]
        );
        assert_eq!(
            assemble(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![[1, 2, 0], [2, 3, 0]]
        );
        assert_eq!(assemble(Mode::Triangles, &[0, 1, 2, 3]), vec![[0, 1, 2]]);
    }

    #[test]
    fn fans_regroup_polygons() {
        let triangles = [
            [0, 1, 2],
            [0, 2, 3],
            [4, 5, 6],
            [4, 6, 7],
            [4, 7, 8],
            [9, 10, 11],
        ];
        assert_eq!(
            fans(&triangles),
            vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7, 8], vec![9, 10, 11]]
        );
    }

    #[test]
    fn fan_interpolation_is_linear_per_triangle() {
        let corners = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        let uvs = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        for (p, expected) in [
            (DVec3::new(1.0, 1.0, 0.0), [0.5, 0.5]),
            (DVec3::new(1.5, 0.5, 0.0), [0.75, 0.25]),
            (DVec3::new(0.5, 1.5, 0.0), [0.25, 0.75]),
            (DVec3::new(2.0, 2.0, 0.0), [1.0, 1.0]),
        ] {
            let got = interpolate_on_fan(&corners, &uvs, p);
            assert!(
                (got[0] - expected[0]).abs() < 1e-12 && (got[1] - expected[1]).abs() < 1e-12,
                "{p}: {got:?}"
            );
        }
    }

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("my%20file.bin"), "my file.bin");
        assert_eq!(percent_decode("plain.bin"), "plain.bin");
        assert_eq!(percent_decode("bad%zz.bin"), "bad%zz.bin");
        assert_eq!(percent_decode("end%2"), "end%2");
    }
}
