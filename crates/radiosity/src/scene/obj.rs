//! Wavefront OBJ reader (design.md sections 6 and 7).
//!
//! Our own small parser rather than a crate, for the error messages: every
//! problem is reported with its file and line, and anything the grammar does
//! not allow is an error, not a guess. Materials come from the MTL libraries
//! named by `mtllib` ([`super::mtl`]: `Kd` is the reflectance, each channel
//! in [0, 1), `Ke` the emitted radiant exitance in W/m^2). Faces are
//! single-sided, front by counter-clockwise winding; [`super::polygon`]
//! turns each into planar convex pieces. The comment directive
//! `#@camera ex ey ez tx ty tz ux uy uz fov` gives the scene's camera,
//! `#@mesh PATCH ELEMENT` its suggested mesh sizes in metres and `#@light`
//! a light of a registered kind (point, spot, sun, lambert:
//! [`super::light::parse_directive`]) or a
//! luminaire from an IES photometric file named relative to the OBJ
//! (`#@light ies FILE.ies X Y Z [DX DY DZ] [MULTIPLIER]`, [`super::ies`]);
//! other programs read them as comments.
//!
//! Text is read as [`super::text`] says: it may start with a UTF-8
//! byte-order mark and end its lines with LF, CR LF or CR alone (old Mac
//! files). Loading works from bytes ([`parse_bytes`]) as well as from
//! files, so that the fuzzers in `fuzz/` reach the same code as the command
//! line. Every load is bounded by [`Limits`].

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::mtl::{Material, parse_mtl_into};
use super::polygon::{self, FaceProblem, Warp};
use super::text::{decode, length, logical_lines, number, quoted};
use super::{Camera, Light, Limits, Location, MeshHint, Scene, SceneError, Surface};

pub use super::polygon::PLANARITY_TOLERANCE;

/// Largest coordinate accepted, metres: beyond it a scene in metres has
/// lost all precision in its small features (and squared lengths approach
/// the range of `f64`).
pub const MAX_COORDINATE: f64 = 1e12;

/// Most `#@light` directives a file may hold: each light costs a shadow
/// segment per receiver.
pub const MAX_LIGHTS: usize = 65_536;

/// Reads a material library named by `mtllib`, returning its path (for
/// messages) and its text.
pub type LibraryResolver<'a> = dyn FnMut(&str) -> Result<(PathBuf, String), SceneError> + 'a;

/// Reads a material library named by `mtllib`, returning its path (for
/// messages) and its bytes.
pub type BytesResolver<'a> = dyn FnMut(&str) -> Result<(PathBuf, Vec<u8>), SceneError> + 'a;

/// Reads an `.obj` file and the material libraries it names (relative to
/// its folder).
pub fn load_file(path: &Path) -> Result<Scene, SceneError> {
    load_file_with(path, &Limits::default())
}

/// [`load_file`] with explicit limits.
pub fn load_file_with(path: &Path, limits: &Limits) -> Result<Scene, SceneError> {
    let bytes = super::read_input(path, limits)?;
    let folder = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    parse_bytes(&name, path, &bytes, limits, &mut |lib: &str| {
        let lib_path = folder.join(lib);
        super::read_input(&lib_path, limits).map(|bytes| (lib_path, bytes))
    })
}

/// Parses OBJ text with the default limits. `resolve` reads a material
/// library named by `mtllib` and returns its path (for messages) and text.
pub fn parse(
    name: &str,
    path: &Path,
    text: &str,
    resolve: &mut LibraryResolver<'_>,
) -> Result<Scene, SceneError> {
    parse_bytes(
        name,
        path,
        text.as_bytes(),
        &Limits::default(),
        &mut |lib: &str| resolve(lib).map(|(path, text)| (path, text.into_bytes())),
    )
}

/// Parses an OBJ file's bytes. `path` only names the file in messages;
/// `resolve` supplies the material libraries it names.
pub fn parse_bytes(
    name: &str,
    path: &Path,
    bytes: &[u8],
    limits: &Limits,
    resolve: &mut BytesResolver<'_>,
) -> Result<Scene, SceneError> {
    let text = decode(path, bytes)?;
    let mut parser = ObjParser {
        path,
        limits,
        positions: Vec::new(),
        texture_coordinates: 0,
        normals: 0,
        materials: HashMap::new(),
        libraries: std::collections::HashSet::new(),
        current: None,
        surfaces: Vec::new(),
        faces: 0,
        degenerate: Vec::new(),
        warped: Vec::new(),
        camera: None,
        lights: Vec::new(),
        panes: Vec::new(),
        portals: Vec::new(),
        current_name: String::new(),
        portal_materials: Vec::new(),
        profiles: HashMap::new(),
        mesh_hint: None,
        ignored: Vec::new(),
        warnings: Vec::new(),
        statements: 0,
    };
    for line in logical_lines(path, &text, limits) {
        let (line_no, line) = line?;
        parser.statement(line_no, &line, resolve)?;
    }
    parser.finish(name)
}

/// The statements of the OBJ format that carry nothing a radiosity solve
/// uses: skipped without a word.
const OBJ_SKIPPED: [&str; 4] = ["o", "g", "s", "mg"];

/// The other statements of the OBJ format (free-form geometry, lines,
/// points, display attributes): ignored with a warning. A keyword that is
/// in neither list is not OBJ (often a typo, such as `usemt`, that would
/// silently give faces the wrong material) and is an error.
const OBJ_UNSUPPORTED: [&str; 25] = [
    "p",
    "l",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "maplib",
];

struct ObjParser<'a> {
    path: &'a Path,
    limits: &'a Limits,
    positions: Vec<DVec3>,
    texture_coordinates: usize,
    normals: usize,
    materials: HashMap<String, Material>,
    libraries: std::collections::HashSet<String>,
    current: Option<Material>,
    surfaces: Vec<Surface>,
    faces: u32,
    degenerate: Vec<usize>,
    warped: Vec<(usize, Warp)>,
    camera: Option<Camera>,
    lights: Vec<Light>,
    /// Glass faces ([`super::glass`]).
    panes: Vec<super::glass::Pane>,
    portals: Vec<crate::scene::portal::Marked>,
    /// The name of the material of [`ObjParser::current`].
    current_name: String,
    /// `#@portal MATERIAL`: the material, the directive's line, and
    /// whether a face used it.
    portal_materials: Vec<(String, usize, bool)>,
    /// Photometric profiles read so far, by the name `#@light ies` gave.
    profiles: HashMap<String, std::sync::Arc<super::ies::Profile>>,
    mesh_hint: Option<MeshHint>,
    ignored: Vec<String>,
    warnings: Vec<String>,
    statements: usize,
}

impl ObjParser<'_> {
    fn error(&self, line: usize, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            location: Location::line(self.path, line),
            message: message.into(),
        }
    }

    fn numbers<const N: usize>(
        &self,
        line_no: usize,
        args: &[&str],
    ) -> Result<[f64; N], SceneError> {
        let mut out = [0.0; N];
        for (slot, token) in out.iter_mut().zip(args) {
            *slot = number(token).map_err(|m| self.error(line_no, m))?;
        }
        Ok(out)
    }

    fn statement(
        &mut self,
        line_no: usize,
        line: &str,
        resolve: &mut BytesResolver<'_>,
    ) -> Result<(), SceneError> {
        let trimmed = line.trim();
        if let Some(rest) = trimmed.strip_prefix("#@camera") {
            let camera = Camera::parse(rest)
                .map_err(|m| self.error(line_no, format!("bad #@camera directive: {m}")))?;
            self.camera = Some(camera);
            return Ok(());
        }
        if let Some(rest) = trimmed.strip_prefix("#@light") {
            if self.lights.len() >= MAX_LIGHTS {
                return Err(self.error(
                    line_no,
                    format!("more than {MAX_LIGHTS} #@light directives"),
                ));
            }
            let name = format!("#@light at line {line_no}");
            let light = if rest.split_whitespace().next() == Some("ies") {
                self.luminaire(line_no, rest, name, resolve)?
            } else {
                super::light::parse_directive(rest, name)
                    .map_err(|m| self.error(line_no, format!("bad #@light directive: {m}")))?
            };
            self.lights.push(light);
            return Ok(());
        }
        if let Some(rest) = trimmed.strip_prefix("#@portal") {
            let name = rest.trim();
            if name.is_empty() {
                return Err(self.error(
                    line_no,
                    "bad #@portal directive: give the material whose faces are portals",
                ));
            }
            self.portal_materials
                .push((name.to_string(), line_no, false));
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
                directive: Some(Location::line(self.path, line_no)),
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
                if !matches!(args.len(), 3 | 4 | 6) {
                    return Err(self.error(
                        line_no,
                        format!(
                            "a vertex 'v' takes x y z (optionally w, or r g b), found {} numbers",
                            args.len()
                        ),
                    ));
                }
                let xyz = self.numbers::<3>(line_no, &args)?;
                for token in &args[3..] {
                    number(token).map_err(|m| self.error(line_no, m))?;
                }
                if let Some(c) = xyz.iter().find(|c| c.abs() > MAX_COORDINATE) {
                    return Err(self.error(
                        line_no,
                        format!(
                            "coordinate {c:e} is beyond {MAX_COORDINATE:e} m: coordinates are \
                             metres, and at that size a scene has no precision left"
                        ),
                    ));
                }
                if self.positions.len() >= self.limits.max_vertices {
                    return Err(self.error(
                        line_no,
                        format!(
                            "more than {} vertices, the limit (raise it with --max-vertices)",
                            self.limits.max_vertices
                        ),
                    ));
                }
                self.positions.push(DVec3::from_array(xyz));
            }
            "vt" | "vn" | "vp" => {
                let counts = match keyword {
                    "vn" => 3..=3,
                    _ => 1..=3,
                };
                if !counts.contains(&args.len()) {
                    let wanted = match keyword {
                        "vn" => "x y z",
                        "vt" => "u [v [w]]",
                        _ => "u [v [w]]",
                    };
                    return Err(self.error(
                        line_no,
                        format!("'{keyword}' takes {wanted}, found {} numbers", args.len()),
                    ));
                }
                for token in &args {
                    number(token).map_err(|m| self.error(line_no, m))?;
                }
                match keyword {
                    "vt" => self.texture_coordinates += 1,
                    "vn" => self.normals += 1,
                    _ => {}
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
                        format!(
                            "material {} is not defined in any loaded material library (mtllib)",
                            quoted(&name)
                        ),
                    )
                })?;
                self.current = Some(material);
                self.current_name = name;
            }
            "mtllib" => {
                if args.is_empty() {
                    return Err(self.error(line_no, "'mtllib' needs a file name"));
                }
                // A single name may contain spaces; otherwise each token
                // names a library.
                let whole = args.join(" ");
                let names: Vec<String> = if args.len() > 1
                    && (self.libraries.contains(&whole) || resolve(&whole).is_ok())
                {
                    vec![whole]
                } else {
                    args.iter().map(|s| s.to_string()).collect()
                };
                for lib in names {
                    // Each library is read once, however often it is named:
                    // a million `mtllib big.mtl` lines must not read it a
                    // million times.
                    if !self.libraries.insert(lib.clone()) {
                        continue;
                    }
                    let (lib_path, bytes) = resolve(&lib).map_err(|e| {
                        self.error(
                            line_no,
                            format!(
                                "cannot read material library {}: {}",
                                quoted(&lib),
                                inner_message(&e)
                            ),
                        )
                    })?;
                    let text = decode(&lib_path, &bytes)?;
                    parse_mtl_into(
                        &lib_path,
                        &text,
                        self.limits,
                        &mut self.materials,
                        &mut self.warnings,
                    )?;
                }
            }
            other if OBJ_SKIPPED.contains(&other) => {}
            other if OBJ_UNSUPPORTED.contains(&other) || other == "usemap" => {
                let other = quoted(other);
                if !self.ignored.contains(&other) {
                    self.ignored.push(other);
                }
            }
            other => {
                return Err(self.error(
                    line_no,
                    format!(
                        "{} is not an OBJ statement (v, vt, vn, f, usemtl, mtllib, o, g, s, ...)",
                        quoted(other)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The position a face's vertex reference (`v`, `v/vt`, `v//vn` or
    /// `v/vt/vn`, indices 1-based or negative from the end) names.
    fn reference(&self, line_no: usize, token: &str) -> Result<DVec3, SceneError> {
        let mut split = token.splitn(4, '/');
        let mut parts: [&str; 4] = [""; 4];
        let mut count = 0;
        for part in split.by_ref() {
            parts[count] = part;
            count += 1;
        }
        let parts = &parts[..count];
        let bad_form = || {
            self.error(
                line_no,
                format!(
                    "{} is not a vertex reference (v, v/vt, v//vn or v/vt/vn)",
                    quoted(token)
                ),
            )
        };
        let (vt, vn) = match parts {
            [_] => (None, None),
            [_, vt] if !vt.is_empty() => (Some(*vt), None),
            [_, vt, vn] if !vn.is_empty() => ((!vt.is_empty()).then_some(*vt), Some(*vn)),
            _ => return Err(bad_form()),
        };
        let resolve = |text: &str, what: &str, count: usize| -> Result<usize, SceneError> {
            let index: i64 = text.parse().map_err(|_| {
                self.error(
                    line_no,
                    format!(
                        "{} in {} is not a {what} index",
                        quoted(text),
                        quoted(token)
                    ),
                )
            })?;
            let count_i = count as i64;
            let resolved = match index {
                i if i > 0 => i - 1,
                i if i < 0 => count_i + i,
                _ => -1,
            };
            if resolved < 0 || resolved >= count_i {
                return Err(self.error(
                    line_no,
                    format!("{what} index {index} is out of range ({count} defined so far)"),
                ));
            }
            Ok(resolved as usize)
        };
        let v = resolve(parts[0], "vertex", self.positions.len())?;
        if let Some(vt) = vt {
            resolve(vt, "texture coordinate", self.texture_coordinates)?;
        }
        if let Some(vn) = vn {
            resolve(vn, "normal", self.normals)?;
        }
        Ok(self.positions[v])
    }

    fn face(&mut self, line_no: usize, args: &[&str]) -> Result<(), SceneError> {
        if args.len() < 3 {
            return Err(self.error(
                line_no,
                format!("a face needs at least 3 vertices, found {}", args.len()),
            ));
        }
        if args.len() > self.limits.max_corners {
            return Err(self.error(
                line_no,
                format!(
                    "the face has {} corners, more than the limit of {} (raise it with --max-corners)",
                    args.len(),
                    self.limits.max_corners
                ),
            ));
        }
        if self.faces as usize >= self.limits.max_faces {
            return Err(self.error(
                line_no,
                format!(
                    "more than {} faces, the limit (raise it with --max-faces)",
                    self.limits.max_faces
                ),
            ));
        }
        let polygon = args
            .iter()
            .map(|token| self.reference(line_no, token))
            .collect::<Result<Vec<DVec3>, _>>()?;
        let material = self.current.ok_or_else(|| {
            self.error(
                line_no,
                "face has no material: put 'usemtl NAME' (defined in an mtllib) before it",
            )
        })?;
        let face = self.faces;
        self.faces += 1;
        match polygon::convex_pieces(&polygon) {
            Ok(pieces) => {
                if let Some(warp) = pieces.warp {
                    self.warped.push((line_no, warp));
                }
                let portal = self
                    .portal_materials
                    .iter_mut()
                    .find(|(name, _, _)| *name == self.current_name);
                if let Some((_, _, used)) = portal {
                    *used = true;
                    for piece in pieces.polygons {
                        self.portals.push(super::portal::Marked {
                            polygon: piece,
                            material: self.current_name.clone(),
                            location: Location::line(self.path, line_no),
                        });
                    }
                    return Ok(());
                }
                for piece in pieces.polygons {
                    if material.transmittance != DVec3::ZERO {
                        // Glass: a pane, not a surface.
                        if let Some(p) = super::glass::Pane::new(
                            piece,
                            material.transmittance,
                            &self.current_name,
                        ) {
                            self.panes.push(p);
                        }
                        continue;
                    }
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
            Err(problem) => Err(self.error(line_no, face_message(&problem))),
        }
    }

    /// `#@light ies FILE.ies X Y Z [DX DY DZ] [MULTIPLIER]`: the profile
    /// read relative to the OBJ file (once per file name).
    fn luminaire(
        &mut self,
        line_no: usize,
        rest: &str,
        name: String,
        resolve: &mut BytesResolver<'_>,
    ) -> Result<Light, SceneError> {
        let bad =
            |parser: &Self, m: String| parser.error(line_no, format!("bad #@light directive: {m}"));
        let mut words = rest.split_whitespace().skip(1);
        let Some(file) = words.next() else {
            return Err(bad(
                self,
                "'ies' needs a file name: #@light ies FILE.ies X Y Z".into(),
            ));
        };
        let numbers: Vec<f64> = words
            .map(|w| number(w).map_err(|m| bad(self, m)))
            .collect::<Result<_, _>>()?;
        let (position, nadir, multiplier) =
            super::light::luminaire_numbers(&numbers).map_err(|m| bad(self, m))?;
        let profile = match self.profiles.get(file) {
            Some(p) => p.clone(),
            None => {
                let (path, bytes) = resolve(file).map_err(|e| {
                    bad(
                        self,
                        format!("cannot read {}: {}", quoted(file), inner_message(&e)),
                    )
                })?;
                let profile = super::ies::parse(&bytes).map_err(|e| {
                    bad(
                        self,
                        format!("{}:{}: {}", path.display(), e.line, e.message),
                    )
                })?;
                let profile = std::sync::Arc::new(profile);
                self.profiles.insert(file.to_string(), profile.clone());
                profile
            }
        };
        super::light::luminaire(name, position, nadir, None, multiplier, profile)
            .map_err(|e| bad(self, e.to_string()))
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
        if self.surfaces.is_empty() && !(self.panes.is_empty() && self.portals.is_empty()) {
            return Err(file_error(format!(
                "all {} faces are glass or portals: the scene has no surface to light",
                self.faces
            )));
        }
        if self.surfaces.is_empty() {
            return Err(file_error(format!(
                "all {} faces are degenerate (no area)",
                self.faces
            )));
        }
        let mut warnings = self.warnings;
        if let Some(first) = self.degenerate.first() {
            warnings.push(format!(
                "{}: dropped {} degenerate face(s) with no area (first at line {first})",
                self.path.display(),
                self.degenerate.len()
            ));
        }
        const NAMED: usize = 3;
        for (line, warp) in self.warped.iter().take(NAMED) {
            warnings.push(format!(
                "{}:{line}: the face is not planar (a corner is {} off its plane, {:.3}% of its \
                 size): split into {} triangles folding by {:.2} degrees",
                self.path.display(),
                length(warp.deviation),
                100.0 * warp.deviation / warp.size,
                warp.triangles,
                warp.fold_degrees
            ));
        }
        if self.warped.len() > NAMED {
            let (line, worst) = self.warped[NAMED..]
                .iter()
                .max_by(|a, b| a.1.fold_degrees.total_cmp(&b.1.fold_degrees))
                .expect("more than NAMED");
            warnings.push(format!(
                "{}: {} more non-planar faces split into triangles (the largest fold, {:.2} \
                 degrees, at line {line})",
                self.path.display(),
                self.warped.len() - NAMED,
                worst.fold_degrees
            ));
        }
        if !self.ignored.is_empty() {
            warnings.push(format!(
                "{}: ignored unsupported statement(s): {}",
                self.path.display(),
                self.ignored.join(", ")
            ));
        }
        if let Some((name, line, _)) = self.portal_materials.iter().find(|p| !p.2) {
            return Err(SceneError::Invalid {
                location: Location::line(self.path, *line),
                message: format!(
                    "bad #@portal directive: no face uses material {}",
                    quoted(name)
                ),
            });
        }
        let mut surfaces = self.surfaces;
        super::merge::group_by_face(&mut surfaces);
        Ok(Scene {
            name: name.to_string(),
            surfaces,
            lights: self.lights,
            panes: self.panes,
            portals: self.portals,
            camera: self.camera,
            mesh_hint: self.mesh_hint,
            warnings,
        })
    }
}

/// Why a face is refused, in words a user can act on. Corners are numbered
/// as they appear on the `f` line, from 1.
fn face_message(problem: &FaceProblem) -> String {
    match problem {
        FaceProblem::Degenerate => "the face has no area".into(),
        FaceProblem::TooWarped(warp) => format!(
            "the face is not planar: a corner is {} ({:.1}% of its size) off its plane, and split \
             into triangles it would fold by {:.0} degrees (more than {:.0}), so the intended \
             shape is unclear: split it into triangles or planar faces yourself",
            length(warp.deviation),
            100.0 * warp.deviation / warp.size,
            warp.fold_degrees,
            polygon::MAX_FOLD_DEGREES
        ),
        FaceProblem::Crossing {
            first,
            second,
            corners,
        } => format!(
            "the face's outline crosses itself (its edge from corner {} to {} meets its edge \
             from corner {} to {}): a face must be a simple polygon, so split it into faces that \
             are",
            first + 1,
            (first + 1) % corners + 1,
            second + 1,
            (second + 1) % corners + 1
        ),
        FaceProblem::Coincident(a, b) => format!(
            "corners {} and {} of the face are at the same point, so its outline touches itself: \
             split it into simple faces",
            a + 1,
            b + 1
        ),
        FaceProblem::Untriangulable => {
            "the face could not be triangulated: split it into triangles".into()
        }
    }
}

/// The message of an error without its location prefix.
fn inner_message(error: &SceneError) -> String {
    match error {
        SceneError::Io { source, .. } => source.to_string(),
        SceneError::Invalid { message, .. } => message.clone(),
        SceneError::NotFound(name) => format!("{} not found", quoted(name)),
    }
}

#[cfg(test)]
mod tests;
