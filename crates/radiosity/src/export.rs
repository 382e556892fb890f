//! Results out (design.md section 6): the picture as PNG (tone-mapped sRGB),
//! PFM or OpenEXR (linear radiosity), the per-vertex radiosities and the
//! values at sensor points as CSV, the run's counters as JSON, the element
//! mesh with its colours as binary PLY, and glTF 2.0 ([`gltf`]: baked
//! meshes and exported scenes).
//!
//! Every file is written to a temporary name beside its destination and
//! renamed only once all of a run's outputs are complete, so a failed run
//! leaves no half-written file behind. A destination that is a symbolic
//! link is written through: the link's target is replaced, the link stays.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::mesh::Mesh;
use crate::render::{self, Image};
use crate::scene::Scene;

pub mod gltf;
pub mod lightmap;

/// A file being written under a temporary name; [`Staged::commit`] moves it
/// into place, dropping it uncommitted deletes it.
pub struct Staged {
    temporary: PathBuf,
    destination: PathBuf,
    committed: bool,
}

impl Staged {
    /// Writes `contents` through `write` to a temporary file beside `path`
    /// (beside the file it links to, if it is a symbolic link).
    pub fn write(
        path: &Path,
        write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
    ) -> io::Result<Staged> {
        let target = resolve_links(path)?;
        let staged = Staged {
            temporary: temporary_beside(&target, "tmp")?,
            destination: target,
            committed: false,
        };
        let mut writer = BufWriter::new(File::create(&staged.temporary)?);
        write(&mut writer)?;
        writer
            .into_inner()
            .map_err(|e| e.into_error())?
            .sync_all()?;
        Ok(staged)
    }

    /// Renames the temporary file to its destination.
    pub fn commit(mut self) -> io::Result<()> {
        std::fs::rename(&self.temporary, &self.destination)?;
        self.committed = true;
        Ok(())
    }

    /// Where the file will end up.
    #[must_use]
    pub fn destination(&self) -> &Path {
        &self.destination
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.temporary);
        }
    }
}

/// Most symbolic links followed from one output path, as the kernel's
/// own limit (`ELOOP`).
const MAX_LINKS: usize = 40;

/// The file a path finally names: symbolic links followed (also a dangling
/// one, whose target is then created), other paths unchanged.
pub fn resolve_links(path: &Path) -> io::Result<PathBuf> {
    let mut current = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        match std::fs::symlink_metadata(&current) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = std::fs::read_link(&current)?;
                current = match current.parent() {
                    Some(folder) if target.is_relative() => folder.join(target),
                    _ => target,
                };
            }
            _ => return Ok(current),
        }
    }
    Err(io::Error::other(format!(
        "more than {MAX_LINKS} symbolic links in a chain"
    )))
}

/// A hidden name beside `path` unique to this process:
/// `.NAME.PID.SUFFIX`.
fn temporary_beside(path: &Path, suffix: &str) -> io::Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
    let mut temporary_name = std::ffi::OsString::from(".");
    temporary_name.push(name);
    temporary_name.push(format!(".{}.{suffix}", std::process::id()));
    Ok(path.with_file_name(temporary_name))
}

/// Checks that `path` can be written before any work is done: creates and
/// removes a file beside it (beside its target, for a symbolic link), so a
/// read-only, missing or non-folder parent is reported at once rather than
/// after the solve.
pub fn probe_writable(path: &Path) -> io::Result<()> {
    let target = resolve_links(path)?;
    if target.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "this is a folder: give a file name",
        ));
    }
    let probe = temporary_beside(&target, "probe")?;
    File::options().write(true).create_new(true).open(&probe)?;
    std::fs::remove_file(&probe)
}

/// Writes 8-bit sRGB pixels as PNG.
pub fn write_png(out: &mut impl Write, width: u32, height: u32, rgb: &[u8]) -> io::Result<()> {
    let mut encoder = png::Encoder::new(out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    // Rendered pictures compress well even at the fast setting, which
    // takes a fraction of the default's time.
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().map_err(io::Error::other)?;
    writer.write_image_data(rgb).map_err(io::Error::other)?;
    writer.finish().map_err(io::Error::other)
}

/// Writes the linear picture as a Portable Float Map (little-endian RGB
/// floats, bottom row first), readable by most HDR tools.
pub fn write_pfm(out: &mut impl Write, image: &Image) -> io::Result<()> {
    write!(out, "PF\n{} {}\n-1.0\n", image.width, image.height)?;
    for row in image.pixels.chunks(image.width as usize).rev() {
        for p in row {
            for c in p.to_array() {
                out.write_all(&c.to_le_bytes())?;
            }
        }
    }
    Ok(())
}

/// The CSV header of `--vertices`.
pub const VERTEX_CSV_HEADER: &str = "x,y,z,nx,ny,nz,surface,r,g,b";

/// Writes one row per vertex: position, unit normal, surface id (input face
/// order) and radiosity `B`.
pub fn write_vertices_csv(
    out: &mut impl Write,
    scene: &Scene,
    mesh: &Mesh,
    radiosity: &[DVec3],
) -> io::Result<()> {
    writeln!(out, "{VERTEX_CSV_HEADER}")?;
    for (v, b) in mesh.vertices.iter().zip(radiosity) {
        let (p, n) = (v.position, v.normal);
        let face = scene.surfaces[v.surface as usize].face;
        writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{}",
            p.x, p.y, p.z, n.x, n.y, n.z, face, b.x, b.y, b.z
        )?;
    }
    Ok(())
}

/// The CSV header of `--sensors-out`.
pub const SENSOR_CSV_HEADER: &str = "x,y,z,nx,ny,nz,er,eg,eb,br,bg,bb,lux";

/// The last column `--sensors-out` gains under an overcast sky alone.
pub const DAYLIGHT_FACTOR_COLUMN: &str = "daylight_factor";

/// Writes one row per sensor point, in input order: the position and unit
/// normal as given, the irradiance `E` (W/m^2), the radiosity `B = Ke + Kd
/// E` of the surface the point lies on (W/m^2) and the illuminance in lux
/// as Radiance computes it ([`crate::photometry::lux`]). Like the vertex CSV,
/// `E` and `B` hold the light shot so far (no ambient term). With
/// `daylight` (the overcast sky's unobstructed horizontal illuminance, lux),
/// a last column [`DAYLIGHT_FACTOR_COLUMN`]: the illuminance as a
/// percentage of it.
pub fn write_sensors_csv(
    out: &mut impl Write,
    scene: &Scene,
    points: &[crate::sensors::SensorPoint],
    receivers: &[crate::solver::Receiver],
    irradiance: &[DVec3],
    daylight: Option<f64>,
) -> io::Result<()> {
    match daylight {
        Some(_) => writeln!(out, "{SENSOR_CSV_HEADER},{DAYLIGHT_FACTOR_COLUMN}")?,
        None => writeln!(out, "{SENSOR_CSV_HEADER}")?,
    }
    for ((point, receiver), e) in points.iter().zip(receivers).zip(irradiance) {
        let (p, n) = (point.position, point.normal);
        let b = crate::sensors::radiosity(scene, receiver, *e);
        write!(
            out,
            "{},{},{},{},{},{},{},{},{},{},{},{},{}",
            p.x,
            p.y,
            p.z,
            n.x,
            n.y,
            n.z,
            e.x,
            e.y,
            e.z,
            b.x,
            b.y,
            b.z,
            crate::photometry::lux(*e)
        )?;
        match daylight {
            Some(horizontal) => {
                writeln!(out, ",{}", 100.0 * crate::photometry::lux(*e) / horizontal)?
            }
            None => writeln!(out)?,
        }
    }
    Ok(())
}

/// Writes the linear picture as OpenEXR (32-bit float RGB, radiosity in
/// W/m^2 per pixel, top row first).
pub fn write_exr(out: &mut (impl Write + io::Seek), image: &Image) -> io::Result<()> {
    use exr::prelude::{
        Encoding, Image as ExrImage, LineOrder, SpecificChannels, Vec2, WritableImage,
    };
    let width = image.width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = image.pixels[y * width + x];
        (p.x, p.y, p.z)
    });
    // Tiles in increasing order: the same bytes on every run.
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::FAST_LOSSLESS
    };
    ExrImage::from_encoded_channels((width, image.height as usize), encoding, channels)
        .write()
        .to_buffered(out)
        .map_err(io::Error::other)
}

/// Writes the element mesh as binary little-endian PLY for MeshLab and
/// CloudCompare: per vertex its position, unit normal, the 8-bit sRGB colour
/// the picture shows (`display` times `exposure`, through the picture's
/// sRGB curve) and the linear radiosity `B` (W/m^2, ambient excluded) as
/// float properties `radiosity_r/g/b`; faces are the mesh's conforming triangles ([`Mesh::triangles`]: no
/// T-vertices).
pub fn write_ply(
    out: &mut impl Write,
    mesh: &Mesh,
    display: &[DVec3],
    exposure: f64,
    radiosity: &[DVec3],
) -> io::Result<()> {
    let triangles = mesh.triangles();
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment radiosity {}: colours are the picture's \
         sRGB, radiosity_* is B in W/m^2\nelement vertex {}\nproperty float x\nproperty float \
         y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float \
         radiosity_r\nproperty float radiosity_g\nproperty float radiosity_b\nelement face \
         {}\nproperty list uchar uint vertex_indices\nend_header\n",
        env!("CARGO_PKG_VERSION"),
        mesh.vertices.len(),
        triangles.len()
    )?;
    for ((v, d), b) in mesh.vertices.iter().zip(display).zip(radiosity) {
        let n = v.normal.normalize_or_zero();
        for c in [v.position.x, v.position.y, v.position.z, n.x, n.y, n.z] {
            out.write_all(&(c as f32).to_le_bytes())?;
        }
        let shown = *d * exposure;
        out.write_all(&[
            render::srgb8(shown.x as f32),
            render::srgb8(shown.y as f32),
            render::srgb8(shown.z as f32),
        ])?;
        for c in [b.x, b.y, b.z] {
            out.write_all(&(c as f32).to_le_bytes())?;
        }
    }
    for t in &triangles {
        out.write_all(&[3])?;
        for v in t.corners {
            out.write_all(&v.to_le_bytes())?;
        }
    }
    Ok(())
}
