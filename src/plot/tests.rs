//! The plots' pixels, bytes and errors.

use super::*;

const WHITE_RGB: Rgb = [255, 255, 255];

fn decode(png_bytes: &[u8]) -> (png::OutputInfo, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::Cursor::new(png_bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info, buf)
}

#[test]
fn points_land_where_the_axes_say() {
    let plot = Plot::new("Test plot", "x (m)", "y (m)")
        .size(400, 300)
        .x_range(0.0, 10.0)
        .y_range(0.0, 10.0)
        .scatter("pts", &[(2.0, 3.0), (7.5, 8.0), (10.3, 5.0)])
        .line("flat", &[(0.0, 5.0), (10.0, 5.0)]);
    let r = plot.render().unwrap();
    assert_eq!((r.width, r.height, r.rgb.len()), (400, 300, 400 * 300 * 3));
    // Linear mapping: the axis corners bound the frame, x grows right, y grows up.
    let (x0, y0) = r.to_pixel(0.0, 0.0).unwrap();
    let (x1, y1) = r.to_pixel(10.0, 10.0).unwrap();
    assert!(x1 > x0 && y1 < y0);
    let (xm, ym) = r.to_pixel(2.0, 3.0).unwrap();
    // Within a pixel of the linear interpolation (plotters floors, this rounds).
    assert!((f64::from(xm) - (f64::from(x0) + 0.2 * f64::from(x1 - x0))).abs() <= 1.0);
    assert!((f64::from(ym) - (f64::from(y0) - 0.3 * f64::from(y0 - y1))).abs() <= 1.0);
    // Markers in the first palette colour, the line in the second, above it background.
    assert_eq!(r.pixel(xm, ym), PALETTE[0]);
    let (xp, yp) = r.to_pixel(7.5, 8.0).unwrap();
    assert_eq!(r.pixel(xp, yp), PALETTE[0]);
    let (xl, yl) = r.to_pixel(5.0, 5.0).unwrap(); // off the x = 4, 6 grid lines
    assert_eq!(r.pixel(xl, yl), PALETTE[1]);
    assert_eq!(r.pixel(xl, yl - 5), WHITE_RGB);
    // The point outside the fixed x range is clipped: not drawn right of the axes.
    assert_eq!(r.to_pixel(10.3, 5.0), None);
    let (xo, yo) = r.coord.translate(&(10.3, 5.0));
    assert!(xo < 400, "the clipped marker would be inside the image");
    assert_eq!(r.pixel(xo as u32, yo as u32), WHITE_RGB);
}

#[test]
fn same_data_gives_the_same_png_bytes() {
    let plot = || {
        Plot::new("Residuals", "time (s)", "residual (m)")
            .scatter("x", &[(0.0, 0.01), (1.0, -0.02), (2.0, 0.005)])
            .line("fit", &[(0.0, 0.0), (2.0, 0.0)])
            .histogram("h", &[0.2, 0.4, 0.5, 1.5], 3)
    };
    let a = plot().render().unwrap().png_bytes().unwrap();
    let b = plot().render().unwrap().png_bytes().unwrap();
    assert_eq!(a, b);
    let c = plot().size(801, 560).render().unwrap().png_bytes().unwrap();
    assert_ne!(a, c, "a different plot gives different bytes");
}

/// A report-like plot; set `KINESCAN_PLOT_OUT=dir` to keep the PNGs for a visual check.
#[test]
fn save_png_writes_a_decodable_non_blank_file() {
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
    let shifted: Vec<f64> = values.iter().map(|v| 0.5 * v + 0.3).collect();
    let hist_path = out.join("plot_hist.png");
    Plot::new("Plane residuals", "distance (mm)", "count")
        .histogram("before", &values, 25)
        .histogram("after", &shifted, 25)
        .save_png(&hist_path)
        .unwrap();
    for p in [scatter_path, hist_path] {
        let (info, rgb) = decode(&std::fs::read(&p).unwrap());
        assert_eq!((info.width, info.height), (800, 560));
        assert_eq!(info.color_type, png::ColorType::Rgb);
        // Not blank: text (black) and the first series' colour are drawn.
        let count = |c: Rgb| rgb.chunks_exact(3).filter(|px| *px == c).count();
        assert!(count([0, 0, 0]) > 500, "{p:?}: no text or frame");
        assert!(count(PALETTE[0]) > 200, "{p:?}: no data drawn");
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
    assert!(Plot::new("t", "x", "y")
        .size(100, 100)
        .line("l", &[(0.0, 0.0), (1.0, 1.0)])
        .render()
        .is_err());
}
