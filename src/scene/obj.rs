//! Wavefront OBJ + MTL reader (design.md sections 6 and 7).
//!
//! Our own small parser rather than a crate, for the error messages: every
//! problem is reported with its file and line. `Kd` is the reflectance
//! (each channel in [0, 1)), `Ke` the emitted radiant exitance in W/m^2.
//! Faces are single-sided, front by counter-clockwise winding. Convex planar
//! faces stay whole; concave planar faces are triangulated by ear clipping;
//! non-planar faces are rejected; faces with no area are dropped with a
//! warning. The comment directive `#@camera ex ey ez tx ty tz ux uy uz fov`
//! gives the scene's camera and `#@mesh PATCH ELEMENT` its suggested mesh
//! sizes in metres.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::{Camera, Location, MeshHint, Scene, SceneError, Surface};
use crate::geometry;

/// Largest distance of a corner from the face's plane, relative to the face's
/// diameter, that still counts as planar. Exporters writing six decimals stay
/// well inside it; a visibly warped quad does not.
pub const PLANARITY_TOLERANCE: f64 = 1e-3;

/// Reads a material library named by `mtllib`, returning its path (for
/// messages) and its text.
pub type LibraryResolver<'a> = dyn FnMut(&str) -> Result<(PathBuf, String), SceneError> + 'a;

/// A material as read from an MTL file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// `Kd`: diffuse reflectance.
    pub rho: DVec3,
    /// `Ke`: emitted radiant exitance, W/m^2.
    pub emission: DVec3,
}

/// Reads an `.obj` file and the material libraries it names (relative to
/// its folder).
pub fn load_file(path: &Path) -> Result<Scene, SceneError> {
    let text = read_text(path)?;
    let folder = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    parse(&name, path, &text, &mut |lib: &str| {
        let lib_path = folder.join(lib);
        read_text(&lib_path).map(|text| (lib_path, text))
    })
}

/// Reads a file as text, refusing binary content with a clear message.
fn read_text(path: &Path) -> Result<String, SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        location: Location::file(path),
        source,
    })?;
    let invalid = |message: &str| SceneError::Invalid {
        location: Location::file(path),
        message: message.into(),
    };
    if bytes.contains(&0) {
        return Err(invalid(
            "this is a binary file, not a Wavefront OBJ/MTL text file",
        ));
    }
    String::from_utf8(bytes).map_err(|_| invalid("the file is not UTF-8 text"))
}

/// Parses OBJ text. `resolve` reads a material library named by `mtllib`
/// and returns its path (for messages) and text.
pub fn parse(
    name: &str,
    path: &Path,
    text: &str,
    resolve: &mut LibraryResolver<'_>,
) -> Result<Scene, SceneError> {
    let mut parser = ObjParser {
        path,
        positions: Vec::new(),
        materials: HashMap::new(),
        current: None,
        surfaces: Vec::new(),
        faces: 0,
        degenerate: Vec::new(),
        camera: None,
        mesh_hint: None,
        ignored: Vec::new(),
        statements: 0,
    };
    for (line_no, line) in logical_lines(text) {
        parser.statement(line_no, &line, resolve)?;
    }
    parser.finish(name)
}

/// Joins backslash-continued lines; yields (first line number, text without
/// comment).
fn logical_lines(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut pending: Option<(usize, String)> = None;
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim_end_matches('\r');
        let (start, mut acc) = pending.take().unwrap_or((i + 1, String::new()));
        if let Some(stripped) = raw.strip_suffix('\\') {
            acc.push_str(stripped);
            acc.push(' ');
            pending = Some((start, acc));
        } else {
            acc.push_str(raw);
            out.push((start, acc));
        }
    }
    if let Some(p) = pending {
        out.push(p);
    }
    out
}

struct ObjParser<'a> {
    path: &'a Path,
    positions: Vec<DVec3>,
    materials: HashMap<String, Material>,
    current: Option<Material>,
    surfaces: Vec<Surface>,
    faces: u32,
    degenerate: Vec<usize>,
    camera: Option<Camera>,
    mesh_hint: Option<MeshHint>,
    ignored: Vec<String>,
    statements: usize,
}

impl ObjParser<'_> {
    fn error(&self, line: usize, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            location: Location::line(self.path, line),
            message: message.into(),
        }
    }

    fn statement(
        &mut self,
        line_no: usize,
        line: &str,
        resolve: &mut LibraryResolver<'_>,
    ) -> Result<(), SceneError> {
        let trimmed = line.trim();
        if let Some(rest) = trimmed.strip_prefix("#@camera") {
            let camera = Camera::parse(rest)
                .map_err(|m| self.error(line_no, format!("bad #@camera directive: {m}")))?;
            self.camera = Some(camera);
            return Ok(());
        }
        if let Some(rest) = trimmed.strip_prefix("#@mesh") {
            let sizes: Vec<f64> = rest
                .split_whitespace()
                .map(|t| number(t).ok().filter(|v| *v > 0.0))
                .collect::<Option<_>>()
                .filter(|v: &Vec<f64>| v.len() == 2)
                .ok_or_else(|| {
                    self.error(
                        line_no,
                        "bad #@mesh directive: give two positive sizes in metres (patch, element)",
                    )
                })?;
            self.mesh_hint = Some(MeshHint {
                patch_size: sizes[0],
                element_size: sizes[1],
            });
            return Ok(());
        }
        let content = trimmed.split('#').next().unwrap_or("").trim();
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else {
            return Ok(());
        };
        self.statements += 1;
        let args: Vec<&str> = tokens.collect();
        match keyword {
            "v" => {
                if args.len() < 3 || args.len() > 7 {
                    return Err(self.error(
                        line_no,
                        format!(
                            "a vertex 'v' needs 3 coordinates (x y z), found {}",
                            args.len()
                        ),
                    ));
                }
                let mut xyz = [0.0; 3];
                for (slot, token) in xyz.iter_mut().zip(&args) {
                    *slot = number(token).map_err(|m| self.error(line_no, m))?;
                }
                for token in &args[3..] {
                    number(token).map_err(|m| self.error(line_no, m))?;
                }
                self.positions.push(DVec3::from_array(xyz));
            }
            "vt" | "vn" | "vp" => {
                for token in &args {
                    number(token).map_err(|m| self.error(line_no, m))?;
                }
            }
            "f" | "fo" => self.face(line_no, &args)?,
            "usemtl" => {
                let name = args.join(" ");
                if name.is_empty() {
                    return Err(self.error(line_no, "'usemtl' needs a material name"));
                }
                let material = self.materials.get(&name).copied().ok_or_else(|| {
                    self.error(
                        line_no,
                        format!("material '{name}' is not defined in any loaded material library (mtllib)"),
                    )
                })?;
                self.current = Some(material);
            }
            "mtllib" => {
                if args.is_empty() {
                    return Err(self.error(line_no, "'mtllib' needs a file name"));
                }
                // A single name may contain spaces; otherwise each token
                // names a library.
                let whole = args.join(" ");
                let names: Vec<String> = if args.len() > 1 && resolve_exists(resolve, &whole) {
                    vec![whole]
                } else {
                    args.iter().map(|s| s.to_string()).collect()
                };
                for lib in names {
                    let (lib_path, text) = resolve(&lib).map_err(|e| {
                        self.error(
                            line_no,
                            format!(
                                "cannot read material library '{lib}': {}",
                                inner_message(&e)
                            ),
                        )
                    })?;
                    parse_mtl(&lib_path, &text, &mut self.materials)?;
                }
            }
            "o" | "g" | "s" | "mg" => {}
            other => {
                if !self.ignored.iter().any(|k| k == other) {
                    self.ignored.push(other.to_string());
                }
            }
        }
        Ok(())
    }

    fn face(&mut self, line_no: usize, args: &[&str]) -> Result<(), SceneError> {
        if args.len() < 3 {
            return Err(self.error(
                line_no,
                format!("a face needs at least 3 vertices, found {}", args.len()),
            ));
        }
        let mut polygon = Vec::with_capacity(args.len());
        for token in args {
            let index_text = token.split('/').next().unwrap_or("");
            let index: i64 = index_text
                .parse()
                .map_err(|_| self.error(line_no, format!("'{token}' is not a vertex index")))?;
            let count = self.positions.len() as i64;
            let resolved = if index > 0 {
                index - 1
            } else if index < 0 {
                count + index
            } else {
                -1
            };
            if resolved < 0 || resolved >= count {
                return Err(self.error(
                    line_no,
                    format!(
                        "vertex index {index} is out of range ({count} vertices defined so far)"
                    ),
                ));
            }
            polygon.push(self.positions[resolved as usize]);
        }
        let material = self.current.ok_or_else(|| {
            self.error(
                line_no,
                "face has no material: put 'usemtl NAME' (defined in an mtllib) before it",
            )
        })?;
        let face = self.faces;
        self.faces += 1;
        match convex_pieces(polygon) {
            Ok(pieces) => {
                for piece in pieces {
                    // convex_pieces only returns pieces with area.
                    if let Some(s) = Surface::new(piece, material.rho, material.emission, face) {
                        self.surfaces.push(s);
                    }
                }
                Ok(())
            }
            Err(FaceProblem::Degenerate) => {
                self.degenerate.push(line_no);
                Ok(())
            }
            Err(FaceProblem::NonPlanar {
                deviation,
                diameter,
            }) => Err(self.error(
                line_no,
                format!(
                    "non-planar face: a corner is {deviation:.3e} off the face's plane \
                     ({:.2}% of its size); split it into triangles",
                    100.0 * deviation / diameter
                ),
            )),
        }
    }

    fn finish(self, name: &str) -> Result<Scene, SceneError> {
        let file_error = |message: String| SceneError::Invalid {
            location: Location::file(self.path),
            message,
        };
        if self.statements == 0 {
            return Err(file_error("the file is empty: no vertices or faces".into()));
        }
        if self.faces == 0 {
            return Err(file_error("the file has no faces ('f' lines)".into()));
        }
        if self.surfaces.is_empty() {
            return Err(file_error(format!(
                "all {} faces are degenerate (no area)",
                self.faces
            )));
        }
        if !self.surfaces.iter().any(Surface::is_emitter) {
            return Err(file_error(
                "the scene has no emitter: no face uses a material with Ke > 0".into(),
            ));
        }
        let mut warnings = Vec::new();
        if let Some(first) = self.degenerate.first() {
            warnings.push(format!(
                "{}: dropped {} degenerate face(s) with no area (first at line {first})",
                self.path.display(),
                self.degenerate.len()
            ));
        }
        if !self.ignored.is_empty() {
            warnings.push(format!(
                "{}: ignored unsupported statement(s): {}",
                self.path.display(),
                self.ignored.join(", ")
            ));
        }
        Ok(Scene {
            name: name.to_string(),
            surfaces: self.surfaces,
            camera: self.camera,
            mesh_hint: self.mesh_hint,
            warnings,
        })
    }
}

fn resolve_exists(resolve: &mut LibraryResolver<'_>, name: &str) -> bool {
    resolve(name).is_ok()
}

/// The message of an error without its location prefix.
fn inner_message(error: &SceneError) -> String {
    match error {
        SceneError::Io { source, .. } => source.to_string(),
        SceneError::Invalid { message, .. } => message.clone(),
        SceneError::NotFound(name) => format!("'{name}' not found"),
    }
}

/// Parses a finite number, with a message naming the token.
fn number(token: &str) -> Result<f64, String> {
    let v: f64 = token
        .parse()
        .map_err(|_| format!("'{token}' is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("'{token}' is not a finite number"))
    }
}

/// Reads an MTL file into `materials`.
fn parse_mtl(
    path: &Path,
    text: &str,
    materials: &mut HashMap<String, Material>,
) -> Result<(), SceneError> {
    let error = |line: usize, message: String| SceneError::Invalid {
        location: Location::line(path, line),
        message,
    };
    let mut current: Option<String> = None;
    for (line_no, line) in logical_lines(text) {
        let content = line.split('#').next().unwrap_or("").trim();
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        let args: Vec<&str> = tokens.collect();
        match keyword {
            "newmtl" => {
                let name = args.join(" ");
                if name.is_empty() {
                    return Err(error(line_no, "'newmtl' needs a material name".into()));
                }
                materials.insert(
                    name.clone(),
                    Material {
                        rho: DVec3::ZERO,
                        emission: DVec3::ZERO,
                    },
                );
                current = Some(name);
            }
            "Kd" | "Ke" => {
                let Some(name) = &current else {
                    return Err(error(line_no, format!("'{keyword}' before any 'newmtl'")));
                };
                if args
                    .first()
                    .is_some_and(|a| *a == "spectral" || *a == "xyz")
                {
                    return Err(error(
                        line_no,
                        format!("'{keyword} {}' is not supported: give r g b", args[0]),
                    ));
                }
                if args.is_empty() || args.len() > 3 {
                    return Err(error(
                        line_no,
                        format!(
                            "'{keyword}' needs 1 or 3 numbers (r g b), found {}",
                            args.len()
                        ),
                    ));
                }
                let mut rgb = [0.0; 3];
                for (i, slot) in rgb.iter_mut().enumerate() {
                    let token = args.get(i).unwrap_or(&args[0]);
                    *slot = number(token).map_err(|m| error(line_no, m))?;
                }
                let value = DVec3::from_array(rgb);
                let material = materials
                    .get_mut(name)
                    .expect("current material was inserted by newmtl");
                if keyword == "Kd" {
                    if value.min_element() < 0.0 || value.max_element() >= 1.0 {
                        return Err(error(
                            line_no,
                            format!(
                                "reflectance Kd {} {} {} of material '{name}' is outside [0, 1): \
                                 no surface reflects all the light it receives",
                                rgb[0], rgb[1], rgb[2]
                            ),
                        ));
                    }
                    material.rho = value;
                } else {
                    if value.min_element() < 0.0 {
                        return Err(error(
                            line_no,
                            format!(
                                "emission Ke {} {} {} of material '{name}' is negative",
                                rgb[0], rgb[1], rgb[2]
                            ),
                        ));
                    }
                    material.emission = value;
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Why a face cannot become surfaces.
pub(super) enum FaceProblem {
    Degenerate,
    NonPlanar { deviation: f64, diameter: f64 },
}

/// Splits an input face into planar convex pieces: drops repeated and
/// collinear corners, checks planarity, and ear-clips concave faces.
pub(super) fn convex_pieces(mut polygon: Vec<DVec3>) -> Result<Vec<Vec<DVec3>>, FaceProblem> {
    let diameter = geometry::diameter(&polygon);
    if diameter == 0.0 {
        return Err(FaceProblem::Degenerate);
    }
    let tolerance = 1e-9 * diameter;
    polygon.dedup_by(|a, b| a.distance(*b) <= tolerance);
    while polygon.len() > 1 && polygon[0].distance(polygon[polygon.len() - 1]) <= tolerance {
        polygon.pop();
    }
    if polygon.len() < 3 {
        return Err(FaceProblem::Degenerate);
    }
    let area_vector = geometry::newell_area_vector(&polygon);
    // An area below (1e-9 diameter)^2 is round-off of a line or a point.
    if 0.5 * area_vector.length() <= 1e-12 * diameter * diameter {
        return Err(FaceProblem::Degenerate);
    }
    let normal = area_vector.normalize();
    let offset = geometry::plane_offset(&polygon, normal);
    let deviation = polygon
        .iter()
        .map(|p| (normal.dot(*p) - offset).abs())
        .fold(0.0, f64::max);
    if deviation > PLANARITY_TOLERANCE * diameter {
        return Err(FaceProblem::NonPlanar {
            deviation,
            diameter,
        });
    }
    // Project onto the plane so every later test sees an exactly planar face.
    for p in &mut polygon {
        *p -= normal * (normal.dot(*p) - offset);
    }
    remove_collinear(&mut polygon, normal, tolerance);
    if polygon.len() < 3 {
        return Err(FaceProblem::Degenerate);
    }
    if geometry::is_convex(&polygon, normal, tolerance * diameter) {
        return Ok(vec![polygon]);
    }
    let triangles = ear_clip(&polygon, normal);
    if triangles.is_empty() {
        return Err(FaceProblem::Degenerate);
    }
    Ok(triangles)
}

/// Removes corners that lie on the line through their neighbours.
fn remove_collinear(polygon: &mut Vec<DVec3>, normal: DVec3, tolerance: f64) {
    let mut i = 0;
    while polygon.len() >= 3 && i < polygon.len() {
        let n = polygon.len();
        let a = polygon[(i + n - 1) % n];
        let b = polygon[i];
        let c = polygon[(i + 1) % n];
        let ac = c - a;
        let len = ac.length();
        let off_line = if len > 0.0 {
            ac.cross(b - a).dot(normal).abs() / len
        } else {
            0.0
        };
        if off_line <= tolerance {
            polygon.remove(i);
            i = 0;
        } else {
            i += 1;
        }
    }
}

/// Ear-clipping triangulation of a simple planar polygon (counter-clockwise
/// about `normal`). Triangles with no area are skipped.
fn ear_clip(polygon: &[DVec3], normal: DVec3) -> Vec<Vec<DVec3>> {
    let mut remaining: Vec<DVec3> = polygon.to_vec();
    let mut triangles = Vec::new();
    let mut guard = 0;
    while remaining.len() > 3 && guard < 10 * polygon.len() * polygon.len() {
        guard += 1;
        let n = remaining.len();
        let mut clipped = false;
        for i in 0..n {
            let a = remaining[(i + n - 1) % n];
            let b = remaining[i];
            let c = remaining[(i + 1) % n];
            if (b - a).cross(c - b).dot(normal) <= 0.0 {
                continue;
            }
            let triangle = [a, b, c];
            let tri_normal = normal;
            let contains_other = remaining.iter().enumerate().any(|(j, p)| {
                j != i
                    && j != (i + n - 1) % n
                    && j != (i + 1) % n
                    && geometry::convex_contains(&triangle, tri_normal, *p, 0.0)
            });
            if contains_other {
                continue;
            }
            triangles.push(triangle.to_vec());
            remaining.remove(i);
            clipped = true;
            break;
        }
        if !clipped {
            break;
        }
    }
    if remaining.len() == 3 {
        triangles.push(remaining);
    }
    triangles.retain(|t| geometry::area(t) > 0.0);
    triangles
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_with(obj: &str, mtl: &str) -> Result<Scene, SceneError> {
        let mtl = mtl.to_string();
        parse("t", Path::new("t.obj"), obj, &mut |name: &str| {
            if name == "t.mtl" {
                Ok((PathBuf::from("t.mtl"), mtl.clone()))
            } else {
                Err(SceneError::Io {
                    location: Location::file(Path::new(name)),
                    source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
                })
            }
        })
    }

    const MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 10 10 10\nnewmtl grey\nKd 0.5\n";

    #[test]
    fn quad_stays_whole_and_concave_face_is_triangulated() {
        let obj = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.25 0\n\
                   usemtl light\nf 1 2 3 4\nusemtl grey\nf 1 2 3 5\n";
        // Second face: (0,0) (1,0) (1,1) (0.5,0.25) is concave at (0.5,0.25).
        let scene = parse_with(obj, MTL).unwrap();
        assert_eq!(scene.surfaces[0].polygon.len(), 4);
        assert!(scene.surfaces.len() >= 3);
        let concave_area: f64 = scene.surfaces[1..].iter().map(|s| s.area).sum();
        let expected = geometry::area(&[
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.5, 0.25, 0.0),
        ]);
        assert!((concave_area - expected).abs() < 1e-12);
        assert!(scene.surfaces[1..].iter().all(|s| s.face == 1));
        assert_eq!(scene.surfaces[1].rho, DVec3::splat(0.5));
    }

    #[test]
    fn errors_name_the_line() {
        let obj = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl light\nf 1 2 9\n";
        let message = parse_with(obj, MTL).unwrap_err().to_string();
        assert!(message.starts_with("t.obj:6:"), "{message}");
        assert!(message.contains("out of range"), "{message}");
    }

    #[test]
    fn reflectance_of_one_is_rejected_in_the_mtl() {
        let obj = "mtllib t.mtl\nv 0 0 0\n";
        let message = parse_with(obj, "newmtl a\nKd 1 0.5 0.5\n")
            .unwrap_err()
            .to_string();
        assert!(message.starts_with("t.mtl:2:"), "{message}");
    }

    #[test]
    fn negative_indices_and_slashes() {
        let obj = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl light\nf -3/1/1 -2//1 -1/2\n";
        let scene = parse_with(obj, MTL).unwrap();
        assert_eq!(scene.surfaces.len(), 1);
        assert_eq!(scene.surfaces[0].normal, DVec3::Z);
    }

    #[test]
    fn collinear_corner_is_removed() {
        let obj = "mtllib t.mtl\nv 0 0 0\nv 0.5 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl light\nf 1 2 3 4 5\n";
        let scene = parse_with(obj, MTL).unwrap();
        assert_eq!(scene.surfaces[0].polygon.len(), 4);
    }
}
