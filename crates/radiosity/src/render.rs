//! Pictures: the element mesh drawn with Gouraud shading of the vertex
//! radiosities (plus the display-only ambient term of design.md section 2),
//! as the paper's Figure 5.1 was shown on a workstation.
//!
//! A software rasteriser: near-plane clipping, back-face culling (surfaces
//! are single-sided), a depth buffer, perspective-correct interpolation,
//! supersampling for anti-aliasing, then exposure and sRGB tone mapping.
//! Rows are rasterised in parallel bands.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::final_gather::Point;
use crate::geometry::clip;
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::{Camera, Scene};

/// How to draw a picture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The view.
    pub camera: Camera,
    /// Supersampling factor per axis (`s x s` samples a pixel).
    pub supersampling: u32,
}

/// Largest accepted picture side, in pixels.
pub const MAX_SIDE: u32 = 16_384;

/// A linear-light RGB picture (radiosity units, W/m^2).
#[derive(Clone, Debug)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels, top row first.
    pub pixels: Vec<Vec3>,
    /// Fraction of each pixel's samples that hit a surface.
    pub coverage: Vec<f32>,
}

/// Colour of pixels that see no surface.
const BACKGROUND: Vec3 = Vec3::ZERO;

/// A triangle after projection: screen x, y and 1/depth per corner, and the
/// colour divided by depth (for perspective-correct interpolation); its
/// corners in the world and its surface, for the final pass.
#[derive(Clone, Copy, Debug)]
struct ScreenTriangle {
    x: [f32; 3],
    y: [f32; 3],
    inv_z: [f32; 3],
    colour_over_z: [Vec3; 3],
    min_y: f32,
    max_y: f32,
    world: [DVec3; 3],
    surface: u32,
}

/// What the final pass adds at each sample ([`render_shaded`]): given the
/// samples' surface points, the radiosity to add to what the mesh shows
/// there (W/m^2 per channel).
pub type Shade<'s> = &'s (dyn Fn(&[Point]) -> Vec<DVec3> + Sync);

/// A sample's surface point, as the rasteriser found it.
#[derive(Clone, Copy, Debug)]
struct Found {
    triangle: u32,
    /// Perspective-correct barycentric weights of corners 1 and 2.
    weights: [f32; 2],
}

/// Camera basis and projection scale.
struct View {
    eye: DVec3,
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    near: f64,
    /// Pixels per unit of x/z.
    scale: f64,
    centre_x: f64,
    centre_y: f64,
}

impl View {
    fn new(camera: &Camera, width: u32, height: u32, near: f64) -> View {
        let forward = (camera.target - camera.eye).normalize();
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        let tan_half = (0.5 * camera.fov_degrees.to_radians()).tan();
        View {
            eye: camera.eye,
            right,
            up,
            forward,
            near,
            scale: 0.5 * f64::from(height) / tan_half,
            centre_x: 0.5 * f64::from(width),
            centre_y: 0.5 * f64::from(height),
        }
    }

    /// Camera-space coordinates: (right, up, depth).
    fn to_camera(&self, p: DVec3) -> DVec3 {
        let d = p - self.eye;
        DVec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.forward))
    }

    /// World coordinates of a camera-space point.
    fn to_world(&self, c: DVec3) -> DVec3 {
        self.eye + self.right * c.x + self.up * c.y + self.forward * c.z
    }
}

/// Draws the mesh with the given per-vertex display radiosities.
#[must_use]
pub fn render(scene: &Scene, mesh: &Mesh, colours: &[DVec3], settings: &RenderSettings) -> Image {
    render_shaded(scene, mesh, colours, settings, None)
}

/// [`render`], adding at every sample what `shade` gives at its surface
/// point ([`crate::final_gather`]): the `k`-th of a pixel's `s x s`
/// samples is `Point::sample = Some((k, s^2))`, seeded by its pixel's
/// index.
#[must_use]
pub fn render_shaded(
    scene: &Scene,
    mesh: &Mesh,
    colours: &[DVec3],
    settings: &RenderSettings,
    shade: Option<Shade<'_>>,
) -> Image {
    render_planned(scene, mesh, colours, settings, shade, &|_| {})
}

/// [`render_shaded`], telling `planned` how many samples `shade` will be
/// given in all once every band is rasterised and before any is shaded
/// (for a progress display: the samples that see a surface).
#[must_use]
pub fn render_planned(
    scene: &Scene,
    mesh: &Mesh,
    colours: &[DVec3],
    settings: &RenderSettings,
    shade: Option<Shade<'_>>,
    planned: &(dyn Fn(u64) + Sync),
) -> Image {
    let s = settings.supersampling.max(1);
    let (w, h) = (settings.width * s, settings.height * s);
    let (lo, hi) = scene.bounds();
    let near = 1e-4 * (hi - lo).length().max(1e-9);
    let view = View::new(&settings.camera, w, h, near);
    let triangles = project(scene, mesh, colours, &view);

    // Whole pixels a band (16 rows or the next multiple of the
    // supersampling), so a pixel's samples are shaded together.
    let band_rows = 16usize.next_multiple_of(s as usize);
    let mut samples = vec![BACKGROUND; (w * h) as usize];
    let mut hits = vec![false; (w * h) as usize];
    // Every band rasterised first (the samples' surface points kept when
    // they are to be shaded), then shaded.
    let found: Vec<Vec<Found>> = samples
        .par_chunks_mut(band_rows * w as usize)
        .zip(hits.par_chunks_mut(band_rows * w as usize))
        .enumerate()
        .map(|(band, (colour_rows, hit_rows))| {
            let y0 = band * band_rows;
            let rows = colour_rows.len() / w as usize;
            let mut depth = vec![0.0f32; colour_rows.len()];
            let mut found = vec![
                Found {
                    triangle: 0,
                    weights: [0.0; 2],
                };
                if shade.is_some() {
                    colour_rows.len()
                } else {
                    0
                }
            ];
            for (i, t) in triangles.iter().enumerate() {
                if t.max_y < y0 as f32 || t.min_y > (y0 + rows) as f32 {
                    continue;
                }
                let mut target = Target {
                    colour: colour_rows,
                    hit: hit_rows,
                    depth: &mut depth,
                    found: &mut found,
                    triangle: i as u32,
                };
                rasterise(t, w, y0, rows, &mut target);
            }
            found
        })
        .collect();
    if let Some(shade) = shade {
        planned(hits.iter().filter(|h| **h).count() as u64);
        samples
            .par_chunks_mut(band_rows * w as usize)
            .zip(hits.par_chunks(band_rows * w as usize))
            .zip(&found)
            .enumerate()
            .for_each(|(band, ((colour_rows, hit_rows), found))| {
                shade_band(
                    shade,
                    &triangles,
                    found,
                    hit_rows,
                    colour_rows,
                    (band * band_rows, w as usize, s as usize),
                    settings.width as usize,
                );
            });
    }
    downsample(&samples, &hits, settings.width, settings.height, s)
}

/// Projects the mesh's conforming triangles ([`Mesh::triangles`]), culling
/// back faces and clipping at the near plane.
fn project(scene: &Scene, mesh: &Mesh, colours: &[DVec3], view: &View) -> Vec<ScreenTriangle> {
    let mut out = Vec::with_capacity(mesh.elements.len() * 2);
    let mut polygon: Vec<(DVec3, DVec3)> = Vec::with_capacity(8);
    let mut clipped: Vec<(DVec3, DVec3)> = Vec::with_capacity(8);
    for triangle in mesh.triangles() {
        let element = &mesh.elements[triangle.element as usize];
        let surface = &scene.surfaces[element.surface as usize];
        if surface.normal.dot(view.eye) - surface.offset <= 0.0 {
            continue;
        }
        polygon.clear();
        for c in triangle.corners {
            polygon.push((
                view.to_camera(mesh.vertices[c as usize].position),
                colours[c as usize],
            ));
        }
        clip::clip_into(&polygon, |(p, _)| p.z - view.near, &mut clipped);
        if clipped.len() < 3 {
            continue;
        }
        let screen: Vec<(f64, f64, f64, DVec3)> = clipped
            .iter()
            .map(|(p, c)| {
                let inv_z = 1.0 / p.z;
                (
                    view.centre_x + view.scale * p.x * inv_z,
                    view.centre_y - view.scale * p.y * inv_z,
                    inv_z,
                    *c * inv_z,
                )
            })
            .collect();
        for i in 1..screen.len() - 1 {
            let tri = [screen[0], screen[i], screen[i + 1]];
            let ys = tri.map(|v| v.1 as f32);
            let corner = [clipped[0].0, clipped[i].0, clipped[i + 1].0];
            out.push(ScreenTriangle {
                x: tri.map(|v| v.0 as f32),
                y: ys,
                inv_z: tri.map(|v| v.2 as f32),
                colour_over_z: tri.map(|v| v.3.as_vec3()),
                min_y: ys[0].min(ys[1]).min(ys[2]),
                max_y: ys[0].max(ys[1]).max(ys[2]),
                world: corner.map(|c| view.to_world(c)),
                surface: element.surface,
            });
        }
    }
    out
}

/// A band's buffers, and the index of the triangle being drawn.
struct Target<'b> {
    colour: &'b mut [Vec3],
    hit: &'b mut [bool],
    depth: &'b mut [f32],
    /// Empty unless the final pass needs each sample's surface point.
    found: &'b mut [Found],
    triangle: u32,
}

/// The final pass over one band: each covered sample's surface point (its
/// triangle's corners weighted, in f64, clamped inside the triangle), then
/// `shade` for all of them at once.
fn shade_band(
    shade: Shade<'_>,
    triangles: &[ScreenTriangle],
    found: &[Found],
    hit: &[bool],
    colour: &mut [Vec3],
    (y0, w, s): (usize, usize, usize),
    width: usize,
) {
    let mut points = Vec::new();
    let mut at = Vec::new();
    for (i, (f, hit)) in found.iter().zip(hit).enumerate() {
        if !hit {
            continue;
        }
        let t = &triangles[f.triangle as usize];
        let (row, column) = (y0 + i / w, i % w);
        let [b1, b2] = f.weights.map(|x| f64::from(x).clamp(0.0, 1.0));
        let total = (b1 + b2).max(1.0);
        let (b1, b2) = (b1 / total, b2 / total);
        let position = t.world[0] + (t.world[1] - t.world[0]) * b1 + (t.world[2] - t.world[0]) * b2;
        let pixel = (row / s) * width + column / s;
        points.push(Point {
            surface: t.surface,
            position,
            sample: Some((((row % s) * s + column % s) as u32, (s * s) as u32)),
            seed: pixel as u64,
        });
        at.push(i);
    }
    if points.is_empty() {
        return;
    }
    // A pixel's samples one after another, in their order.
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by_key(|&i| (points[i].seed, points[i].sample.map_or(0, |(k, _)| k)));
    let points: Vec<Point> = order.iter().map(|&i| points[i]).collect();
    let at: Vec<usize> = order.iter().map(|&i| at[i]).collect();
    for (i, added) in at.into_iter().zip(shade(&points)) {
        colour[i] += added.as_vec3();
    }
}

/// Rasterises one triangle into a band of rows starting at `y0`, with the
/// top-left fill rule so shared edges are drawn once.
fn rasterise(t: &ScreenTriangle, width: u32, y0: usize, rows: usize, target: &mut Target<'_>) {
    let (x, y) = (t.x, t.y);
    let area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    // Orient counter-clockwise in screen space (y down) for edge tests.
    let (order, area) = if area > 0.0 {
        ([0usize, 1, 2], area)
    } else {
        ([0usize, 2, 1], -area)
    };
    let px = order.map(|i| x[i]);
    let py = order.map(|i| y[i]);
    let inv_z = order.map(|i| t.inv_z[i]);
    let col = order.map(|i| t.colour_over_z[i]);
    let min_x = px[0].min(px[1]).min(px[2]).floor().max(0.0) as usize;
    let max_x = (px[0].max(px[1]).max(px[2]).ceil() as usize).min(width as usize);
    let band_min = (t.min_y.floor().max(y0 as f32) as usize).max(y0);
    let band_max = (t.max_y.ceil() as usize).min(y0 + rows);
    // Edge k runs from corner k+1 to corner k+2; its function is positive
    // inside.
    let edge = |k: usize, sx: f32, sy: f32| {
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        (px[b] - px[a]) * (sy - py[a]) - (py[b] - py[a]) * (sx - px[a])
    };
    let top_left: [bool; 3] = std::array::from_fn(|k| {
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        let (dx, dy) = (px[b] - px[a], py[b] - py[a]);
        (dy == 0.0 && dx > 0.0) || dy < 0.0
    });
    for row in band_min..band_max {
        let sy = row as f32 + 0.5;
        let line = (row - y0) * width as usize;
        for column in min_x..max_x {
            let sx = column as f32 + 0.5;
            let w = [edge(0, sx, sy), edge(1, sx, sy), edge(2, sx, sy)];
            let inside = (0..3).all(|k| w[k] > 0.0 || (w[k] == 0.0 && top_left[k]));
            if !inside {
                continue;
            }
            let b = [w[0] / area, w[1] / area, w[2] / area];
            let iz = b[0] * inv_z[0] + b[1] * inv_z[1] + b[2] * inv_z[2];
            let index = line + column;
            if iz <= target.depth[index] {
                continue;
            }
            target.depth[index] = iz;
            target.colour[index] = (col[0] * b[0] + col[1] * b[1] + col[2] * b[2]) / iz;
            target.hit[index] = true;
            if let Some(f) = target.found.get_mut(index) {
                // Perspective-correct weights of the original corners 1
                // and 2 (the order was permuted above).
                let mut weight = [0.0f32; 3];
                for k in 0..3 {
                    weight[order[k]] = b[k] * inv_z[k] / iz;
                }
                *f = Found {
                    triangle: target.triangle,
                    weights: [weight[1], weight[2]],
                };
            }
        }
    }
}

/// Box-filters `s x s` samples into each pixel.
fn downsample(samples: &[Vec3], hits: &[bool], width: u32, height: u32, s: u32) -> Image {
    let (w, s_us) = (width as usize, s as usize);
    let big_w = w * s_us;
    let weight = 1.0 / (s * s) as f32;
    let mut pixels = vec![Vec3::ZERO; w * height as usize];
    let mut coverage = vec![0.0f32; w * height as usize];
    pixels
        .par_chunks_mut(w)
        .zip(coverage.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (row, cov))| {
            for (x, (p, c)) in row.iter_mut().zip(cov.iter_mut()).enumerate() {
                let mut sum = Vec3::ZERO;
                let mut count = 0u32;
                for sy in 0..s_us {
                    let base = (y * s_us + sy) * big_w + x * s_us;
                    for sx in 0..s_us {
                        sum += samples[base + sx];
                        count += u32::from(hits[base + sx]);
                    }
                }
                *p = sum * weight;
                *c = count as f32 * weight;
            }
        });
    Image {
        width,
        height,
        pixels,
        coverage,
    }
}

/// How bright the picture is made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    /// Scale so the 90th percentile of the luminance of covered pixels
    /// maps to 0.8, then apply `ev` stops more.
    Auto {
        /// Extra stops.
        ev: f64,
    },
    /// Multiply radiosity by this factor.
    Scale(f64),
}

impl Image {
    /// The linear scale factor an exposure setting gives for this picture.
    #[must_use]
    pub fn exposure_scale(&self, exposure: Exposure) -> f64 {
        match exposure {
            Exposure::Scale(s) => s,
            Exposure::Auto { ev } => {
                let mut lums: Vec<f64> = self
                    .pixels
                    .iter()
                    .zip(&self.coverage)
                    .filter(|(_, c)| **c > 0.5)
                    .map(|(p, _)| luminance(p.as_dvec3()))
                    .filter(|l| *l > 0.0)
                    .collect();
                if lums.is_empty() {
                    return 2f64.powf(ev);
                }
                let k = ((lums.len() - 1) as f64 * 0.9) as usize;
                let (_, p90, _) = lums.select_nth_unstable_by(k, f64::total_cmp);
                0.8 / *p90 * 2f64.powf(ev)
            }
        }
    }

    /// 8-bit sRGB pixels (RGB, row-major): exposure, clamp, sRGB curve.
    #[must_use]
    pub fn to_srgb8(&self, scale: f64) -> Vec<u8> {
        let scale = scale as f32;
        self.pixels
            .iter()
            .flat_map(|p| {
                let v = *p * scale;
                [srgb8(v.x), srgb8(v.y), srgb8(v.z)]
            })
            .collect()
    }
}

/// The sRGB transfer curve, quantised to 8 bits (the pictures' mapping,
/// shared with the PLY colours).
#[must_use]
pub fn srgb8(linear: f32) -> u8 {
    let v = linear.clamp(0.0, 1.0);
    let encoded = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (encoded * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSettings;
    use crate::scene::Surface;

    #[test]
    fn srgb_curve_end_points() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(2.0), 255);
        // sRGB 128/255 = 0.50196 decodes to linear 0.21586.
        assert_eq!(srgb8(0.215_86), 128);
        assert_eq!(srgb8(0.2), 124);
    }

    /// A square filling the middle of the view renders with its colour and
    /// covers the expected fraction of the picture; seen from behind it is
    /// culled.
    #[test]
    fn square_coverage_and_culling() {
        let square = vec![
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ];
        let scene = Scene {
            name: "t".into(),
            surfaces: vec![Surface::new(square, DVec3::splat(0.5), DVec3::ONE, 0).unwrap()],
            lights: Vec::new(),
            panes: Vec::new(),
            portals: Vec::new(),
            camera: None,
            mesh_hint: None,
            warnings: Vec::new(),
        };
        let mesh = Mesh::build(&scene, &MeshSettings::default()).unwrap();
        let colours = vec![DVec3::new(0.25, 0.5, 0.75); mesh.vertices.len()];
        // fov 90 at distance 2: the view spans [-2, 2], the square [-1, 1].
        let camera = Camera {
            eye: DVec3::new(0.0, 0.0, 2.0),
            target: DVec3::ZERO,
            up: DVec3::Y,
            fov_degrees: 90.0,
        };
        let settings = RenderSettings {
            width: 64,
            height: 64,
            camera,
            supersampling: 2,
        };
        let image = render(&scene, &mesh, &colours, &settings);
        let covered: f32 = image.coverage.iter().sum::<f32>() / (64.0 * 64.0);
        assert!((covered - 0.25).abs() < 0.01, "{covered}");
        let centre = image.pixels[32 * 64 + 32];
        assert!((centre - Vec3::new(0.25, 0.5, 0.75)).length() < 1e-5);
        let behind = RenderSettings {
            camera: Camera {
                eye: DVec3::new(0.0, 0.0, -2.0),
                ..camera
            },
            ..settings
        };
        let image = render(&scene, &mesh, &colours, &behind);
        assert_eq!(image.coverage.iter().sum::<f32>(), 0.0);
    }
}
