//! PNG plots for reports: scatter, line and histogram series with axes, numeric tick labels,
//! title, axis labels and a legend.
//!
//! Drawn with `plotters` into an in-memory RGB buffer (bitmap backend, text through `ab_glyph`
//! with the embedded DejaVu Sans: no system font is looked up) and encoded with the `png`
//! crate. Output bytes depend only on the plot's content. Non-finite values are skipped.
//!
//! ```no_run
//! # fn main() -> kinescan::Result<()> {
//! kinescan::plot::Plot::new("Residuals", "time (s)", "residual (m)")
//!     .scatter("x", &[(0.0, 0.01), (1.0, -0.02)])
//!     .line("fit", &[(0.0, 0.0), (1.0, 0.0)])
//!     .save_png("residuals.png")?;
//! # Ok(()) }
//! ```

mod axes;

use std::path::Path;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::{Error, Result};
use axes::{axis_range, bin, Ticks};

/// An RGB colour.
pub type Rgb = [u8; 3];

/// Series colours, assigned in the order series are added.
pub const PALETTE: [Rgb; 8] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [23, 190, 207],
    [140, 86, 75],
    [227, 119, 194],
];

/// The font family every text is drawn in (DejaVu Sans, registered once).
const FONT: &str = "sans-serif";
const TITLE_PX: u32 = 22;
const LABEL_PX: u32 = 16;
const TICK_PX: u32 = 14;
/// Most tick marks per axis; plotters places them at multiples of a 1-2-5 step.
const MAX_TICKS: usize = 8;
const LEGEND_PX: u32 = 14;
const MARKER_RADIUS_PX: i32 = 3;
const LINE_WIDTH_PX: u32 = 2;
const GRID: RGBColor = RGBColor(225, 225, 225);
/// Opacity of histogram bar fills, so overlapping histograms both stay visible.
const BAR_FILL_ALPHA: f64 = 0.3;
/// Width of a legend row's key (marker, line or square) before its name.
const LEGEND_KEY_PX: i32 = 30;

enum Kind {
    Scatter(Vec<(f64, f64)>),
    Line(Vec<(f64, f64)>),
    Histogram { values: Vec<f64>, bins: usize },
}

struct Series {
    name: String,
    color: Rgb,
    kind: Kind,
}

/// A plot under construction; series are drawn in the order added (histograms first, then
/// lines, then scatter markers on top), the legend lists them in the order added.
pub struct Plot {
    title: String,
    x_label: String,
    y_label: String,
    width: u32,
    height: u32,
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
    series: Vec<Series>,
}

/// Data coordinates -> pixels of the drawn axes.
type Coord = Cartesian2d<RangedCoordf64, RangedCoordf64>;
/// The axes being drawn into the RGB buffer.
type Chart<'a, 'b> = ChartContext<'a, BitMapBackend<'b>, Coord>;
/// What drawing returns: plotters' errors boxed (they only reach the message).
type DrawResult<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// A rendered plot: the RGB pixels and the data-to-pixel mapping.
pub struct Rendered {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// Row-major RGB bytes, `3 * width * height`.
    pub rgb: Vec<u8>,
    coord: Coord,
}

impl Rendered {
    /// Pixel (column, row from the top) where data point (x, y) is drawn, if inside the axes.
    pub fn to_pixel(&self, x: f64, y: f64) -> Option<(u32, u32)> {
        let (px, py) = self.coord.translate(&(x, y));
        // The pixel ranges' ends are the last pixels of the axes (drawn too).
        let (xs, ys) = (
            self.coord.get_x_axis_pixel_range(),
            self.coord.get_y_axis_pixel_range(),
        );
        let inside = (xs.start..=xs.end).contains(&px) && (ys.start..=ys.end).contains(&py);
        inside.then_some((px as u32, py as u32))
    }

    /// Colour at column `px`, row `py` (from the top).
    pub fn pixel(&self, px: u32, py: u32) -> Rgb {
        let i = 3 * (py as usize * self.width as usize + px as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// The image as PNG bytes (8-bit RGB, no metadata chunks).
    pub fn png_bytes(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let err = |e: png::EncodingError| Error::Invalid(format!("PNG encoding: {e}"));
        let mut writer = enc.write_header().map_err(err)?;
        writer.write_image_data(&self.rgb).map_err(err)?;
        writer.finish().map_err(err)?;
        Ok(out)
    }
}

impl Plot {
    /// An empty 800 x 560 px plot.
    pub fn new(title: &str, x_label: &str, y_label: &str) -> Self {
        Plot {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            width: 800,
            height: 560,
            x_range: None,
            y_range: None,
            series: Vec::new(),
        }
    }

    /// Image size in pixels (at least 200 x 150 is sensible).
    pub fn size(mut self, width: u32, height: u32) -> Self {
        (self.width, self.height) = (width, height);
        self
    }

    /// Fixed x axis range instead of the data's padded extent.
    pub fn x_range(mut self, lo: f64, hi: f64) -> Self {
        self.x_range = Some((lo, hi));
        self
    }

    /// Fixed y axis range instead of the data's padded extent.
    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = Some((lo, hi));
        self
    }

    /// Adds (x, y) points drawn as filled markers.
    pub fn scatter(self, name: &str, points: &[(f64, f64)]) -> Self {
        self.push(name, Kind::Scatter(points.to_vec()))
    }

    /// Adds a polyline through (x, y) points in the given order.
    pub fn line(self, name: &str, points: &[(f64, f64)]) -> Self {
        self.push(name, Kind::Line(points.to_vec()))
    }

    /// Adds a histogram of `values` in `bins` equal bins over their range (y = count).
    pub fn histogram(self, name: &str, values: &[f64], bins: usize) -> Self {
        self.push(
            name,
            Kind::Histogram {
                values: values.to_vec(),
                bins,
            },
        )
    }

    /// Sets the colour of the series added last (instead of its palette colour), e.g. to draw
    /// a fit in the colour of its data.
    pub fn color(mut self, color: Rgb) -> Self {
        if let Some(s) = self.series.last_mut() {
            s.color = color;
        }
        self
    }

    fn push(mut self, name: &str, kind: Kind) -> Self {
        let color = PALETTE[self.series.len() % PALETTE.len()];
        self.series.push(Series {
            name: name.into(),
            color,
            kind,
        });
        self
    }

    /// Writes the plot as a PNG at `path` through [`crate::io::atomic::write_atomic`].
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<()> {
        let bytes = self.render()?.png_bytes()?;
        crate::io::atomic::write_atomic(path.as_ref(), &bytes)
    }

    /// Draws the plot. Errors when there is no finite data, a histogram has 0 bins, a fixed
    /// range is empty or the image is smaller than 200 x 150 px.
    pub fn render(&self) -> Result<Rendered> {
        if self.width < 200 || self.height < 150 {
            return Err(self.invalid(format!(
                "{} x {} px is too small (min 200 x 150)",
                self.width, self.height
            )));
        }
        register_font()?;
        let hists = self.histograms()?;
        let x = axis_range(self.x_range, self.data_extent(&hists, true), false)
            .map_err(|e| self.invalid(e))?;
        let y = axis_range(self.y_range, self.data_extent(&hists, false), true)
            .map_err(|e| self.invalid(e))?;
        let mut rgb = vec![255; 3 * self.width as usize * self.height as usize];
        let coord = self
            .draw(&mut rgb, x, y, &hists)
            .map_err(|e| self.invalid(format!("drawing: {e}")))?;
        Ok(Rendered {
            width: self.width,
            height: self.height,
            rgb,
            coord,
        })
    }

    fn invalid(&self, what: impl std::fmt::Display) -> Error {
        Error::Invalid(format!("plot `{}`: {what}", self.title))
    }

    /// Draws into `rgb`: plotters does not clip series to the axes, so the series are drawn
    /// first and everything outside the axes is then painted over (title, tick labels, axis
    /// labels and legend drawn last).
    fn draw(
        &self,
        rgb: &mut [u8],
        x: (f64, f64),
        y: (f64, f64),
        hists: &[Binned],
    ) -> DrawResult<Coord> {
        let (x_ticks, y_ticks) = (Ticks::new(x, MAX_TICKS), Ticks::new(y, MAX_TICKS));
        let root = BitMapBackend::with_buffer(rgb, (self.width, self.height)).into_drawing_area();
        let title_style = (FONT, TITLE_PX).into_font();
        let area = root.titled(&self.title, title_style.clone())?;
        let tick_font = TextStyle::from((FONT, TICK_PX).into_font());
        let y_tick_w = y_ticks
            .labels()
            .iter()
            .map(|l| root.estimate_text_size(l, &tick_font).map(|s| s.0))
            .try_fold(0, |w, s| s.map(|s| w.max(s)))?;
        let mut chart = ChartBuilder::on(&area)
            .margin(10)
            .margin_right(20)
            .x_label_area_size(TICK_PX + LABEL_PX + 30)
            .y_label_area_size(y_tick_w + LABEL_PX + 24)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
        chart
            .configure_mesh()
            .x_labels(MAX_TICKS)
            .y_labels(MAX_TICKS)
            .bold_line_style(GRID)
            .light_line_style(TRANSPARENT)
            .axis_style(TRANSPARENT)
            .draw()?;
        self.draw_series(&mut chart, hists)?;
        let (xs, ys) = chart.plotting_area().get_pixel_range();
        for outside in margins(&xs, &ys, self.width as i32, self.height as i32) {
            root.draw(&Rectangle::new(outside, WHITE.filled()))?;
        }
        root.titled(&self.title, title_style)?;
        let x_format = |v: &f64| x_ticks.label(*v);
        let y_format = |v: &f64| y_ticks.label(*v);
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(MAX_TICKS)
            .y_labels(MAX_TICKS)
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .x_label_formatter(&x_format)
            .y_label_formatter(&y_format)
            .label_style(tick_font)
            .axis_desc_style((FONT, LABEL_PX))
            .draw()?;
        root.draw(&Rectangle::new(
            [(xs.start - 1, ys.start - 1), (xs.end, ys.end)],
            BLACK,
        ))?;
        // The chart's own mapping (as `ChartBuilder` sets it up): last pixel inclusive, y up.
        let coord = Coord::new(
            x.0..x.1,
            y.0..y.1,
            (xs.start..xs.end - 1, ys.end - 1..ys.start),
        );
        self.legend(&mut chart, &coord)?;
        root.present()?;
        Ok(coord)
    }

    fn draw_series(&self, chart: &mut Chart<'_, '_>, hists: &[Binned]) -> DrawResult<()> {
        let mut hist_iter = hists.iter();
        for s in &self.series {
            if matches!(s.kind, Kind::Histogram { .. }) {
                let (edges, counts) = hist_iter.next().ok_or("histogram without bins")?;
                let c = rgb(s.color);
                let bars = counts
                    .iter()
                    .enumerate()
                    .map(|(i, &n)| [(edges[i], 0.0), (edges[i + 1], n as f64)]);
                chart.draw_series(
                    bars.clone()
                        .map(|r| Rectangle::new(r, c.mix(BAR_FILL_ALPHA).filled())),
                )?;
                chart.draw_series(bars.map(|r| Rectangle::new(r, c)))?;
            }
        }
        for s in &self.series {
            if let Kind::Line(p) = &s.kind {
                let style = rgb(s.color).stroke_width(LINE_WIDTH_PX);
                chart.draw_series(LineSeries::new(finite(p), style))?;
            }
        }
        for s in &self.series {
            if let Kind::Scatter(p) = &s.kind {
                let style = rgb(s.color).filled();
                chart.draw_series(finite(p).map(|p| Circle::new(p, MARKER_RADIUS_PX, style)))?;
            }
        }
        Ok(())
    }
}

impl Plot {
    /// Bin edges and counts of each histogram series, in series order.
    fn histograms(&self) -> Result<Vec<Binned>> {
        let mut out = Vec::new();
        for s in &self.series {
            if let Kind::Histogram { values, bins } = &s.kind {
                if *bins == 0 {
                    return Err(self.invalid(format_args!("histogram `{}` has 0 bins", s.name)));
                }
                out.push(bin(values, *bins));
            }
        }
        Ok(out)
    }

    /// (min, max) of finite data along x (or y), None without data.
    fn data_extent(&self, hists: &[Binned], along_x: bool) -> Option<(f64, f64)> {
        let mut vals: Vec<f64> = Vec::new();
        for s in &self.series {
            if let Kind::Scatter(p) | Kind::Line(p) = &s.kind {
                vals.extend(p.iter().map(|&(x, y)| if along_x { x } else { y }));
            }
        }
        for (edges, counts) in hists {
            if along_x {
                vals.extend(edges.first().into_iter().chain(edges.last()));
            } else {
                vals.push(0.0);
                vals.extend(counts.iter().map(|&c| c as f64));
            }
        }
        let finite = vals.into_iter().filter(|v| v.is_finite());
        finite.fold(None, |acc, v| {
            Some(acc.map_or((v, v), |(lo, hi): (f64, f64)| (lo.min(v), hi.max(v))))
        })
    }

    /// The legend: one row per series in the order added (a marker, a line segment or a
    /// filled square in its colour, then its name), in the corner covering the fewest points.
    fn legend<'a>(&self, chart: &mut Chart<'a, 'a>, coord: &Coord) -> DrawResult<()> {
        if self.series.is_empty() {
            return Ok(());
        }
        for s in &self.series {
            let c = rgb(s.color);
            let entry = chart.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?;
            entry.label(s.name.as_str());
            match s.kind {
                Kind::Scatter(_) => entry
                    .legend(move |(x, y)| Circle::new((x + 10, y), MARKER_RADIUS_PX, c.filled())),
                Kind::Line(_) => entry.legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], c.stroke_width(LINE_WIDTH_PX))
                }),
                Kind::Histogram { .. } => entry.legend(move |(x, y)| {
                    Rectangle::new([(x + 4, y - 6), (x + 16, y + 6)], c.filled())
                }),
            };
        }
        let font = TextStyle::from((FONT, LEGEND_PX).into_font());
        let mut rows = MultiLineText::<(i32, i32), &str>::new((0, 0), &font);
        self.series
            .iter()
            .for_each(|s| rows.push_line(s.name.as_str()));
        let (w, h) = rows.estimate_dimension()?;
        chart
            .configure_series_labels()
            .position(self.legend_corner(coord, (w + LEGEND_KEY_PX + 20, h + 20)))
            .legend_area_size(LEGEND_KEY_PX as u32)
            .margin(10)
            .background_style(WHITE)
            .border_style(BLACK)
            .label_font(font.clone())
            .draw()?;
        Ok(())
    }

    /// The axes corner (top-right, top-left, bottom-right, bottom-left, first wins ties) whose
    /// `(w, h)` px legend box, 5 px in from the axes as plotters places it, covers the fewest
    /// scatter/line points.
    fn legend_corner(&self, coord: &Coord, (w, h): (i32, i32)) -> SeriesLabelPosition {
        let (xs, ys) = (
            coord.get_x_axis_pixel_range(),
            coord.get_y_axis_pixel_range(),
        );
        let (left, right) = (xs.start + 5, xs.end - w - 5);
        let (top, bottom) = (ys.start + 5, ys.end - h - 5);
        let pixels: Vec<(i32, i32)> = self
            .series
            .iter()
            .filter_map(|s| match &s.kind {
                Kind::Scatter(p) | Kind::Line(p) => Some(finite(p)),
                Kind::Histogram { .. } => None,
            })
            .flatten()
            .map(|p| coord.translate(&p))
            .collect();
        let covered = |&(x0, y0, _): &(i32, i32, SeriesLabelPosition)| {
            let hit = |&&(px, py): &&(i32, i32)| px >= x0 && px < x0 + w && py >= y0 && py < y0 + h;
            pixels.iter().filter(hit).count()
        };
        use SeriesLabelPosition::*;
        let corners = [
            (right, top, UpperRight),
            (left, top, UpperLeft),
            (right, bottom, LowerRight),
            (left, bottom, LowerLeft),
        ];
        corners
            .into_iter()
            .min_by_key(covered)
            .map_or(UpperRight, |c| c.2)
    }
}

/// Edges and counts of one histogram.
type Binned = (Vec<f64>, Vec<u64>);

fn rgb([r, g, b]: Rgb) -> RGBColor {
    RGBColor(r, g, b)
}

fn finite(points: &[(f64, f64)]) -> impl Iterator<Item = (f64, f64)> + Clone + '_ {
    points
        .iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
}

/// The four rectangles of a `width` x `height` image outside the pixel ranges `xs`, `ys`.
fn margins(
    xs: &std::ops::Range<i32>,
    ys: &std::ops::Range<i32>,
    width: i32,
    height: i32,
) -> [[(i32, i32); 2]; 4] {
    [
        [(0, 0), (width, ys.start - 1)],
        [(0, ys.end), (width, height)],
        [(0, 0), (xs.start - 1, height)],
        [(xs.end, 0), (width, height)],
    ]
}

/// Registers DejaVu Sans (embedded by the `dejavu` crate) as [`FONT`], once per process.
fn register_font() -> Result<()> {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok()
    });
    ok.then_some(())
        .ok_or_else(|| Error::Invalid("plot: the embedded DejaVu Sans font did not load".into()))
}

#[cfg(test)]
mod tests;
