//! Wavefront OBJ + MTL reader (design.md sections 6 and 7).
//!
//! Our own small parser rather than a crate, for the error messages: every
//! problem is reported with its file and line, and anything the grammar does
//! not allow is an error, not a guess. `Kd` is the reflectance (each channel
//! in [0, 1)), `Ke` the emitted radiant exitance in W/m^2. Faces are
//! single-sided, front by counter-clockwise winding; [`super::polygon`]
//! turns each into planar convex pieces. The comment directive
//! `#@camera ex ey ez tx ty tz ux uy uz fov` gives the scene's camera and
//! `#@mesh PATCH ELEMENT` its suggested mesh sizes in metres.
//!
//! Text may start with a UTF-8 byte-order mark and end its lines with LF,
//! CR LF or CR alone (old Mac files). Loading works from bytes
//! ([`parse_bytes`], [`parse_mtl`]) as well as from files, so that the
//! fuzzers in `fuzz/` reach the same code as the command line. Every load is
//! bounded by [`Limits`].

use std::borrow::Cow;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::polygon::{self, FaceProblem, Warp};
use super::{Camera, Limits, Location, MeshHint, Scene, SceneError, Surface};

pub use super::polygon::PLANARITY_TOLERANCE;

/// Largest coordinate accepted, metres: beyond it a scene in metres has
/// lost all precision in its small features (and squared lengths approach
/// the range of `f64`).
pub const MAX_COORDINATE: f64 = 1e12;

/// Reads a material library named by `mtllib`, returning its path (for
/// messages) and its text.
pub type LibraryResolver<'a> = dyn FnMut(&str) -> Result<(PathBuf, String), SceneError> + 'a;

/// Reads a material library named by `mtllib`, returning its path (for
/// messages) and its bytes.
pub type BytesResolver<'a> = dyn FnMut(&str) -> Result<(PathBuf, Vec<u8>), SceneError> + 'a;

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

/// Turns a file's bytes into text: a UTF-8 byte-order mark is skipped;
/// NUL bytes (binary data), UTF-16 and invalid UTF-8 are refused with the
/// line where they are.
pub fn decode<'a>(path: &Path, bytes: &'a [u8]) -> Result<Cow<'a, str>, SceneError> {
    let invalid = |line: Option<usize>, message: String| SceneError::Invalid {
        location: Location {
            path: path.to_path_buf(),
            line,
        },
        message,
    };
    if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
        return Err(invalid(
            None,
            "the file is UTF-16 text: save it as UTF-8 (or ASCII)".into(),
        ));
    }
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let line_of = |offset: usize| line_number(&bytes[..offset]);
    if let Some(offset) = bytes.iter().position(|&b| b == 0) {
        return Err(invalid(
            Some(line_of(offset)),
            "a NUL byte: this looks like a binary file, not Wavefront OBJ/MTL text".into(),
        ));
    }
    match std::str::from_utf8(bytes) {
        Ok(text) => Ok(Cow::Borrowed(text)),
        Err(e) => Err(invalid(
            Some(line_of(e.valid_up_to())),
            format!(
                "byte 0x{:02X} is not UTF-8 text: save the file as UTF-8",
                bytes[e.valid_up_to()]
            ),
        )),
    }
}

/// The 1-based line that starts after `before`, counting LF, CR LF and lone
/// CR as line ends (as [`logical_lines`] does).
fn line_number(before: &[u8]) -> usize {
    let mut line = 1;
    let mut previous = 0u8;
    for &b in before {
        if b == b'\n' && previous != b'\r' || b == b'\r' {
            line += 1;
        }
        previous = b;
    }
    line
}

/// Lines of `text` ending in LF, CR LF or a lone CR, with backslash
/// continuations joined: `(first line number, text)`. Each physical and
/// logical line is checked against `limits.max_line_bytes`.
fn logical_lines<'a>(
    path: &'a Path,
    text: &'a str,
    limits: &'a Limits,
) -> impl Iterator<Item = Result<(usize, Cow<'a, str>), SceneError>> + 'a {
    let mut rest = text;
    let mut next_line = 1;
    let too_long = move |line: usize, bytes: usize| SceneError::Invalid {
        location: Location::line(path, line),
        message: format!(
            "the line is {bytes} bytes long, more than the limit of {} bytes \
             (raise it with --max-line-length)",
            limits.max_line_bytes
        ),
    };
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let start = next_line;
        let mut joined: Option<String> = None;
        loop {
            let end = rest.find(['\n', '\r']).unwrap_or(rest.len());
            let line = &rest[..end];
            let after = match rest.as_bytes().get(end) {
                Some(b'\r') if rest.as_bytes().get(end + 1) == Some(&b'\n') => end + 2,
                Some(_) => end + 1,
                None => end,
            };
            rest = &rest[after..];
            next_line += 1;
            if line.len() > limits.max_line_bytes {
                return Some(Err(too_long(next_line - 1, line.len())));
            }
            match (line.strip_suffix('\\'), joined.as_mut()) {
                (Some(head), _) if !rest.is_empty() => {
                    let acc = joined.get_or_insert_with(String::new);
                    acc.push_str(head);
                    acc.push(' ');
                    if acc.len() > limits.max_line_bytes {
                        return Some(Err(too_long(start, acc.len())));
                    }
                }
                (head, Some(acc)) => {
                    acc.push_str(head.unwrap_or(line));
                    if acc.len() > limits.max_line_bytes {
                        return Some(Err(too_long(start, acc.len())));
                    }
                    return Some(Ok((start, Cow::Owned(joined.take().unwrap_or_default()))));
                }
                (head, None) => return Some(Ok((start, Cow::Borrowed(head.unwrap_or(line))))),
            }
        }
    })
}

/// Input text for a message: quoted, control characters escaped, cut to a
/// readable length.
#[must_use]
pub fn quoted(text: &str) -> String {
    const SHOWN: usize = 40;
    let mut out = String::from("'");
    for (i, c) in text.chars().enumerate() {
        if i == SHOWN {
            let _ = write!(out, "...' ({} bytes)", text.len());
            return out;
        }
        out.extend(c.escape_debug());
    }
    out.push('\'');
    out
}

/// A length in metres for a message, in a unit a person reads at a glance.
pub(crate) fn length(metres: f64) -> String {
    if metres >= 1.0 {
        format!("{metres:.3} m")
    } else if metres >= 0.01 {
        format!("{:.1} cm", metres * 100.0)
    } else if metres >= 1e-4 {
        format!("{:.2} mm", metres * 1000.0)
    } else {
        format!("{metres:.2e} m")
    }
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
                for piece in pieces.polygons {
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
        let mut surfaces = self.surfaces;
        super::merge::group_by_face(&mut surfaces);
        Ok(Scene {
            name: name.to_string(),
            surfaces,
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

/// Parses a finite number, with a message naming the token.
fn number(token: &str) -> Result<f64, String> {
    let v: f64 = token
        .parse()
        .map_err(|_| format!("{} is not a number", quoted(token)))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{} is not a finite number", quoted(token)))
    }
}

/// MTL statements that carry nothing a radiosity solve uses: skipped
/// without a word. Anything else unknown is named in a warning.
const MTL_SKIPPED: [&str; 21] = [
    "Ka",
    "Ks",
    "Ns",
    "Ni",
    "d",
    "Tr",
    "Tf",
    "illum",
    "sharpness",
    "bump",
    "disp",
    "decal",
    "refl",
    "norm",
    "Pr",
    "Pm",
    "Ps",
    "Pc",
    "Pcr",
    "aniso",
    "anisor",
];

/// Parses an MTL file's bytes into its materials; warnings (ignored
/// statements) are appended to `warnings`.
pub fn parse_mtl(
    path: &Path,
    bytes: &[u8],
    limits: &Limits,
    warnings: &mut Vec<String>,
) -> Result<HashMap<String, Material>, SceneError> {
    let text = decode(path, bytes)?;
    let mut materials = HashMap::new();
    parse_mtl_into(path, &text, limits, &mut materials, warnings)?;
    Ok(materials)
}

fn parse_mtl_into(
    path: &Path,
    text: &str,
    limits: &Limits,
    materials: &mut HashMap<String, Material>,
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    let error = |line: usize, message: String| SceneError::Invalid {
        location: Location::line(path, line),
        message,
    };
    let mut current: Option<String> = None;
    let mut ignored: Vec<String> = Vec::new();
    for line in logical_lines(path, text, limits) {
        let (line_no, line) = line?;
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
                if args.len() != 1 && args.len() != 3 {
                    return Err(error(
                        line_no,
                        format!(
                            "'{keyword}' takes 1 number (grey) or 3 (r g b), found {}",
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
                let shown = quoted(name);
                let Some(material) = materials.get_mut(name) else {
                    return Err(error(line_no, format!("material {shown} vanished")));
                };
                if keyword == "Kd" {
                    if value.min_element() < 0.0 || value.max_element() >= 1.0 {
                        return Err(error(
                            line_no,
                            format!(
                                "reflectance Kd {} {} {} of material {shown} is outside [0, 1): \
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
                                "emission Ke {} {} {} of material {shown} is negative",
                                rgb[0], rgb[1], rgb[2]
                            ),
                        ));
                    }
                    material.emission = value;
                }
            }
            other if MTL_SKIPPED.contains(&other) || other.starts_with("map_") => {}
            other => {
                let other = quoted(other);
                if ignored.len() < 10 && !ignored.contains(&other) {
                    ignored.push(other);
                }
            }
        }
    }
    if !ignored.is_empty() {
        warnings.push(format!(
            "{}: ignored unsupported statement(s): {}",
            path.display(),
            ignored.join(", ")
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry;

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

    fn message(obj: &str, mtl: &str) -> String {
        parse_with(obj, mtl).unwrap_err().to_string()
    }

    const MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 10 10 10\nnewmtl grey\nKd 0.5\n";
    const HEAD: &str = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl light\n";

    #[test]
    fn quad_stays_whole_and_concave_face_is_triangulated() {
        let obj = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.25 0\n\
                   usemtl light\nf 1 2 3 4\nusemtl grey\nf 1 2 3 5\n";
        // Second face: (0,0) (1,0) (1,1) (0.5,0.25) is concave at (0.5,0.25).
        let scene = parse_with(obj, MTL).unwrap();
        assert_eq!(scene.surfaces[0].polygon.len(), 4);
        assert_eq!(scene.surfaces.len(), 3);
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
        assert_eq!(
            message(obj, MTL),
            "t.obj:6: vertex index 9 is out of range (3 defined so far)"
        );
    }

    #[test]
    fn reflectance_of_one_is_rejected_in_the_mtl() {
        let obj = "mtllib t.mtl\nv 0 0 0\n";
        let message = message(obj, "newmtl a\nKd 1 0.5 0.5\n");
        assert!(message.starts_with("t.mtl:2:"), "{message}");
    }

    #[test]
    fn negative_indices_and_slashes() {
        let obj = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvn 0 0 1\n\
                   usemtl light\nf -3/1/1 -2//1 -1/2\n";
        let scene = parse_with(obj, MTL).unwrap();
        assert_eq!(scene.surfaces.len(), 1);
        assert_eq!(scene.surfaces[0].normal, DVec3::Z);
    }

    #[test]
    fn malformed_references_are_errors() {
        for (face, expected) in [
            (
                "f 1/2/3/4 2 3",
                "t.obj:7: '1/2/3/4' is not a vertex reference (v, v/vt, v//vn or v/vt/vn)",
            ),
            (
                "f 1/x/2 2 3",
                "t.obj:7: 'x' in '1/x/2' is not a texture coordinate index",
            ),
            (
                "f 1/ 2 3",
                "t.obj:7: '1/' is not a vertex reference (v, v/vt, v//vn or v/vt/vn)",
            ),
            (
                "f 1// 2 3",
                "t.obj:7: '1//' is not a vertex reference (v, v/vt, v//vn or v/vt/vn)",
            ),
            (
                "f 1/1 2 3",
                "t.obj:7: texture coordinate index 1 is out of range (0 defined so far)",
            ),
            (
                "f 1//1 2 3",
                "t.obj:7: normal index 1 is out of range (0 defined so far)",
            ),
        ] {
            assert_eq!(message(&format!("{HEAD}{face}\n"), MTL), expected);
        }
    }

    #[test]
    fn wrong_counts_of_numbers_are_errors() {
        let mtl = MTL.replace("Kd 0.5 0.5 0.5", "Kd 0.5 0.5");
        assert_eq!(
            message(HEAD, &mtl),
            "t.mtl:2: 'Kd' takes 1 number (grey) or 3 (r g b), found 2"
        );
        let mtl = MTL.replace("Ke 10 10 10", "Ke 10 10 10 10");
        assert_eq!(
            message(HEAD, &mtl),
            "t.mtl:3: 'Ke' takes 1 number (grey) or 3 (r g b), found 4"
        );
        assert_eq!(
            message(&format!("{HEAD}vn 0 1\n"), MTL),
            "t.obj:7: 'vn' takes x y z, found 2 numbers"
        );
        assert_eq!(
            message(&format!("{HEAD}v 1 2 3 4 5\n"), MTL),
            "t.obj:7: a vertex 'v' takes x y z (optionally w, or r g b), found 5 numbers"
        );
    }

    #[test]
    fn self_intersecting_faces_are_errors() {
        let bow_tie = "mtllib t.mtl\nv 0 0 0\nv 1 1 0\nv 1 0 0\nv 0 1 0\nusemtl light\nf 1 2 3 4\n";
        assert_eq!(
            message(bow_tie, MTL),
            "t.obj:7: the face's outline crosses itself (its edge from corner 1 to 2 meets its \
             edge from corner 3 to 4): a face must be a simple polygon, so split it into faces \
             that are"
        );
        let mut pentagram = String::from("mtllib t.mtl\n");
        for i in 0..5 {
            let a = std::f64::consts::TAU * (2 * i) as f64 / 5.0;
            pentagram += &format!("v {} {} 0\n", a.cos(), a.sin());
        }
        pentagram += "usemtl light\nf 1 2 3 4 5\n";
        let message = message(&pentagram, MTL);
        assert!(
            message.starts_with("t.obj:8: the face's outline crosses itself"),
            "{message}"
        );
    }

    #[test]
    fn byte_order_mark_and_old_mac_line_ends_are_read() {
        let obj = format!("\u{feff}{HEAD}f 1 2 3 4\n");
        let mtl = format!("\u{feff}{MTL}");
        assert_eq!(parse_with(&obj, &mtl).unwrap().surfaces.len(), 1);
        let obj = format!("{HEAD}f 1 2 3 4\n").replace('\n', "\r");
        let mtl = MTL.replace('\n', "\r");
        assert_eq!(parse_with(&obj, &mtl).unwrap().surfaces.len(), 1);
        let obj = format!("{HEAD}f 1 2 9\n").replace('\n', "\r");
        assert!(message(&obj, MTL).starts_with("t.obj:7: vertex index 9"));
    }

    #[test]
    fn nul_byte_is_named_with_its_line() {
        let obj = format!("{HEAD}# a comment \0 with a NUL\nf 1 2 3 4\n");
        assert_eq!(
            message(&obj, MTL),
            "t.obj:7: a NUL byte: this looks like a binary file, not Wavefront OBJ/MTL text"
        );
    }

    #[test]
    fn long_names_are_cut_in_messages() {
        let name = "x".repeat(1_000_000);
        let message = message(&format!("{HEAD}usemtl {name}\n"), MTL);
        assert_eq!(
            message,
            format!(
                "t.obj:7: material '{}...' (1000000 bytes) is not defined in any loaded \
                 material library (mtllib)",
                "x".repeat(40)
            )
        );
    }

    #[test]
    fn limits_name_the_option_that_raises_them() {
        let limits = Limits {
            max_corners: 3,
            max_faces: 1,
            max_vertices: 4,
            max_line_bytes: 20,
            ..Limits::default()
        };
        let run = |obj: &str| {
            parse_bytes(
                "t",
                Path::new("t.obj"),
                obj.as_bytes(),
                &limits,
                &mut |_| Ok((PathBuf::from("t.mtl"), MTL.as_bytes().to_vec())),
            )
            .unwrap_err()
            .to_string()
        };
        assert_eq!(
            run(&format!("{HEAD}f 1 2 3 4\n")),
            "t.obj:7: the face has 4 corners, more than the limit of 3 (raise it with --max-corners)"
        );
        assert_eq!(
            run(&format!("{HEAD}f 1 2 3\nf 1 3 4\n")),
            "t.obj:8: more than 1 faces, the limit (raise it with --max-faces)"
        );
        assert_eq!(
            run(&format!("{HEAD}v 0 0 1\n")),
            "t.obj:7: more than 4 vertices, the limit (raise it with --max-vertices)"
        );
        assert_eq!(
            run(&format!("{HEAD}# a comment that is too long\n")),
            "t.obj:7: the line is 28 bytes long, more than the limit of 20 bytes (raise it with \
             --max-line-length)"
        );
        assert_eq!(
            run(&format!("{HEAD}f 1 \\\n2 \\\n3 \\\n4 \\\n1 \\\n2 \\\n3\n")),
            "t.obj:7: the line is 21 bytes long, more than the limit of 20 bytes (raise it with \
             --max-line-length)"
        );
    }

    #[test]
    fn unknown_statements_are_errors_and_unsupported_ones_warnings() {
        assert_eq!(
            message(&format!("{HEAD}usemt grey\nf 1 2 3\n"), MTL),
            "t.obj:7: 'usemt' is not an OBJ statement (v, vt, vn, f, usemtl, mtllib, o, g, s, ...)"
        );
        let scene = parse_with(&format!("{HEAD}l 1 2\nf 1 2 3\ncurv 0 1 1 2\n"), MTL).unwrap();
        assert_eq!(
            scene.warnings,
            ["t.obj: ignored unsupported statement(s): 'l', 'curv'"]
        );
    }

    #[test]
    fn a_library_named_many_times_is_read_once() {
        let mut reads = 0;
        let obj = format!("{}{HEAD}f 1 2 3\n", "mtllib t.mtl\n".repeat(1000));
        let scene = parse_bytes(
            "t",
            Path::new("t.obj"),
            obj.as_bytes(),
            &Limits::default(),
            &mut |_| {
                reads += 1;
                Ok((PathBuf::from("t.mtl"), MTL.as_bytes().to_vec()))
            },
        );
        assert!(scene.is_ok());
        assert_eq!(reads, 1);
    }

    #[test]
    fn collinear_corner_is_removed() {
        let obj = "mtllib t.mtl\nv 0 0 0\nv 0.5 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl light\nf 1 2 3 4 5\n";
        let scene = parse_with(obj, MTL).unwrap();
        assert_eq!(scene.surfaces[0].polygon.len(), 4);
    }

    #[test]
    fn continuation_lines_join() {
        let obj = format!("{HEAD}f 1 2 \\\n 3 \\\r\n4\n");
        let scene = parse_with(&obj, MTL).unwrap();
        assert_eq!(scene.surfaces[0].polygon.len(), 4);
    }
}
