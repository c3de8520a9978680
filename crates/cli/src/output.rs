//! Everything the commands write: tables and lines on stdout, JSON reports, PNG images,
//! the node-count heatmap, and SVG scatter plots.

use crate::commands::Result;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// `println!` that stops quietly when stdout is gone (`quiver ... | head`) instead of panicking.
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}
pub(crate) use outln;

/// `print!` with the same rule as [`outln!`].
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($t)*);
    }};
}

pub(crate) use out;

/// A report as a two-column table: key, value (floats to three decimals).
pub(crate) fn print_table(report: &Value) {
    let Value::Object(map) = report else { return };
    let width = map.keys().map(|k| k.len()).max().unwrap_or(0);
    for (k, v) in map {
        let shown = match v {
            Value::String(s) => s.clone(),
            Value::Number(n) if n.is_f64() => format!("{:.3}", n.as_f64().unwrap_or(f64::NAN)),
            other => other.to_string(),
        };
        outln!("{k:<width$}  {shown}");
    }
}

/// Writes `report` as pretty JSON to `path`, if given.
pub(crate) fn write_json(path: Option<&PathBuf>, report: &Value) -> Result<()> {
    if let Some(p) = path {
        let text = serde_json::to_string_pretty(report)?;
        std::fs::write(p, text + "\n").map_err(|e| format!("cannot write {}: {e}", p.display()))?;
    }
    Ok(())
}

/// Writes an 8-bit RGB image.
pub(crate) fn write_png(path: &Path, w: u32, h: u32, rgb: &[[u8; 3]]) -> Result<()> {
    let fail = |e: &dyn std::fmt::Display| format!("cannot write {}: {e}", path.display());
    let file = std::fs::File::create(path).map_err(|e| fail(&e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(|e| fail(&e))?;
    writer
        .write_image_data(rgb.as_flattened())
        .map_err(|e| fail(&e))?;
    writer.finish().map_err(|e| fail(&e))?;
    Ok(())
}

/// A false-colour picture of per-ray node counts: dark blue (few) through green and yellow to
/// red (the most, at the 99th percentile so a few outliers do not wash out the image).
pub(crate) fn heatmap(counts: &[u32], width: usize) -> (usize, Vec<[u8; 3]>) {
    let mut sorted = counts.to_vec();
    sorted.sort_unstable();
    let top = sorted
        .get(sorted.len() * 99 / 100)
        .copied()
        .unwrap_or(1)
        .max(1) as f32;
    let px = counts
        .iter()
        .map(|&c| {
            let x = (c as f32 / top).min(1.0);
            let ramp = [
                (0.0, [0.0, 0.0, 0.3]),
                (0.33, [0.0, 0.6, 1.0]),
                (0.66, [1.0, 1.0, 0.0]),
                (1.0, [1.0, 0.0, 0.0]),
            ];
            let k = ramp.windows(2).position(|w| x <= w[1].0).unwrap_or(2);
            let (a, b) = (ramp[k], ramp[k + 1]);
            let f = (x - a.0) / (b.0 - a.0);
            let ch = |i: usize| ((a.1[i] + (b.1[i] - a.1[i]) * f) * 255.0 + 0.5) as u8;
            [ch(0), ch(1), ch(2)]
        })
        .collect();
    (width, px)
}

/// One point of a [`scatter_svg`] plot.
pub(crate) struct Point {
    pub x: f64,
    /// Plotted on a log scale as `log10(1 + y)`, so zero is at the bottom.
    pub y: f64,
    pub label: String,
    /// An SVG colour.
    pub color: &'static str,
}

/// A scatter plot as SVG: linear x from 0, logarithmic y (`1 + y`), labelled points.
pub(crate) fn scatter_svg(title: &str, x_label: &str, y_label: &str, points: &[Point]) -> String {
    let (w, h, m) = (760.0, 480.0, 70.0);
    let xmax = points.iter().map(|p| p.x).fold(0.0f64, f64::max).max(1e-12) * 1.1;
    let ymax = points
        .iter()
        .map(|p| p.y)
        .fold(10.0f64, f64::max)
        .log10()
        .ceil();
    let x = |v: f64| m + v / xmax * (w - 2.0 * m);
    let y = |v: f64| h - m - (1.0 + v).log10() / ymax * (h - 2.0 * m);
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='11'>\n\
         <rect width='100%' height='100%' fill='white'/>\n\
         <text x='{}' y='20' text-anchor='middle' font-size='14'>{title}</text>\n\
         <line x1='{m}' y1='{}' x2='{}' y2='{}' stroke='black'/><line x1='{m}' y1='{m}' x2='{m}' y2='{}' stroke='black'/>\n\
         <text x='{}' y='{}' text-anchor='middle'>{x_label}</text>\n\
         <text x='16' y='{}' transform='rotate(-90 16 {})' text-anchor='middle'>{y_label}</text>\n",
        w / 2.0, h - m, w - m, h - m, h - m, w / 2.0, h - 20.0, h / 2.0, h / 2.0
    );
    for k in 0..=ymax as i32 {
        let v = 10f64.powi(k) - 1.0;
        s += &format!(
            "<text x='{}' y='{}' text-anchor='end'>{}</text>\n",
            m - 6.0,
            y(v) + 4.0,
            10f64.powi(k) as u64 - 1
        );
    }
    for k in 0..=4 {
        let v = xmax * k as f64 / 4.0;
        s += &format!(
            "<text x='{}' y='{}' text-anchor='middle'>{v:.0}</text>\n",
            x(v),
            h - m + 16.0
        );
    }
    for (i, p) in points.iter().enumerate() {
        let (px, py) = (x(p.x), y(p.y));
        s += &format!(
            "<circle cx='{px:.1}' cy='{py:.1}' r='5' fill='{}' fill-opacity='0.7'/><text x='{:.1}' y='{:.1}'>{}</text>\n",
            p.color,
            px + 7.0,
            py - 4.0 + (i % 2) as f64 * 12.0,
            p.label
        );
    }
    s + "</svg>\n"
}
