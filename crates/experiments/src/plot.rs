//! Just enough plotting for the colour-scale pictures of the paper's
//! section 4 (Figures 4.3 and 4.5): an RGB [`Canvas`], perceptual colour
//! maps ([`ColourMap::Viridis`], [`ColourMap::Magma`] and a blue-white-red
//! [`ColourMap::Diverging`] one), linear and logarithmic [`Scale`]s, a colour
//! bar with tick labels, and a tiny built-in 5x7 bitmap font, so that the
//! pictures carry their own scale without any extra dependency.
//!
//! A [`Panel`] is a field sampled on a regular grid (row 0 at the top),
//! drawn one pixel per sample with a title above, axis ticks below and to
//! the left, an optional marker under the plot (the source's extent) and
//! the colour bar on the right. Its size depends only on the grid's
//! ([`panel_size`]), so several panels line up in a [`Canvas::grid`].

use std::io;
use std::path::Path;

/// An 8-bit sRGB colour.
pub type Rgb = [u8; 3];

/// White.
pub const WHITE: Rgb = [255, 255, 255];
/// Black.
pub const BLACK: Rgb = [0, 0, 0];
/// The grey of missing values (NaN).
pub const GREY: Rgb = [128, 128, 128];

/// Width and height of a glyph of the built-in font, in font pixels.
pub const GLYPH: (usize, usize) = (5, 7);

/// An RGB picture, row 0 at the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major RGB bytes, `3 * width * height` of them.
    pub rgb: Vec<u8>,
}

impl Canvas {
    /// A canvas filled with `background`.
    #[must_use]
    pub fn new(width: usize, height: usize, background: Rgb) -> Canvas {
        Canvas {
            width,
            height,
            rgb: background.repeat(width * height),
        }
    }

    /// The colour at `(x, y)`; `None` outside the canvas.
    #[must_use]
    pub fn pixel(&self, x: usize, y: usize) -> Option<Rgb> {
        (x < self.width && y < self.height).then(|| {
            let i = 3 * (y * self.width + x);
            [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
        })
    }

    /// Sets one pixel; coordinates outside the canvas are ignored.
    pub fn set(&mut self, x: i64, y: i64, colour: Rgb) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            let i = 3 * (y as usize * self.width + x as usize);
            self.rgb[i..i + 3].copy_from_slice(&colour);
        }
    }

    /// Fills a rectangle (clipped to the canvas).
    pub fn fill(&mut self, x: i64, y: i64, width: usize, height: usize, colour: Rgb) {
        for dy in 0..height as i64 {
            for dx in 0..width as i64 {
                self.set(x + dx, y + dy, colour);
            }
        }
    }

    /// Draws the one-pixel outline of a rectangle.
    pub fn outline(&mut self, x: i64, y: i64, width: usize, height: usize, colour: Rgb) {
        if width == 0 || height == 0 {
            return;
        }
        let (w, h) = (width as i64, height as i64);
        for dx in 0..w {
            self.set(x + dx, y, colour);
            self.set(x + dx, y + h - 1, colour);
        }
        for dy in 0..h {
            self.set(x, y + dy, colour);
            self.set(x + w - 1, y + dy, colour);
        }
    }

    /// Copies `other` with its top-left corner at `(x, y)`.
    pub fn draw(&mut self, other: &Canvas, x: i64, y: i64) {
        for row in 0..other.height {
            for column in 0..other.width {
                if let Some(c) = other.pixel(column, row) {
                    self.set(x + column as i64, y + row as i64, c);
                }
            }
        }
    }

    /// Writes `text` in the built-in font, each font pixel `scale` pixels
    /// wide, its top-left corner at `(x, y)`. Lower-case letters are drawn
    /// as capitals; a character the font lacks is drawn as a hollow box.
    pub fn text(&mut self, x: i64, y: i64, text: &str, scale: usize, colour: Rgb) {
        let s = scale.max(1) as i64;
        for (i, ch) in text.chars().enumerate() {
            let left = x + i as i64 * advance(scale) as i64;
            let rows = glyph(ch);
            for (row, bits) in rows.iter().enumerate() {
                for (column, b) in bits.bytes().enumerate() {
                    if b == b'#' {
                        let (gx, gy) = (left + column as i64 * s, y + row as i64 * s);
                        self.fill(gx, gy, s as usize, s as usize, colour);
                    }
                }
            }
        }
    }

    /// Lays canvases out on a grid of `columns` columns, each cell as large
    /// as the largest canvas, `gap` pixels apart; `None` leaves a cell
    /// empty.
    #[must_use]
    pub fn grid(cells: &[Option<&Canvas>], columns: usize, gap: usize, background: Rgb) -> Canvas {
        let columns = columns.max(1);
        let rows = cells.len().div_ceil(columns);
        let cell_w = cells.iter().flatten().map(|c| c.width).max().unwrap_or(0);
        let cell_h = cells.iter().flatten().map(|c| c.height).max().unwrap_or(0);
        let width = columns * cell_w + (columns + 1) * gap;
        let height = rows * cell_h + (rows + 1) * gap;
        let mut out = Canvas::new(width, height, background);
        for (i, cell) in cells.iter().enumerate() {
            if let Some(c) = cell {
                let x = gap + (i % columns) * (cell_w + gap);
                let y = gap + (i / columns) * (cell_h + gap);
                out.draw(c, x as i64, y as i64);
            }
        }
        out
    }

    /// Writes the canvas as an 8-bit RGB PNG, through a temporary file.
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

/// Horizontal distance from one character to the next at `scale`.
#[must_use]
pub fn advance(scale: usize) -> usize {
    (GLYPH.0 + 1) * scale.max(1)
}

/// Width in pixels of `text` at `scale` (no trailing space).
#[must_use]
pub fn text_width(text: &str, scale: usize) -> usize {
    let n = text.chars().count();
    if n == 0 {
        0
    } else {
        n * advance(scale) - scale.max(1)
    }
}

/// Whether the built-in font has a glyph for `ch` (lower case counts as
/// upper case).
#[must_use]
pub fn has_glyph(ch: char) -> bool {
    let upper = ch.to_ascii_uppercase();
    FONT.iter().any(|(c, _)| *c == upper)
}

fn glyph(ch: char) -> [&'static str; 7] {
    let upper = ch.to_ascii_uppercase();
    FONT.iter().find(|(c, _)| *c == upper).map_or(
        [
            "#####", "#...#", "#...#", "#...#", "#...#", "#...#", "#####",
        ],
        |(_, rows)| *rows,
    )
}

/// The font: 5x7 glyphs, `#` inked.
const FONT: &[(char, [&str; 7])] = &[
    (
        ' ',
        [
            ".....", ".....", ".....", ".....", ".....", ".....", ".....",
        ],
    ),
    (
        '0',
        [
            ".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###.",
        ],
    ),
    (
        '1',
        [
            "..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###.",
        ],
    ),
    (
        '2',
        [
            ".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####",
        ],
    ),
    (
        '3',
        [
            "#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###.",
        ],
    ),
    (
        '4',
        [
            "...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#.",
        ],
    ),
    (
        '5',
        [
            "#####", "#....", "####.", "....#", "....#", "#...#", ".###.",
        ],
    ),
    (
        '6',
        [
            "..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###.",
        ],
    ),
    (
        '7',
        [
            "#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#...",
        ],
    ),
    (
        '8',
        [
            ".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###.",
        ],
    ),
    (
        '9',
        [
            ".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##..",
        ],
    ),
    (
        '.',
        [
            ".....", ".....", ".....", ".....", ".....", ".##..", ".##..",
        ],
    ),
    (
        ',',
        [
            ".....", ".....", ".....", ".....", ".##..", "..#..", ".#...",
        ],
    ),
    (
        '-',
        [
            ".....", ".....", ".....", "#####", ".....", ".....", ".....",
        ],
    ),
    (
        '+',
        [
            ".....", "..#..", "..#..", "#####", "..#..", "..#..", ".....",
        ],
    ),
    (
        '%',
        [
            "##...", "##..#", "...#.", "..#..", ".#...", "#..##", "...##",
        ],
    ),
    (
        '(',
        [
            "...#.", "..#..", ".#...", ".#...", ".#...", "..#..", "...#.",
        ],
    ),
    (
        ')',
        [
            ".#...", "..#..", "...#.", "...#.", "...#.", "..#..", ".#...",
        ],
    ),
    (
        ':',
        [
            ".....", ".##..", ".##..", ".....", ".##..", ".##..", ".....",
        ],
    ),
    (
        '=',
        [
            ".....", ".....", "#####", ".....", "#####", ".....", ".....",
        ],
    ),
    (
        '/',
        [
            ".....", "....#", "...#.", "..#..", ".#...", "#....", ".....",
        ],
    ),
    (
        '<',
        [
            "...#.", "..#..", ".#...", "#....", ".#...", "..#..", "...#.",
        ],
    ),
    (
        '>',
        [
            ".#...", "..#..", "...#.", "....#", "...#.", "..#..", ".#...",
        ],
    ),
    (
        '|',
        [
            "..#..", "..#..", "..#..", "..#..", "..#..", "..#..", "..#..",
        ],
    ),
    (
        'A',
        [
            ".###.", "#...#", "#...#", "#####", "#...#", "#...#", "#...#",
        ],
    ),
    (
        'B',
        [
            "####.", "#...#", "#...#", "####.", "#...#", "#...#", "####.",
        ],
    ),
    (
        'C',
        [
            ".###.", "#...#", "#....", "#....", "#....", "#...#", ".###.",
        ],
    ),
    (
        'D',
        [
            "###..", "#..#.", "#...#", "#...#", "#...#", "#..#.", "###..",
        ],
    ),
    (
        'E',
        [
            "#####", "#....", "#....", "####.", "#....", "#....", "#####",
        ],
    ),
    (
        'F',
        [
            "#####", "#....", "#....", "####.", "#....", "#....", "#....",
        ],
    ),
    (
        'G',
        [
            ".###.", "#...#", "#....", "#.###", "#...#", "#...#", ".####",
        ],
    ),
    (
        'H',
        [
            "#...#", "#...#", "#...#", "#####", "#...#", "#...#", "#...#",
        ],
    ),
    (
        'I',
        [
            ".###.", "..#..", "..#..", "..#..", "..#..", "..#..", ".###.",
        ],
    ),
    (
        'J',
        [
            "..###", "...#.", "...#.", "...#.", "...#.", "#..#.", ".##..",
        ],
    ),
    (
        'K',
        [
            "#...#", "#..#.", "#.#..", "##...", "#.#..", "#..#.", "#...#",
        ],
    ),
    (
        'L',
        [
            "#....", "#....", "#....", "#....", "#....", "#....", "#####",
        ],
    ),
    (
        'M',
        [
            "#...#", "##.##", "#.#.#", "#.#.#", "#...#", "#...#", "#...#",
        ],
    ),
    (
        'N',
        [
            "#...#", "#...#", "##..#", "#.#.#", "#..##", "#...#", "#...#",
        ],
    ),
    (
        'O',
        [
            ".###.", "#...#", "#...#", "#...#", "#...#", "#...#", ".###.",
        ],
    ),
    (
        'P',
        [
            "####.", "#...#", "#...#", "####.", "#....", "#....", "#....",
        ],
    ),
    (
        'Q',
        [
            ".###.", "#...#", "#...#", "#...#", "#.#.#", "#..#.", ".##.#",
        ],
    ),
    (
        'R',
        [
            "####.", "#...#", "#...#", "####.", "#.#..", "#..#.", "#...#",
        ],
    ),
    (
        'S',
        [
            ".####", "#....", "#....", ".###.", "....#", "....#", "####.",
        ],
    ),
    (
        'T',
        [
            "#####", "..#..", "..#..", "..#..", "..#..", "..#..", "..#..",
        ],
    ),
    (
        'U',
        [
            "#...#", "#...#", "#...#", "#...#", "#...#", "#...#", ".###.",
        ],
    ),
    (
        'V',
        [
            "#...#", "#...#", "#...#", "#...#", "#...#", ".#.#.", "..#..",
        ],
    ),
    (
        'W',
        [
            "#...#", "#...#", "#...#", "#.#.#", "#.#.#", "#.#.#", ".#.#.",
        ],
    ),
    (
        'X',
        [
            "#...#", "#...#", ".#.#.", "..#..", ".#.#.", "#...#", "#...#",
        ],
    ),
    (
        'Y',
        [
            "#...#", "#...#", ".#.#.", "..#..", "..#..", "..#..", "..#..",
        ],
    ),
    (
        'Z',
        [
            "#####", "....#", "...#.", "..#..", ".#...", "#....", "#####",
        ],
    ),
];

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
    /// Title drawn above the plot.
    pub title: &'a str,
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

/// Font scale of the labels.
const FONT_SCALE: usize = 2;
const LEFT: usize = 64;
const TOP: usize = 30;
const BOTTOM: usize = 40;
const BAR_GAP: usize = 16;
const BAR_WIDTH: usize = 20;
const RIGHT: usize = BAR_GAP + BAR_WIDTH + 6 + 7 * 12 + 8;
const MARKER: Rgb = [90, 90, 90];

/// Size in pixels of a [`Panel`] whose grid is `width x height`.
#[must_use]
pub fn panel_size(width: usize, height: usize) -> (usize, usize) {
    (LEFT + width + RIGHT, TOP + height + BOTTOM)
}

impl Panel<'_> {
    /// Draws the panel: plot, ticks, marker and colour bar on white.
    ///
    /// # Panics
    ///
    /// If `values` does not hold `width * height` samples.
    #[must_use]
    pub fn draw(&self) -> Canvas {
        assert_eq!(self.values.len(), self.width * self.height, "panel size");
        let (w, h) = (self.width, self.height);
        let (cw, ch) = panel_size(w, h);
        let mut canvas = Canvas::new(cw, ch, WHITE);
        let (x0, y0) = (LEFT as i64, TOP as i64);
        let glyph_h = GLYPH.1 * FONT_SCALE;

        canvas.text(
            x0,
            ((TOP - glyph_h) / 2) as i64,
            self.title,
            FONT_SCALE,
            BLACK,
        );
        for (i, v) in self.values.iter().enumerate() {
            let c = self.map.colour(self.scale.position(*v));
            canvas.set(x0 + (i % w) as i64, y0 + (i / w) as i64, c);
        }
        canvas.outline(x0 - 1, y0 - 1, w + 2, h + 2, BLACK);

        // Data to pixel: x from the left edge, y from the top edge.
        let (xl, xr) = self.x_range;
        let (yb, yt) = self.y_range;
        let px = |x: f64| x0 + ((x - xl) / (xr - xl) * w as f64).round() as i64;
        let py = |y: f64| y0 + ((yt - y) / (yt - yb) * h as f64).round() as i64;
        let below = y0 + h as i64 + 1;
        if let Some((a, b)) = self.marker {
            let (a, b) = (px(a), px(b));
            canvas.fill(a, below + 1, (b - a).max(1) as usize, 4, MARKER);
        }
        // Labels that would overlap the previous one are left out (small
        // plots); the tick marks stay.
        let mut free_from = i64::MIN;
        let mut x_ticks: Vec<(i64, &String)> = self
            .x_ticks
            .iter()
            .map(|(x, label)| (px(*x).clamp(x0, x0 + w as i64 - 1), label))
            .collect();
        x_ticks.sort_by_key(|&(p, _)| p);
        for (p, label) in x_ticks {
            canvas.fill(p, below + 6, 1, 4, BLACK);
            let lw = text_width(label, FONT_SCALE) as i64;
            let left = (p - lw / 2).clamp(0, cw as i64 - lw);
            if left >= free_from {
                canvas.text(left, below + 12, label, FONT_SCALE, BLACK);
                free_from = left + lw + advance(FONT_SCALE) as i64;
            }
        }
        let mut free_above = i64::MAX;
        let mut y_ticks: Vec<(i64, &String)> = self
            .y_ticks
            .iter()
            .map(|(y, label)| (py(*y).clamp(y0, y0 + h as i64 - 1), label))
            .collect();
        y_ticks.sort_by_key(|&(p, _)| std::cmp::Reverse(p));
        for (p, label) in y_ticks {
            canvas.fill(x0 - 6, p, 4, 1, BLACK);
            let lw = text_width(label, FONT_SCALE) as i64;
            let top = (p - glyph_h as i64 / 2).clamp(0, ch as i64 - glyph_h as i64);
            if top + glyph_h as i64 <= free_above {
                canvas.text(x0 - 9 - lw, top, label, FONT_SCALE, BLACK);
                free_above = top - FONT_SCALE as i64;
            }
        }

        let bar = colour_bar(self.map, self.scale, &self.bar_ticks, h);
        canvas.draw(&bar, x0 + (w + BAR_GAP) as i64, y0 - bar_padding() as i64);
        canvas
    }
}

/// Rows of white above and below a [`colour_bar`]: half a label's height.
#[must_use]
pub fn bar_padding() -> usize {
    GLYPH.1 * FONT_SCALE / 2
}

/// A vertical colour bar `height` pixels tall, bottom = the scale's minimum,
/// with its ticks labelled on the right. The canvas has [`bar_padding`]
/// rows above and below the bar, so the extreme labels are not cut.
#[must_use]
pub fn colour_bar(map: ColourMap, scale: Scale, ticks: &[Tick], height: usize) -> Canvas {
    let glyph_h = GLYPH.1 * FONT_SCALE;
    let width = RIGHT - BAR_GAP;
    let pad = bar_padding();
    let mut bar = Canvas::new(width, height + 2 * pad, WHITE);
    let h = height.max(1);
    for row in 0..h {
        let t = 1.0 - (row as f64 + 0.5) / h as f64;
        bar.fill(0, (pad + row) as i64, BAR_WIDTH, 1, map.colour(t));
    }
    bar.outline(-1, pad as i64 - 1, BAR_WIDTH + 2, h + 2, BLACK);
    // Ticks from the bottom up; a label that would overlap the one below
    // it is left out (short bars), its tick mark stays.
    let mut order: Vec<&Tick> = ticks.iter().filter(|t| !t.0.is_nan()).collect();
    order.sort_by(|a, b| scale.position(a.0).total_cmp(&scale.position(b.0)));
    let mut free_above = i64::MAX;
    for (value, label) in order {
        let t = scale.position(*value);
        let row = pad as i64 + ((1.0 - t) * (h - 1) as f64).round() as i64;
        bar.fill(BAR_WIDTH as i64, row, 4, 1, BLACK);
        let top = row - glyph_h as i64 / 2;
        if top + glyph_h as i64 <= free_above {
            bar.text(BAR_WIDTH as i64 + 7, top, label, FONT_SCALE, BLACK);
            free_above = top - FONT_SCALE as i64;
        }
    }
    bar
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
    fn text_is_drawn_where_asked() {
        assert!(
            "0123456789.-+%E()=/<>ABCDEFGHIJKLMNOPQRSTUVWXYZ:,|"
                .chars()
                .all(has_glyph)
        );
        assert_eq!(text_width("1E-3", 2), 4 * 12 - 2);
        let mut c = Canvas::new(20, 20, WHITE);
        c.text(1, 1, "1", 1, BLACK);
        // '1' has ink at column 2 of its top row.
        assert_eq!(c.pixel(3, 1), Some(BLACK));
        assert_eq!(c.pixel(1, 1), Some(WHITE));
    }

    #[test]
    fn panels_have_their_announced_size() {
        let values = vec![0.5; 30 * 10];
        let panel = Panel {
            title: "(A) TEST",
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
        let c = panel.draw();
        assert_eq!((c.width, c.height), panel_size(30, 10));
        assert_eq!(
            c.pixel(LEFT + 3, TOP + 3),
            Some(ColourMap::Viridis.colour(0.5))
        );
        let grid = Canvas::grid(&[Some(&c), None, Some(&c)], 2, 4, WHITE);
        assert_eq!(grid.width, 2 * c.width + 3 * 4);
        assert_eq!(grid.height, 2 * c.height + 3 * 4);
    }
}
