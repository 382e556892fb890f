//! The lightmap bake's glTF document: the input's own document (nodes,
//! meshes, primitives, materials, animations) with every placed triangle
//! primitive given `TEXCOORD_1` and the lightmap texture (Khronos glTF 2.0
//! specification, *Meshes*, *Accessors*, *Textures*).
//!
//! A primitive whose lightmap coordinates were generated is rewritten: each
//! attribute (and morph target) gathered through the layout's vertex map,
//! so vertices split at chart seams copy every value of the vertex they
//! come from, and its triangles written as a list. A mesh drawn by several
//! nodes gets one copy per further node, since each draw covers its own
//! texels. The binary data is written afresh: the accessors and buffer
//! views still used (data the rewritten primitives no longer need is
//! dropped), external images embedded, one buffer in all.

use std::collections::HashMap;

use gltf_json as json;
use json::validation::{Checked, USize64};

use super::atlas::Layout;
use crate::export::gltf::{BakeMode, Builder, extras_object, unlit_material};
use crate::scene::gltf::Appearance;

/// The first `needed` elements of an accessor, one after another (strides
/// removed, sparse substitutions applied, no buffer view: zeros), and the
/// size of one element. Only those elements are read or allocated, and
/// every offset is checked, so a hostile count or offset is an error.
fn dense(
    root: &json::Root,
    buffers: &[Vec<u8>],
    index: usize,
    needed: usize,
) -> Result<(Vec<u8>, usize), String> {
    use json::accessor::Type;
    let what = format!("accessor {index}");
    let accessor = root
        .accessors
        .get(index)
        .ok_or_else(|| format!("{what} does not exist"))?;
    let (Checked::Valid(kind), Checked::Valid(component)) =
        (accessor.type_, accessor.component_type)
    else {
        return Err(format!("{what} has an unknown type"));
    };
    let components = match kind {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 => 4,
        _ => {
            return Err(format!(
                "{what}: a matrix vertex attribute is not supported"
            ));
        }
    };
    let size = component.0.size() * components;
    let count = usize::try_from(accessor.count.0).unwrap_or(usize::MAX);
    if count < needed {
        return Err(format!(
            "{what} has {count} elements, but its primitive uses {needed} vertices"
        ));
    }
    let overflow = || format!("{what}: its offsets overflow");
    // `n` elements of `size` bytes, `stride` apart, from `offset` into
    // buffer view `view`.
    let read = |view: usize, offset: u64, stride: usize, n: usize, size: usize| {
        let v = root
            .buffer_views
            .get(view)
            .ok_or_else(|| format!("{what} refers to buffer view {view}, which does not exist"))?;
        let buffer = buffers
            .get(v.buffer.value())
            .ok_or_else(|| format!("buffer view {view} refers to a missing buffer"))?;
        let base = v.byte_offset.map_or(0, |o| o.0);
        let start = base.checked_add(offset).ok_or_else(overflow)?;
        let end = base.checked_add(v.byte_length.0).ok_or_else(overflow)?;
        let need = if n == 0 {
            0
        } else {
            (n as u64 - 1)
                .checked_mul(stride as u64)
                .and_then(|x| x.checked_add(size as u64))
                .ok_or_else(overflow)?
        };
        if start.checked_add(need).is_none_or(|e| e > end) || end > buffer.len() as u64 {
            return Err(format!("{what} reads past the end of buffer view {view}"));
        }
        let mut out = Vec::with_capacity(n * size);
        for i in 0..n {
            let at = (start + (i * stride) as u64) as usize;
            out.extend_from_slice(&buffer[at..at + size]);
        }
        Ok(out)
    };
    let mut out = match accessor.buffer_view {
        Some(view) => {
            let stride = root
                .buffer_views
                .get(view.value())
                .and_then(|v| v.byte_stride)
                .map_or(size, |s| s.0);
            read(
                view.value(),
                accessor.byte_offset.map_or(0, |o| o.0),
                stride,
                needed,
                size,
            )?
        }
        None => vec![0; needed * size],
    };
    if let Some(sparse) = &accessor.sparse {
        let n = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
        if n > count {
            return Err(format!(
                "{what}: more sparse values ({n}) than elements ({count})"
            ));
        }
        let Checked::Valid(index_type) = sparse.indices.component_type else {
            return Err(format!("{what}: sparse indices of an unknown type"));
        };
        let index_size = index_type.0.size();
        // Indices and values are tightly packed.
        let indices = read(
            sparse.indices.buffer_view.value(),
            sparse.indices.byte_offset.0,
            index_size,
            n,
            index_size,
        )?;
        let values = read(
            sparse.values.buffer_view.value(),
            sparse.values.byte_offset.0,
            size,
            n,
            size,
        )?;
        for (k, b) in indices.chunks_exact(index_size).enumerate() {
            let i = match index_size {
                1 => usize::from(b[0]),
                2 => usize::from(u16::from_le_bytes([b[0], b[1]])),
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize,
            };
            if i >= count {
                return Err(format!(
                    "{what}: sparse index {i} is past its count {count}"
                ));
            }
            if i < needed {
                out[i * size..(i + 1) * size].copy_from_slice(&values[k * size..(k + 1) * size]);
            }
        }
    }
    Ok((out, size))
}

/// An accessor to add once the binary data is laid out: its JSON (buffer
/// view still unset) and bytes.
struct Pending {
    accessor: usize,
    bytes: Vec<u8>,
    target: json::buffer::Target,
}

/// Adds an accessor of `count` elements of `kind` (component, type,
/// normalized) to `root`, its bytes kept in `pending`.
fn push_accessor(
    root: &mut json::Root,
    pending: &mut Vec<Pending>,
    bytes: Vec<u8>,
    count: usize,
    kind: (json::accessor::ComponentType, json::accessor::Type, bool),
    bounds: Option<(Vec<f32>, Vec<f32>)>,
    target: json::buffer::Target,
) -> json::Index<json::Accessor> {
    let index = root.push(json::Accessor {
        buffer_view: None,
        byte_offset: None,
        count: USize64::from(count),
        component_type: Checked::Valid(json::accessor::GenericComponentType(kind.0)),
        extensions: None,
        extras: Default::default(),
        type_: Checked::Valid(kind.1),
        min: bounds.as_ref().map(|(lo, _)| serde_json::json!(lo)),
        max: bounds.as_ref().map(|(_, hi)| serde_json::json!(hi)),
        name: None,
        normalized: kind.2,
        sparse: None,
    });
    pending.push(Pending {
        accessor: index.value(),
        bytes,
        target,
    });
    index
}

/// Bounds of float VEC3 positions (required on `POSITION`).
fn float_bounds(bytes: &[u8], components: usize) -> (Vec<f32>, Vec<f32>) {
    let mut lo = vec![f32::INFINITY; components];
    let mut hi = vec![f32::NEG_INFINITY; components];
    for element in bytes.chunks_exact(4 * components) {
        for (k, c) in element.chunks_exact(4).enumerate() {
            let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            lo[k] = lo[k].min(v);
            hi[k] = hi[k].max(v);
        }
    }
    (lo, hi)
}

/// Gathers accessor `index` through `xref` into a new accessor.
fn gather(
    root: &mut json::Root,
    appearance: &Appearance,
    pending: &mut Vec<Pending>,
    index: usize,
    xref: &[u32],
    is_position: bool,
) -> Result<json::Index<json::Accessor>, String> {
    // `dense` reads (and checks) every element up to the largest asked.
    let needed = xref.iter().max().map_or(0, |&v| v as usize + 1);
    let (bytes, size) = dense(root, &appearance.buffers, index, needed)?;
    let mut out = Vec::with_capacity(xref.len() * size);
    for &v in xref {
        let v = v as usize;
        out.extend_from_slice(&bytes[v * size..(v + 1) * size]);
    }
    let source = &root.accessors[index];
    let (Checked::Valid(component), Checked::Valid(kind)) = (source.component_type, source.type_)
    else {
        return Err(format!("accessor {index} has an unknown type"));
    };
    let normalized = source.normalized;
    let components = size / component.0.size();
    // Bounds are required on POSITION and must match the data exactly;
    // they are recomputed for float data (positions are floats:
    // `check_input`) and left out otherwise.
    let float = component.0 == json::accessor::ComponentType::F32;
    let bounds =
        (float && (is_position || source.min.is_some())).then(|| float_bounds(&out, components));
    Ok(push_accessor(
        root,
        pending,
        out,
        xref.len(),
        (component.0, kind, normalized),
        bounds,
        json::buffer::Target::ArrayBuffer,
    ))
}

/// What the lightmap texture is and how the document uses it.
pub struct LightmapImage {
    /// PNG bytes of the 8-bit sRGB lightmap.
    pub png: Vec<u8>,
    /// Lit (materials become unlit, showing the lightmap) or irradiance
    /// (materials kept, the lightmap referenced from the scene's extras).
    pub mode: BakeMode,
    /// Per placed primitive: whether the lightmap shows its back side (a
    /// double-sided material lit from behind).
    pub back_side: Vec<bool>,
}

/// Builds the document: the input's, rewritten (see the module
/// documentation). Returns the builder, to which the caller adds the
/// camera and metadata, and the lightmap's texture index.
///
/// # Errors
/// When an accessor the rewrite reads is malformed (the message names it).
pub fn rewrite(
    appearance: &Appearance,
    layout: &Layout,
    image: &LightmapImage,
) -> Result<(Builder, json::Index<json::Texture>), String> {
    use json::mesh::Semantic;
    let mut root = appearance.json.clone();
    let mut pending: Vec<Pending> = Vec::new();
    // Which output mesh and primitive each placed primitive is.
    let mut drawn: HashMap<usize, usize> = HashMap::new();
    let mut copies: HashMap<(usize, usize), usize> = HashMap::new();
    let mut lightmapped: Vec<(usize, usize)> = Vec::new();
    for (use_, plan) in appearance.primitives.iter().zip(&layout.primitives) {
        // Primitives with no triangle (fewer than three indices) draw
        // nothing and are left as they are.
        if plan.triangles.is_empty() {
            continue;
        }
        let first = *drawn.entry(use_.mesh).or_insert(use_.node);
        let mesh = if first == use_.node {
            use_.mesh
        } else {
            *copies.entry((use_.node, use_.mesh)).or_insert_with(|| {
                let copy = root.meshes[use_.mesh].clone();
                let index = root.push(copy).value();
                root.nodes[use_.node].mesh = Some(json::Index::new(index as u32));
                index
            })
        };
        lightmapped.push((mesh, use_.primitive));
    }
    let placed = appearance.primitives.iter().zip(&layout.primitives);
    let drawn = placed
        .enumerate()
        .filter(|(_, (_, plan))| !plan.triangles.is_empty());
    for ((k, (_, plan)), &(mesh, p)) in drawn.zip(&lightmapped) {
        let source = root.meshes[mesh].primitives[p].clone();
        let mut primitive = source.clone();
        if image.mode == BakeMode::Lit {
            // The solve already took the vertex colours into the
            // reflectance: an unlit material would multiply by them again.
            primitive
                .attributes
                .retain(|semantic, _| !matches!(semantic, Checked::Valid(Semantic::Colors(_))));
        }
        if image.back_side.get(k).copied().unwrap_or(false) {
            let mut extras = extras_object(&source.extras);
            extras["radiosity"] = serde_json::json!({ "lightmap_side": "back" });
            primitive.extras = crate::export::gltf::raw_extras(&extras);
        }
        if layout.generated {
            for (semantic, accessor) in &source.attributes {
                if *semantic == Checked::Valid(Semantic::TexCoords(1)) {
                    continue;
                }
                let position = *semantic == Checked::Valid(Semantic::Positions);
                let new = gather(
                    &mut root,
                    appearance,
                    &mut pending,
                    accessor.value(),
                    &plan.xref,
                    position,
                )?;
                primitive.attributes.insert(semantic.clone(), new);
            }
            if let Some(targets) = &mut primitive.targets {
                for target in targets {
                    for slot in [
                        &mut target.positions,
                        &mut target.normals,
                        &mut target.tangents,
                    ] {
                        if let Some(a) = *slot {
                            let gathered = gather(
                                &mut root,
                                appearance,
                                &mut pending,
                                a.value(),
                                &plan.xref,
                                false,
                            )?;
                            *slot = Some(gathered);
                        }
                    }
                }
            }
            let uv: Vec<u8> = plan
                .uv
                .iter()
                .flat_map(|c| c.iter().flat_map(|x| x.to_le_bytes()))
                .collect();
            let uv_accessor = push_accessor(
                &mut root,
                &mut pending,
                uv,
                plan.uv.len(),
                (
                    json::accessor::ComponentType::F32,
                    json::accessor::Type::Vec2,
                    false,
                ),
                None,
                json::buffer::Target::ArrayBuffer,
            );
            primitive
                .attributes
                .insert(Checked::Valid(Semantic::TexCoords(1)), uv_accessor);
            // Texture coordinate sets are numbered from 0 without gaps: a
            // primitive with none gets the lightmap's as TEXCOORD_0 too.
            primitive
                .attributes
                .entry(Checked::Valid(Semantic::TexCoords(0)))
                .or_insert(uv_accessor);
            let (bytes, component) = if plan.xref.len() <= usize::from(u16::MAX) {
                (
                    plan.triangles
                        .iter()
                        .flatten()
                        .flat_map(|i| (*i as u16).to_le_bytes())
                        .collect::<Vec<u8>>(),
                    json::accessor::ComponentType::U16,
                )
            } else {
                (
                    plan.triangles
                        .iter()
                        .flatten()
                        .flat_map(|i| i.to_le_bytes())
                        .collect(),
                    json::accessor::ComponentType::U32,
                )
            };
            primitive.indices = Some(push_accessor(
                &mut root,
                &mut pending,
                bytes,
                plan.triangles.len() * 3,
                (component, json::accessor::Type::Scalar, false),
                None,
                json::buffer::Target::ElementArrayBuffer,
            ));
            primitive.mode = Checked::Valid(json::mesh::Mode::Triangles);
        }
        root.meshes[mesh].primitives[p] = primitive;
    }
    let mut b = compact(root, appearance, pending)?;
    // The lightmap: one image, sampled linearly, clamped at the edges.
    let view = b.view(&image.png, None);
    let image_index = b.root.push(json::Image {
        buffer_view: Some(view),
        mime_type: Some(json::image::MimeType("image/png".into())),
        name: Some("lightmap".into()),
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let sampler = b.root.push(json::texture::Sampler {
        mag_filter: Some(Checked::Valid(json::texture::MagFilter::Linear)),
        min_filter: Some(Checked::Valid(json::texture::MinFilter::Linear)),
        name: Some("lightmap".into()),
        wrap_s: Checked::Valid(json::texture::WrappingMode::ClampToEdge),
        wrap_t: Checked::Valid(json::texture::WrappingMode::ClampToEdge),
        extensions: None,
        extras: Default::default(),
    });
    let texture = b.root.push(json::Texture {
        name: Some("lightmap".into()),
        sampler: Some(sampler),
        source: image_index,
        extensions: None,
        extras: Default::default(),
    });
    if image.mode == BakeMode::Lit {
        unlit_materials(&mut b.root, &lightmapped, texture);
    }
    Ok((b, texture))
}

/// Lit mode: every material of a lightmapped primitive shows the lightmap
/// unlit. A material that other primitives (points, lines, meshes not in
/// the scene) also use is copied instead of changed.
fn unlit_materials(
    root: &mut json::Root,
    lightmapped: &[(usize, usize)],
    texture: json::Index<json::Texture>,
) {
    let marked: std::collections::HashSet<(usize, usize)> = lightmapped.iter().copied().collect();
    let mut shared = std::collections::HashSet::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if !marked.contains(&(m, p))
                && let Some(material) = primitive.material
            {
                shared.insert(material.value());
            }
        }
    }
    let unlit = |name: Option<String>, double_sided: bool| {
        let lightmap = json::texture::Info {
            index: texture,
            tex_coord: 1,
            extensions: None,
            extras: Default::default(),
        };
        unlit_material(name, Some(lightmap), double_sided)
    };
    let mut replaced: HashMap<Option<usize>, usize> = HashMap::new();
    for &(m, p) in lightmapped {
        let old = root.meshes[m].primitives[p].material.map(|i| i.value());
        let new = *replaced.entry(old).or_insert_with(|| match old {
            Some(i) if !shared.contains(&i) => {
                let source = &root.materials[i];
                root.materials[i] = unlit(source.name.clone(), source.double_sided);
                i
            }
            Some(i) => {
                let source = &root.materials[i];
                let material = unlit(
                    Some(format!(
                        "{} (lightmap)",
                        source.name.clone().unwrap_or_default()
                    )),
                    source.double_sided,
                );
                root.push(material).value()
            }
            None => root.push(unlit(Some("lightmap".into()), false)).value(),
        });
        root.meshes[m].primitives[p].material = Some(json::Index::new(new as u32));
    }
}

/// Extensions known to hold no accessor, buffer view or buffer index
/// (besides every `KHR_materials_*`): with only these, data nobody uses
/// any more can be dropped and the rest renumbered.
const NO_DATA_REFERENCES: [&str; 9] = [
    "KHR_lights_punctual",
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "KHR_xmp_json_ld",
    "KHR_animation_pointer",
    "KHR_mesh_quantization",
    crate::scene::gltf::NGON_EXTENSION,
];

/// Whether every extension the document holds is known to reference no
/// vertex data (see [`NO_DATA_REFERENCES`]).
fn only_known_extensions(root: &json::Root) -> bool {
    crate::export::gltf::extension_name_list(root)
        .iter()
        .all(|e| e.starts_with("KHR_materials_") || NO_DATA_REFERENCES.contains(&e.as_str()))
}

/// Writes the binary data afresh (see the module documentation): the
/// accessors still referenced, their buffer views' bytes, the images, and
/// the pending accessors' bytes. A document holding an extension not
/// known to reference no data keeps every accessor and buffer view at its
/// index, so what the extension points at stays valid.
fn compact(
    mut root: json::Root,
    appearance: &Appearance,
    pending: Vec<Pending>,
) -> Result<Builder, String> {
    let keep_all = !only_known_extensions(&root);
    // Accessors referenced anywhere.
    let mut used = vec![keep_all; root.accessors.len()];
    let mut mark = |a: &json::Index<json::Accessor>| {
        if let Some(u) = used.get_mut(a.value()) {
            *u = true;
        }
    };
    for mesh in &root.meshes {
        for p in &mesh.primitives {
            p.attributes.values().for_each(&mut mark);
            p.indices.iter().for_each(&mut mark);
            for t in p.targets.iter().flatten() {
                t.positions
                    .iter()
                    .chain(&t.normals)
                    .chain(&t.tangents)
                    .for_each(&mut mark);
            }
        }
    }
    for skin in &root.skins {
        skin.inverse_bind_matrices.iter().for_each(&mut mark);
    }
    for animation in &root.animations {
        for s in &animation.samplers {
            mark(&s.input);
            mark(&s.output);
        }
    }
    let mut accessor_map = vec![None; root.accessors.len()];
    let mut accessors = Vec::new();
    for (i, a) in root.accessors.iter().enumerate() {
        if used[i] {
            accessor_map[i] = Some(accessors.len() as u32);
            accessors.push(a.clone());
        }
    }
    let remap = |a: &mut json::Index<json::Accessor>| {
        if let Some(Some(n)) = accessor_map.get(a.value()) {
            *a = json::Index::new(*n);
        }
    };
    for mesh in &mut root.meshes {
        for p in &mut mesh.primitives {
            p.attributes.values_mut().for_each(remap);
            p.indices.iter_mut().for_each(remap);
            for t in p.targets.iter_mut().flatten() {
                t.positions
                    .iter_mut()
                    .chain(&mut t.normals)
                    .chain(&mut t.tangents)
                    .for_each(remap);
            }
        }
    }
    for skin in &mut root.skins {
        skin.inverse_bind_matrices.iter_mut().for_each(remap);
    }
    for animation in &mut root.animations {
        for s in &mut animation.samplers {
            remap(&mut s.input);
            remap(&mut s.output);
        }
    }
    // Buffer views still referenced, copied keeping their alignment.
    let old_views = std::mem::take(&mut root.buffer_views);
    let mut b = Builder::new();
    b.root = root;
    b.root.buffers.clear();
    let mut view_map: HashMap<usize, json::Index<json::buffer::View>> = HashMap::new();
    let mut copy_view =
        |b: &mut Builder, v: usize| -> Result<json::Index<json::buffer::View>, String> {
            if let Some(&n) = view_map.get(&v) {
                return Ok(n);
            }
            let view = old_views
                .get(v)
                .ok_or_else(|| format!("buffer view {v} does not exist"))?;
            let offset = view.byte_offset.map_or(0, |o| o.0);
            let bytes = appearance
                .buffers
                .get(view.buffer.value())
                .and_then(|buffer| {
                    let end = offset.checked_add(view.byte_length.0)?;
                    buffer.get(usize::try_from(offset).ok()?..usize::try_from(end).ok()?)
                })
                .ok_or_else(|| format!("buffer view {v} lies outside its buffer"))?;
            while b.bin.len() % 8 != (offset % 8) as usize {
                b.bin.push(0);
            }
            let start = b.bin.len();
            b.bin.extend_from_slice(bytes);
            let mut copy = view.clone();
            copy.buffer = json::Index::new(0);
            copy.byte_offset = Some(USize64::from(start));
            let n = b.root.push(copy);
            view_map.insert(v, n);
            Ok(n)
        };
    if keep_all {
        for v in 0..old_views.len() {
            copy_view(&mut b, v)?;
        }
    }
    for a in &mut accessors {
        if let Some(v) = a.buffer_view {
            a.buffer_view = Some(copy_view(&mut b, v.value())?);
        }
        if let Some(sparse) = &mut a.sparse {
            sparse.indices.buffer_view = copy_view(&mut b, sparse.indices.buffer_view.value())?;
            sparse.values.buffer_view = copy_view(&mut b, sparse.values.buffer_view.value())?;
        }
    }
    for (i, image) in b.root.images.clone().iter().enumerate() {
        let data = appearance.images.get(i);
        let mut out = image.clone();
        match (image.buffer_view, data) {
            (Some(v), _) => out.buffer_view = Some(copy_view(&mut b, v.value())?),
            (None, Some(data)) => {
                out.buffer_view = Some(b.view(&data.bytes, None));
                out.mime_type = Some(json::image::MimeType(data.mime_type.clone()));
            }
            (None, None) => {}
        }
        out.uri = None;
        b.root.images[i] = out;
    }
    for p in pending {
        let n = accessor_map[p.accessor].ok_or("a new accessor went unused")? as usize;
        let view = b.view(&p.bytes, Some(p.target));
        accessors[n].buffer_view = Some(view);
        accessors[n].byte_offset = Some(USize64(0));
    }
    b.root.accessors = accessors;
    Ok(b)
}
