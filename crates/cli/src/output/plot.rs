//! SVG scatter plots ([`scatter_svg`]).

use std::io;

/// One point of a [`scatter_svg`] plot.
pub(crate) struct Point {
    pub x: f64,
    /// Plotted on a log scale as `log10(1 + y)`, so zero is at the bottom.
    pub y: f64,
    pub label: String,
    /// An SVG colour.
    pub color: &'static str,
}

/// How a [`scatter_svg`] plot scales its x axis.
#[derive(Clone, Copy)]
pub(crate) struct Axes<'a> {
    /// Logarithmic x over the decades the points span (positive x only) instead of linear
    /// from 0: for quantities spanning several orders of magnitude, such as build times.
    pub x_log: bool,
    /// Colour key drawn at the top right: (name, SVG colour); empty for none.
    pub legend: &'a [(&'a str, &'a str)],
}

/// A scatter plot as SVG: linear x from 0 (or logarithmic, see [`Axes`]), logarithmic y
/// (`1 + y`), labelled points. A point that cannot be placed (a NaN or infinite coordinate,
/// a negative y, a non-positive x on a log axis) is left out, named in a note under the title
/// and in a warning on stderr: no coordinate in the file is ever NaN or infinite, and an
/// infinite value cannot stretch the axes.
pub(crate) fn scatter_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[Point],
    axes: Axes<'_>,
) -> String {
    let placeable =
        |p: &Point| p.x.is_finite() && p.y.is_finite() && p.y >= 0.0 && (!axes.x_log || p.x > 0.0);
    let (points, left_out): (Vec<&Point>, Vec<&Point>) = points.iter().partition(|p| placeable(p));
    let (w, h, m) = (760.0, 480.0, 70.0);
    // Text goes into the SVG escaped: labels are scene names, which may be any file path.
    let (title_text, x_label, y_label) = (xml(title), xml(x_label), xml(y_label));
    let xmax = points.iter().map(|p| p.x).fold(0.0f64, f64::max).max(1e-12) * 1.1;
    let ymax = points
        .iter()
        .map(|p| p.y)
        .fold(10.0f64, f64::max)
        .log10()
        .ceil();
    // Decades for a log x axis: from the smallest positive x's to the largest's.
    let lo = points
        .iter()
        .map(|p| p.x)
        .filter(|&x| x > 0.0)
        .fold(f64::INFINITY, f64::min)
        .min(xmax)
        .log10()
        .floor();
    let hi = xmax.log10().ceil().max(lo + 1.0);
    let x = |v: f64| {
        let f = if axes.x_log {
            (v.max(1e-300).log10() - lo) / (hi - lo)
        } else {
            v / xmax
        };
        m + f * (w - 2.0 * m)
    };
    let y = |v: f64| h - m - (1.0 + v).log10() / ymax * (h - 2.0 * m);
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='11'>\n\
         <rect width='100%' height='100%' fill='white'/>\n\
         <text x='{}' y='20' text-anchor='middle' font-size='14'>{title_text}</text>\n\
         <line x1='{m}' y1='{}' x2='{}' y2='{}' stroke='black'/><line x1='{m}' y1='{m}' x2='{m}' y2='{}' stroke='black'/>\n\
         <text x='{}' y='{}' text-anchor='middle'>{x_label}</text>\n\
         <text x='16' y='{}' transform='rotate(-90 16 {})' text-anchor='middle'>{y_label}</text>\n",
        w / 2.0, h - m, w - m, h - m, h - m, w / 2.0, h - 20.0, h / 2.0, h / 2.0
    );
    if !left_out.is_empty() {
        let shown: Vec<String> = left_out
            .iter()
            .map(|p| format!("{} ({}, {})", p.label, p.x, p.y))
            .collect();
        let note = format!(
            "{} point(s) left out, not placeable on these axes: {}",
            left_out.len(),
            shown.join(", ")
        );
        use std::io::Write as _;
        // A failed stderr has nowhere to be reported; the plot is still written.
        let _ = writeln!(io::stderr(), "warning: plot '{title}': {note}");
        s += &format!(
            "<text x='{}' y='36' text-anchor='middle' fill='firebrick'>{}</text>\n",
            w / 2.0,
            xml(&note)
        );
    }
    for k in 0..=ymax as i32 {
        let v = 10f64.powi(k) - 1.0;
        s += &format!(
            "<text x='{}' y='{}' text-anchor='end'>{}</text>\n",
            m - 6.0,
            y(v) + 4.0,
            10f64.powi(k) as u64 - 1
        );
    }
    let ticks: Vec<f64> = if axes.x_log {
        (lo as i32..=hi as i32).map(|k| 10f64.powi(k)).collect()
    } else {
        (0..=4).map(|k| xmax * k as f64 / 4.0).collect()
    };
    for v in ticks {
        // Log ticks are powers of ten (0.01 … 1000); linear ones whole numbers.
        let text = if axes.x_log {
            format!("{v}")
        } else {
            format!("{v:.0}")
        };
        s += &format!(
            "<text x='{}' y='{}' text-anchor='middle'>{text}</text>\n",
            x(v),
            h - m + 16.0
        );
    }
    for (i, (name, color)) in axes.legend.iter().enumerate() {
        let ly = m + 12.0 * i as f64;
        s += &format!(
            "<circle cx='{}' cy='{ly}' r='4' fill='{color}'/><text x='{}' y='{}'>{}</text>\n",
            w - m - 90.0,
            w - m - 82.0,
            ly + 4.0,
            xml(name)
        );
    }
    for (i, p) in points.iter().enumerate() {
        let (px, py) = (x(p.x), y(p.y));
        s += &format!(
            "<circle cx='{px:.1}' cy='{py:.1}' r='5' fill='{}' fill-opacity='0.7'/><text x='{:.1}' y='{:.1}'>{}</text>\n",
            p.color,
            px + 7.0,
            py - 4.0 + (i % 2) as f64 * 12.0,
            xml(&p.label)
        );
    }
    s + "</svg>\n"
}

/// `text` with XML's five special characters escaped, for SVG text and attributes.
fn xml(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '\'' => out.push_str("&apos;"),
            '"' => out.push_str("&quot;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No NaN or infinity reaches the SVG, whatever the points: an infinite y used to make
    /// the y axis loop to i32::MAX, a NaN x printed `NaN` coordinates.
    #[test]
    fn scatter_plot_leaves_out_points_it_cannot_place_and_says_so() {
        let p = |x: f64, y: f64, label: &str| Point {
            x,
            y,
            label: label.into(),
            color: "black",
        };
        let points = [
            p(1.0, 2.0, "fine"),
            p(f64::NAN, 1.0, "nan-x"),
            p(3.0, f64::INFINITY, "inf-y"),
            p(f64::NEG_INFINITY, 1.0, "neg-inf-x"),
            p(2.0, -5.0, "negative-y"),
            p(0.0, 1.0, "zero-x"),
            p(1.5, 1.0, "<a&b's>.obj"),
        ];
        for x_log in [false, true] {
            let axes = Axes { x_log, legend: &[] };
            let svg = scatter_svg("t", "x", "y", &points, axes);
            let numbers = svg
                .split(['\'', '>', '<', ' '])
                .filter(|t| t.parse::<f64>().is_ok());
            for t in numbers {
                assert!(t.parse::<f64>().unwrap().is_finite(), "{t} in {svg}");
            }
            assert!(!svg.contains("NaN") || svg.contains("nan-x (NaN"), "{svg}");
            assert!(svg.contains(">fine</text>"));
            // Labels are escaped: a scene path may hold any character.
            assert!(svg.contains(">&lt;a&amp;b&apos;s&gt;.obj</text>"), "{svg}");
            let left = if x_log { 5 } else { 4 };
            assert!(svg.contains(&format!("{left} point(s) left out")), "{svg}");
            assert!(svg.len() < 10_000, "{} bytes", svg.len());
            // Only the note shows the values that could not be placed.
            let circles = svg.matches("<circle").count();
            assert_eq!(circles, points.len() - left, "{svg}");
        }
    }
}
