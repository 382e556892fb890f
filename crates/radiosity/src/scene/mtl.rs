//! Wavefront MTL material libraries (design.md sections 6 and 7): `newmtl`
//! names a material, `Kd` is its reflectance (1 number for grey or 3 for
//! r g b, each channel in [0, 1)) and `Ke` its emitted radiant exitance in
//! W/m^2 (not negative). The statements of the format that carry nothing a
//! radiosity solve uses (specular terms, transparency, texture maps, ...)
//! are skipped without a word; any other statement is named in one warning
//! per file. Every problem is an error naming the file and line. The text
//! is read as [`super::text`] says; [`parse_mtl`] works from bytes, so the
//! fuzzers in `fuzz/` reach the same code as the command line.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use super::text::{decode, logical_lines, number, quoted};
use super::{Limits, Location, SceneError};

/// A material as read from an MTL file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// `Kd`: diffuse reflectance.
    pub rho: DVec3,
    /// `Ke`: emitted radiant exitance, W/m^2.
    pub emission: DVec3,
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

/// Parses MTL text into `materials` (a later `newmtl` of the same name
/// replaces the earlier one); warnings are appended to `warnings`.
pub(super) fn parse_mtl_into(
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
