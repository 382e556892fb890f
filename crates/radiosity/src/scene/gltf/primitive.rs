//! Primitives to surfaces (the glTF 2.0 specification's *Meshes*): each
//! triangle primitive's positions, indices, texture coordinates and
//! `COLOR_0` are read through their accessors and checked against the
//! vertex count; its triangles, or the polygons `FB_ngon_encoding` encodes,
//! are transformed to world space (a negative determinant reverses the
//! winding) and turned into planar convex surfaces
//! ([`crate::scene::polygon`]), two back to back for a double-sided
//! material, with the reflectance times the polygon's mean `COLOR_0`.
//! Points and lines are skipped with a warning, and the triangles of the
//! whole scene, instances included, are bounded by `--max-faces`.

use glam::{DMat4, DVec3};
use gltf_json as json;
use json::validation::Checked;

use super::super::polygon::{FaceProblem, convex_pieces};
use super::fan::{NGON_EXTENSION, assemble, fans, interpolate_on_fan};
use super::{ImageData, Loader, MaterialInfo, SceneError, Surface, label};

/// One polygon of the input (a triangle, or an n-gon from a fan) with its
/// per-corner data.
struct SourcePolygon {
    corners: Vec<DVec3>,
    uvs: Vec<Vec<[f64; 2]>>,
    colour: DVec3,
}

impl Loader<'_> {
    /// Loads every primitive of mesh `index` under `world`. Returns whether
    /// the mesh has morph targets.
    pub(super) fn load_mesh(
        &mut self,
        node: usize,
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
            let shared_positions = std::sync::Arc::clone(
                self.shared_positions
                    .entry(position_accessor.value())
                    .or_insert_with(|| {
                        std::sync::Arc::new(
                            (0..vertex_count)
                                .map(|v| {
                                    let x = positions.get(v);
                                    [x[0], x[1], x[2]]
                                })
                                .collect(),
                        )
                    }),
            );
            let uv1_accessor = attribute(Semantic::TexCoords(1)).map(|a| a.value());
            let shared_uv1 = match (uv1_accessor, uv_sets.get(1)) {
                (Some(a), Some(d)) => Some(std::sync::Arc::clone(
                    self.shared_uv1.entry((a, vertex_count)).or_insert_with(|| {
                        std::sync::Arc::new(
                            (0..vertex_count)
                                .map(|v| {
                                    let uv = d.get(v);
                                    [uv[0] as f32, uv[1] as f32]
                                })
                                .collect(),
                        )
                    }),
                )),
                _ => None,
            };
            self.primitives.push(super::PrimitiveUse {
                node,
                mesh: index,
                primitive: p,
                world,
                positions: shared_positions,
                triangles: triangles
                    .iter()
                    .map(|t| [t[0] as u32, t[1] as u32, t[2] as u32])
                    .collect(),
                uv1: shared_uv1,
                double_sided: material.double_sided,
                polygons: ngon.then(|| {
                    polygons
                        .iter()
                        .enumerate()
                        .flat_map(|(k, p)| std::iter::repeat_n(k as u32, p.len().saturating_sub(2)))
                        .collect()
                }),
            });
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
        let name = || match material_index {
            Some(i) => super::label("material", i, self.root.materials[i].name.as_ref()),
            None => "the default material".to_string(),
        };
        if material.portal {
            let (material, location) = (name(), crate::scene::Location::file(&self.path));
            for piece in pieces {
                self.portals.push(crate::scene::portal::Marked {
                    polygon: piece,
                    material: material.clone(),
                    location: location.clone(),
                });
            }
            return Ok(());
        }
        if material.transmittance != DVec3::ZERO {
            // Glass: panes, not surfaces.
            let name = name();
            for piece in pieces {
                if let Some(pane) =
                    crate::scene::glass::Pane::new(piece, material.transmittance, &name)
                {
                    self.panes.push(pane);
                }
            }
            return Ok(());
        }
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
}
