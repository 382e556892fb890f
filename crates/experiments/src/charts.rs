//! Log-log line charts as SVG, drawn with `plotters`, for the experiments
//! that go beyond the paper (`accuracy-curve`: accuracy against time,
//! `scale`: cost against scene size): one axis pair, lines with a legend
//! entry each, and the legend box. The paper's own figures keep the
//! bitmap plots of [`super::plot`].

use std::ops::Range;

use plotters::coord::Shift;
use plotters::coord::combinators::LogCoord;
use plotters::prelude::*;

/// A chart with both axes logarithmic, on an SVG drawing area.
pub type LogLog<'a, 'b> =
    ChartContext<'a, SVGBackend<'b>, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>;

/// Axes over `x` and `y` (both logarithmic) with their labels, under
/// `caption` in `caption_size` points, drawn on `area`.
pub fn log_log<'a, 'b>(
    area: &'a DrawingArea<SVGBackend<'b>, Shift>,
    caption: &str,
    caption_size: u32,
    (x, x_desc): (Range<f64>, &str),
    (y, y_desc): (Range<f64>, &str),
) -> Result<LogLog<'a, 'b>, String> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", caption_size))
        .margin(14)
        .x_label_area_size(50)
        .y_label_area_size(64)
        .build_cartesian_2d(x.log_scale(), y.log_scale())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(chart)
}

/// A line through `points` in `colour`, with a legend entry `name`.
pub fn line(
    chart: &mut LogLog<'_, '_>,
    name: &str,
    colour: RGBColor,
    points: impl IntoIterator<Item = (f64, f64)>,
) -> Result<(), String> {
    chart
        .draw_series(LineSeries::new(points, colour.stroke_width(2)))
        .map_err(|e| e.to_string())?
        .label(name)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
    Ok(())
}

/// The legend of the lines drawn, in a framed box at `position`.
pub fn legend<'a, 'b: 'a>(
    chart: &mut LogLog<'a, 'b>,
    position: SeriesLabelPosition,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(position)
        .draw()
        .map_err(|e| e.to_string())
}
