//! The error pictures of `radiosity experiment validate` (beyond the
//! paper): the relative error `B / Bref - 1` at every sampled point the
//! scene's camera sees, drawn as a dot on the rasterised solution in grey
//! (blue too dark, red too bright), and panels put side by side with a
//! colour bar.

use glam::DVec3;

use plotters::prelude::{Circle, Color, RGBColor};

use super::Error;
use super::plot::{self, BLACK, ColourMap, GREY, Picture, Scale};
use radiosity::accel::{self, Accel};
use radiosity::mesh::Mesh;
use radiosity::render::{self, Exposure, RenderSettings};
use radiosity::scene::{Camera, Scene};

/// The colour bar of the error pictures spans this relative error either
/// way; larger errors take the end colours.
pub const ERROR_RANGE: f64 = 0.2;

/// A point of an error picture.
#[derive(Clone, Copy, Debug)]
pub struct ErrorPoint {
    /// Where (on its surface).
    pub position: DVec3,
    /// Its surface's normal.
    pub normal: DVec3,
    /// Its surface id, which cannot hide it.
    pub group: u32,
    /// `B / Bref - 1`; `None` for points left out of the median (too dark,
    /// or no reference), drawn grey.
    pub relative: Option<f64>,
}

/// Draws `points` as dots on the solution, rendered with our rasteriser
/// from `camera` and shown in light grey; points the camera does not see
/// (behind a surface, facing away, out of view) are left out. The dot
/// colour is [`ColourMap::Diverging`] over `+-ERROR_RANGE`: blue too dark,
/// white right, red too bright. The picture is `size` pixels; its title
/// goes into the report.
///
/// # Errors
///
/// If plotting fails.
pub fn error_picture(
    scene: &Scene,
    mesh: &Mesh,
    display: &[DVec3],
    camera: Camera,
    points: &[ErrorPoint],
    size: (u32, u32),
) -> Result<Picture, Error> {
    let (width, height) = size;
    let image = render::render(
        scene,
        mesh,
        display,
        &RenderSettings {
            width,
            height,
            camera,
            supersampling: 2,
        },
    );
    let srgb = image.to_srgb8(image.exposure_scale(Exposure::Auto { ev: 0.0 }));
    // Lightened grey, so the dots' colours stand out.
    let grey: Vec<u8> = srgb
        .chunks_exact(3)
        .flat_map(|c| {
            let luma =
                0.2126 * f64::from(c[0]) + 0.7152 * f64::from(c[1]) + 0.0722 * f64::from(c[2]);
            [(110.0 + 0.55 * luma).round() as u8; 3]
        })
        .collect();
    let background = Picture {
        width: width as usize,
        height: height as usize,
        rgb: grey,
    };
    let occluder = Accel::Bvh.build(&scene.surfaces);
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let scale = 0.5 * f64::from(height) / (0.5 * camera.fov_degrees.to_radians()).tan();
    let scale_map = Scale::Linear {
        min: -ERROR_RANGE,
        max: ERROR_RANGE,
    };
    let mut visible: Vec<(f64, f64, f64, plot::Rgb)> = Vec::new();
    for point in points {
        let d = point.position - camera.eye;
        let depth = d.dot(forward);
        if depth <= 0.0 || point.normal.dot(-d) <= 0.0 {
            continue;
        }
        let (from, to) = accel::shorten(camera.eye, point.position);
        if occluder.occluded(from, to, [point.group, point.group]) {
            continue;
        }
        let x = 0.5 * f64::from(width) + scale * d.dot(right) / depth;
        let y = 0.5 * f64::from(height) - scale * d.dot(up) / depth;
        if !(0.0..f64::from(width)).contains(&x) || !(0.0..f64::from(height)).contains(&y) {
            continue;
        }
        let colour = match point.relative {
            Some(r) => ColourMap::Diverging.colour(scale_map.position(r)),
            None => GREY,
        };
        visible.push((depth, x, y, colour));
    }
    // Far dots first, so near ones are drawn over them.
    visible.sort_by(|a, b| b.0.total_cmp(&a.0));
    let radius = (f64::from(width) / 160.0).max(2.0).round() as u32;
    Picture::draw(background.width, background.height, |area| {
        background.blit(area, 0, 0)?;
        for (_, x, y, colour) in visible {
            let centre = (x.floor() as i32, y.floor() as i32);
            for (r, c) in [(radius + 1, BLACK), (radius, colour)] {
                area.draw(&Circle::new(centre, r, RGBColor(c[0], c[1], c[2]).filled()))
                    .map_err(|e| Error::Experiment(format!("plot: {e}")))?;
            }
        }
        Ok(())
    })
}

/// The error pictures of one scene side by side, one per preset, with the
/// colour bar of [`ERROR_RANGE`] on the right (tick marks at -100%, -50%,
/// 0, 50% and 100% of it).
///
/// # Errors
///
/// If plotting fails.
pub fn error_pictures(panels: &[Picture]) -> Result<Picture, Error> {
    const GAP: usize = 6;
    const BAR: usize = 40;
    let cells: Vec<Option<&Picture>> = panels.iter().map(Some).collect();
    let grid = plot::grid(&cells, cells.len(), GAP)?;
    let ticks: Vec<plot::Tick> = [-1.0, -0.5, 0.0, 0.5, 1.0]
        .iter()
        .map(|&f| (f * ERROR_RANGE, String::new()))
        .collect();
    Picture::draw(grid.width + BAR, grid.height, |area| {
        grid.blit(area, 0, 0)?;
        plot::colour_bar(
            area,
            (grid.width + GAP, 2 * GAP),
            ColourMap::Diverging,
            Scale::Linear {
                min: -ERROR_RANGE,
                max: ERROR_RANGE,
            },
            &ticks,
            grid.height - 4 * GAP,
        )
    })
}
