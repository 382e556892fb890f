//! Lightmap bakes (`--bake-target lightmap`), beyond the paper: light baked
//! the way game engines take it (Unity's and Godot's bakers, Bakery,
//! lightmapper.h; three.js's `lightMap`, Bevy's `Lightmap`): the user's own
//! meshes, nodes and materials kept, a second UV set (`TEXCOORD_1`) and a
//! lightmap texture holding the solved light.
//!
//! The pipeline: [`atlas`] lays out `TEXCOORD_1` (the input's own, or
//! charts generated at `--lightmap-density` texels per metre, capped at
//! `--lightmap-max-size` texels a side); [`texels`] finds each texel's
//! surface point and its value in the solved element mesh, and pads the
//! charts; `document` rewrites the input glTF around them. The values are
//! the vertex bake's ([`crate::app::bake_values`]): lit radiance at the
//! picture's exposure (lit mode, shown by `KHR_materials_unlit`), or
//! irradiance over pi times a recorded scale (irradiance mode, materials
//! kept). The texture is 8-bit sRGB PNG inside the file; an OpenEXR copy of
//! the same values before clamping and 8-bit rounding (half floats) is
//! written beside it (`NAME.lightmap.exr`), for HDR pipelines.
//!
//! A scene read from OBJ or built in has no glTF document: its surfaces are
//! first written as `export-scene` writes them ([`appearance_of_scene`]),
//! and that document is the one lightmapped.
//!
//! The lightmap holds one value per point, but a double-sided material
//! was solved as two surfaces back to back: each such primitive shows the
//! side that receives more light (the inside of a room whose walls face
//! out), chosen over its texels, and says so in its `extras`
//! (`radiosity.lightmap_side: "back"`).

pub mod atlas;
mod document;
pub mod texels;

use std::io;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DVec3, Vec3};
use gltf_json as json;
use rayon::prelude::*;

use crate::export::gltf::{BakeMode, extension_name_list, extras_object, raw_extras};
use crate::mesh::Mesh;
use crate::scene::gltf::Appearance;
use crate::scene::{Camera, LoadOptions, Scene};

pub use atlas::{AtlasSettings, Layout};

/// Default `--lightmap-density`, texels per metre (a texel of 3 cm, about
/// what engines default to for interiors).
pub const DEFAULT_DENSITY: f64 = 32.0;

/// Default `--lightmap-max-size`, texels a side: what nearly every GPU
/// that runs WebGL 2 samples (the standard guarantees 2048).
pub const DEFAULT_MAX_SIZE: u32 = 4096;

/// Largest `--lightmap-density` accepted, texels per metre (a texel of a
/// millimetre).
pub const MAX_DENSITY: f64 = 1000.0;

/// Largest `--lightmap-max-size` accepted.
pub const MAX_MAX_SIZE: u32 = 16384;

/// Empty texels kept around each chart, filled by dilation.
pub const PADDING: u32 = 2;

/// How far a texel's surface point is moved towards its triangle's
/// centroid, as a fraction of the way.
const INSIDE: f64 = 1e-3;

/// A file to write: its path and bytes.
pub type StagedFile = (PathBuf, Vec<u8>);

/// A lightmap bake to write.
pub struct LightmapBake<'a> {
    /// The scene solved.
    pub scene: &'a Scene,
    /// Its element mesh.
    pub mesh: &'a Mesh,
    /// The glTF document to lightmap (the input's, or
    /// [`appearance_of_scene`]).
    pub appearance: &'a Appearance,
    /// The linear value per mesh vertex, before clamping.
    pub values: &'a [DVec3],
    /// What the final pass adds at each texel's surface point, in the
    /// values' units ([`crate::final_gather`]); `None`: the vertices'
    /// values alone.
    pub shade: Option<crate::render::Shade<'a>>,
    /// Lit or irradiance.
    pub mode: BakeMode,
    /// Density and size.
    pub settings: AtlasSettings,
    /// The view written as the file's camera.
    pub camera: Camera,
    /// Width over height of the picture.
    pub aspect_ratio: f64,
    /// Recorded in the scene's `extras.radiosity`.
    pub metadata: serde_json::Value,
}

/// What a lightmap bake made (the `--stats` file's `lightmap`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LightmapReport {
    /// Lightmap width, texels.
    pub width: u32,
    /// Lightmap height, texels.
    pub height: u32,
    /// Texels per metre.
    pub density: f64,
    /// Whether `TEXCOORD_1` was generated.
    pub generated: bool,
    /// Charts packed.
    pub charts: u32,
    /// Texels showing a surface point.
    pub texels: usize,
    /// Of those, how many found no element of their surface (filled from
    /// their neighbours within a few texels, else black).
    pub missing: usize,
    /// What the user should know: the density lowered to fit, texels
    /// without a surface, materials whose `TEXCOORD_1` textures now read
    /// the lightmap's coordinates.
    pub warnings: Vec<String>,
    /// Seconds laying out the charts.
    pub layout_seconds: f64,
    /// Seconds computing the texels and encoding the files.
    pub texel_seconds: f64,
}

/// The glTF document `export-scene` writes for `scene`, read back: the
/// document a lightmap bake of a scene from OBJ (or built in) rewrites.
///
/// # Errors
/// If writing or reading the document fails.
pub fn appearance_of_scene(scene: &Scene) -> io::Result<Appearance> {
    let name = Path::new("scene.glb");
    let files = crate::export::gltf::export_scene(scene, name)?;
    let bytes = &files
        .first()
        .ok_or_else(|| io::Error::other("export-scene wrote nothing"))?
        .1;
    let options = LoadOptions {
        // The scene was within the user's limits when it was read.
        limits: crate::scene::Limits {
            max_file_bytes: u64::MAX,
            max_faces: usize::MAX,
            max_vertices: usize::MAX,
            ..crate::scene::Limits::default()
        },
        ..LoadOptions::default()
    };
    let (_, appearance) = crate::scene::gltf::load_slice(
        &scene.name,
        name,
        bytes,
        &mut |_| Err(io::Error::other("no external files")),
        &options,
    )
    .map_err(|e| io::Error::other(e.to_string()))?;
    Ok(appearance)
}

/// A texel side: the mesh's value there (NaN: none) and its surface point
/// (surface, position), if one was found.
type Side = (Vec3, Option<(u32, DVec3)>);

/// Every texel's front and back (for double-sided materials) values, a
/// batch of texels at a time: what `sides` gives (the mesh's value, NaN
/// for none, and the surface point), plus what the final pass gives at
/// the point when there is one (`shade`). A batch's points are found once
/// and never held for the whole lightmap.
fn side_values(
    texels: usize,
    sides: &(dyn Fn(usize) -> [Side; 2] + Sync),
    shade: Option<crate::render::Shade<'_>>,
) -> Vec<[Vec3; 2]> {
    const BATCH: usize = 1 << 16;
    let mut values = Vec::with_capacity(texels);
    for start in (0..texels).step_by(BATCH) {
        let end = (start + BATCH).min(texels);
        let pairs: Vec<[Side; 2]> = (start..end).into_par_iter().map(sides).collect();
        values.extend(pairs.iter().map(|[front, back]| [front.0, back.0]));
        let Some(shade) = shade else {
            continue;
        };
        let mut batch = Vec::new();
        let mut at = Vec::new();
        for (offset, pair) in pairs.iter().enumerate() {
            for (side, (_, point)) in pair.iter().enumerate() {
                if let Some((surface, position)) = *point {
                    let texel = start + offset;
                    batch.push(crate::final_gather::Point {
                        surface,
                        position,
                        sample: None,
                        seed: (texel * 2 + side) as u64,
                    });
                    at.push((texel, side));
                }
            }
        }
        if batch.is_empty() {
            continue;
        }
        for ((texel, side), added) in at.into_iter().zip(shade(&batch)) {
            values[texel][side] += added.as_vec3();
        }
    }
    values
}

/// The lightmap's linear values, `width x height`, top row first; the
/// counts of texels shown and texels that found no surface; and which
/// placed primitives show their back side.
fn texel_values(bake: &LightmapBake<'_>, layout: &Layout) -> (Vec<Vec3>, usize, usize, Vec<bool>) {
    let (width, height) = (layout.width, layout.height);
    let primitives = &bake.appearance.primitives;
    // World corners and front normal of every output triangle (a negative
    // determinant reverses the winding, as the loader does). Only the
    // corners are transformed: primitives may share one large accessor.
    let world: Vec<Vec<([DVec3; 3], DVec3)>> = primitives
        .iter()
        .zip(&layout.primitives)
        .map(|(use_, plan)| {
            let side = if use_.world.determinant() < 0.0 {
                -1.0
            } else {
                1.0
            };
            plan.triangles
                .iter()
                .map(|t| {
                    let c = t.map(|v| {
                        let p = use_.positions[plan.xref[v as usize] as usize];
                        use_.world.transform_point3(DVec3::from(p))
                    });
                    let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero();
                    (c, side * n)
                })
                .collect()
        })
        .collect();
    let uv: Vec<Vec<[[f32; 2]; 3]>> = layout
        .primitives
        .iter()
        .map(|plan| {
            plan.triangles
                .iter()
                .map(|t| t.map(|v| plan.uv[v as usize]))
                .collect()
        })
        .collect();
    let claims = texels::claims(width, height, &uv);
    let (lo, hi) = bake.scene.bounds();
    let locator = crate::mesh::locator::Locator::new(
        bake.mesh,
        crate::mesh::locator::RELATIVE_TOLERANCE * (hi - lo).length(),
    );
    // The value at a point facing along `n` and the surface it lies on;
    // NaN where no element is found.
    let located = |p: DVec3, n: DVec3| {
        locator
            .locate(p, n)
            .map_or((Vec3::NAN, None), |(corners, bary)| {
                let value = corners
                    .iter()
                    .zip(bary)
                    .map(|(v, w)| bake.values[*v as usize] * w)
                    .sum::<DVec3>()
                    .as_vec3();
                let surface = bake.mesh.vertices[corners[0] as usize].surface;
                (value, Some((surface, p)))
            })
    };
    // Front and (for double-sided materials) back of every texel: the
    // mesh's value (NaN: none) and the surface point.
    let texel_sides = |texel: usize| {
        let none = (Vec3::NAN, None);
        let Some(c) = claims[texel] else {
            return [none; 2];
        };
        let (corners, n) = world[c.primitive as usize][c.triangle as usize];
        // A hair inside the triangle: a texel clamped onto an edge shared
        // with another surface in the same plane (a ceiling around its
        // lamp) takes its own surface's light.
        let w = c.bary.map(|w| f64::from(w) * (1.0 - INSIDE) + INSIDE / 3.0);
        let p = corners[0] + (corners[1] - corners[0]) * w[1] + (corners[2] - corners[0]) * w[2];
        let back = if primitives[c.primitive as usize].double_sided {
            located(p, -n)
        } else {
            none
        };
        [located(p, n), back]
    };
    let both = side_values(claims.len(), &texel_sides, bake.shade);
    // Each double-sided primitive shows its brighter side.
    let mut sums = vec![[0.0f64; 2]; primitives.len()];
    for (claim, pair) in claims.iter().zip(&both) {
        if let Some(c) = claim {
            let s = &mut sums[c.primitive as usize];
            for side in 0..2 {
                if !pair[side].is_nan() {
                    s[side] += f64::from(pair[side].element_sum());
                }
            }
        }
    }
    let back_side: Vec<bool> = sums.iter().map(|s| s[1] > s[0]).collect();
    let shown = claims.iter().filter(|c| c.is_some()).count();
    let mut pixels: Vec<Vec3> = claims
        .iter()
        .zip(&both)
        .map(|(claim, pair)| match claim {
            Some(c) => pair[usize::from(back_side[c.primitive as usize])],
            None => Vec3::NAN,
        })
        .collect();
    drop(both);
    drop(claims);
    let missing = shown - pixels.iter().filter(|v| !v.is_nan()).count();
    texels::dilate(&mut pixels, width, height, PADDING + 2);
    for p in &mut pixels {
        if p.is_nan() {
            *p = Vec3::ZERO;
        }
    }
    (pixels, shown, missing, back_side)
}

/// Writes a lightmap bake; returns the files to stage (`.glb`, or `.gltf`
/// and `.bin`; then the `.lightmap.exr`) and what was made.
///
/// # Errors
/// If the charts cannot be laid out, the input's data is malformed, or
/// encoding fails.
pub fn bake(bake: &LightmapBake<'_>, path: &Path) -> io::Result<(Vec<StagedFile>, LightmapReport)> {
    check_input(bake.appearance).map_err(io::Error::other)?;
    let start = Instant::now();
    let layout = atlas::layout(&bake.appearance.primitives, &bake.settings)
        .map_err(|e| io::Error::other(format!("lightmap layout: {e}")))?;
    let layout_time = start.elapsed();
    let start = Instant::now();
    let (pixels, texels, missing, back_side) = texel_values(bake, &layout);
    let (width, height) = (layout.width, layout.height);
    let srgb: Vec<u8> = pixels
        .iter()
        .flat_map(|p| p.to_array().map(crate::render::srgb8))
        .collect();
    let mut png = Vec::new();
    crate::export::write_png(&mut png, width, height, &srgb)?;
    drop(srgb);
    let mut exr = io::Cursor::new(Vec::new());
    write_exr(&mut exr, width, &pixels)?;
    let (mut b, texture) = document::rewrite(
        bake.appearance,
        &layout,
        &document::LightmapImage {
            png,
            mode: bake.mode,
            back_side,
        },
    )
    .map_err(|e| io::Error::other(format!("lightmap bake: {e}")))?;
    let exr_path = path.with_extension("lightmap.exr");
    let exr_name = exr_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut metadata = bake.metadata.clone();
    if let Some(object) = metadata.as_object_mut() {
        object.insert(
            "lightmap".into(),
            serde_json::json!({
                "texture": texture.value(),
                "texCoord": 1,
                "width": layout.width,
                "height": layout.height,
                "texels_per_metre": layout.density,
                "uv_generated": layout.generated,
                "encoding": "sRGB 8-bit; the values before clamping and rounding, linear, in the EXR",
                "exr": exr_name,
            }),
        );
    }
    let (lo, hi) = bake.scene.bounds();
    let camera = b.camera(&bake.camera, bake.aspect_ratio, 1e-3 * (hi - lo).length());
    add_to_default_scene(&mut b.root, camera, &metadata);
    list_extensions(&mut b.root);
    let mut files = b.finish(path)?;
    files.push((exr_path, exr.into_inner()));
    let mut warnings = Vec::new();
    if layout.density < 0.999 * bake.settings.density {
        warnings.push(format!(
            "lightmap: {:.1} texels per metre, not {}: the lightmap would exceed \
             --lightmap-max-size {} (raise it, or lower --lightmap-density)",
            layout.density, bake.settings.density, bake.settings.max_size
        ));
    }
    if missing > 0 {
        warnings.push(format!(
            "lightmap: {missing} of {texels} texels found no element of their surface (a \
             triangle the solve dropped as degenerate, or off its surface); they took their \
             neighbours' value where one was within {} texels, else black",
            PADDING + 2
        ));
    }
    if layout.generated {
        let json = &bake.appearance.json;
        for m in &json.materials {
            let p = &m.pbr_metallic_roughness;
            let on_uv1 = [
                p.base_color_texture.as_ref().map(|t| t.tex_coord),
                p.metallic_roughness_texture.as_ref().map(|t| t.tex_coord),
                m.normal_texture.as_ref().map(|t| t.tex_coord),
                m.occlusion_texture.as_ref().map(|t| t.tex_coord),
                m.emissive_texture.as_ref().map(|t| t.tex_coord),
            ]
            .contains(&Some(1));
            if on_uv1 && bake.mode == BakeMode::Irradiance {
                warnings.push(format!(
                    "lightmap: material {} samples a texture on TEXCOORD_1, which now holds the \
                     lightmap's coordinates",
                    m.name.as_deref().unwrap_or("(unnamed)")
                ));
            }
        }
    }
    let report = LightmapReport {
        warnings,
        width: layout.width,
        height: layout.height,
        density: layout.density,
        generated: layout.generated,
        charts: layout.charts,
        texels,
        missing,
        layout_seconds: layout_time.as_secs_f64(),
        texel_seconds: start.elapsed().as_secs_f64(),
    };
    Ok((files, report))
}

/// Extensions whose data the rewrite would renumber without knowing it:
/// per-node instance attributes (accessors) and compressed vertex data
/// (buffer views).
const UNREWRITABLE: [&str; 4] = [
    "EXT_mesh_gpu_instancing",
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
];

/// Checks, before a solve, that a lightmap bake can rewrite `appearance`'s
/// document: no extension in `UNREWRITABLE`, float positions
/// (quantised ones would need integer bounds). Returns what stands in the
/// way.
///
/// # Errors
/// The first problem found, naming the extension or the mesh.
pub fn check_input(appearance: &Appearance) -> Result<(), String> {
    let json = &appearance.json;
    if let Some(name) = json
        .extensions_used
        .iter()
        .find(|e| UNREWRITABLE.contains(&e.as_str()))
    {
        return Err(format!(
            "the file uses {name}, whose data the lightmap rewrite cannot carry over; \
             remove it (e.g. re-export without compression or instancing) or bake vertices"
        ));
    }
    for p in &appearance.primitives {
        let position = json
            .meshes
            .get(p.mesh)
            .and_then(|m| m.primitives.get(p.primitive))
            .and_then(|q| {
                q.attributes.get(&json::validation::Checked::Valid(
                    json::mesh::Semantic::Positions,
                ))
            });
        let float = position
            .and_then(|a| json.accessors.get(a.value()))
            .is_some_and(|a| {
                matches!(
                    a.component_type,
                    json::validation::Checked::Valid(json::accessor::GenericComponentType(
                        json::accessor::ComponentType::F32
                    ))
                )
            });
        if !float {
            return Err(format!(
                "mesh {} primitive {}: positions are not floats (KHR_mesh_quantization); \
                 re-export without quantisation or bake vertices",
                p.mesh, p.primitive
            ));
        }
    }
    Ok(())
}

/// `extensionsUsed` from what the document holds, and `extensionsRequired`
/// kept to those still used.
fn list_extensions(root: &mut json::Root) {
    root.extensions_used = extension_name_list(root);
    let used = root.extensions_used.clone();
    root.extensions_required.retain(|e| used.contains(e));
}

/// Writes the lightmap as OpenEXR: RGB half floats (three significant
/// digits, as engines store HDR lightmaps), PIZ-compressed, its tiles in
/// increasing order (compressed in parallel, written in order: the same
/// bytes on every run).
fn write_exr(out: &mut (impl io::Write + io::Seek), width: u32, pixels: &[Vec3]) -> io::Result<()> {
    use exr::prelude::{
        Encoding, Image as ExrImage, LineOrder, SpecificChannels, Vec2, WritableImage, f16,
    };
    let width = width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = pixels[y * width + x];
        (f16::from_f32(p.x), f16::from_f32(p.y), f16::from_f32(p.z))
    });
    ExrImage::from_encoded_channels(
        (width, pixels.len() / width.max(1)),
        Encoding {
            line_order: LineOrder::Increasing,
            ..Encoding::SMALL_FAST_LOSSLESS
        },
        channels,
    )
    .write()
    .to_buffered(out)
    .map_err(io::Error::other)
}

/// Lays out `TEXCOORD_1` for `appearance` and writes the rewritten
/// document as `.glb` bytes with a black lightmap, without a solution: the
/// document a bake writes around its texels, for checking the rewrite on
/// any input (the `lightmap` fuzz target).
///
/// # Errors
/// As [`bake`]: the layout fails or the input's data is malformed.
pub fn rewrite_blank(
    appearance: &Appearance,
    settings: &AtlasSettings,
) -> Result<(Layout, Vec<u8>), String> {
    let layout = atlas::layout(&appearance.primitives, settings)?;
    let pixels = vec![0u8; 3 * layout.width as usize * layout.height as usize];
    let mut png = Vec::new();
    crate::export::write_png(&mut png, layout.width, layout.height, &pixels)
        .map_err(|e| e.to_string())?;
    let image = document::LightmapImage {
        png,
        mode: BakeMode::Lit,
        back_side: vec![false; appearance.primitives.len()],
    };
    let (mut b, _) = document::rewrite(appearance, &layout, &image)?;
    b.root.extensions_used = extension_name_list(&b.root);
    let mut files = b
        .finish(Path::new("blank.glb"))
        .map_err(|e| e.to_string())?;
    Ok((layout, files.swap_remove(0).1))
}

/// Puts the bake's camera node in the default scene (made of the root
/// nodes when the document has none), its camera first of the document's,
/// and the metadata in the scene's extras.
fn add_to_default_scene(
    root: &mut json::Root,
    camera: json::Index<json::Node>,
    metadata: &serde_json::Value,
) {
    let index = match root.scene.map(|s| s.value()) {
        Some(s) if s < root.scenes.len() => s,
        _ if !root.scenes.is_empty() => 0,
        _ => {
            let mut is_child = vec![false; root.nodes.len()];
            for node in &root.nodes {
                for c in node.children.iter().flatten() {
                    if let Some(flag) = is_child.get_mut(c.value()) {
                        *flag = true;
                    }
                }
            }
            let nodes = (0..root.nodes.len())
                .filter(|&i| !is_child[i] && i != camera.value())
                .map(|i| json::Index::new(i as u32))
                .collect();
            root.push(json::Scene {
                extensions: None,
                extras: Default::default(),
                name: None,
                nodes,
            })
            .value()
        }
    };
    // The bake's camera first, where viewers look for the default view.
    if let Some(ours) = root.cameras.pop() {
        root.cameras.insert(0, ours);
        for (n, node) in root.nodes.iter_mut().enumerate() {
            if let Some(c) = &mut node.camera {
                *c = json::Index::new(if n == camera.value() {
                    0
                } else {
                    c.value() as u32 + 1
                });
            }
        }
    }
    root.scene = Some(json::Index::new(index as u32));
    let scene = &mut root.scenes[index];
    scene.nodes.push(camera);
    let mut extras = extras_object(&scene.extras);
    extras["radiosity"] = metadata.clone();
    scene.extras = raw_extras(&extras);
}
