//! The lightmap bake measured (beyond the paper; the bake of
//! [`radiosity::export::lightmap`]): for built-in scenes written by
//! `export-scene`, Blender exports and Sponza, a lit lightmap bake is
//! written and read back as a user's engine would read it, and checked:
//!
//! - the same meshes and primitives as the input (copies for meshes drawn
//!   twice come after), and how much seams split vertices;
//! - no overlapping charts: texel centres strictly inside two triangles of
//!   `TEXCOORD_1`;
//! - accuracy: at 300 points drawn uniformly by area over the input's
//!   triangles, the lightmap (the EXR copy, i.e. before 8-bit rounding,
//!   sampled bilinearly at the point's `TEXCOORD_1`, as a GPU samples) against
//!   the radiosity `B` the same solve gathers at the point as a sensor
//!   (`--sensors`); the bake holds `B` (exposure 1, no ambient term) under
//!   the default final pass (the direct light at each texel's point, the
//!   mesh's indirect part: [`radiosity::final_gather`]), so the two are
//!   directly comparable; beside it, the mesh's own value there;
//! - the bake's own time (layout, texels, encoding), beyond the solve.

use std::path::{Path, PathBuf};
use std::time::Duration;

use glam::DVec3;
use radiosity::app;
use radiosity::export::gltf::BakeMode;
use radiosity::export::lightmap::{self, AtlasSettings, LightmapBake, LightmapReport};
use radiosity::final_gather::{FinalGather, FinalPass, Point};
use radiosity::render::Shade;
use radiosity::scene::sky::Daylight;
use radiosity::scene::{self, LoadOptions};
use radiosity::sensors::{self, SensorPoint};
use radiosity::solver::{Preset, Settings, Solver};

use crate::validate::{solve_then, uniform};
use crate::{Context, Error, Report, table};

/// Points compared per scene.
pub const POINTS: usize = 300;

/// One scene to bake.
pub struct Case {
    /// Its name in the report.
    pub name: &'static str,
    /// The scene file.
    pub input: PathBuf,
    /// Lightmap texels per metre.
    pub density: f64,
    /// Solve time limit.
    pub time_limit: Option<Duration>,
}

/// A point drawn on a placed primitive of the input.
struct Sample {
    primitive: usize,
    triangle: usize,
    bary: [f64; 3],
    position: DVec3,
    normal: DVec3,
}

/// One scene's results.
pub struct Row {
    /// The case's name.
    pub name: &'static str,
    /// Triangles placed.
    pub triangles: usize,
    /// Whether the written file has the input's meshes with the same
    /// primitives.
    pub primitives_kept: bool,
    /// What the bake made.
    pub report: LightmapReport,
    /// Vertices written over vertices read, lightmapped primitives.
    pub split: f64,
    /// Texel centres strictly inside two `TEXCOORD_1` triangles.
    pub overlaps: usize,
    /// L1 of the lightmap against sensors.
    pub l1: f64,
    /// L1 of the element mesh's interpolation against sensors.
    pub mesh_l1: f64,
    /// Share of points within 3%.
    pub within: f64,
    /// Largest relative error of a point.
    pub worst: f64,
    /// Seconds of the solve.
    pub solve_seconds: f64,
}

/// `n` points uniform by area over the placed primitives' triangles.
fn sample(appearance: &scene::gltf::Appearance, n: usize) -> Vec<Sample> {
    let mut triangles = Vec::new();
    for (k, use_) in appearance.primitives.iter().enumerate() {
        let world = lightmap::atlas::world_points(use_);
        let flip = use_.world.determinant() < 0.0;
        for (t, tri) in use_.triangles.iter().enumerate() {
            let c = tri.map(|v| world[v as usize]);
            let cross = (c[1] - c[0]).cross(c[2] - c[0]);
            let area = 0.5 * cross.length();
            if area > 0.0 {
                let normal = if flip { -cross } else { cross }.normalize();
                triangles.push((k, t, c, normal, area));
            }
        }
    }
    let total: f64 = triangles.iter().map(|t| t.4).sum();
    let mut unit = uniform(0x0001_1687_43A9);
    (0..n)
        .map(|_| {
            let mut pick = unit() * total;
            let &(primitive, triangle, c, normal, _) = triangles
                .iter()
                .find(|t| {
                    pick -= t.4;
                    pick < 0.0
                })
                .unwrap_or_else(|| triangles.last().expect("a scene has triangles"));
            let (mut a, mut b) = (unit(), unit());
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            let bary = [1.0 - a - b, a, b];
            Sample {
                primitive,
                triangle,
                bary,
                position: c[0] * bary[0] + c[1] * bary[1] + c[2] * bary[2],
                normal,
            }
        })
        .collect()
}

/// A written primitive: `TEXCOORD_1`, triangle indices, and whether it
/// shows its back side.
type Written = (Vec<[f32; 2]>, Vec<u32>, bool);

/// The written document's lightmapped primitives in the loader's order
/// (default scene, nodes depth first): `TEXCOORD_1`, triangles, and whether
/// the back side is shown.
fn read_back(glb: &[u8]) -> Result<(Vec<usize>, Vec<Written>), String> {
    let gltf = gltf::Gltf::from_slice(glb).map_err(|e| e.to_string())?;
    let blob = gltf.blob.clone().ok_or("no binary chunk")?;
    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or("no scene")?;
    let mut out = Vec::new();
    let mut stack: Vec<gltf::Node<'_>> = scene
        .nodes()
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    while let Some(node) = stack.pop() {
        if let Some(mesh) = node.mesh() {
            for p in mesh.primitives() {
                let reader = p.reader(|_| Some(&blob));
                let Some(uv) = reader.read_tex_coords(1) else {
                    continue;
                };
                let uv: Vec<[f32; 2]> = uv.into_f32().collect();
                let indices: Vec<u32> = reader
                    .read_indices()
                    .map(|i| i.into_u32().collect())
                    .unwrap_or_else(|| (0..uv.len() as u32).collect());
                let back = p
                    .extras()
                    .as_ref()
                    .is_some_and(|raw| raw.get().contains("\"back\""));
                out.push((uv, indices, back));
            }
        }
        let children: Vec<_> = node.children().collect();
        stack.extend(children.into_iter().rev());
    }
    let primitives = gltf.meshes().map(|m| m.primitives().len()).collect();
    Ok((primitives, out))
}

/// Bilinear lookup at `uv` in a linear RGB image (glTF's convention: v down,
/// texel centres at half-integers), clamped at the edges as the sampler is.
fn bilinear(pixels: &[[f32; 3]], width: usize, height: usize, uv: [f64; 2]) -> DVec3 {
    let x = (uv[0] * width as f64 - 0.5).clamp(0.0, (width - 1) as f64);
    let y = (uv[1] * height as f64 - 0.5).clamp(0.0, (height - 1) as f64);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let at = |x: usize, y: usize| {
        let p = pixels[y * width + x];
        DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
    };
    (at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx) * (1.0 - fy)
        + (at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx) * fy
}

/// Texel centres strictly inside two or more `TEXCOORD_1` triangles.
fn overlapping_texels(primitives: &[Written], width: u32, height: u32) -> usize {
    let mut count = vec![0u8; width as usize * height as usize];
    for (uv, indices, _) in primitives {
        for t in indices.chunks_exact(3) {
            let c = [0, 1, 2].map(|k| {
                let p = uv[t[k] as usize];
                glam::DVec2::new(
                    f64::from(p[0]) * f64::from(width),
                    f64::from(p[1]) * f64::from(height),
                )
            });
            let area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
            if area.abs() < 1e-12 {
                continue;
            }
            let lo = c[0].min(c[1]).min(c[2]).floor().max(glam::DVec2::ZERO);
            let hi = c[0].max(c[1]).max(c[2]).ceil();
            for y in lo.y as u32..(hi.y as u32).min(height) {
                for x in lo.x as u32..(hi.x as u32).min(width) {
                    let p = glam::DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                    let w = [
                        (c[2] - c[1]).perp_dot(p - c[1]) / area,
                        (c[0] - c[2]).perp_dot(p - c[2]) / area,
                        (c[1] - c[0]).perp_dot(p - c[0]) / area,
                    ];
                    if w.iter().all(|&w| w > 1e-6) {
                        let slot = &mut count[(y * width + x) as usize];
                        *slot = slot.saturating_add(1);
                    }
                }
            }
        }
    }
    count.iter().filter(|&&c| c > 1).count()
}

/// Bakes and checks one scene.
///
/// # Errors
/// If it fails to load, solve, bake or read back.
pub fn measure(context: &Context, case: &Case) -> Result<Row, Error> {
    let failed = |what: &str, e: String| Error::Experiment(format!("{}: {what}: {e}", case.name));
    let name = case.input.to_string_lossy().into_owned();
    let loaded = scene::load_with(&name, &LoadOptions::default()).map_err(app::Error::from)?;
    let appearance = match loaded.appearance {
        Some(a) => a,
        None => lightmap::appearance_of_scene(&loaded.scene)
            .map_err(|e| failed("export", e.to_string()))?,
    };
    let samples = sample(&appearance, POINTS);
    // Both sides where the material is double-sided: the bake says which it shows.
    let mut points = Vec::new();
    for s in &samples {
        // Single-sided: the front twice, keeping two rows per sample.
        let back = if appearance.primitives[s.primitive].double_sided {
            -1.0
        } else {
            1.0
        };
        for side in [1.0, back] {
            points.push(SensorPoint {
                position: s.position,
                normal: side * s.normal,
                line: points.len() + 1,
            });
        }
    }
    let mut settings = Settings::adaptive();
    settings.time_limit = case.time_limit;
    let out = context.path(&format!("lightmap-{}.glb", case.name));
    // The bake under the default final pass (the direct light at each
    // texel), made while the solver is there.
    let bake_with = |solver: &Solver<'_>| {
        let pass = FinalPass::new(solver, FinalGather::of_preset(Preset::Adaptive));
        let values = pass.vertex_display(solver.radiosity(), DVec3::ZERO);
        let shade = |p: &[Point]| pass.shade(p);
        let bake = LightmapBake {
            scene: solver.scene(),
            mesh: solver.mesh(),
            appearance: &appearance,
            values: &values,
            shade: (pass.mode() != FinalGather::Off).then_some(&shade as Shade<'_>),
            mode: BakeMode::Lit,
            settings: AtlasSettings {
                density: case.density,
                ..AtlasSettings::default()
            },
            camera: radiosity::view::camera_or_framing(solver.scene()),
            aspect_ratio: 4.0 / 3.0,
            metadata: serde_json::json!({}),
        };
        lightmap::bake(&bake, &out)
    };
    let (solved, baked) = solve_then(
        &case.input,
        Daylight::default(),
        &settings,
        None,
        &points,
        bake_with,
    )?;
    let receivers = sensors::receivers(&solved.scene, &points, Path::new("lightmap points"))
        .map_err(app::Error::from)?;
    let exact: Vec<DVec3> = receivers
        .iter()
        .zip(&solved.sensor_irradiance)
        .map(|(r, e)| sensors::radiosity(&solved.scene, r, *e))
        .collect();
    let (files, report) = baked.map_err(|e| failed("bake", e.to_string()))?;
    for (path, bytes) in &files {
        crate::write_file(path, bytes)?;
    }
    let (primitives, written) =
        read_back(&files[0].1).map_err(|e| failed("reading the bake", e))?;
    let exr_path = &files.last().expect("the bake writes an EXR").0;
    let image = exr::prelude::read_first_rgba_layer_from_file(
        exr_path,
        |size, _| (size.0, size.1, vec![[0f32; 3]; size.0 * size.1]),
        |(w, _, pixels): &mut (usize, usize, Vec<[f32; 3]>),
         at,
         (r, g, b, _): (f32, f32, f32, f32)| {
            pixels[at.1 * *w + at.0] = [r, g, b];
        },
    )
    .map_err(|e| failed("reading the EXR", e.to_string()))?;
    let (width, height, pixels) = image.layer_data.channel_data.pixels;
    if written.len() != appearance.primitives.len() {
        return Err(failed(
            "reading the bake",
            format!(
                "{} lightmapped primitives, {} placed",
                written.len(),
                appearance.primitives.len()
            ),
        ));
    }
    let input_primitives: Vec<usize> = appearance
        .json
        .meshes
        .iter()
        .map(|m| m.primitives.len())
        .collect();
    let primitives_kept = primitives.get(..input_primitives.len()) == Some(&input_primitives[..]);
    let (lo, hi) = solved.scene.bounds();
    let locator = radiosity::mesh::locator::Locator::new(
        &solved.mesh,
        sensors::RELATIVE_TOLERANCE * (hi - lo).length(),
    );
    let mean = exact.iter().map(|b| b.element_sum()).sum::<f64>() / exact.len().max(1) as f64;
    let (mut difference, mut total, mut within, mut worst) = (0.0, 0.0, 0, 0.0f64);
    let mut mesh_difference = 0.0;
    for (i, s) in samples.iter().enumerate() {
        let (uv, indices, back) = &written[s.primitive];
        let corners = &indices[3 * s.triangle..3 * s.triangle + 3];
        let at = [0, 1].map(|k| {
            corners
                .iter()
                .zip(s.bary)
                .map(|(v, w)| f64::from(uv[*v as usize][k]) * w)
                .sum::<f64>()
        });
        let texel = bilinear(&pixels, width, height, at);
        let b = exact[2 * i + usize::from(*back)];
        let normal = if *back { -s.normal } else { s.normal };
        let on_mesh = locator
            .locate(s.position, normal)
            .map_or(DVec3::ZERO, |(v, w)| {
                v.iter()
                    .zip(w)
                    .map(|(v, w)| solved.radiosity[*v as usize] * w)
                    .sum()
            });
        mesh_difference += (on_mesh - b).abs().element_sum();
        let d = (texel - b).abs().element_sum();
        difference += d;
        total += b.element_sum();
        // Relative to the point's own value, or to a tenth of the mean for
        // points in deep shadow, where any relative error is large.
        let relative = d / b.element_sum().max(0.1 * mean).max(1e-300);
        worst = worst.max(relative);
        if std::env::var_os("LIGHTMAP_DEBUG").is_some() && relative > 0.2 {
            eprintln!(
                "{} point {i}: primitive {} triangle {} uv {at:?} texel {texel:.3} B {b:.3} mesh {on_mesh:.3} back {back} p {:.3}",
                case.name, s.primitive, s.triangle, s.position
            );
        }
        if relative <= 0.03 {
            within += 1;
        }
    }
    let input_vertices: usize = appearance
        .primitives
        .iter()
        .map(|p| {
            let mut used: Vec<u32> = p.triangles.iter().flatten().copied().collect();
            used.sort_unstable();
            used.dedup();
            used.len()
        })
        .sum();
    let output_vertices: usize = written.iter().map(|w| w.0.len()).sum();
    Ok(Row {
        name: case.name,
        triangles: appearance
            .primitives
            .iter()
            .map(|p| p.triangles.len())
            .sum(),
        primitives_kept,
        overlaps: overlapping_texels(&written, report.width, report.height),
        report,
        split: output_vertices as f64 / input_vertices.max(1) as f64,
        l1: difference / total.max(1e-300),
        mesh_l1: mesh_difference / total.max(1e-300),
        within: within as f64 / samples.len() as f64,
        worst,
        solve_seconds: solved.solve_seconds,
    })
}

/// The scenes: built-ins through `export-scene`, the Blender exports of the
/// tests, and (unless quick) Sponza at a minute of solving.
fn cases(context: &Context) -> Result<Vec<Case>, Error> {
    let mut cases = Vec::new();
    for name in ["cornell", "room"] {
        let scene = scene::load(name).map_err(app::Error::from)?;
        let path = context.path(&format!("{name}-export.glb"));
        let files = radiosity::export::gltf::export_scene(&scene, &path).map_err(|source| {
            Error::Output {
                path: path.clone(),
                source,
            }
        })?;
        for (path, bytes) in files {
            crate::write_file(&path, &bytes)?;
        }
        cases.push(Case {
            name,
            input: path,
            density: if name == "cornell" { 128.0 } else { 32.0 },
            time_limit: None,
        });
    }
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data");
    for (name, file) in [
        ("blender-cornell", "blender-cornell.glb"),
        ("blender-lights", "blender-lights.glb"),
    ] {
        cases.push(Case {
            name,
            input: data.join(file),
            density: 64.0,
            time_limit: None,
        });
    }
    if !context.quick {
        let scenes = context
            .scenes
            .clone()
            .unwrap_or_else(|| PathBuf::from("../shared/scenes"));
        let sponza = scenes.join("sponza_dabrovic/sponza_dabrovic.obj");
        if sponza.is_file() {
            cases.push(Case {
                name: "sponza",
                input: sponza,
                density: lightmap::DEFAULT_DENSITY,
                time_limit: Some(Duration::from_secs(60)),
            });
        }
    }
    Ok(cases)
}

/// Runs the lightmap measurements.
///
/// # Errors
/// If a scene fails to load, solve or bake.
pub fn lightmap(context: &Context) -> Result<Report, Error> {
    let mut rows = Vec::new();
    for case in cases(context)? {
        rows.push(measure(context, &case)?);
    }
    let mut report = Report::default();
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.name.to_string(),
                r.triangles.to_string(),
                format!("{} x {}", r.report.width, r.report.height),
                format!("{:.1}", r.report.density),
                if r.report.generated {
                    r.report.charts.to_string()
                } else {
                    "input's".into()
                },
                format!("{:.2}", r.split),
                if r.primitives_kept {
                    "yes".into()
                } else {
                    "NO".into()
                },
                r.overlaps.to_string(),
                format!("{:.2}%", 100.0 * r.l1),
                format!("{:.2}%", 100.0 * r.mesh_l1),
                format!("{:.0}%", 100.0 * r.within),
                format!("{:.1}%", 100.0 * r.worst),
                format!("{:.2}", r.report.layout_seconds),
                format!("{:.2}", r.report.texel_seconds),
                format!("{:.1}", r.solve_seconds),
            ]
        })
        .collect();
    report.body.push_str(&table(
        &[
            "scene",
            "triangles",
            "lightmap",
            "texels/m",
            "charts",
            "vertices out/in",
            "same primitives",
            "overlapping texels",
            "L1 vs sensors",
            "mesh L1 vs sensors",
            "points within 3%",
            "worst point",
            "layout s",
            "texels + files s",
            "solve s",
        ],
        &body,
    ));
    report.paragraph(&format!(
        "\nLit lightmap bakes holding B (exposure 1, no ambient term) under the default final \
         pass (the direct light evaluated at each texel's point plus the mesh's indirect part), \
         read back from the written .glb and its EXR (values before 8-bit rounding), sampled \
         bilinearly at the TEXCOORD_1 of {POINTS} points drawn uniformly by area over the \
         input's triangles, against B gathered at the same points as sensors in the same solve. \
         L1 = sum |lightmap - B| / sum B over points and channels. Overlapping texels: texel \
         centres strictly inside two TEXCOORD_1 triangles. Mesh L1: the element mesh itself, \
         interpolated at the same points as the picture and the vertex bake interpolate it \
         (what the texels held with --final-gather off). A point's relative error is taken \
         against its own B, or a tenth of the mean B for points darker than that. Built-in \
         scenes are baked from their export-scene .glb."
    ));
    report.files.extend(
        rows.iter()
            .map(|r| context.path(&format!("lightmap-{}.glb", r.name))),
    );
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The written bake of the built-in Cornell box, read back: the same
    /// primitives, no overlapping texels, and within 3% of the sensors.
    #[test]
    fn the_cornell_bake_matches_its_sensors() {
        let dir = tempfile::tempdir().unwrap();
        let context = Context {
            out: dir.path().to_path_buf(),
            quick: true,
            command: String::new(),
            scenes: None,
            embree_python: None,
            reference: None,
            device: radiosity_gpu::DeviceChoice::Cpu,
        };
        let case = cases(&context).unwrap().into_iter().next().unwrap();
        assert_eq!(case.name, "cornell");
        let row = measure(&context, &case).unwrap();
        assert!(row.primitives_kept);
        assert_eq!(row.overlaps, 0);
        assert!(row.l1 <= 0.03, "L1 against sensors {}", row.l1);
        // The lightmap adds little to the mesh's own interpolation error.
        assert!(
            row.l1 <= row.mesh_l1 + 0.005,
            "{} against the mesh's {}",
            row.l1,
            row.mesh_l1
        );
    }
}
