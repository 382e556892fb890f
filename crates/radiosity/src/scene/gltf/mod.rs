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
//! - `KHR_lights_punctual` lights become point, spot and sun lights
//!   (candela; lux for directional lights), each at its node's origin and
//!   shining along the node's -z axis; a light whose `extras` hold
//!   `"ies": "FILE.ies"` (a URI, relative to the glTF) is a luminaire with
//!   that photometric profile, its nadir the node's -z axis and its C0 the
//!   node's +x axis, times `"ies_multiplier"` (default 1); its glTF
//!   intensity, colour and cone are then not used.
//!
//! glTF stores floats in single precision. Each is widened to the shortest
//! decimal that rounds to it (what the author or exporter most likely
//! wrote), so `0.1f32` reads as `0.1`, and a scene written by
//! `export-scene` from decimal input reads back with the same coordinates.
//! `export-scene` also records exact reflectance and exitance in the
//! material's `extras`, used when they agree with the standard fields.
//!
//! The loader's files follow the specification's ideas: `container` reads
//! the file (GLB chunks, buffers and their URIs, images) and checks its
//! header; `accessor` decodes accessors into numbers; `material` turns
//! materials and textures into reflectance and emission; `nodes` walks the
//! node hierarchy (transforms, instancing, cameras, lights); `primitive`
//! turns a mesh's primitives into surfaces, and `fan` assembles their
//! triangles (lists, strips, fans) and the polygons `FB_ngon_encoding`
//! encodes. This file holds the entry points and what they share: the
//! loading state, labels for messages and the widening of single-precision
//! floats.

mod accessor;
mod container;
mod fan;
mod material;
mod nodes;
mod primitive;

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use glam::DVec3;
use gltf_json as json;

use super::{Camera, Light, LoadOptions, Location, MeshHint, Scene, SceneError, Surface};

pub use accessor::MAX_VIEWLESS_ELEMENTS;
pub use container::ImageData;
pub use fan::{NGON_EXTENSION, interpolate_on_fan};
pub use material::{MAX_TEXTURE_BYTES, MAX_TEXTURE_SIDE, TextureError, mean_linear_colour};

use accessor::Data;
use material::MaterialInfo;

/// Reads an external file named by a URI (already percent-decoded),
/// relative to the glTF file.
pub type Resolver<'a> = dyn FnMut(&str) -> std::io::Result<Vec<u8>> + 'a;

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
    /// The bytes of every buffer, in `json.buffers` order (a lightmap bake
    /// rewrites the input's primitives from them).
    pub buffers: Vec<Vec<u8>>,
    /// Every placed triangle primitive, in loading order.
    pub primitives: Vec<PrimitiveUse>,
}

/// One triangle primitive placed in the scene by one node: what a lightmap
/// bake needs to give it a second UV set and to find its surface points.
#[derive(Clone, Debug)]
pub struct PrimitiveUse {
    /// The node that places it.
    pub node: usize,
    /// Its mesh (`json.meshes`).
    pub mesh: usize,
    /// Its index among the mesh's primitives.
    pub primitive: usize,
    /// The node's world transform.
    pub world: glam::DMat4,
    /// Vertex positions, in the mesh's own frame (widened as the
    /// surfaces' are; shared by the primitives reading one accessor).
    pub positions: std::sync::Arc<Vec<[f64; 3]>>,
    /// Its triangles (lists, strips and fans assembled), vertex indices in
    /// the primitive's winding.
    pub triangles: Vec<[u32; 3]>,
    /// `TEXCOORD_1`, when the primitive has one (shared likewise).
    pub uv1: Option<std::sync::Arc<Vec<[f32; 2]>>>,
    /// Whether the material is double-sided (both faces lit in the solve).
    pub double_sided: bool,
    /// For a primitive carrying `FB_ngon_encoding`, the polygon each
    /// triangle belongs to (a polygon's triangles keep one chart, so the
    /// encoding stays valid).
    pub polygons: Option<Vec<u32>>,
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
    container::check_container(bytes).map_err(invalid)?;
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
        primitives: Vec::new(),
        shared_positions: HashMap::new(),
        shared_uv1: HashMap::new(),
        texcoord_sets: 0,
        faces: 0,
        triangles: 0,
        degenerate: 0,
        camera: None,
        lights: Vec::new(),
        panes: Vec::new(),
        portals: Vec::new(),
        profiles: HashMap::new(),
        capped: Vec::new(),
    };
    loader.check_header()?;
    loader.load_buffers(gltf.blob.as_deref(), resolve)?;
    let images = loader.load_images(resolve)?;
    loader.load_scene(&images, resolve)?;
    let mesh_hint = loader.mesh_hint();
    let scene = loader.finish(name, mesh_hint)?;
    let appearance = Appearance {
        material: std::mem::take(&mut loader.material_of),
        uvs: std::mem::take(&mut loader.uvs),
        texcoord_sets: loader.texcoord_sets,
        json: root.clone(),
        images,
        buffers: std::mem::take(&mut loader.buffers),
        primitives: std::mem::take(&mut loader.primitives),
    };
    Ok((scene, appearance))
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
    primitives: Vec<PrimitiveUse>,
    /// Positions and `TEXCOORD_1` already converted for
    /// [`PrimitiveUse`], by accessor (and vertex count).
    shared_positions: HashMap<usize, std::sync::Arc<Vec<[f64; 3]>>>,
    shared_uv1: HashMap<(usize, usize), std::sync::Arc<Vec<[f32; 2]>>>,
    texcoord_sets: usize,
    faces: u32,
    /// Triangles read so far, over every instance of every mesh: bounded
    /// by `limits.max_faces` (`--max-faces`), since a mesh a few bytes long
    /// may hold millions of triangles and be instanced by many nodes.
    triangles: usize,
    degenerate: usize,
    camera: Option<Camera>,
    lights: Vec<Light>,
    /// Glass ([`crate::scene::glass`]).
    panes: Vec<crate::scene::glass::Pane>,
    portals: Vec<crate::scene::portal::Marked>,
    /// Photometric profiles read so far, by URI.
    profiles: HashMap<String, std::sync::Arc<super::ies::Profile>>,
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

impl Loader<'_> {
    fn error(&self, message: String) -> SceneError {
        SceneError::Invalid {
            location: Location::file(&self.path),
            message,
        }
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
        if self.surfaces.is_empty() && !(self.panes.is_empty() && self.portals.is_empty()) {
            return Err(self.error(format!(
                "all {} triangles are glass or portals: the scene has no surface to light",
                self.faces
            )));
        }
        if self.surfaces.is_empty() {
            return Err(self.error(format!(
                "all {} triangles are degenerate (no area)",
                self.faces
            )));
        }
        let mut warnings = std::mem::take(&mut self.warnings);
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
            lights: std::mem::take(&mut self.lights),
            panes: std::mem::take(&mut self.panes),
            portals: std::mem::take(&mut self.portals),
            camera: self.camera,
            mesh_hint,
            warnings,
        })
    }
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
}
