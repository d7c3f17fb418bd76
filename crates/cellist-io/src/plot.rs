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

/// One named curve of a chart.
pub struct Series<'a> {
    /// Legend text.
    pub label: &'a str,
    /// The points `(x, y)`, in drawing order.
    pub points: &'a [(f64, f64)],
}

/// A tick label that keeps small and large values apart: scientific notation
/// below 0.01 and from 10^5 on (so `4e-5` does not print as `0.00004` or `0.0`).
fn tick_label(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() < 1e-2 || v.abs() >= 1e5 {
        format!("{v:.2e}")
    } else {
        format!("{v:.3}")
    }
}

/// Draws `series` as lines on one chart and writes it to `path` (PNG), replacing the
/// file only once the picture is complete.
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series<'_>],
) -> Result<(), String> {
    register_font();
    let (x_range, y_range) = ranges(series);
    let temp = path.with_extension("partial.png");
    {
        let root = BitMapBackend::new(&temp, (960, 640)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 26))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(80)
            .build_cartesian_2d(x_range, y_range)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .y_label_formatter(&|v| tick_label(*v))
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| e.to_string())?;
        for (k, s) in series.iter().enumerate() {
            let colour = Palette99::pick(k).to_rgba();
            chart
                .draw_series(LineSeries::new(
                    s.points.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label(s.label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 16))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    std::fs::rename(&temp, path).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Axis ranges covering every point, widened a little (and made non-empty).
fn ranges(series: &[Series<'_>]) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for &(x, y) in series.iter().flat_map(|s| s.points) {
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
        assert_eq!(tick_label(-0.25), "-0.250");
        assert_eq!(tick_label(2.0e6), "2.00e6");
    }

    #[test]
    fn writes_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("chart.png");
        let pts: Vec<(f64, f64)> = (0..50)
            .map(|k| (k as f64, (k as f64 * 0.2).sin()))
            .collect();
        line_chart(
            &path,
            "sine",
            "x",
            "y",
            &[Series {
                label: "sin",
                points: &pts,
            }],
        )
        .unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(!dir.path().join("chart.partial.png").exists());
    }
}
