//! Wavefront MTL material libraries (design.md sections 6 and 7): `newmtl`
//! names a material, `Kd` is its reflectance (1 number for grey or 3 for
//! r g b, each channel in [0, 1)) and `Ke` its emitted radiant exitance in
//! W/m^2 (not negative); dissolve `d` (or `Tr`, its complement) below 1
//! makes the material glass of transmittance `(1 - d) Tf`
//! ([`super::glass`]; `Tf`, 1 or 3 numbers, white when absent; each value
//! in [0, 1]). The statements of the format that carry nothing a radiosity
//! solve uses (specular terms, texture maps, ...) are skipped without a
//! word; any other statement is named in one warning
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
    /// Glass: the fraction of light let through, `(1 - d) Tf`; zero for an
    /// opaque material ([`crate::scene::glass`]).
    pub transmittance: DVec3,
}

/// MTL statements that carry nothing a radiosity solve uses: skipped
/// without a word. Anything else unknown is named in a warning.
const MTL_SKIPPED: [&str; 18] = [
    "Ka",
    "Ks",
    "Ns",
    "Ni",
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
    // Each material's dissolve and transmission filter as read so far.
    let mut glass: HashMap<String, (f64, DVec3)> = HashMap::new();
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
                        transmittance: DVec3::ZERO,
                    },
                );
                glass.insert(name.clone(), (1.0, DVec3::ONE));
                current = Some(name);
            }
            "Kd" | "Ke" => {
                let Some(name) = &current else {
                    return Err(error(line_no, format!("'{keyword}' before any 'newmtl'")));
                };
                if let Some(refused) = spectral(keyword, &args) {
                    return Err(error(line_no, refused));
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
                let rgb = rgb(&args).map_err(|m| error(line_no, m))?;
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
            "d" | "Tr" | "Tf" => {
                let Some(name) = &current else {
                    return Err(error(line_no, format!("'{keyword}' before any 'newmtl'")));
                };
                // `d -halo F`: the halo form dissolves by angle; taken as F.
                let values: Vec<&str> = args.iter().copied().filter(|a| *a != "-halo").collect();
                if let Some(refused) = spectral(keyword, &values) {
                    return Err(error(line_no, refused));
                }
                let wanted = if keyword == "Tf" { [1, 3] } else { [1, 1] };
                if !wanted.contains(&values.len()) {
                    return Err(error(
                        line_no,
                        format!(
                            "'{keyword}' takes {}, found {} numbers",
                            if keyword == "Tf" {
                                "1 number (grey) or 3 (r g b)"
                            } else {
                                "1 number"
                            },
                            values.len()
                        ),
                    ));
                }
                let rgb = rgb(&values).map_err(|m| error(line_no, m))?;
                if rgb.iter().any(|v| !(0.0..=1.0).contains(v)) {
                    return Err(error(
                        line_no,
                        format!(
                            "'{keyword}' of material {} must be from 0 to 1, not {}",
                            quoted(name),
                            values.join(" ")
                        ),
                    ));
                }
                let entry = glass.entry(name.clone()).or_insert((1.0, DVec3::ONE));
                match keyword {
                    "d" => entry.0 = rgb[0],
                    "Tr" => entry.0 = 1.0 - rgb[0],
                    _ => entry.1 = DVec3::from_array(rgb),
                }
                let (dissolve, filter) = *entry;
                if let Some(material) = materials.get_mut(name) {
                    material.transmittance = if dissolve < 1.0 {
                        filter * (1.0 - dissolve)
                    } else {
                        DVec3::ZERO
                    };
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

/// The refusal of a colour statement given as a spectrum or in XYZ.
fn spectral(keyword: &str, args: &[&str]) -> Option<String> {
    args.first()
        .filter(|a| **a == "spectral" || **a == "xyz")
        .map(|a| format!("'{keyword} {a}' is not supported: give r g b"))
}

/// Three numbers from one (grey) or three (r g b), the count checked by
/// the caller.
fn rgb(args: &[&str]) -> Result<[f64; 3], String> {
    let mut rgb = [0.0; 3];
    for (i, slot) in rgb.iter_mut().enumerate() {
        *slot = number(args.get(i).unwrap_or(&args[0]))?;
    }
    Ok(rgb)
}
