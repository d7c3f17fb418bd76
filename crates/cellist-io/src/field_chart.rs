//! Readable pictures of a 2D particle field (e.g. the vorticity of a vortex-particle
//! run): the field painted as by [`FieldPainter`] in a square plot area with axes,
//! tick labels, axis titles, a title and a vertical colour bar, written as an RGB PNG.
//!
//! The field is painted straight into a pixel buffer (one pass over the particles,
//! whatever their number) and blitted into the chart; `plotters` draws only the
//! text, axes and frames around it.

use crate::{AtomicFile, FieldPainter};
use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;
use plotters::element::BitMapElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::io;
use std::path::Path;

/// The family of the bundled DejaVu Sans (registered by [`crate::plot`]).
const FAMILY: &str = crate::plot::FAMILY;

/// Font sizes in pixels.
const TITLE_FONT: u32 = 18;
const TICK_FONT: u32 = 15;
const AXIS_FONT: u32 = 16;

/// Layout in pixels (see [`FieldChart::plot_area`]).
const MARGIN: u32 = 12;
const TITLE_HEIGHT: u32 = 40;
const LEFT_LABELS: u32 = 72;
const BOTTOM_LABELS: u32 = 50;
const BAR_GAP: u32 = 20;
const BAR_WIDTH: u32 = 22;
const RIGHT_LABELS: u32 = 92;
/// The narrowest chart: its plot area is then 100 pixels wide.
const MIN_WIDTH: u32 = MARGIN + LEFT_LABELS + 100 + BAR_GAP + BAR_WIDTH + RIGHT_LABELS + MARGIN;

/// What a field chart shows and how large it is. The field's colours are those of
/// [`FieldPainter`]: blue for `-scale` (and below), white for 0, red for `+scale` (and
/// above); grey where no particle's square reaches. The colour bar runs from
/// `-scale` to `+scale`, or from 0 for a field of magnitudes.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldChart {
    /// The width of the picture in pixels (at least 330, raised if smaller); the
    /// height follows so that the plot area is square ([`FieldChart::height`]).
    pub width: u32,
    /// The lower left corner of the view.
    pub lo: [f64; 2],
    /// The side of the square view `[lo, lo + side)^2`.
    pub side: f64,
    /// The particle spacing: each particle paints the square of this side around it.
    pub spacing: f64,
    /// The colour scale: values at or beyond `±scale` get the end colours.
    pub scale: f64,
    /// The chart's title, e.g. `"vorticity at t = 1.250"`.
    pub title: String,
    /// The colour bar's label, e.g. `"ω = Γ/h²"`.
    pub value_label: String,
    /// The unit of length of the axes, e.g. `"σ"` (axis titles `x (σ)`, `y (σ)`);
    /// empty for plain `x` and `y`.
    pub unit: String,
    /// The names of the horizontal and vertical axes (`"x"`, `"y"`).
    pub axes: [String; 2],
    /// The view is a periodic box: particle squares that cross an edge of the
    /// view wrap to the other side ([`FieldChart::render`]; otherwise they are
    /// clipped).
    pub periodic: bool,
    /// The values are magnitudes, never negative (`|ω|`): the colour bar runs
    /// from 0 (white) to `scale` (red), without the blue half no value takes.
    pub magnitude: bool,
}

impl FieldChart {
    /// A 640-pixel-wide chart of the view `[lo, lo + side)^2` for particles `spacing`
    /// apart with colours saturating at `|value| = scale`, with an empty title, the
    /// value label `"value"`, no unit, axes `x` and `y`, not periodic, signed
    /// values.
    pub fn new(lo: [f64; 2], side: f64, spacing: f64, scale: f64) -> Self {
        FieldChart {
            width: 640,
            lo,
            side,
            spacing,
            scale,
            title: String::new(),
            value_label: "value".into(),
            unit: String::new(),
            axes: ["x".into(), "y".into()],
            periodic: false,
            magnitude: false,
        }
    }

    /// The width of the picture in pixels (`width`, raised to the minimum).
    pub fn picture_width(&self) -> u32 {
        self.width.max(MIN_WIDTH)
    }

    /// The height of the picture in pixels.
    pub fn height(&self) -> u32 {
        TITLE_HEIGHT + self.plot_side() + BOTTOM_LABELS + MARGIN
    }

    fn plot_side(&self) -> u32 {
        self.picture_width() - (MIN_WIDTH - 100)
    }

    /// The plot area in pixels: its top left pixel `[column, row]` and its side. The
    /// field's pixel `(i, j)` (column, row from the top) covers
    /// `x = lo[0] + (i, i + 1) * side / n`, `y = lo[1] + side - (j, j + 1) * side / n`.
    pub fn plot_area(&self) -> ([u32; 2], u32) {
        ([MARGIN + LEFT_LABELS, TITLE_HEIGHT], self.plot_side())
    }

    /// The colour bar in pixels: its top left pixel `[column, row]`, width and height.
    /// Its top row is the colour of `+scale`, its bottom row that of `-scale`
    /// (of 0 for a field of [`magnitude`](FieldChart::magnitude)s).
    pub fn colour_bar_area(&self) -> ([u32; 2], u32, u32) {
        let ([x0, y0], n) = self.plot_area();
        ([x0 + n + BAR_GAP, y0], BAR_WIDTH, n)
    }

    /// Renders the chart of `points` (`(position, value)` pairs) and returns its RGB
    /// pixels, 3 bytes each, row by row from the top: [`FieldChart::picture_width`]
    /// by [`FieldChart::height`] of them.
    pub fn render(&self, points: impl IntoIterator<Item = ([f64; 2], f64)>) -> io::Result<Vec<u8>> {
        let invalid = |what: &str| Err(io::Error::new(io::ErrorKind::InvalidInput, what));
        if !(self.side > 0.0 && self.side.is_finite()) {
            return invalid("field chart: the side of the view must be positive and finite");
        }
        if !(self.lo[0].is_finite() && self.lo[1].is_finite()) {
            return invalid("field chart: the corner of the view must be finite");
        }
        if !(self.spacing >= 0.0 && self.spacing.is_finite()) {
            return invalid("field chart: the particle spacing must be finite and not negative");
        }
        let (_, n) = self.plot_area();
        let palette = FieldPainter::palette();
        let (mut painter, lo) = if self.periodic {
            // the periodic painter's box is [0, side)^2
            let painter = FieldPainter::new(n, self.side, self.spacing, self.scale);
            (painter, self.lo)
        } else {
            let painter = FieldPainter::with_view(n, self.lo, self.side, self.spacing, self.scale);
            (painter, [0.0; 2])
        };
        let shifted = points
            .into_iter()
            .map(|([x, y], v)| ([x - lo[0], y - lo[1]], v));
        let field = palette_rgb(painter.render(shifted), &palette);
        let scale = painter.scale();
        let low = if self.magnitude { 0.0 } else { -scale };
        self.render_painted(field, (low, scale), |value| {
            palette_rgb(&[painter.colour_index(value)], &palette)
                .try_into()
                .expect("three bytes")
        })
    }

    /// The chart around a picture painted elsewhere: `field` holds the RGB pixels
    /// of the plot area (its side from [`FieldChart::plot_area`], rows from the
    /// top), and the colour bar runs from `range.0` (bottom) to `range.1` (top)
    /// in the colours `colour(value)`. Returns the picture's RGB pixels.
    pub fn render_painted(
        &self,
        field: Vec<u8>,
        range: (f64, f64),
        colour: impl Fn(f64) -> [u8; 3],
    ) -> io::Result<Vec<u8>> {
        let (_, bar_width, bar_height) = self.colour_bar_area();
        let mut bar = Vec::with_capacity((3 * bar_width * bar_height) as usize);
        for row in 0..bar_height {
            let t = 1.0 - (row as f64 + 0.5) / bar_height as f64;
            let rgb = colour(range.0 + t * (range.1 - range.0));
            for _ in 0..bar_width {
                bar.extend_from_slice(&rgb);
            }
        }
        crate::plot::register_font();
        let (width, height) = (self.picture_width(), self.height());
        let mut pixels = vec![255u8; (3 * width * height) as usize];
        self.draw(&mut pixels, field, bar, range)
            .map_err(|e| io::Error::other(format!("field chart: {e}")))?;
        Ok(pixels)
    }

    /// Draws text, axes and frames with plotters and blits the painted `field` and
    /// colour `bar` (RGB) into their areas.
    fn draw(
        &self,
        pixels: &mut [u8],
        field: Vec<u8>,
        bar: Vec<u8>,
        (low, high): (f64, f64),
    ) -> Result<(), Box<dyn std::error::Error>> {
        let (width, height) = (self.picture_width(), self.height());
        let ([x0, y0], n) = self.plot_area();
        let ([bar_x, bar_y], bar_width, bar_height) = self.colour_bar_area();
        let root = BitMapBackend::with_buffer(pixels, (width, height)).into_drawing_area();
        root.fill(&WHITE)?;
        let title_style = (FAMILY, TITLE_FONT)
            .into_font()
            .color(&BLACK)
            .pos(Pos::new(HPos::Center, VPos::Center));
        root.draw_text(
            &self.title,
            &title_style,
            ((x0 + n / 2) as i32, (TITLE_HEIGHT / 2 - 2) as i32),
        )?;
        let tick_style = (FAMILY, TICK_FONT).into_font().color(&BLACK);
        let axis_style = (FAMILY, AXIS_FONT).into_font().color(&BLACK);

        // The field: axes in the label areas left of and below the plot area.
        let field_area = root
            .clone()
            .shrink((x0 - LEFT_LABELS, y0), (LEFT_LABELS + n, n + BOTTOM_LABELS));
        let [lx, ly] = self.lo;
        let mut chart = ChartBuilder::on(&field_area)
            .x_label_area_size(BOTTOM_LABELS)
            .y_label_area_size(LEFT_LABELS)
            .build_cartesian_2d(lx..lx + self.side, ly..ly + self.side)?;
        // The field is blitted where plotters maps the view, to the pixel.
        if chart.plotting_area().get_pixel_range()
            != (x0 as i32..(x0 + n) as i32, y0 as i32..(y0 + n) as i32)
        {
            return Err("the plot area is not where the field is painted".into());
        }
        let axis_title = |name: &str| {
            if self.unit.is_empty() {
                name.to_string()
            } else {
                format!("{name} ({})", self.unit)
            }
        };
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(7)
            .y_labels(7)
            .x_label_formatter(&|v| tick_text(*v))
            .y_label_formatter(&|v| tick_text(*v))
            .label_style(tick_style.clone())
            .axis_desc_style(axis_style.clone())
            .x_desc(axis_title(&self.axes[0]))
            .draw()?;
        // The y axis title, reading upwards, just left of the widest tick label (the
        // ticks are those plotters chose above).
        let mut widest = 0;
        for v in RangedCoordf64::from(ly..ly + self.side).key_points(7usize) {
            widest = widest.max(root.estimate_text_size(&tick_text(v), &tick_style)?.0);
        }
        let y_title = axis_title(&self.axes[1]);
        let (_, title_height) = root.estimate_text_size(&y_title, &axis_style)?;
        let title_x = (x0 as i32 - 10 - widest as i32 - 10 - title_height as i32 / 2)
            .max(title_height as i32 / 2 + 2);
        root.draw_text(
            &y_title,
            &axis_style
                .transform(FontTransform::Rotate270)
                .pos(Pos::new(HPos::Center, VPos::Center)),
            (title_x, (y0 + n / 2) as i32),
        )?;
        root.draw(
            &BitMapElement::with_owned_buffer((x0 as i32, y0 as i32), (n, n), field)
                .ok_or("field buffer too small")?,
        )?;
        root.draw(&frame([x0, y0], n, n))?;

        // The colour bar: five ticks from low to high, labels left-aligned just right
        // of them, the value label (reading upwards) right of the widest tick label.
        let bar_right = (bar_x + bar_width) as i32;
        let mut widest = 0;
        for k in 0..=4 {
            let f = 0.25 * k as f64;
            let text = tick_text(low + f * (high - low));
            let row = bar_y as i32 + ((1.0 - f) * (bar_height - 1) as f64).round() as i32;
            root.draw(&PathElement::new(
                vec![(bar_right, row), (bar_right + 5, row)],
                BLACK.stroke_width(1),
            ))?;
            let style = tick_style.pos(Pos::new(HPos::Left, VPos::Center));
            root.draw_text(&text, &style, (bar_right + 8, row))?;
            widest = widest.max(root.estimate_text_size(&text, &tick_style)?.0);
        }
        let (_, label_height) = root.estimate_text_size(&self.value_label, &axis_style)?;
        let label_x = (bar_right as u32 + 8 + widest + 10 + label_height / 2)
            .min(width - label_height / 2 - 2);
        root.draw_text(
            &self.value_label,
            &axis_style
                .transform(FontTransform::Rotate270)
                .pos(Pos::new(HPos::Center, VPos::Center)),
            (label_x as i32, (bar_y + bar_height / 2) as i32),
        )?;
        root.draw(
            &BitMapElement::with_owned_buffer(
                (bar_x as i32, bar_y as i32),
                (bar_width, bar_height),
                bar,
            )
            .ok_or("colour bar buffer too small")?,
        )?;
        root.draw(&frame([bar_x, bar_y], bar_width, bar_height))?;
        root.present()?;
        Ok(())
    }
}

/// A black rectangle just outside the `width` x `height` pixels from `corner`.
fn frame(corner: [u32; 2], width: u32, height: u32) -> Rectangle<(i32, i32)> {
    let [x, y] = corner.map(|c| c as i32);
    Rectangle::new(
        [(x - 1, y - 1), (x + width as i32, y + height as i32)],
        BLACK.stroke_width(1),
    )
}

/// A short tick label: up to four significant digits without trailing zeros, in
/// scientific notation below 10^-3 and from 10^5 on.
fn tick_text(v: f64) -> String {
    fn trim(s: &str) -> &str {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.')
        } else {
            s
        }
    }
    let a = v.abs();
    // Ticks that should be 0 but carry rounding noise (e.g. 5.55e-17) print as 0.
    if a < 1e-12 || !v.is_finite() {
        return if v.is_finite() {
            "0".into()
        } else {
            v.to_string()
        };
    }
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        trim(&format!("{v:.decimals$}")).to_string()
    } else {
        let s = format!("{v:.3e}");
        match s.split_once('e') {
            Some((mantissa, exponent)) => format!("{}e{exponent}", trim(mantissa)),
            None => s,
        }
    }
}

/// Renders the chart of `points` (`(position, value)` pairs) and writes it to `path`
/// as an RGB PNG, whole or not at all: nothing is written if rendering fails, and
/// the file appears under its name only once complete.
pub fn field_chart(
    path: &Path,
    chart: &FieldChart,
    points: impl IntoIterator<Item = ([f64; 2], f64)>,
) -> io::Result<()> {
    write_chart(path, chart, &chart.render(points)?)
}

/// `indices` into `palette` (RGB triples) as RGB pixels.
pub fn palette_rgb(indices: &[u8], palette: &[u8]) -> Vec<u8> {
    indices
        .iter()
        .flat_map(|&i| palette[3 * i as usize..3 * i as usize + 3].iter().copied())
        .collect()
}

/// Writes the RGB `pixels` of `chart` (from [`FieldChart::render`] or
/// [`FieldChart::render_painted`]) to `path` as a PNG, whole or not at all.
pub fn write_chart(path: &Path, chart: &FieldChart, pixels: &[u8]) -> io::Result<()> {
    let mut file = AtomicFile::create(path)?;
    {
        let mut encoder = png::Encoder::new(file.writer(), chart.picture_width(), chart.height());
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(io::Error::other)?;
        writer.write_image_data(pixels).map_err(io::Error::other)?;
        writer.finish().map_err(io::Error::other)?;
    }
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_png::{dark_pixels, decode, pixel};

    fn palette_colour(index: u8) -> [u8; 3] {
        let p = FieldPainter::palette();
        let k = 3 * index as usize;
        [p[k], p[k + 1], p[k + 2]]
    }

    /// A lattice on the view [-1, 3)^2 with spacing 0.25: positive (+1.5, twice the
    /// scale) around the centre (1, 1), negative elsewhere.
    fn lattice() -> impl Iterator<Item = ([f64; 2], f64)> {
        let (n, h) = (16, 0.25);
        (0..n * n).map(move |k| {
            let x = [
                -1.0 + ((k % n) as f64 + 0.5) * h,
                -1.0 + ((k / n) as f64 + 0.5) * h,
            ];
            let r2 = (x[0] - 1.0).powi(2) + (x[1] - 1.0).powi(2);
            (x, if r2 < 0.5 { 1.5 } else { -0.3 })
        })
    }

    fn example() -> FieldChart {
        FieldChart {
            title: "vorticity at t = 1.250".into(),
            value_label: "ω = Γ/h²".into(),
            unit: "σ".into(),
            ..FieldChart::new([-1.0, -1.0], 4.0, 0.25, 0.75)
        }
    }

    #[test]
    fn writes_a_png_with_the_field_and_the_colour_bar() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("omega.png");
        let chart = example();
        field_chart(&path, &chart, lattice()).unwrap();
        let (width, height, rgb) = decode(&path);
        assert_eq!((width, height), (640, chart.height()));
        assert_eq!(rgb.len(), (3 * width * height) as usize);
        // nothing but the chart in the directory
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

        let red = palette_colour(255);
        let blue = palette_colour(1);
        let ([x0, y0], n) = chart.plot_area();
        assert_eq!(n, 410);
        assert_eq!(height - n, TITLE_HEIGHT + BOTTOM_LABELS + MARGIN);
        // the middle of the plot area: x = y = 1, saturated positive
        assert_eq!(pixel(&rgb, width, [x0 + n / 2, y0 + n / 2]), red);
        // a corner: light blue (-0.3 of 0.75)
        let corner = pixel(&rgb, width, [x0 + 3, y0 + n - 3]);
        assert_eq!(corner, palette_colour(chart_index(&chart, -0.3)));
        assert!(corner[2] > corner[0]);
        // the frame around the plot area
        assert_eq!(pixel(&rgb, width, [x0 - 1, y0 + 10]), [0, 0, 0]);

        let ([bx, by], bw, bh) = chart.colour_bar_area();
        assert_eq!(pixel(&rgb, width, [bx + bw / 2, by]), red);
        assert_eq!(pixel(&rgb, width, [bx + bw / 2, by + bh - 1]), blue);
        assert_eq!(
            pixel(&rgb, width, [bx + bw / 2, by + bh / 2]),
            [255, 255, 255]
        );
        // there is text: dark pixels in the title band and left of the plot area
        let dark = |xs, ys| dark_pixels(&rgb, width, xs, ys);
        assert!(dark(x0..x0 + n, 0..y0 - 2) > 50);
        assert!(dark(0..x0 - 2, y0..y0 + n) > 50);
        assert!(dark(x0..x0 + n, y0 + n + 2..height) > 50);
        assert!(dark(bx + bw + 2..width, by..by + bh) > 50);
    }

    /// A field of magnitudes: its colour bar runs from white (0) at the
    /// bottom to red (`scale`) at the top, with no blue.
    #[test]
    fn a_magnitude_bar_runs_from_zero() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("magnitude.png");
        let chart = FieldChart {
            magnitude: true,
            ..example()
        };
        let points = lattice().map(|(x, v)| (x, v.abs()));
        field_chart(&path, &chart, points).unwrap();
        let (width, _, rgb) = decode(&path);
        let ([bx, by], bw, bh) = chart.colour_bar_area();
        let bar = |row| pixel(&rgb, width, [bx + bw / 2, by + row]);
        assert_eq!(bar(0), palette_colour(255));
        assert_eq!(bar(bh - 1), palette_colour(chart_index(&chart, 0.0)));
        // halfway up (the middle of its row): about scale / 2, a light red
        let middle = bar(bh / 2);
        let value = (1.0 - (bh / 2) as f64 / bh as f64 - 0.5 / bh as f64) * chart.scale;
        assert_eq!(middle, palette_colour(chart_index(&chart, value)));
        assert!(middle[0] > middle[2]);
        assert!((0..bh).all(|row| bar(row)[0] >= bar(row)[2]));
    }

    fn chart_index(chart: &FieldChart, value: f64) -> u8 {
        FieldPainter::with_view(16, chart.lo, chart.side, chart.spacing, chart.scale)
            .colour_index(value)
    }

    #[test]
    fn a_missing_directory_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no-such-dir").join("omega.png");
        let err = field_chart(&path, &example(), lattice()).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        assert!(!path.exists());
        // an empty view is an error too, and writes nothing
        let path = dir.path().join("empty.png");
        let chart = FieldChart::new([0.0, 0.0], 0.0, 0.1, 1.0);
        assert!(field_chart(&path, &chart, lattice()).is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn narrow_charts_are_widened_and_the_plot_stays_square() {
        let chart = FieldChart {
            width: 10,
            ..example()
        };
        let pixels = chart.render(lattice()).unwrap();
        let (_, n) = chart.plot_area();
        assert_eq!(n, 100);
        assert_eq!(chart.picture_width(), MIN_WIDTH);
        assert_eq!(pixels.len(), (3 * MIN_WIDTH * chart.height()) as usize);
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_text(0.0), "0");
        assert_eq!(tick_text(5.551115123125783e-17), "0");
        assert_eq!(tick_text(0.75), "0.75");
        assert_eq!(tick_text(-0.375), "-0.375");
        assert_eq!(tick_text(2.0), "2");
        assert_eq!(tick_text(0.30000000000000004), "0.3");
        assert_eq!(tick_text(1234.5678), "1235");
        assert_eq!(tick_text(-2.5e-4), "-2.5e-4");
        assert_eq!(tick_text(1.0e6), "1e6");
    }

    /// Renders the example chart the lead looks at (`cargo test ... -- --ignored`).
    #[test]
    #[ignore]
    fn example_picture() {
        // a Lamb-Oseen-like vortex pair on 200 x 200 particles
        let (n, side) = (200, 2.0 * std::f64::consts::PI);
        let h = side / n as f64;
        let points = (0..n * n).map(move |k| {
            let x = [((k % n) as f64 + 0.5) * h, ((k / n) as f64 + 0.5) * h];
            let blob = |c: [f64; 2], s: f64| {
                let r2 = (x[0] - c[0]).powi(2) + (x[1] - c[1]).powi(2);
                s * (-r2 / 0.4).exp()
            };
            (x, blob([2.4, 3.2], 2.0) + blob([3.9, 3.2], -2.0))
        });
        let chart = FieldChart {
            title: "vorticity at t = 1.250".into(),
            value_label: "ω = Γ/h²".into(),
            unit: "σ".into(),
            ..FieldChart::new([0.0, 0.0], side, h, 2.0)
        };
        let start = std::time::Instant::now();
        field_chart(Path::new("/tmp/field_chart_example.png"), &chart, points).unwrap();
        println!("{} particles in {:?}", n * n, start.elapsed());
    }
}
