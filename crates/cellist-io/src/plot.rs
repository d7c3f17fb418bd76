//! PNG line charts, drawn without system font libraries (DejaVu Sans is compiled in).

use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// The family name the bundled DejaVu Sans is registered under.
pub(crate) const FAMILY: &str = "sans-serif";

/// Registers the bundled font once (every chart calls this first).
pub(crate) fn register_font() {
    REGISTER.call_once(|| {
        // The font is compiled in and known to parse; a failure here would be a bug.
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .unwrap_or_else(|_| panic!("the bundled DejaVu Sans font did not load"));
    });
}

/// How a curve is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeriesStyle {
    /// A solid line.
    Line,
    /// A solid line with a dot at each point (measurements).
    Points,
    /// A dashed grey line (references: ideal scaling, slopes).
    Reference,
}

/// One named curve of a chart.
pub struct Series<'a> {
    /// Legend text.
    pub label: &'a str,
    /// The points `(x, y)`, in drawing order.
    pub points: &'a [(f64, f64)],
    /// How it is drawn.
    pub style: SeriesStyle,
}

impl<'a> Series<'a> {
    /// A solid line.
    pub fn line(label: &'a str, points: &'a [(f64, f64)]) -> Self {
        Series {
            label,
            points,
            style: SeriesStyle::Line,
        }
    }
}

/// A chart: title, axis labels (with units), which axes are logarithmic, and its
/// curves.
pub struct Chart<'a> {
    /// Title.
    pub title: &'a str,
    /// Label of the horizontal axis.
    pub x_label: &'a str,
    /// Label of the vertical axis.
    pub y_label: &'a str,
    /// Logarithmic horizontal axis (points with x <= 0 are left out).
    pub log_x: bool,
    /// Logarithmic vertical axis (points with y <= 0 are left out).
    pub log_y: bool,
    /// The curves.
    pub series: &'a [Series<'a>],
}

/// A tick label that keeps small and large values apart: scientific notation
/// below 0.01 and from 10^5 on (so `4e-5` does not print as `0.00004` or `0.0`).
fn tick_label(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() < 1e-2 || v.abs() >= 1e5 {
        format!("{v:.2e}")
    } else {
        trim_zeros(format!("{v:.3}"))
    }
}

/// `1.500` as `1.5`, `2.000` as `2`.
fn trim_zeros(text: String) -> String {
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

/// A tick label of a logarithmic axis: three significant digits, no trailing
/// zeros (`15.8`, `20`, `126`), scientific notation below 0.01 and from 10^5 on.
fn log_tick_label(v: f64) -> String {
    if v.abs() < 1e-2 || v.abs() >= 1e5 {
        return format!("{v:.2e}");
    }
    let decimals = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    trim_zeros(format!("{v:.decimals$}"))
}

/// Draws `series` as lines on one chart with linear axes and writes it to `path`
/// (PNG), replacing the file only once the picture is complete.
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series<'_>],
) -> Result<(), String> {
    draw_chart(
        path,
        &Chart {
            title,
            x_label,
            y_label,
            log_x: false,
            log_y: false,
            series,
        },
    )
}

/// Draws `chart` and writes it to `path` (PNG), replacing the file only once the
/// picture is complete. A logarithmic axis is drawn linear in log10 of the value,
/// its ticks labelled with the values.
pub fn draw_chart(path: &Path, chart: &Chart<'_>) -> Result<(), String> {
    register_font();
    let map = |x: f64, log: bool| if log { x.log10() } else { x };
    let curves: Vec<Vec<(f64, f64)>> = chart
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter(|&&(x, y)| (!chart.log_x || x > 0.0) && (!chart.log_y || y > 0.0))
                .map(|&(x, y)| (map(x, chart.log_x), map(y, chart.log_y)))
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect()
        })
        .collect();
    let (x_range, y_range) = ranges(&curves);
    // a linear tick within a billionth of the axis' width of 0 is 0 (the tick
    // positions' rounding, e.g. -6.8e-21)
    let label = |v: f64, log: bool, range: &std::ops::Range<f64>| {
        if log {
            log_tick_label(10f64.powf(v))
        } else if v.abs() <= 1e-9 * (range.end - range.start) {
            tick_label(0.0)
        } else {
            tick_label(v)
        }
    };
    let temp = path.with_extension("partial.png");
    {
        let root = BitMapBackend::new(&temp, (960, 640)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut plot = ChartBuilder::on(&root)
            .caption(chart.title, ("sans-serif", 26))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(80)
            .build_cartesian_2d(x_range.clone(), y_range.clone())
            .map_err(|e| e.to_string())?;
        plot.configure_mesh()
            .x_desc(chart.x_label)
            .y_desc(chart.y_label)
            .x_label_formatter(&|v| label(*v, chart.log_x, &x_range))
            .y_label_formatter(&|v| label(*v, chart.log_y, &y_range))
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| e.to_string())?;
        let (mut colours, mut references) = (0, 0);
        for (s, points) in chart.series.iter().zip(&curves) {
            let colour = match s.style {
                SeriesStyle::Reference => {
                    references += 1;
                    REFERENCE_COLOURS[(references - 1) % REFERENCE_COLOURS.len()].to_rgba()
                }
                _ => {
                    colours += 1;
                    Palette99::pick(colours - 1).to_rgba()
                }
            };
            let stroke = colour.stroke_width(2);
            let drawn = match s.style {
                SeriesStyle::Reference => plot
                    .draw_series(DashedLineSeries::new(points.iter().copied(), 8, 6, stroke))
                    .map_err(|e| e.to_string())?,
                _ => plot
                    .draw_series(LineSeries::new(points.iter().copied(), stroke))
                    .map_err(|e| e.to_string())?,
            };
            drawn.label(s.label).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
            if s.style == SeriesStyle::Points {
                plot.draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                    .map_err(|e| e.to_string())?;
            }
        }
        plot.configure_series_labels()
            .position(legend_corner(&curves, (x_range.clone(), y_range.clone())))
            .label_font(("sans-serif", 16))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    std::fs::rename(&temp, path).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The colours of reference lines (ideal scaling, slopes): greys and muted hues,
/// told apart from the measured curves by their dashes.
const REFERENCE_COLOURS: [RGBColor; 4] = [
    RGBColor(90, 90, 90),
    RGBColor(150, 120, 80),
    RGBColor(110, 130, 170),
    RGBColor(160, 110, 150),
];

/// The corner of the plot where the legend hides the least of the curves: the
/// one whose legend-sized box (the outer 40 % of the width, 25 % of the height)
/// holds the fewest of the curves' points and of the points along their
/// segments.
fn legend_corner(
    curves: &[Vec<(f64, f64)>],
    (x, y): (std::ops::Range<f64>, std::ops::Range<f64>),
) -> SeriesLabelPosition {
    let corners = [
        (SeriesLabelPosition::UpperRight, true, true),
        (SeriesLabelPosition::UpperLeft, false, true),
        (SeriesLabelPosition::LowerRight, true, false),
        (SeriesLabelPosition::LowerLeft, false, false),
    ];
    let unit = |(px, py): (f64, f64)| {
        (
            (px - x.start) / (x.end - x.start),
            (py - y.start) / (y.end - y.start),
        )
    };
    let samples: Vec<(f64, f64)> = curves
        .iter()
        .flat_map(|c| {
            c.windows(2)
                .flat_map(|w| {
                    let (a, b) = (unit(w[0]), unit(w[1]));
                    (0..8).map(move |k| {
                        let t = k as f64 / 8.0;
                        (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
                    })
                })
                .chain(c.last().map(|&p| unit(p)))
        })
        .collect();
    let count = |right: bool, upper: bool| {
        samples
            .iter()
            .filter(|&&(u, v)| {
                let across = if right { u > 0.6 } else { u < 0.4 };
                let along = if upper { v > 0.75 } else { v < 0.25 };
                across && along
            })
            .count()
    };
    corners
        .into_iter()
        .min_by_key(|&(_, right, upper)| count(right, upper))
        .map_or(SeriesLabelPosition::UpperRight, |(corner, _, _)| corner)
}

/// Axis ranges covering every point, widened a little (and made non-empty).
fn ranges(curves: &[Vec<(f64, f64)>]) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for &(x, y) in curves.iter().flatten() {
        if x.is_finite() && y.is_finite() {
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
    }
    let widen = |a: f64, b: f64| {
        if !a.is_finite() {
            return 0.0..1.0;
        }
        let pad = ((b - a) * 0.05).max(1e-12 * a.abs().max(1.0));
        a - pad..b + pad
    };
    (widen(lo.0, hi.0), widen(lo.1, hi.1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_tell_small_values_apart() {
        assert_eq!(tick_label(0.0), "0");
        assert_eq!(tick_label(4e-5), "4.00e-5");
        assert_eq!(tick_label(3.5e-5), "3.50e-5");
        assert_eq!(tick_label(-0.25), "-0.25");
        assert_eq!(tick_label(2.0e6), "2.00e6");
        assert_eq!(tick_label(15.0), "15");
        assert_eq!(log_tick_label(15.849), "15.8");
        assert_eq!(log_tick_label(19.953), "20");
        assert_eq!(log_tick_label(125.89), "126");
        assert_eq!(log_tick_label(0.031623), "0.0316");
        assert_eq!(log_tick_label(3.16e-3), "3.16e-3");
        assert_eq!(tick_label(15.5), "15.5");
        assert_eq!(tick_label(0.0125), "0.013");
    }

    #[test]
    fn writes_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("chart.png");
        let pts: Vec<(f64, f64)> = (0..50)
            .map(|k| (k as f64, (k as f64 * 0.2).sin()))
            .collect();
        line_chart(&path, "sine", "x", "y", &[Series::line("sin", &pts)]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(!dir.path().join("chart.partial.png").exists());
    }
}
