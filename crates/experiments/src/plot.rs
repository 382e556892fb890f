//! The colour-scale pictures of the paper's section 4 (Figures 4.3 and
//! 4.5) and the validation's error pictures, drawn with `plotters`' bitmap
//! backend: perceptual colour maps ([`ColourMap::Viridis`],
//! [`ColourMap::Magma`] and a blue-white-red [`ColourMap::Diverging`] one),
//! linear and logarithmic [`Scale`]s, colour bars with tick marks, and
//! [`grid`]s of pictures. The pictures hold no text: titles and tick labels
//! go into the report beside them ([`Panel::axes`]).
//!
//! A [`Panel`] is a field sampled on a regular grid (row 0 at the top),
//! drawn one pixel per sample with tick marks below and to the left, an
//! optional marker under the plot (the source's extent) and the colour bar
//! on the right. Its size depends only on the grid's ([`panel_size`]), so
//! several panels line up in a [`grid`].

use std::io;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::{
    BitMapBackend, BitMapElement, DrawingArea, IntoDrawingArea, RGBColor, Rectangle,
};
use plotters::style::ShapeStyle;

use crate::Error;

/// An 8-bit sRGB colour.
pub type Rgb = [u8; 3];

/// White.
pub const WHITE: Rgb = [255, 255, 255];
/// Black.
pub const BLACK: Rgb = [0, 0, 0];
/// The grey of missing values (NaN).
pub const GREY: Rgb = [128, 128, 128];

/// A finished RGB picture, row 0 at the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Picture {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major RGB bytes, `3 * width * height` of them.
    pub rgb: Vec<u8>,
}

/// A drawing area on a picture being drawn.
pub type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Why drawing failed (the bitmap backend on a buffer hardly does).
fn failed(e: &dyn std::fmt::Display) -> Error {
    Error::Experiment(format!("plot: {e}"))
}

impl Picture {
    /// A `width x height` picture on white, drawn by `paint`.
    ///
    /// # Errors
    ///
    /// If plotting fails.
    pub fn draw(
        width: usize,
        height: usize,
        paint: impl FnOnce(&Area<'_>) -> Result<(), Error>,
    ) -> Result<Picture, Error> {
        let size = (
            u32::try_from(width).map_err(|e| failed(&e))?,
            u32::try_from(height).map_err(|e| failed(&e))?,
        );
        let mut rgb = WHITE.repeat(width * height);
        {
            let area = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
            paint(&area)?;
            area.present().map_err(|e| failed(&e))?;
        }
        Ok(Picture { width, height, rgb })
    }

    /// The colour at `(x, y)`; `None` outside the picture.
    #[must_use]
    pub fn pixel(&self, x: usize, y: usize) -> Option<Rgb> {
        (x < self.width && y < self.height).then(|| {
            let i = 3 * (y * self.width + x);
            [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
        })
    }

    /// Draws the picture onto `area` with its top-left corner at `(x, y)`.
    ///
    /// # Errors
    ///
    /// If plotting fails.
    pub fn blit(&self, area: &Area<'_>, x: usize, y: usize) -> Result<(), Error> {
        blit_rgb(area, (x, y), (self.width, self.height), &self.rgb)
    }

    /// Writes the picture as an 8-bit RGB PNG, through a temporary file.
    pub fn write_png(&self, path: &Path) -> io::Result<()> {
        let (w, h) = (
            u32::try_from(self.width).map_err(io::Error::other)?,
            u32::try_from(self.height).map_err(io::Error::other)?,
        );
        radiosity::export::Staged::write(path, |out| {
            radiosity::export::write_png(out, w, h, &self.rgb)
        })?
        .commit()
    }
}

/// Draws `width x height` RGB bytes onto `area` at `(x, y)`.
fn blit_rgb(
    area: &Area<'_>,
    (x, y): (usize, usize),
    (width, height): (usize, usize),
    rgb: &[u8],
) -> Result<(), Error> {
    let position = (
        i32::try_from(x).map_err(|e| failed(&e))?,
        i32::try_from(y).map_err(|e| failed(&e))?,
    );
    let size = (
        u32::try_from(width).map_err(|e| failed(&e))?,
        u32::try_from(height).map_err(|e| failed(&e))?,
    );
    let element = BitMapElement::with_ref(position, size, rgb).ok_or_else(|| {
        Error::Experiment(format!(
            "plot: {width}x{height} bitmap of {} bytes",
            rgb.len()
        ))
    })?;
    area.draw(&element).map_err(|e| failed(&e))
}

/// Fills (`filled`) or outlines (one pixel wide) the rectangle of
/// `width x height` pixels whose top-left corner is `(x, y)`; nothing when
/// either side is 0.
fn rectangle(
    area: &Area<'_>,
    (x, y): (i32, i32),
    (width, height): (i32, i32),
    colour: Rgb,
    filled: bool,
) -> Result<(), Error> {
    if width <= 0 || height <= 0 {
        return Ok(());
    }
    let style = ShapeStyle::from(rgb_colour(colour));
    // The bitmap backend fills up to the far corner exclusive but outlines
    // it inclusive.
    let (style, inclusive) = if filled {
        (style.filled(), 0)
    } else {
        (style, 1)
    };
    let far = (x + width - inclusive, y + height - inclusive);
    area.draw(&Rectangle::new([(x, y), far], style))
        .map_err(|e| failed(&e))
}

/// Fills the rectangle of `width x height` pixels at `(x, y)`.
fn fill(
    area: &Area<'_>,
    x: i32,
    y: i32,
    width: i32,
    height: i32,
    colour: Rgb,
) -> Result<(), Error> {
    rectangle(area, (x, y), (width, height), colour, true)
}

/// Outlines the rectangle of `width x height` pixels at `(x, y)`.
fn outline(
    area: &Area<'_>,
    x: i32,
    y: i32,
    width: i32,
    height: i32,
    colour: Rgb,
) -> Result<(), Error> {
    rectangle(area, (x, y), (width, height), colour, false)
}

fn rgb_colour([r, g, b]: Rgb) -> RGBColor {
    RGBColor(r, g, b)
}

/// Lays pictures out on a grid of `columns` columns, each cell as large as
/// the largest picture, `gap` pixels apart on white; `None` leaves a cell
/// empty.
///
/// # Errors
///
/// If plotting fails.
pub fn grid(cells: &[Option<&Picture>], columns: usize, gap: usize) -> Result<Picture, Error> {
    let columns = columns.max(1);
    let rows = cells.len().div_ceil(columns);
    let cell_w = cells.iter().flatten().map(|c| c.width).max().unwrap_or(0);
    let cell_h = cells.iter().flatten().map(|c| c.height).max().unwrap_or(0);
    let width = columns * cell_w + (columns + 1) * gap;
    let height = rows * cell_h + (rows + 1) * gap;
    Picture::draw(width, height, |area| {
        for (i, cell) in cells.iter().enumerate() {
            if let Some(c) = cell {
                let x = gap + (i % columns) * (cell_w + gap);
                let y = gap + (i / columns) * (cell_h + gap);
                c.blit(area, x, y)?;
            }
        }
        Ok(())
    })
}

/// A colour map from `[0, 1]` to sRGB.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourMap {
    /// Matplotlib's viridis (dark blue, green, yellow): perceptually
    /// uniform, legible in grey and to colour-blind readers.
    Viridis,
    /// Matplotlib's magma (black, purple, orange, pale yellow).
    Magma,
    /// Blue, white, red (ColorBrewer's RdBu, reversed): for signed
    /// quantities, white at 0.5.
    Diverging,
}

/// Viridis at 25 equally spaced points (matplotlib's table, sampled).
const VIRIDIS: [u32; 25] = [
    0x440154, 0x471164, 0x481F70, 0x472D7B, 0x443A83, 0x404688, 0x3B528B, 0x365D8D, 0x31688E,
    0x2C728E, 0x287C8E, 0x24868E, 0x21908C, 0x1F9A8A, 0x20A486, 0x27AD81, 0x35B779, 0x47C16E,
    0x5DC863, 0x75D054, 0x8FD744, 0xAADC32, 0xC7E020, 0xE3E418, 0xFDE725,
];

/// Magma at 9 equally spaced points.
const MAGMA: [u32; 9] = [
    0x000004, 0x1C1044, 0x4F127B, 0x812581, 0xB5367A, 0xE55064, 0xFB8761, 0xFEC287, 0xFCFDBF,
];

/// ColorBrewer RdBu (11 classes), from blue to red.
const DIVERGING: [u32; 11] = [
    0x053061, 0x2166AC, 0x4393C3, 0x92C5DE, 0xD1E5F0, 0xF7F7F7, 0xFDDBC7, 0xF4A582, 0xD6604D,
    0xB2182B, 0x67001F,
];

impl ColourMap {
    /// The colour at `t`, clamped to `[0, 1]`, interpolated linearly between
    /// the table's entries; NaN gives [`GREY`].
    #[must_use]
    pub fn colour(self, t: f64) -> Rgb {
        if t.is_nan() {
            return GREY;
        }
        let table: &[u32] = match self {
            ColourMap::Viridis => &VIRIDIS,
            ColourMap::Magma => &MAGMA,
            ColourMap::Diverging => &DIVERGING,
        };
        let u = t.clamp(0.0, 1.0) * (table.len() - 1) as f64;
        let i = (u.floor() as usize).min(table.len() - 2);
        let f = u - i as f64;
        let channel = |c: u32, shift: u32| f64::from((c >> shift) & 0xFF);
        let mix = |shift: u32| {
            let v = channel(table[i], shift) * (1.0 - f) + channel(table[i + 1], shift) * f;
            v.round().clamp(0.0, 255.0) as u8
        };
        [mix(16), mix(8), mix(0)]
    }
}

/// How values map to the colour map's `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scale {
    /// `(v - min) / (max - min)`.
    Linear {
        /// Value at the bottom of the bar.
        min: f64,
        /// Value at the top of the bar.
        max: f64,
    },
    /// `(log10 v - log10 min) / (log10 max - log10 min)`; zero and negative
    /// values go to the bottom.
    Log10 {
        /// Value at the bottom of the bar (positive).
        min: f64,
        /// Value at the top of the bar.
        max: f64,
    },
}

impl Scale {
    /// Where `value` falls, clamped to `[0, 1]`; NaN stays NaN.
    #[must_use]
    pub fn position(self, value: f64) -> f64 {
        if value.is_nan() {
            return f64::NAN;
        }
        let t = match self {
            Scale::Linear { min, max } => (value - min) / (max - min),
            Scale::Log10 { min, max } => {
                if value <= 0.0 {
                    0.0
                } else {
                    (value.log10() - min.log10()) / (max.log10() - min.log10())
                }
            }
        };
        t.clamp(0.0, 1.0)
    }
}

/// A tick: a value and its label.
pub type Tick = (f64, String);

/// A field sampled on a regular grid, and how to draw it.
#[derive(Clone, Debug)]
pub struct Panel<'a> {
    /// Samples, row-major, `width * height`, row 0 at the top.
    pub values: &'a [f64],
    /// Samples per row (pixels).
    pub width: usize,
    /// Rows (pixels).
    pub height: usize,
    /// Colour map.
    pub map: ColourMap,
    /// Value-to-colour scale.
    pub scale: Scale,
    /// Ticks of the colour bar.
    pub bar_ticks: Vec<Tick>,
    /// Horizontal extent `(left edge, right edge)` in data units.
    pub x_range: (f64, f64),
    /// Vertical extent `(bottom edge, top edge)` in data units.
    pub y_range: (f64, f64),
    /// Ticks under the plot, in data units.
    pub x_ticks: Vec<Tick>,
    /// Ticks left of the plot, in data units.
    pub y_ticks: Vec<Tick>,
    /// A horizontal span in data units marked by a bar under the plot.
    pub marker: Option<(f64, f64)>,
}

/// Margins of a [`Panel`] around its plot (room for the tick marks).
const LEFT: usize = 64;
const TOP: usize = 30;
const BOTTOM: usize = 40;
/// From the plot to its colour bar, the bar's width, and the bar's margin.
const BAR_GAP: usize = 16;
const BAR_WIDTH: usize = 20;
const RIGHT: usize = BAR_GAP + BAR_WIDTH + 6 + 7 * 12 + 8;
const MARKER: Rgb = [90, 90, 90];

/// Size in pixels of a [`Panel`] whose grid is `width x height`.
#[must_use]
pub fn panel_size(width: usize, height: usize) -> (usize, usize) {
    (LEFT + width + RIGHT, TOP + height + BOTTOM)
}

/// Labels of ticks in order, `a, b, c`.
#[must_use]
pub fn labels(ticks: &[Tick]) -> String {
    ticks
        .iter()
        .map(|(_, label)| label.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

impl Panel<'_> {
    /// Draws the panel: plot, tick marks, marker and colour bar on white.
    ///
    /// # Errors
    ///
    /// If plotting fails.
    ///
    /// # Panics
    ///
    /// If `values` does not hold `width * height` samples.
    pub fn draw(&self) -> Result<Picture, Error> {
        assert_eq!(self.values.len(), self.width * self.height, "panel size");
        let (w, h) = (self.width, self.height);
        let (cw, ch) = panel_size(w, h);
        Picture::draw(cw, ch, |area| {
            let field: Vec<u8> = self
                .values
                .iter()
                .flat_map(|v| self.map.colour(self.scale.position(*v)))
                .collect();
            blit_rgb(area, (LEFT, TOP), (w, h), &field)?;
            let (x0, y0, wi, hi) = (LEFT as i32, TOP as i32, w as i32, h as i32);
            outline(area, x0 - 1, y0 - 1, wi + 2, hi + 2, BLACK)?;

            // Data to pixel: x from the left edge, y from the top edge.
            let (xl, xr) = self.x_range;
            let (yb, yt) = self.y_range;
            let px = |x: f64| x0 + ((x - xl) / (xr - xl) * w as f64).round() as i32;
            let py = |y: f64| y0 + ((yt - y) / (yt - yb) * h as f64).round() as i32;
            let below = y0 + hi + 1;
            if let Some((a, b)) = self.marker {
                let (a, b) = (px(a), px(b));
                fill(area, a, below + 1, (b - a).max(1), 4, MARKER)?;
            }
            for (x, _) in &self.x_ticks {
                fill(area, px(*x).clamp(x0, x0 + wi - 1), below + 6, 1, 4, BLACK)?;
            }
            for (y, _) in &self.y_ticks {
                fill(area, x0 - 6, py(*y).clamp(y0, y0 + hi - 1), 4, 1, BLACK)?;
            }
            colour_bar(
                area,
                (LEFT + w + BAR_GAP, TOP),
                self.map,
                self.scale,
                &self.bar_ticks,
                h,
            )
        })
    }

    /// The panel's axes in words, for the report: the extents, and the tick
    /// labels of both axes and of the colour bar in order.
    #[must_use]
    pub fn axes(&self) -> String {
        format!(
            "x from {} (left) to {} (right), ticks {}; y from {} (bottom) to {} (top), ticks {}; \
             colour bar ticks {} (bottom to top)",
            self.x_range.0,
            self.x_range.1,
            labels(&self.x_ticks),
            self.y_range.0,
            self.y_range.1,
            labels(&self.y_ticks),
            labels(&self.bar_ticks),
        )
    }
}

/// Draws a vertical colour bar `height` pixels tall with its top-left
/// corner at `(x, y)`, bottom = the scale's minimum, outlined, with a tick
/// mark right of it at each tick's value.
///
/// # Errors
///
/// If plotting fails.
pub fn colour_bar(
    area: &Area<'_>,
    (x, y): (usize, usize),
    map: ColourMap,
    scale: Scale,
    ticks: &[Tick],
    height: usize,
) -> Result<(), Error> {
    let h = height.max(1);
    let bar: Vec<u8> = (0..h)
        .flat_map(|row| {
            let colour = map.colour(1.0 - (row as f64 + 0.5) / h as f64);
            std::iter::repeat_n(colour, BAR_WIDTH).flatten()
        })
        .collect();
    blit_rgb(area, (x, y), (BAR_WIDTH, h), &bar)?;
    let (x, y, bw) = (x as i32, y as i32, BAR_WIDTH as i32);
    outline(area, x - 1, y - 1, bw + 2, h as i32 + 2, BLACK)?;
    for (value, _) in ticks.iter().filter(|t| !t.0.is_nan()) {
        let row = y + ((1.0 - scale.position(*value)) * (h - 1) as f64).round() as i32;
        fill(area, x + bw, row, 4, 1, BLACK)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_maps_hit_their_ends() {
        assert_eq!(ColourMap::Viridis.colour(0.0), [0x44, 0x01, 0x54]);
        assert_eq!(ColourMap::Viridis.colour(1.0), [0xFD, 0xE7, 0x25]);
        assert_eq!(ColourMap::Viridis.colour(7.0), [0xFD, 0xE7, 0x25]);
        assert_eq!(ColourMap::Magma.colour(0.0), [0, 0, 4]);
        assert_eq!(ColourMap::Diverging.colour(0.5), [0xF7, 0xF7, 0xF7]);
        assert_eq!(ColourMap::Viridis.colour(f64::NAN), GREY);
    }

    #[test]
    fn viridis_brightens_monotonically() {
        let lum =
            |c: Rgb| 0.2126 * f64::from(c[0]) + 0.7152 * f64::from(c[1]) + 0.0722 * f64::from(c[2]);
        let mut last = -1.0;
        for i in 0..=100 {
            let l = lum(ColourMap::Viridis.colour(f64::from(i) / 100.0));
            assert!(l >= last - 0.5, "{i}");
            last = l;
        }
    }

    #[test]
    fn scales_map_their_ends() {
        let lin = Scale::Linear { min: 0.0, max: 2.0 };
        assert_eq!(lin.position(1.0), 0.5);
        assert_eq!(lin.position(-3.0), 0.0);
        let log = Scale::Log10 {
            min: 1e-3,
            max: 1.0,
        };
        assert!((log.position(1e-2) - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(log.position(0.0), 0.0);
        assert!(log.position(f64::NAN).is_nan());
    }

    #[test]
    fn rectangles_cover_exactly_their_pixels() {
        let p = Picture::draw(20, 20, |area| {
            fill(area, 2, 3, 4, 5, BLACK)?;
            outline(area, 10, 10, 3, 3, GREY)
        })
        .unwrap();
        assert_eq!(p.pixel(2, 3), Some(BLACK));
        assert_eq!(p.pixel(5, 7), Some(BLACK));
        assert_eq!(p.pixel(6, 7), Some(WHITE));
        assert_eq!(p.pixel(5, 8), Some(WHITE));
        assert_eq!(p.pixel(1, 3), Some(WHITE));
        assert_eq!(p.pixel(10, 10), Some(GREY));
        assert_eq!(p.pixel(12, 12), Some(GREY));
        assert_eq!(p.pixel(11, 11), Some(WHITE));
        assert_eq!(p.pixel(13, 12), Some(WHITE));
    }

    #[test]
    fn panels_have_their_announced_size() {
        let values = vec![0.5; 30 * 10];
        let panel = Panel {
            values: &values,
            width: 30,
            height: 10,
            map: ColourMap::Viridis,
            scale: Scale::Linear { min: 0.0, max: 1.0 },
            bar_ticks: vec![(0.0, "0".into()), (1.0, "1".into())],
            x_range: (0.0, 3.0),
            y_range: (0.0, 1.0),
            x_ticks: vec![(0.0, "0".into())],
            y_ticks: vec![(1.0, "1".into())],
            marker: Some((1.0, 2.0)),
        };
        let c = panel.draw().unwrap();
        assert_eq!((c.width, c.height), panel_size(30, 10));
        assert_eq!(
            c.pixel(LEFT + 3, TOP + 3),
            Some(ColourMap::Viridis.colour(0.5))
        );
        // The frame, the marker under the source, the colour bar's ends.
        assert_eq!(c.pixel(LEFT - 1, TOP - 1), Some(BLACK));
        assert_eq!(c.pixel(LEFT + 15, TOP + 10 + 2), Some(MARKER));
        assert_eq!(c.pixel(LEFT + 5, TOP + 10 + 2), Some(WHITE));
        let bar_x = LEFT + 30 + BAR_GAP + 1;
        assert_eq!(c.pixel(bar_x, TOP), Some(ColourMap::Viridis.colour(0.95)));
        assert_eq!(
            c.pixel(bar_x, TOP + 9),
            Some(ColourMap::Viridis.colour(0.05))
        );
        assert!(
            panel
                .axes()
                .contains("colour bar ticks 0, 1 (bottom to top)")
        );
        let grid = grid(&[Some(&c), None, Some(&c)], 2, 4).unwrap();
        assert_eq!(grid.width, 2 * c.width + 3 * 4);
        assert_eq!(grid.height, 2 * c.height + 3 * 4);
        assert_eq!(
            grid.pixel(4 + LEFT + 3, 4 + TOP + 3),
            c.pixel(LEFT + 3, TOP + 3)
        );
        assert_eq!(grid.pixel(8 + c.width + LEFT + 3, 4 + TOP + 3), Some(WHITE));
    }
}
