//! Pictures of bodies in space (gravity runs): the bodies projected on a plane
//! (`xy`, `xz` or `yz`) as dots coloured by their speed `|v|`, nearer bodies drawn
//! over farther ones, in a square view fixed for a run. The frame around them
//! (title, axes with their unit, the speed colour bar) is [`FieldChart`]'s; the
//! colours are [`DiscPainter`]'s speed scale, so that all pictures coloured by
//! speed read alike.

use crate::parts::{kth_smallest, Parts, Whole};
use crate::{write_chart, DiscPainter, FieldChart};
use std::io;
use std::path::Path;

/// The plane bodies are projected on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    /// x across, y up (seen from +z).
    Xy,
    /// x across, z up (seen from -y).
    Xz,
    /// y across, z up (seen from +x).
    Yz,
}

impl Plane {
    /// The planes by name.
    pub const ALL: [(&'static str, Plane); 3] =
        [("xy", Plane::Xy), ("xz", Plane::Xz), ("yz", Plane::Yz)];

    /// The plane called `name` (`"xy"`, `"xz"`, `"yz"`).
    pub fn from_name(name: &str) -> Option<Plane> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|&(_, p)| p)
    }

    /// The plane's name.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(_, p)| *p == self)
            .map(|(n, _)| *n)
            .expect("every plane is named")
    }

    /// The coordinates shown across and up, and the one along the line of
    /// sight.
    pub fn axes(self) -> [usize; 3] {
        match self {
            Plane::Xy => [0, 1, 2],
            Plane::Xz => [0, 2, 1],
            Plane::Yz => [1, 2, 0],
        }
    }

    /// The names of the axes shown across and up.
    pub fn axis_names(self) -> [&'static str; 2] {
        let [a, b, _] = self.axes();
        [["x", "y", "z"][a], ["x", "y", "z"][b]]
    }

    /// The depth of a position: larger is nearer the viewer (drawn later).
    fn depth(self, x: &[f64; 3]) -> f64 {
        match self {
            Plane::Xy => x[2],
            Plane::Xz => -x[1],
            Plane::Yz => x[0],
        }
    }

    fn project(self, x: &[f64; 3]) -> [f64; 2] {
        let [a, b, _] = self.axes();
        [x[a], x[b]]
    }
}

/// A picture of bodies: the frame (its `width`, the view `lo`, `side`, `title`,
/// `value_label`, `unit` and axis names; `spacing` and `scale` unused), the plane
/// and the speed that the colour scale ends at.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyChart {
    /// The frame around the bodies.
    pub frame: FieldChart,
    /// The plane of projection.
    pub plane: Plane,
    /// The top of the colour scale: faster bodies get its top colour.
    pub top_speed: f64,
    /// The radius of a body's dot in pixels (a dot covers at least its centre
    /// pixel).
    pub dot_radius: f64,
}

impl BodyChart {
    /// A 640-pixel-wide picture of the square `[lo, lo + side)^2` of `plane`, the
    /// colour scale from 0 to `top_speed`, dots for `bodies` bodies (smaller for
    /// more bodies), the colour bar labelled `speed |v|`.
    pub fn new(plane: Plane, lo: [f64; 2], side: f64, top_speed: f64, bodies: usize) -> Self {
        let mut frame = FieldChart::new(lo, side, 0.0, 1.0);
        frame.value_label = "speed |v|".into();
        frame.axes = plane.axis_names().map(String::from);
        let mut chart = BodyChart {
            frame,
            plane,
            top_speed: if top_speed > 0.0 && top_speed.is_finite() {
                top_speed
            } else {
                1.0
            },
            dot_radius: 1.0,
        };
        chart.set_dot_radius(bodies);
        chart
    }

    /// Sets the dots' radius for `bodies` bodies at the current width: about a
    /// third of the spacing of as many bodies on a lattice filling the view,
    /// between 0.8 and 5 pixels.
    pub fn set_dot_radius(&mut self, bodies: usize) {
        let (_, n) = self.frame.plot_area();
        self.dot_radius = (0.35 * n as f64 / (bodies.max(1) as f64).sqrt()).clamp(0.8, 5.0);
    }

    /// The square view around `positions` projected on `plane`: centred on their
    /// centre of mass (`masses`, or equal masses; non-finite positions left out),
    /// its half side 1.1 times the distance (in the larger of the two coordinates)
    /// within which `fraction` of the bodies lie, so that a few escaping bodies do
    /// not shrink the picture. Returns `(lower corner, side)`; `([-1, -1], 2)`
    /// without bodies.
    pub fn view_around(
        positions: &[[f64; 3]],
        masses: Option<&[f64]>,
        plane: Plane,
        fraction: f64,
    ) -> ([f64; 2], f64) {
        Self::view_among(positions, masses, plane, fraction, &Whole)
    }

    /// [`view_around`](Self::view_around) of bodies divided among the
    /// processes of `parts` (collective), this one holding `positions` and
    /// `masses`: the same view as one process holding them all.
    pub fn view_among(
        positions: &[[f64; 3]],
        masses: Option<&[f64]>,
        plane: Plane,
        fraction: f64,
        parts: &dyn Parts,
    ) -> ([f64; 2], f64) {
        let finite =
            || (0..positions.len()).filter(|&i| positions[i].iter().all(|c| c.is_finite()));
        let weight = |i: usize| masses.map_or(1.0, |m| m[i]);
        // the total weight (from -0.0, as `Iterator::sum` starts) and the count
        let mut sums = [-0.0, 0.0];
        parts.fold(&mut sums, &mut |s| {
            for i in finite() {
                s[0] += weight(i);
                s[1] += 1.0;
            }
        });
        let [total, count] = sums;
        if count == 0.0 {
            return ([-1.0, -1.0], 2.0);
        }
        let mut centre = [0.0; 2];
        parts.fold(&mut centre, &mut |c| {
            for i in finite() {
                let [a, b] = plane.project(&positions[i]);
                let w = if total > 0.0 {
                    weight(i) / total
                } else {
                    1.0 / count
                };
                c[0] += w * a;
                c[1] += w * b;
            }
        });
        let k = ((fraction.clamp(0.0, 1.0) * count).ceil() as u64).clamp(1, count as u64);
        let distance = kth_smallest(k, parts, &mut |visit| {
            for i in finite() {
                let [a, b] = plane.project(&positions[i]);
                visit((a - centre[0]).abs().max((b - centre[1]).abs()));
            }
        });
        let mut half = 1.1 * distance;
        if !(half > 0.0 && half.is_finite()) {
            half = 1.0;
        }
        ([centre[0] - half, centre[1] - half], 2.0 * half)
    }

    /// The colour scale's top for bodies moving at `velocities`: the speed that
    /// `fraction` of them do not exceed, at least `floor`, rounded up to 1, 1.2,
    /// 1.5, 2, 2.5, 3, 4, 5, 6 or 8 times a power of ten. 1 if that is not a
    /// positive number.
    pub fn speed_scale(velocities: &[[f64; 3]], fraction: f64, floor: f64) -> f64 {
        Self::speed_scale_among(velocities, fraction, floor, &Whole)
    }

    /// [`speed_scale`](Self::speed_scale) of bodies divided among the
    /// processes of `parts` (collective), this one holding `velocities`.
    pub fn speed_scale_among(
        velocities: &[[f64; 3]],
        fraction: f64,
        floor: f64,
        parts: &dyn Parts,
    ) -> f64 {
        let speeds = || {
            velocities
                .iter()
                .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
                .filter(|s| s.is_finite())
        };
        let mut count = [speeds().count() as u64];
        parts.add_up(&mut count);
        let quantile = if count[0] == 0 {
            0.0
        } else {
            let k = ((fraction.clamp(0.0, 1.0) * count[0] as f64).ceil() as u64).clamp(1, count[0]);
            kth_smallest(k, parts, &mut |visit| speeds().for_each(&mut *visit))
        };
        let top = quantile.max(if floor.is_finite() { floor } else { 0.0 });
        if !(top > 0.0 && top.is_finite()) {
            return 1.0;
        }
        let power = 10f64.powf(top.log10().floor());
        let mantissa = top / power;
        let nice = [1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0]
            .into_iter()
            .find(|&m| m >= mantissa * (1.0 - 1e-12))
            .unwrap_or(10.0);
        nice * power
    }

    /// The palette of the dots (RGB triples): the colours of
    /// [`DiscPainter::palette`] in use, white background first.
    pub fn palette() -> Vec<u8> {
        let mut rgb = DiscPainter::palette();
        rgb.truncate(3 * DiscPainter::COLOURS);
        rgb
    }

    /// How many of `positions` lie outside the view (or are not finite).
    pub fn outside(&self, positions: &[[f64; 3]]) -> usize {
        let [lx, ly] = self.frame.lo;
        let side = self.frame.side;
        positions
            .iter()
            .filter(|x| {
                let [a, b] = self.plane.project(x);
                !(a >= lx && a < lx + side && b >= ly && b < ly + side)
            })
            .count()
    }

    /// Paints the bodies in the plot area: its RGB pixels, rows from the top,
    /// white where no body is (an error unless there are as many velocities
    /// as positions).
    pub fn paint(&self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) -> io::Result<Vec<u8>> {
        let mut canvas = self.canvas();
        canvas.add(0, positions, velocities)?;
        Ok(canvas.pixels)
    }

    /// An empty canvas of the plot area, to paint bodies on a block at a
    /// time ([`BodyCanvas::add`]).
    pub fn canvas(&self) -> BodyCanvas<'_> {
        let (_, n) = self.frame.plot_area();
        let size = n as usize;
        BodyCanvas {
            chart: self,
            palette: Self::palette(),
            pixels: vec![255u8; 3 * size * size],
            nearest: vec![(f64::NEG_INFINITY, 0); size * size],
            outside: 0,
        }
    }

    /// Renders the picture of bodies at `positions` moving at `velocities`: the
    /// RGB pixels, [`FieldChart::picture_width`] by [`FieldChart::height`] of the
    /// frame.
    pub fn render(&self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) -> io::Result<Vec<u8>> {
        self.render_painted(self.paint(positions, velocities)?)
    }

    /// The picture around plot-area pixels `painted` (of [`BodyChart::paint`]
    /// or [`BodyCanvas::pixels`]): the RGB pixels of the frame.
    pub fn render_painted(&self, painted: Vec<u8>) -> io::Result<Vec<u8>> {
        let palette = Self::palette();
        let top = self.top_speed;
        self.frame.render_painted(painted, (0.0, top), |speed| {
            let k = 3 * DiscPainter::speed_colour(speed, top) as usize;
            [palette[k], palette[k + 1], palette[k + 2]]
        })
    }
}

/// Bodies painted on a [`BodyChart`]'s plot area a block at a time: each
/// pixel takes the colour of the nearest body covering it (the largest
/// depth, then the latest in input order), the picture painting them all at
/// once, farther first, leaves; what is held is the pixels and each one's
/// nearest body, not the bodies.
pub struct BodyCanvas<'c> {
    chart: &'c BodyChart,
    palette: Vec<u8>,
    pixels: Vec<u8>,
    /// Per pixel: the depth and input place of the body painted there.
    nearest: Vec<(f64, usize)>,
    outside: usize,
}

impl BodyCanvas<'_> {
    /// Paints bodies `first..` of the input at `positions` moving at
    /// `velocities` (as many: else an error), and counts those outside the
    /// view (or not finite). Bodies with a coordinate that is not finite are
    /// not drawn.
    pub fn add(
        &mut self,
        first: usize,
        positions: &[[f64; 3]],
        velocities: &[[f64; 3]],
    ) -> io::Result<()> {
        if positions.len() != velocities.len() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "body chart: as many velocities as positions are needed",
            ));
        }
        let chart = self.chart;
        self.outside += chart.outside(positions);
        let (_, n) = chart.frame.plot_area();
        let size = n as usize;
        let per_unit = n as f64 / chart.frame.side;
        let [lx, ly] = chart.frame.lo;
        let r = chart.dot_radius;
        for (k, (x, v)) in positions.iter().zip(velocities).enumerate() {
            if !x.iter().all(|c| c.is_finite()) {
                continue;
            }
            let key = (chart.plane.depth(x), first + k);
            let [a, b] = chart.plane.project(x);
            let (cx, cy) = ((a - lx) * per_unit, (ly + chart.frame.side - b) * per_unit);
            if !(cx > -r && cx < n as f64 + r && cy > -r && cy < n as f64 + r) {
                continue;
            }
            let speed = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let c = 3 * DiscPainter::speed_colour(speed, chart.top_speed) as usize;
            let colour = &self.palette[c..c + 3];
            let span = |c: f64| {
                let lo = (c - r).floor().max(0.0) as usize;
                let hi = ((c + r).ceil() as usize).min(size);
                lo..hi
            };
            let centre = (cx.floor(), cy.floor());
            for py in span(cy) {
                for px in span(cx) {
                    let (dx, dy) = (px as f64 + 0.5 - cx, py as f64 + 0.5 - cy);
                    if dx * dx + dy * dy <= r * r || (px as f64, py as f64) == centre {
                        let q = py * size + px;
                        let (depth, place) = self.nearest[q];
                        if key.0.total_cmp(&depth).then(key.1.cmp(&place)).is_gt() {
                            self.nearest[q] = key;
                            self.pixels[3 * q..3 * q + 3].copy_from_slice(colour);
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The bodies added so far outside the view (or not finite).
    pub fn outside(&self) -> usize {
        self.outside
    }

    /// The painted plot area's RGB pixels, rows from the top.
    pub fn pixels(self) -> Vec<u8> {
        self.pixels
    }
}

/// Renders the picture of bodies and writes it to `path` as an RGB PNG, whole or
/// not at all.
pub fn body_chart(
    path: &Path,
    chart: &BodyChart,
    positions: &[[f64; 3]],
    velocities: &[[f64; 3]],
) -> io::Result<()> {
    write_chart(path, &chart.frame, &chart.render(positions, velocities)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_png::{dark_pixels, decode, pixel};
    use crate::{ChartPalette, GifAnimation};

    fn speed_rgb(speed: f64, top: f64) -> [u8; 3] {
        let p = BodyChart::palette();
        let k = 3 * DiscPainter::speed_colour(speed, top) as usize;
        [p[k], p[k + 1], p[k + 2]]
    }

    /// A ring of 200 bodies of radius 1 around (1, 2, 3) in the xz plane, moving
    /// at speeds 0 to 2, and one far away.
    fn ring() -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let mut x = Vec::new();
        let mut v = Vec::new();
        for k in 0..200 {
            let a = k as f64 * std::f64::consts::TAU / 200.0;
            x.push([1.0 + a.cos(), 2.0, 3.0 + a.sin()]);
            let s = 2.0 * k as f64 / 199.0;
            v.push([-s * a.sin(), 0.0, s * a.cos()]);
        }
        x.push([1e6, 2.0, 3.0]);
        v.push([0.0; 3]);
        (x, v)
    }

    #[test]
    fn the_view_is_a_square_around_the_centre_of_mass_without_the_outliers() {
        let (x, _) = ring();
        let (lo, side) = BodyChart::view_around(&x, None, Plane::Xz, 0.98);
        // the far body moves the centre of mass by 1e6 / 201 along x: weigh it 0
        let mut m = vec![1.0; 201];
        m[200] = 0.0;
        let (lo_m, side_m) = BodyChart::view_around(&x, Some(&m), Plane::Xz, 0.98);
        assert!((side_m - 2.2).abs() < 1e-9, "{side_m}");
        assert!((lo_m[0] - (1.0 - 1.1)).abs() < 1e-9 && (lo_m[1] - (3.0 - 1.1)).abs() < 1e-9);
        assert!(side.is_finite() && lo[0].is_finite());
        // one body, or none: a view of side 2
        assert_eq!(
            BodyChart::view_around(&[[5.0, 6.0, 7.0]], None, Plane::Xy, 0.98),
            ([4.0, 5.0], 2.0)
        );
        assert_eq!(
            BodyChart::view_around(&[], None, Plane::Xy, 0.98),
            ([-1.0, -1.0], 2.0)
        );
    }

    /// The view and the speed scale of bodies cut into runs among 2 to 4
    /// processes (one of them empty, some bodies not finite) are one
    /// process's, bit for bit, on every process.
    #[test]
    fn views_over_parts_are_one_process_views() {
        let (mut x, mut v) = ring();
        x[17] = [f64::NAN, 0.0, 0.0];
        v[40] = [f64::INFINITY, 0.0, 0.0];
        let m: Vec<f64> = (0..x.len()).map(|k| 0.5 + (k % 7) as f64 / 3.0).collect();
        // both views' corners and sides and the speed scale, as bits
        let views = |x: &[[f64; 3]], v: &[[f64; 3]], m: &[f64], parts: &dyn Parts| {
            let (lo, side) = BodyChart::view_among(x, Some(m), Plane::Xz, 0.98, parts);
            let (lo2, side2) = BodyChart::view_among(x, None, Plane::Xy, 0.9, parts);
            let top = BodyChart::speed_scale_among(v, 0.98, 0.3, parts);
            [lo[0], lo[1], side, lo2[0], lo2[1], side2, top].map(f64::to_bits)
        };
        let whole = views(&x, &v, &m, &Whole);
        let n = x.len();
        for ranks in 2..=4 {
            let cut = |r: usize| if r == 1 { 0 } else { n * r / ranks };
            let got = crate::parts::testkit::run(ranks, |me| {
                let run = cut(me.rank)..cut(me.rank + 1);
                views(&x[run.clone()], &v[run.clone()], &m[run], me)
            });
            for got in got {
                assert_eq!(got, whole, "{ranks} ranks");
            }
        }
    }

    /// Bodies painted a block at a time, or one at a time in any order
    /// (each with its input place), give the pixels of painting them all
    /// at once: where they overlap the nearest shows, and of two at the
    /// same depth the later in the input.
    #[test]
    fn bodies_painted_in_blocks_are_painted_at_once() {
        let (mut x, mut v) = ring();
        // a pile on one spot: depths 0.5, 0.9, 0.9, 0.1 (plane xy: depth z)
        for (k, z) in [0.5, 0.9, 0.9, 0.1].into_iter().enumerate() {
            x.push([1.0, 1.0, z]);
            v.push([0.5 * k as f64, 0.0, 0.0]);
        }
        let chart = BodyChart::new(Plane::Xy, [-0.5, 0.5], 3.0, 2.0, x.len());
        let whole = chart.paint(&x, &v).unwrap();
        let mut blocks = chart.canvas();
        for start in (0..x.len()).step_by(7) {
            let end = x.len().min(start + 7);
            blocks.add(start, &x[start..end], &v[start..end]).unwrap();
        }
        assert_eq!(blocks.outside(), chart.outside(&x));
        assert!(blocks.pixels() == whole);
        let mut shuffled = chart.canvas();
        let odd = (0..x.len()).rev().filter(|k| k % 2 == 1);
        for k in odd.chain((0..x.len()).step_by(2)) {
            shuffled.add(k, &x[k..k + 1], &v[k..k + 1]).unwrap();
        }
        assert!(shuffled.pixels() == whole);
        // the pile's spot shows body 2 (depth 0.9, after body 1): speed 1.0
        let (_, n) = chart.frame.plot_area();
        let per_unit = n as f64 / 3.0;
        let (px, py) = ((1.5 * per_unit) as usize, (2.5 * per_unit) as usize);
        let at = 3 * (py * n as usize + px);
        assert_eq!(whole[at..at + 3], speed_rgb(1.0, 2.0));
        assert!(chart.canvas().add(0, &x, &v[1..]).is_err());
    }

    #[test]
    fn speed_scales_are_round_numbers() {
        let v = |s: f64| [s, 0.0, 0.0];
        let vs: Vec<[f64; 3]> = (1..=100).map(|k| v(k as f64 / 100.0)).collect();
        assert_eq!(BodyChart::speed_scale(&vs, 0.98, 0.0), 1.0);
        assert_eq!(BodyChart::speed_scale(&vs, 0.5, 0.0), 0.5);
        assert_eq!(BodyChart::speed_scale(&vs, 0.5, 1.3), 1.5);
        assert_eq!(BodyChart::speed_scale(&[v(0.0)], 0.98, 0.0), 1.0);
        assert!((BodyChart::speed_scale(&[v(0.031)], 1.0, 0.0) - 0.04).abs() < 1e-15);
        assert_eq!(BodyChart::speed_scale(&[v(f64::NAN)], 1.0, 0.0), 1.0);
    }

    #[test]
    fn writes_a_png_with_the_bodies_the_colour_bar_and_a_gif_frame() {
        let (x, v) = ring();
        let mut m = vec![1.0; x.len()];
        m[200] = 0.0;
        let (lo, side) = BodyChart::view_around(&x, Some(&m), Plane::Xz, 0.98);
        let mut chart = BodyChart::new(Plane::Xz, lo, side, 2.0, x.len());
        chart.frame.title = "bodies at t = 1.00 (step 100)".into();
        chart.frame.unit = "simulation units, G = 1".into();
        assert_eq!(chart.frame.axes, ["x".to_string(), "z".to_string()]);
        assert_eq!(chart.outside(&x), 1);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bodies.png");
        body_chart(&path, &chart, &x, &v).unwrap();
        let (width, height, rgb) = decode(&path);
        assert_eq!((width, height), (640, chart.frame.height()));

        // the body at angle 0, (2, 3) in x, z, moves at speed 0: the bottom colour
        let ([x0, y0], n) = chart.frame.plot_area();
        let to_px = |a: f64, b: f64| {
            let f = n as f64 / side;
            [
                x0 + ((a - lo[0]) * f) as u32,
                y0 + ((lo[1] + side - b) * f) as u32,
            ]
        };
        assert_eq!(pixel(&rgb, width, to_px(2.0, 3.0)), speed_rgb(0.0, 2.0));
        // the body at angle pi (k = 100) moves at 2 * 100/199
        assert_eq!(
            pixel(&rgb, width, to_px(0.0, 3.0)),
            speed_rgb(200.0 / 199.0, 2.0)
        );
        // the centre of the ring is empty, white
        assert_eq!(pixel(&rgb, width, to_px(1.0, 3.0)), [255, 255, 255]);
        // the colour bar: the top colour at the top, speed 0 at the bottom
        let ([bx, by], bw, bh) = chart.frame.colour_bar_area();
        let row_speed = |row: u32| 2.0 * (1.0 - (row as f64 + 0.5) / bh as f64);
        assert_eq!(
            pixel(&rgb, width, [bx + bw / 2, by]),
            speed_rgb(row_speed(0), 2.0)
        );
        assert_eq!(speed_rgb(row_speed(0), 2.0), speed_rgb(1.995, 2.0));
        assert_eq!(
            pixel(&rgb, width, [bx + bw / 2, by + bh - 1]),
            speed_rgb(0.0, 2.0)
        );
        // every row of the bar is one of the palette's speed colours
        for row in by..by + bh {
            let c = pixel(&rgb, width, [bx + 1, row]);
            let palette = BodyChart::palette();
            assert!(palette[6..].chunks(3).any(|p| p == c), "{c:?}");
        }
        // text: dark pixels in the title band, left of and below the plot area
        let dark = |xs, ys| dark_pixels(&rgb, width, xs, ys);
        assert!(dark(x0..x0 + n, 0..y0 - 2) > 50);
        assert!(dark(0..x0 - 2, y0..y0 + n) > 50);
        assert!(dark(x0..x0 + n, y0 + n + 2..height) > 50);

        // the same picture as a GIF frame in the chart palette
        let palette = ChartPalette::new(&BodyChart::palette());
        let indices = palette.indices(&rgb);
        let gif_path = dir.path().join("bodies.gif");
        let mut gif = GifAnimation::create(&gif_path, width, height, palette.rgb()).unwrap();
        gif.add_frame(&indices, 10).unwrap();
        gif.add_frame(&indices, 10).unwrap();
        gif.finish().unwrap();
        let mut options = gif::DecodeOptions::new();
        options.set_color_output(gif::ColorOutput::RGBA);
        let mut decoder = options
            .read_info(std::fs::File::open(&gif_path).unwrap())
            .unwrap();
        let mut frames = 0;
        while let Some(frame) = decoder.read_next_frame().unwrap() {
            assert_eq!((frame.width as u32, frame.height as u32), (width, height));
            let k = 4 * (to_px(2.0, 3.0)[1] * width + to_px(2.0, 3.0)[0]) as usize;
            let c = [frame.buffer[k], frame.buffer[k + 1], frame.buffer[k + 2]];
            let want = speed_rgb(0.0, 2.0);
            assert!((0..3).all(|i| (c[i] as i32 - want[i] as i32).abs() <= 12));
            frames += 1;
        }
        assert_eq!(frames, 2);
    }

    /// Renders the example pictures the lead looks at (`cargo test ... --
    /// --ignored`): a rotating cloud as a PNG, and the same chart as a GIF frame
    /// decoded back to a PNG.
    #[test]
    #[ignore]
    fn example_picture() {
        // 5000 bodies in a Plummer-like cloud turning about z
        let mut state: u64 = 7;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (mut x, mut v) = (Vec::new(), Vec::new());
        for _ in 0..5000 {
            let r = 1.0 / (uniform().powf(-2.0 / 3.0) - 1.0).sqrt();
            let (c, phi) = (2.0 * uniform() - 1.0, std::f64::consts::TAU * uniform());
            let s = (1.0 - c * c).sqrt();
            let p = [r * s * phi.cos(), r * s * phi.sin(), r * c];
            let speed = (2.0f64).sqrt() * (1.0 + r * r).powf(-0.25) * uniform();
            x.push(p);
            v.push([-speed * phi.sin(), speed * phi.cos(), 0.1 * speed]);
        }
        let (lo, side) = BodyChart::view_around(&x, None, Plane::Xy, 0.98);
        let top = BodyChart::speed_scale(&v, 0.98, 0.0);
        let mut chart = BodyChart::new(Plane::Xy, lo, side, top, x.len());
        chart.frame.title = format!(
            "bodies at t = 1.00 (step 100), {} outside",
            chart.outside(&x)
        );
        chart.frame.unit = "simulation units, G = 1".into();
        chart.frame.value_label = "speed |v| (simulation units)".into();
        let start = std::time::Instant::now();
        let rgb = chart.render(&x, &v).unwrap();
        println!("rendered in {:?}", start.elapsed());
        write_chart(Path::new("/tmp/body_chart_example.png"), &chart.frame, &rgb).unwrap();
        let palette = ChartPalette::new(&BodyChart::palette());
        let start = std::time::Instant::now();
        let indices = palette.indices(&rgb);
        println!("converted in {:?}", start.elapsed());
        let back = crate::palette_rgb(&indices, palette.rgb());
        write_chart(
            Path::new("/tmp/body_chart_example_gif_frame.png"),
            &chart.frame,
            &back,
        )
        .unwrap();
    }

    #[test]
    fn planes_by_name() {
        for (name, plane) in Plane::ALL {
            assert_eq!(Plane::from_name(name), Some(plane));
            assert_eq!(plane.name(), name);
        }
        assert_eq!(Plane::from_name("zx"), None);
        assert_eq!(Plane::Yz.axis_names(), ["y", "z"]);
    }
}
