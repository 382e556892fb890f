//! Lightmap texture coordinates (`TEXCOORD_1`): the input's own second UV
//! set when every primitive has one that a single lightmap can hold, else
//! charts cut, flattened and packed at a texel density in world metres by
//! the `uvunwrap` crate (xatlas's method: charts grown from planar regions,
//! least-squares conformal maps, shape packing with padding).
//!
//! Each placed primitive (a mesh drawn by several nodes counts once per
//! node) is unwrapped in world coordinates, so one texel covers the same
//! area everywhere; vertices are split only at chart seams.

use glam::DVec3;

use crate::scene::gltf::PrimitiveUse;

/// How the lightmap is laid out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasSettings {
    /// Texels per metre asked for.
    pub density: f64,
    /// Largest width or height of the lightmap, texels.
    pub max_size: u32,
    /// Empty texels around each chart.
    pub padding: u32,
}

impl Default for AtlasSettings {
    /// [`super::DEFAULT_DENSITY`], [`super::DEFAULT_MAX_SIZE`],
    /// [`super::PADDING`].
    fn default() -> AtlasSettings {
        AtlasSettings {
            density: super::DEFAULT_DENSITY,
            max_size: super::DEFAULT_MAX_SIZE,
            padding: super::PADDING,
        }
    }
}

/// The lightmap coordinates of every placed primitive.
#[derive(Clone, Debug)]
pub struct Layout {
    /// Lightmap width, texels.
    pub width: u32,
    /// Lightmap height, texels.
    pub height: u32,
    /// Texels per metre (lower than asked when the lightmap would not fit
    /// [`AtlasSettings::max_size`]).
    pub density: f64,
    /// Whether the coordinates were generated (`false`: the input's own
    /// `TEXCOORD_1`).
    pub generated: bool,
    /// Charts packed (0 when the input's coordinates are used).
    pub charts: u32,
    /// One per placed primitive, in [`crate::scene::gltf::Appearance::primitives`]
    /// order.
    pub primitives: Vec<PrimitiveLayout>,
}

/// One placed primitive's lightmap vertices and triangles.
#[derive(Clone, Debug, Default)]
pub struct PrimitiveLayout {
    /// For each output vertex, the input vertex it copies.
    pub xref: Vec<u32>,
    /// For each output vertex, its lightmap coordinate (glTF's convention:
    /// `(0, 0)` is the top-left corner of the image).
    pub uv: Vec<[f32; 2]>,
    /// The input's triangles, in order, over the output vertices.
    pub triangles: Vec<[u32; 3]>,
}

/// World positions of a placed primitive's vertices.
#[must_use]
pub fn world_points(primitive: &PrimitiveUse) -> Vec<DVec3> {
    primitive
        .positions
        .iter()
        .map(|p| primitive.world.transform_point3(DVec3::from(*p)))
        .collect()
}

/// World area of a placed primitive's triangles, square metres.
fn world_area(positions: &[DVec3], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            0.5 * (b - a).cross(c - a).length()
        })
        .sum()
}

/// Whether the input's own `TEXCOORD_1` can be the lightmap's coordinates:
/// every primitive has one, every coordinate lies in [0, 1], no mesh is
/// drawn twice (its instances would share texels) and no two primitives'
/// triangles cover the same texel centre at `size` texels.
fn input_uvs_usable(primitives: &[PrimitiveUse], size: u32) -> bool {
    let mut drawn_by = std::collections::HashMap::new();
    for p in primitives {
        let Some(uv) = &p.uv1 else { return false };
        if *drawn_by.entry(p.mesh).or_insert(p.node) != p.node {
            return false;
        }
        if uv
            .iter()
            .any(|c| !(0.0..=1.0).contains(&c[0]) || !(0.0..=1.0).contains(&c[1]))
        {
            return false;
        }
    }
    // Texel centres strictly inside two triangles: charts overlapping,
    // within a primitive or between two.
    let mut owner = vec![u32::MAX; size as usize * size as usize];
    let mut triangle = 0u32;
    for p in primitives {
        let uv = p.uv1.as_deref().map_or(&[][..], Vec::as_slice);
        for t in &p.triangles {
            let corners = t.map(|i| {
                let c = uv[i as usize];
                [
                    f64::from(c[0]) * f64::from(size),
                    f64::from(c[1]) * f64::from(size),
                ]
            });
            let mut clash = false;
            super::texels::for_texels_strictly_inside(&corners, size, size, |texel| {
                clash |= owner[texel] != u32::MAX;
                owner[texel] = triangle;
            });
            if clash {
                return false;
            }
            triangle += 1;
        }
    }
    true
}

/// Lays out the lightmap of `primitives` (see the module documentation).
///
/// # Errors
/// When the unwrapper fails (a message naming the problem).
pub fn layout(primitives: &[PrimitiveUse], settings: &AtlasSettings) -> Result<Layout, String> {
    let world: Vec<Vec<DVec3>> = primitives.iter().map(world_points).collect();
    // The unwrapper works in single precision: positions relative to the
    // scene's lowest corner, so a scene far from the origin keeps its
    // detail.
    let origin = world
        .iter()
        .flatten()
        .fold(DVec3::INFINITY, |a, p| a.min(*p));
    let relative: Vec<Vec<[f32; 3]>> = world
        .iter()
        .map(|w| {
            w.iter()
                .map(|p| (*p - origin).as_vec3().to_array())
                .collect()
        })
        .collect();
    let area: f64 = world
        .iter()
        .zip(primitives)
        .map(|(w, p)| world_area(w, &p.triangles))
        .sum();
    let max = f64::from(settings.max_size);
    if primitives.iter().all(|p| p.uv1.is_some()) {
        // The input's coordinates: a square lightmap giving about the asked
        // density over the UV area they use.
        let uv_area: f64 = primitives
            .iter()
            .map(|p| {
                let uv = p.uv1.as_deref().map_or(&[][..], Vec::as_slice);
                p.triangles
                    .iter()
                    .map(|t| {
                        let [a, b, c] = t.map(|i| glam::Vec2::from(uv[i as usize]).as_dvec2());
                        0.5 * (b - a).perp_dot(c - a).abs()
                    })
                    .sum::<f64>()
            })
            .sum();
        if uv_area > 0.0 {
            let side = (settings.density * (area / uv_area).sqrt())
                .ceil()
                .min(max)
                .max(1.0) as u32;
            if input_uvs_usable(primitives, side) {
                return Ok(Layout {
                    width: side,
                    height: side,
                    density: f64::from(side) * (uv_area / area.max(f64::MIN_POSITIVE)).sqrt(),
                    generated: false,
                    charts: 0,
                    primitives: primitives
                        .iter()
                        .map(|p| PrimitiveLayout {
                            xref: (0..p.positions.len() as u32).collect(),
                            uv: p.uv1.as_deref().cloned().unwrap_or_default(),
                            triangles: p.triangles.clone(),
                        })
                        .collect(),
                });
            }
        }
    }
    let flat: Vec<Vec<u32>> = primitives
        .iter()
        .map(|p| p.triangles.iter().flatten().copied().collect())
        .collect();
    let inputs: Vec<uvunwrap::MeshInput<'_>> = primitives
        .iter()
        .zip(&relative)
        .zip(&flat)
        .map(|((p, w), indices)| uvunwrap::MeshInput {
            existing_uvs: p.uv1.as_deref().map(Vec::as_slice),
            polygons: p.polygons.as_deref(),
            ..uvunwrap::MeshInput::new(w, indices)
        })
        .collect();
    // Packing leaves some space unused: start from a density whose charts
    // would fill at most half the largest lightmap, then lower it by the
    // overshoot until the lightmap fits.
    let mut density = settings
        .density
        .min((0.5 * max * max / area.max(f64::MIN_POSITIVE)).sqrt());
    for _ in 0..4 {
        let options = uvunwrap::Options {
            density: uvunwrap::Density::Fixed {
                texels_per_unit: density as f32,
                page_size: None,
            },
            padding: settings.padding,
            max_chart_size: settings.max_size.saturating_sub(2 * settings.padding + 2),
            ..uvunwrap::Options::default()
        };
        let atlas = uvunwrap::generate(&inputs, &options).map_err(|e| e.to_string())?;
        let side = atlas.width.max(atlas.height);
        if side > settings.max_size {
            density *= 0.97 * max / f64::from(side);
            continue;
        }
        return Ok(Layout {
            width: atlas.width,
            height: atlas.height,
            density: f64::from(atlas.texels_per_unit),
            generated: true,
            charts: atlas.chart_count,
            primitives: atlas
                .meshes
                .into_iter()
                .map(|m| PrimitiveLayout {
                    xref: m.vertices.iter().map(|v| v.xref).collect(),
                    uv: m.vertices.iter().map(|v| v.uv).collect(),
                    triangles: m
                        .indices
                        .chunks_exact(3)
                        .map(|t| [t[0], t[1], t[2]])
                        .collect(),
                })
                .collect(),
        });
    }
    Err(format!(
        "the charts do not fit a {max}-texel lightmap even at {density:.2} texels per metre"
    ))
}
