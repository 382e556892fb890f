//! Grain: how much a picture's noise shows where the light is smooth
//! (beyond the paper, whose pictures were Gouraud-shaded and so had none;
//! a final pass that traces rays per sample makes penumbrae and many
//! emitters noisy). The figure is the root mean square of the picture
//! less its 5 x 5 median, in 8-bit levels of its luma, over each 16 x 16
//! pixel tile that is smooth (fully covered by surfaces, and whose median
//! picture changes by at most [`EDGE_LEVELS`] between neighbouring pixels:
//! away from silhouettes and sharp shadow edges, where a median moves
//! with the edge); reported as the 95th percentile over the smooth tiles
//! and the worst tile. A median filter keeps edges and removes noise, so
//! the difference is the noise alone wherever the light is smooth, the
//! way denoisers' papers measure residual noise.

/// A tile's side, pixels.
pub const TILE: usize = 16;

/// The median's window, pixels a side.
pub const WINDOW: usize = 5;

/// A tile whose median picture steps by more than this many levels
/// between neighbouring pixels holds an edge and is left out.
pub const EDGE_LEVELS: f64 = 4.0;

/// A picture's grain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grain {
    /// The 95th percentile of the smooth tiles' noise, 8-bit levels.
    pub p95: f64,
    /// The noisiest smooth tile's, 8-bit levels.
    pub worst: f64,
    /// The smooth tiles measured.
    pub tiles: usize,
}

/// The luma (Rec. 709 weights) of 8-bit sRGB pixels, in levels.
#[must_use]
pub fn luma(rgb: &[u8]) -> Vec<f64> {
    rgb.chunks_exact(3)
        .map(|p| 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2]))
        .collect()
}

/// The grain of a `width x height` luma picture (row-major, levels);
/// `covered(i)` says whether pixel `i` shows a surface. `None` when no
/// tile is smooth.
#[must_use]
pub fn grain(
    luma: &[f64],
    width: usize,
    height: usize,
    covered: &dyn Fn(usize) -> bool,
) -> Option<Grain> {
    let half = WINDOW / 2;
    let at = |x: usize, y: usize| luma[y * width + x];
    // The median, where its window lies inside the picture.
    let mut median = vec![f64::NAN; luma.len()];
    let mut window = Vec::with_capacity(WINDOW * WINDOW);
    for y in half..height.saturating_sub(half) {
        for x in half..width.saturating_sub(half) {
            window.clear();
            for wy in y - half..=y + half {
                for wx in x - half..=x + half {
                    window.push(at(wx, wy));
                }
            }
            let middle = window.len() / 2;
            window.select_nth_unstable_by(middle, f64::total_cmp);
            median[y * width + x] = window[middle];
        }
    }
    let mut noise = Vec::new();
    // Tiles whose pixels and their right and lower neighbours all have a
    // median.
    let mut ty = half;
    while ty + TILE < height.saturating_sub(half) {
        let mut tx = half;
        while tx + TILE < width.saturating_sub(half) {
            let mut smooth = true;
            let mut sum = 0.0;
            'tile: for y in ty..ty + TILE {
                for x in tx..tx + TILE {
                    let i = y * width + x;
                    let m = median[i];
                    if !covered(i)
                        || (median[i + 1] - m).abs() > EDGE_LEVELS
                        || (median[i + width] - m).abs() > EDGE_LEVELS
                    {
                        smooth = false;
                        break 'tile;
                    }
                    sum += (luma[i] - m).powi(2);
                }
            }
            if smooth {
                noise.push((sum / (TILE * TILE) as f64).sqrt());
            }
            tx += TILE;
        }
        ty += TILE;
    }
    if noise.is_empty() {
        return None;
    }
    noise.sort_by(f64::total_cmp);
    let rank = ((noise.len() as f64 * 0.95).ceil() as usize).clamp(1, noise.len()) - 1;
    Some(Grain {
        p95: noise[rank],
        worst: noise[noise.len() - 1],
        tiles: noise.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth ramp with an edge down its middle, plus noise from `noise`.
    fn picture(width: usize, height: usize, noise: &mut dyn FnMut() -> f64) -> Vec<f64> {
        (0..width * height)
            .map(|i| {
                let (x, y) = (i % width, i / width);
                let ramp = 60.0 + 0.2 * x as f64 + 0.1 * y as f64;
                let edge = if x >= width / 2 { 80.0 } else { 0.0 };
                ramp + edge + noise()
            })
            .collect()
    }

    #[test]
    fn a_smooth_picture_with_an_edge_has_no_grain() {
        let luma = picture(160, 120, &mut || 0.0);
        let g = grain(&luma, 160, 120, &|_| true).unwrap();
        assert!(g.worst < 1e-9, "{g:?}");
        // The tiles across the edge are left out, the others kept.
        assert!(g.tiles >= 40 && g.tiles < 9 * 7, "{g:?}");
    }

    #[test]
    fn noise_of_a_known_spread_reads_about_that_spread() {
        // Uniform noise of +-3 levels: standard deviation sqrt(3).
        let mut state = 99u64;
        let mut noise = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            6.0 * ((state >> 11) as f64 / (1u64 << 53) as f64) - 3.0
        };
        let luma = picture(320, 240, &mut noise);
        let g = grain(&luma, 320, 240, &|_| true).unwrap();
        let sigma = 3f64.sqrt();
        assert!(g.p95 > 0.8 * sigma && g.p95 < 1.4 * sigma, "{g:?}");
    }

    #[test]
    fn uncovered_pixels_leave_their_tiles_out() {
        let luma = picture(160, 120, &mut || 0.0);
        assert_eq!(grain(&luma, 160, 120, &|_| false), None);
    }
}
