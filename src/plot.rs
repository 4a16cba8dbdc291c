//! Minimal PNG plots for reports: scatter, line and histogram series with axes, numeric tick
//! labels, title, axis labels and a legend.
//!
//! Drawn into an RGB buffer with a built-in 5x7 bitmap font (no system fonts needed) and encoded
//! with the `png` crate. Output bytes depend only on the plot's content. Non-finite values are
//! skipped.
//!
//! ```no_run
//! # fn main() -> kinescan::Result<()> {
//! kinescan::plot::Plot::new("Residuals", "time (s)", "residual (m)")
//!     .scatter("x", &[(0.0, 0.01), (1.0, -0.02)])
//!     .line("fit", &[(0.0, 0.0), (1.0, 0.0)])
//!     .save_png("residuals.png")?;
//! # Ok(()) }
//! ```

use std::path::Path;

use crate::{Error, Result};

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

const WHITE: Rgb = [255, 255, 255];
const BLACK: Rgb = [0, 0, 0];
const GRID: Rgb = [225, 225, 225];
const GLYPH_W: i64 = 5;
const GLYPH_H: i64 = 7;
const TEXT_SCALE: i64 = 2;
const MARKER_RADIUS: i64 = 3;
const TICK_LEN: i64 = 6;
const TARGET_TICKS: f64 = 6.0;

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
/// lines, then scatter markers on top).
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

/// A rendered plot: the RGB pixels and the data-to-pixel mapping.
pub struct Rendered {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// Row-major RGB bytes, `3 * width * height`.
    pub rgb: Vec<u8>,
    frame: Frame,
}

#[derive(Clone, Copy)]
struct Frame {
    left: i64,
    top: i64,
    w: i64,
    h: i64,
    x: (f64, f64),
    y: (f64, f64),
}

impl Frame {
    fn px(&self, x: f64, y: f64) -> (i64, i64) {
        let fx = (x - self.x.0) / (self.x.1 - self.x.0);
        let fy = (y - self.y.0) / (self.y.1 - self.y.0);
        let px = self.left as f64 + fx * (self.w - 1) as f64;
        let py = self.top as f64 + (1.0 - fy) * (self.h - 1) as f64;
        (
            px.round().clamp(-1e6, 1e6) as i64,
            py.round().clamp(-1e6, 1e6) as i64,
        )
    }

    fn inside(&self, px: i64, py: i64) -> bool {
        px >= self.left && px < self.left + self.w && py >= self.top && py < self.top + self.h
    }
}

impl Rendered {
    /// Pixel (column, row from the top) where data point (x, y) is drawn, if inside the axes.
    pub fn to_pixel(&self, x: f64, y: f64) -> Option<(u32, u32)> {
        let (px, py) = self.frame.px(x, y);
        self.frame.inside(px, py).then_some((px as u32, py as u32))
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

    /// Writes the plot as a PNG at `path`, atomically (temporary file, then rename).
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let bytes = self.render()?.png_bytes()?;
        crate::io::atomic::write_atomic(path, &bytes)
    }

    /// Draws the plot. Errors when there is no finite data, a histogram has 0 bins, a fixed
    /// range is empty or the image is smaller than 200 x 150 px.
    pub fn render(&self) -> Result<Rendered> {
        if self.width < 200 || self.height < 150 {
            return Err(Error::Invalid(format!(
                "plot `{}`: {} x {} px is too small (min 200 x 150)",
                self.title, self.width, self.height
            )));
        }
        let hists = self.histograms()?;
        let x = axis_range(
            self.x_range,
            self.data_extent(&hists, true),
            false,
            &self.title,
        )?;
        let y = axis_range(
            self.y_range,
            self.data_extent(&hists, false),
            true,
            &self.title,
        )?;
        let (x_ticks, y_ticks) = (ticks(x), ticks(y));
        let y_tick_w = y_ticks.iter().map(|t| text_width(&t.1)).max().unwrap_or(0);
        let glyph_h = GLYPH_H * TEXT_SCALE;
        let left = 10 + glyph_h + 12 + y_tick_w + TICK_LEN + 4;
        let top = 12 + glyph_h + 12;
        let bottom = TICK_LEN + 6 + glyph_h + 12 + glyph_h + 10;
        let (width, height) = (i64::from(self.width), i64::from(self.height));
        let frame = Frame {
            left,
            top,
            w: width - left - 20,
            h: height - top - bottom,
            x,
            y,
        };
        let mut canvas = Canvas {
            w: width,
            h: height,
            rgb: vec![255; (3 * width * height) as usize],
        };
        canvas.axes(&frame, &x_ticks, &y_ticks);
        self.draw_series(&mut canvas, &frame, &hists);
        canvas.frame_border(&frame);
        self.legend(&mut canvas, &frame);
        canvas.text_centered(&self.title, width / 2, 12);
        let x_label_top = frame.top + frame.h + TICK_LEN + 6 + glyph_h + 12;
        canvas.text_centered(&self.x_label, frame.left + frame.w / 2, x_label_top);
        canvas.text_vertical(
            &self.y_label,
            10,
            frame.top + frame.h / 2 + text_width(&self.y_label) / 2,
        );
        Ok(Rendered {
            width: self.width,
            height: self.height,
            rgb: canvas.rgb,
            frame,
        })
    }

    /// Bin edges and counts of each histogram series, in series order.
    fn histograms(&self) -> Result<Vec<(Vec<f64>, Vec<u64>)>> {
        let mut out = Vec::new();
        for s in &self.series {
            if let Kind::Histogram { values, bins } = &s.kind {
                if *bins == 0 {
                    return Err(Error::Invalid(format!("histogram `{}` has 0 bins", s.name)));
                }
                out.push(bin(values, *bins));
            }
        }
        Ok(out)
    }

    /// (min, max) of finite data along x (or y), None without data.
    fn data_extent(&self, hists: &[(Vec<f64>, Vec<u64>)], along_x: bool) -> Option<(f64, f64)> {
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

    fn draw_series(&self, canvas: &mut Canvas, frame: &Frame, hists: &[(Vec<f64>, Vec<u64>)]) {
        let mut hist_iter = hists.iter();
        for s in &self.series {
            if matches!(s.kind, Kind::Histogram { .. }) {
                if let Some((edges, counts)) = hist_iter.next() {
                    canvas.bars(frame, edges, counts, s.color);
                }
            }
        }
        for s in &self.series {
            if let Kind::Line(p) = &s.kind {
                canvas.polyline(frame, p, s.color);
            }
        }
        for s in &self.series {
            if let Kind::Scatter(p) = &s.kind {
                for &(x, y) in p.iter().filter(|(x, y)| x.is_finite() && y.is_finite()) {
                    let (px, py) = frame.px(x, y);
                    canvas.disc(frame, px, py, s.color);
                }
            }
        }
    }

    /// Top-left of the legend box: the frame corner (top-right, top-left, bottom-right,
    /// bottom-left, first wins ties) covering the fewest scatter/line points.
    fn legend_corner(&self, frame: &Frame, w: i64, h: i64) -> (i64, i64) {
        let (xl, xr) = (frame.left + 8, frame.left + frame.w - w - 8);
        let (yt, yb) = (frame.top + 8, frame.top + frame.h - h - 8);
        let pixels: Vec<(i64, i64)> = self
            .series
            .iter()
            .filter_map(|s| match &s.kind {
                Kind::Scatter(p) | Kind::Line(p) => Some(p),
                Kind::Histogram { .. } => None,
            })
            .flatten()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|&(x, y)| frame.px(x, y))
            .collect();
        let covered = |&(x0, y0): &(i64, i64)| {
            let hit = |&&(px, py): &&(i64, i64)| px >= x0 && px < x0 + w && py >= y0 && py < y0 + h;
            pixels.iter().filter(hit).count()
        };
        let corners = [(xr, yt), (xl, yt), (xr, yb), (xl, yb)];
        corners.into_iter().min_by_key(covered).unwrap_or((xr, yt))
    }

    fn legend(&self, canvas: &mut Canvas, frame: &Frame) {
        if self.series.is_empty() {
            return;
        }
        let row = GLYPH_H * TEXT_SCALE + 6;
        let name_w = self
            .series
            .iter()
            .map(|s| text_width(&s.name))
            .max()
            .unwrap_or(0);
        let (w, h) = (name_w + 40, row * self.series.len() as i64 + 8);
        let (x0, y0) = self.legend_corner(frame, w, h);
        canvas.rect(x0, y0, w, h, WHITE);
        canvas.rect_outline(x0, y0, w, h, BLACK);
        for (i, s) in self.series.iter().enumerate() {
            let cy = y0 + 4 + row * i as i64 + row / 2 - 3;
            match s.kind {
                Kind::Scatter(_) => canvas.disc_unclipped(x0 + 14, cy, s.color),
                Kind::Line(_) => canvas.rect(x0 + 6, cy - 1, 18, 3, s.color),
                Kind::Histogram { .. } => canvas.rect(x0 + 8, cy - 6, 13, 13, s.color),
            }
            canvas.text(&s.name, x0 + 32, cy - GLYPH_H * TEXT_SCALE / 2);
        }
    }
}

/// Equal-width bins over the finite values' range (+-0.5 around a single value).
fn bin(values: &[f64], bins: usize) -> (Vec<f64>, Vec<u64>) {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if finite.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let (lo, hi) = if hi > lo {
        (lo, hi)
    } else {
        (lo - 0.5, hi + 0.5)
    };
    let width = (hi - lo) / bins as f64;
    let edges = (0..=bins).map(|i| lo + width * i as f64).collect();
    let mut counts = vec![0u64; bins];
    for v in finite {
        counts[(((v - lo) / width) as usize).min(bins - 1)] += 1;
    }
    (edges, counts)
}

/// The axis range: fixed, or the data extent padded 5% each side (lower end kept at 0 for
/// non-negative y so histogram bars start on the axis).
fn axis_range(
    fixed: Option<(f64, f64)>,
    extent: Option<(f64, f64)>,
    is_y: bool,
    title: &str,
) -> Result<(f64, f64)> {
    if let Some((lo, hi)) = fixed {
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(Error::Invalid(format!(
                "plot `{title}`: axis range {lo}..{hi} is empty"
            )));
        }
        return Ok((lo, hi));
    }
    let (lo, hi) =
        extent.ok_or_else(|| Error::Invalid(format!("plot `{title}`: no finite data to plot")))?;
    let (lo, hi) = if hi > lo {
        (lo, hi)
    } else {
        (lo - 0.5 * lo.abs().max(1.0), hi + 0.5 * hi.abs().max(1.0))
    };
    let pad = 0.05 * (hi - lo);
    let lo_padded = if is_y && lo == 0.0 { 0.0 } else { lo - pad };
    Ok((lo_padded, hi + pad))
}

/// Ticks at multiples of a 1-2-5 step, with labels.
fn ticks((lo, hi): (f64, f64)) -> Vec<(f64, String)> {
    let raw = (hi - lo) / TARGET_TICKS;
    let mag = 10f64.powf(raw.log10().floor());
    let norm = raw / mag;
    let step = mag
        * if norm < 1.5 {
            1.0
        } else if norm < 3.0 {
            2.0
        } else if norm < 7.0 {
            5.0
        } else {
            10.0
        };
    let decimals = (-(step.log10() + 1e-9).floor()).clamp(0.0, 12.0) as usize;
    let scientific = lo.abs().max(hi.abs()) >= 1e7 || step < 1e-5;
    let (k0, k1) = ((lo / step).ceil() as i64, (hi / step).floor() as i64);
    (k0..=k1)
        .map(|k| {
            let v = if k == 0 { 0.0 } else { k as f64 * step };
            let label = if scientific {
                format!("{v:.3e}")
            } else {
                format!("{v:.decimals$}")
            };
            (v, label)
        })
        .collect()
}

fn text_width(text: &str) -> i64 {
    (text.chars().count() as i64 * (GLYPH_W + 1) - 1).max(0) * TEXT_SCALE
}

struct Canvas {
    w: i64,
    h: i64,
    rgb: Vec<u8>,
}

impl Canvas {
    fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if x >= 0 && y >= 0 && x < self.w && y < self.h {
            let i = 3 * (y * self.w + x) as usize;
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    fn rect(&mut self, x0: i64, y0: i64, w: i64, h: i64, c: Rgb) {
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                self.set(x, y, c);
            }
        }
    }

    fn rect_outline(&mut self, x0: i64, y0: i64, w: i64, h: i64, c: Rgb) {
        self.rect(x0, y0, w, 1, c);
        self.rect(x0, y0 + h - 1, w, 1, c);
        self.rect(x0, y0, 1, h, c);
        self.rect(x0 + w - 1, y0, 1, h, c);
    }

    fn axes(&mut self, f: &Frame, x_ticks: &[(f64, String)], y_ticks: &[(f64, String)]) {
        let glyph_h = GLYPH_H * TEXT_SCALE;
        for (v, label) in x_ticks {
            let (px, _) = f.px(*v, f.y.0);
            self.rect(px, f.top, 1, f.h, GRID);
            self.rect(px, f.top + f.h, 1, TICK_LEN, BLACK);
            self.text_centered(label, px, f.top + f.h + TICK_LEN + 6);
        }
        for (v, label) in y_ticks {
            let (_, py) = f.px(f.x.0, *v);
            self.rect(f.left, py, f.w, 1, GRID);
            self.rect(f.left - TICK_LEN, py, TICK_LEN, 1, BLACK);
            self.text(
                label,
                f.left - TICK_LEN - 4 - text_width(label),
                py - glyph_h / 2,
            );
        }
    }

    fn frame_border(&mut self, f: &Frame) {
        self.rect_outline(f.left - 1, f.top - 1, f.w + 2, f.h + 2, BLACK);
    }

    fn bars(&mut self, f: &Frame, edges: &[f64], counts: &[u64], c: Rgb) {
        let light = c.map(|v| ((u16::from(v) + 2 * 255) / 3) as u8);
        for (i, &n) in counts.iter().enumerate() {
            let (x0, y_top) = f.px(edges[i], n as f64);
            let (x1, y_base) = f.px(edges[i + 1], f.y.0.max(0.0));
            for y in y_top.min(y_base)..=y_top.max(y_base) {
                for x in x0..=x1 {
                    let edge = x == x0 || x == x1 || y == y_top;
                    if f.inside(x, y) {
                        self.set(x, y, if edge { c } else { light });
                    }
                }
            }
        }
    }

    fn polyline(&mut self, f: &Frame, pts: &[(f64, f64)], c: Rgb) {
        let finite = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite();
        let pixels: Vec<(i64, i64)> = pts
            .iter()
            .filter(finite)
            .map(|&(x, y)| f.px(x, y))
            .collect();
        for seg in pixels.windows(2) {
            self.segment(f, seg[0], seg[1], c);
        }
    }

    /// Bresenham segment, 2 px thick, clipped to the frame.
    fn segment(&mut self, f: &Frame, (mut x0, mut y0): (i64, i64), (x1, y1): (i64, i64), c: Rgb) {
        let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
        let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
        let mut err = dx + dy;
        loop {
            for (ox, oy) in [(0, 0), (1, 0), (0, 1)] {
                if f.inside(x0 + ox, y0 + oy) {
                    self.set(x0 + ox, y0 + oy, c);
                }
            }
            if x0 == x1 && y0 == y1 {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x0 += sx;
            }
            if e2 <= dx {
                err += dx;
                y0 += sy;
            }
        }
    }

    fn disc(&mut self, f: &Frame, cx: i64, cy: i64, c: Rgb) {
        self.disc_with(cx, cy, c, |x, y| f.inside(x, y));
    }

    fn disc_unclipped(&mut self, cx: i64, cy: i64, c: Rgb) {
        self.disc_with(cx, cy, c, |_, _| true);
    }

    fn disc_with(&mut self, cx: i64, cy: i64, c: Rgb, keep: impl Fn(i64, i64) -> bool) {
        let r = MARKER_RADIUS;
        for y in -r..=r {
            for x in -r..=r {
                if x * x + y * y <= r * r + 1 && keep(cx + x, cy + y) {
                    self.set(cx + x, cy + y, c);
                }
            }
        }
    }

    /// Text with its top-left corner at (x, y); characters outside ASCII 32-126 draw as '?'.
    fn text(&mut self, text: &str, x: i64, y: i64) {
        for (i, ch) in text.chars().enumerate() {
            let x0 = x + i as i64 * (GLYPH_W + 1) * TEXT_SCALE;
            self.glyph(ch, |gx, gy| (x0 + gx * TEXT_SCALE, y + gy * TEXT_SCALE));
        }
    }

    fn text_centered(&mut self, text: &str, cx: i64, y: i64) {
        self.text(text, cx - text_width(text) / 2, y);
    }

    /// Text rotated 90 degrees counter-clockwise, reading upwards from (x, y_bottom).
    fn text_vertical(&mut self, text: &str, x: i64, y_bottom: i64) {
        for (i, ch) in text.chars().enumerate() {
            let along = i as i64 * (GLYPH_W + 1) * TEXT_SCALE;
            self.glyph(ch, |gx, gy| {
                (
                    x + gy * TEXT_SCALE,
                    y_bottom - along - (gx + 1) * TEXT_SCALE + 1,
                )
            });
        }
    }

    /// Plots each set glyph pixel (gx, gy) as a TEXT_SCALE square at `place(gx, gy)`.
    fn glyph(&mut self, ch: char, place: impl Fn(i64, i64) -> (i64, i64)) {
        let code = ch as u32;
        let index = if (32..=126).contains(&code) {
            code - 32
        } else {
            '?' as u32 - 32
        };
        for (gy, bits) in FONT[index as usize].iter().enumerate() {
            for gx in 0..GLYPH_W {
                if bits >> (GLYPH_W - 1 - gx) & 1 == 1 {
                    let (px, py) = place(gx, gy as i64);
                    self.rect(px, py, TEXT_SCALE, TEXT_SCALE, BLACK);
                }
            }
        }
    }
}

/// 5x7 glyphs for ASCII 32..=126, one row per byte (bit 4 = leftmost column), top row first.
#[rustfmt::skip]
const FONT: [[u8; 7]; 95] = [
    [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000], // ' '
    [0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00000, 0b00100], // '!'
    [0b01010, 0b01010, 0b01010, 0b00000, 0b00000, 0b00000, 0b00000], // '"'
    [0b01010, 0b01010, 0b11111, 0b01010, 0b11111, 0b01010, 0b01010], // '#'
    [0b00100, 0b01111, 0b10100, 0b01110, 0b00101, 0b11110, 0b00100], // '$'
    [0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011], // '%'
    [0b01100, 0b10010, 0b10100, 0b01000, 0b10101, 0b10010, 0b01101], // '&'
    [0b00100, 0b00100, 0b01000, 0b00000, 0b00000, 0b00000, 0b00000], // '\''
    [0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010], // '('
    [0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000], // ')'
    [0b00000, 0b00100, 0b10101, 0b01110, 0b10101, 0b00100, 0b00000], // '*'
    [0b00000, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0b00000], // '+'
    [0b00000, 0b00000, 0b00000, 0b00000, 0b00110, 0b00100, 0b01000], // ','
    [0b00000, 0b00000, 0b00000, 0b11111, 0b00000, 0b00000, 0b00000], // '-'
    [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b01100], // '.'
    [0b00000, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b00000], // '/'
    [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110], // '0'
    [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110], // '1'
    [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111], // '2'
    [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110], // '3'
    [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010], // '4'
    [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110], // '5'
    [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110], // '6'
    [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000], // '7'
    [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110], // '8'
    [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100], // '9'
    [0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b01100, 0b00000], // ':'
    [0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b00100, 0b01000], // ';'
    [0b00010, 0b00100, 0b01000, 0b10000, 0b01000, 0b00100, 0b00010], // '<'
    [0b00000, 0b00000, 0b11111, 0b00000, 0b11111, 0b00000, 0b00000], // '='
    [0b01000, 0b00100, 0b00010, 0b00001, 0b00010, 0b00100, 0b01000], // '>'
    [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b00000, 0b00100], // '?'
    [0b01110, 0b10001, 0b00001, 0b01101, 0b10101, 0b10101, 0b01110], // '@'
    [0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001], // 'A'
    [0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110], // 'B'
    [0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110], // 'C'
    [0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100], // 'D'
    [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111], // 'E'
    [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000], // 'F'
    [0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111], // 'G'
    [0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001], // 'H'
    [0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110], // 'I'
    [0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100], // 'J'
    [0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001], // 'K'
    [0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111], // 'L'
    [0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001], // 'M'
    [0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001], // 'N'
    [0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110], // 'O'
    [0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000], // 'P'
    [0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101], // 'Q'
    [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001], // 'R'
    [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110], // 'S'
    [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100], // 'T'
    [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110], // 'U'
    [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100], // 'V'
    [0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010], // 'W'
    [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001], // 'X'
    [0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100], // 'Y'
    [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111], // 'Z'
    [0b01110, 0b01000, 0b01000, 0b01000, 0b01000, 0b01000, 0b01110], // '['
    [0b00000, 0b10000, 0b01000, 0b00100, 0b00010, 0b00001, 0b00000], // '\\'
    [0b01110, 0b00010, 0b00010, 0b00010, 0b00010, 0b00010, 0b01110], // ']'
    [0b00100, 0b01010, 0b10001, 0b00000, 0b00000, 0b00000, 0b00000], // '^'
    [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b11111], // '_'
    [0b01000, 0b00100, 0b00010, 0b00000, 0b00000, 0b00000, 0b00000], // '`'
    [0b00000, 0b00000, 0b01110, 0b00001, 0b01111, 0b10001, 0b01111], // 'a'
    [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b11110], // 'b'
    [0b00000, 0b00000, 0b01110, 0b10000, 0b10000, 0b10001, 0b01110], // 'c'
    [0b00001, 0b00001, 0b01101, 0b10011, 0b10001, 0b10001, 0b01111], // 'd'
    [0b00000, 0b00000, 0b01110, 0b10001, 0b11111, 0b10000, 0b01110], // 'e'
    [0b00110, 0b01001, 0b01000, 0b11100, 0b01000, 0b01000, 0b01000], // 'f'
    [0b00000, 0b00000, 0b01111, 0b10001, 0b01111, 0b00001, 0b01110], // 'g'
    [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001], // 'h'
    [0b00100, 0b00000, 0b01100, 0b00100, 0b00100, 0b00100, 0b01110], // 'i'
    [0b00010, 0b00000, 0b00110, 0b00010, 0b00010, 0b10010, 0b01100], // 'j'
    [0b10000, 0b10000, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010], // 'k'
    [0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110], // 'l'
    [0b00000, 0b00000, 0b11010, 0b10101, 0b10101, 0b10001, 0b10001], // 'm'
    [0b00000, 0b00000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001], // 'n'
    [0b00000, 0b00000, 0b01110, 0b10001, 0b10001, 0b10001, 0b01110], // 'o'
    [0b00000, 0b00000, 0b11110, 0b10001, 0b11110, 0b10000, 0b10000], // 'p'
    [0b00000, 0b00000, 0b01101, 0b10011, 0b01111, 0b00001, 0b00001], // 'q'
    [0b00000, 0b00000, 0b10110, 0b11001, 0b10000, 0b10000, 0b10000], // 'r'
    [0b00000, 0b00000, 0b01110, 0b10000, 0b01110, 0b00001, 0b11110], // 's'
    [0b01000, 0b01000, 0b11100, 0b01000, 0b01000, 0b01001, 0b00110], // 't'
    [0b00000, 0b00000, 0b10001, 0b10001, 0b10001, 0b10011, 0b01101], // 'u'
    [0b00000, 0b00000, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100], // 'v'
    [0b00000, 0b00000, 0b10001, 0b10001, 0b10101, 0b10101, 0b01010], // 'w'
    [0b00000, 0b00000, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001], // 'x'
    [0b00000, 0b00000, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110], // 'y'
    [0b00000, 0b00000, 0b11111, 0b00010, 0b00100, 0b01000, 0b11111], // 'z'
    [0b00010, 0b00100, 0b00100, 0b01000, 0b00100, 0b00100, 0b00010], // '{'
    [0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100], // '|'
    [0b01000, 0b00100, 0b00100, 0b00010, 0b00100, 0b00100, 0b01000], // '}'
    [0b00000, 0b00000, 0b01000, 0b10101, 0b00010, 0b00000, 0b00000], // '~'
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_inside() {
        let t = ticks((0.0, 10.0));
        let values: Vec<f64> = t.iter().map(|t| t.0).collect();
        assert_eq!(values, [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!(t[1].1, "2");
        let t = ticks((-0.013, 0.021));
        assert!(t.iter().all(|(v, _)| (-0.013..=0.021).contains(v)));
        assert_eq!(t.iter().find(|t| t.0 == 0.0).unwrap().1, "0.000");
    }

    #[test]
    fn points_land_where_the_axes_say() {
        let plot = Plot::new("Test plot", "x (m)", "y (m)")
            .size(400, 300)
            .x_range(0.0, 10.0)
            .y_range(0.0, 10.0)
            .scatter("pts", &[(2.0, 3.0), (7.5, 8.0), (11.0, 5.0)])
            .line("flat", &[(0.0, 5.0), (10.0, 5.0)]);
        let r = plot.render().unwrap();
        assert_eq!((r.width, r.height, r.rgb.len()), (400, 300, 400 * 300 * 3));
        // Linear mapping: the axis corners bound the frame, x grows right, y grows up.
        let (x0, y0) = r.to_pixel(0.0, 0.0).unwrap();
        let (x1, y1) = r.to_pixel(10.0, 10.0).unwrap();
        assert!(x1 > x0 && y1 < y0);
        let (xm, ym) = r.to_pixel(2.0, 3.0).unwrap();
        assert_eq!(xm, (x0 as f64 + 0.2 * f64::from(x1 - x0)).round() as u32);
        assert_eq!(ym, (y0 as f64 - 0.3 * f64::from(y0 - y1)).round() as u32);
        // Markers in the first palette colour, the line in the second, outside data the background.
        assert_eq!(r.pixel(xm, ym), PALETTE[0]);
        let (xp, yp) = r.to_pixel(7.5, 8.0).unwrap();
        assert_eq!(r.pixel(xp, yp), PALETTE[0]);
        assert_eq!(r.to_pixel(11.0, 5.0), None, "out-of-range point is clipped");
        let (xl, yl) = r.to_pixel(5.0, 5.0).unwrap(); // off the x = 4, 6 grid lines
        assert_eq!(r.pixel(xl, yl), PALETTE[1]);
        assert_eq!(r.pixel(xl, yl - 5), WHITE);
        // Deterministic bytes, a valid PNG of the right size.
        let png_bytes = r.png_bytes().unwrap();
        assert_eq!(png_bytes, plot.render().unwrap().png_bytes().unwrap());
        let decoder = png::Decoder::new(std::io::Cursor::new(png_bytes));
        let info = decoder.read_info().unwrap().info().clone();
        assert_eq!((info.width, info.height), (400, 300));
    }

    /// A report-like plot; set `KINESCAN_PLOT_OUT=dir` to keep the PNGs for a visual check.
    #[test]
    fn save_png_writes_a_decodable_file() {
        let dir = tempfile::tempdir().unwrap();
        let keep = std::env::var_os("KINESCAN_PLOT_OUT").map(std::path::PathBuf::from);
        let out = keep.as_deref().unwrap_or(dir.path());
        let t: Vec<f64> = (0..200).map(|i| 345_600.0 + f64::from(i) * 0.05).collect();
        let res = |k: f64| -> Vec<(f64, f64)> {
            t.iter()
                .map(|&t| (t, 0.01 * (t * k).sin() + 0.002 * (t * 7.0 * k).cos()))
                .collect()
        };
        let fit: Vec<(f64, f64)> = t.iter().map(|&t| (t, 0.004 * (t * 0.3).sin())).collect();
        let scatter_path = out.join("plot_scatter.png");
        Plot::new(
            "Sync residuals, run 3",
            "GPS time (s of week)",
            "residual (m)",
        )
        .scatter("along-track", &res(1.3))
        .scatter("across-track", &res(0.7))
        .line("model", &fit)
        .save_png(&scatter_path)
        .unwrap();
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let normal = Normal::new(0.0, 0.8).unwrap();
        let values: Vec<f64> = (0..2000).map(|_| normal.sample(&mut rng)).collect();
        let hist_path = out.join("plot_hist.png");
        Plot::new("Plane residuals", "distance (mm)", "count")
            .histogram("residuals", &values, 25)
            .save_png(&hist_path)
            .unwrap();
        for p in [scatter_path, hist_path] {
            let decoder =
                png::Decoder::new(std::io::BufReader::new(std::fs::File::open(p).unwrap()));
            let info = decoder.read_info().unwrap().info().clone();
            assert_eq!((info.width, info.height), (800, 560));
        }
    }

    #[test]
    fn bad_plots_are_errors() {
        assert!(Plot::new("t", "x", "y").render().is_err());
        assert!(Plot::new("t", "x", "y")
            .histogram("h", &[1.0], 0)
            .render()
            .is_err());
        assert!(Plot::new("t", "x", "y")
            .scatter("s", &[(f64::NAN, 1.0)])
            .render()
            .is_err());
        assert!(Plot::new("t", "x", "y")
            .x_range(1.0, 1.0)
            .line("l", &[(0.0, 0.0)])
            .render()
            .is_err());
    }

    #[test]
    fn histogram_counts_every_finite_value_once() {
        let (edges, counts) = bin(&[0.0, 0.5, 1.0, 2.0, f64::NAN, 4.0], 4);
        assert_eq!(edges, [0.0, 1.0, 2.0, 3.0, 4.0]);
        assert_eq!(counts, [2, 1, 1, 1]); // 4.0 falls in the last (closed) bin
    }
}
