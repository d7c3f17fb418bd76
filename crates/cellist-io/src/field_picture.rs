//! Pictures of a scalar field carried by particles: each particle paints the square
//! of one lattice spacing around it in a blue-white-red colour for its value (blue
//! negative, white zero, red positive, saturating at a fixed scale, so that frames
//! of one run compare). The frames go to [`crate::GifAnimation`] and into the
//! field charts ([`crate::field_chart()`]), with [`FieldPainter::palette`].

const BACKGROUND: u8 = 0;
const FIRST_LEVEL: u8 = 1;
const LEVELS: usize = 255;

/// Paints a square view of a particle field on `size` x `size` pixels: either the
/// periodic box `[0, side)^2` ([`FieldPainter::new`], squares wrap across the edges)
/// or any square `[lo, lo + side)^2` ([`FieldPainter::with_view`], squares are clipped
/// at the edges).
#[derive(Clone, Debug)]
pub struct FieldPainter {
    size: u32,
    lo: [f64; 2],
    side: f64,
    spacing: f64,
    scale: f64,
    periodic: bool,
    pixels: Vec<u8>,
}

impl FieldPainter {
    /// A painter of the periodic box `[0, side)^2` for particles `spacing` apart
    /// whose colours saturate at `|value| = scale`.
    pub fn new(size: u32, side: f64, spacing: f64, scale: f64) -> Self {
        Self::painter(size, [0.0, 0.0], side, spacing, scale, true)
    }

    /// A painter of the square `[lo, lo + side)^2`, not periodic: a particle's square
    /// is clipped at the edges of the view, and particles outside it (or at
    /// non-finite positions) paint nothing.
    pub fn with_view(size: u32, lo: [f64; 2], side: f64, spacing: f64, scale: f64) -> Self {
        Self::painter(size, lo, side, spacing, scale, false)
    }

    fn painter(
        size: u32,
        lo: [f64; 2],
        side: f64,
        spacing: f64,
        scale: f64,
        periodic: bool,
    ) -> Self {
        FieldPainter {
            size: size.max(16),
            lo,
            side,
            spacing,
            scale: if scale > 0.0 && scale.is_finite() {
                scale
            } else {
                1.0
            },
            periodic,
            pixels: Vec::new(),
        }
    }

    /// The palette as RGB triples: index 0 the background (grey), then 255 levels
    /// from blue (`-scale`) through white (0) to red (`+scale`).
    pub fn palette() -> Vec<u8> {
        let mut rgb = vec![128, 128, 128];
        const BLUE: [f64; 3] = [33.0, 72.0, 180.0];
        const RED: [f64; 3] = [190.0, 30.0, 40.0];
        for k in 0..LEVELS {
            let t = 2.0 * k as f64 / (LEVELS - 1) as f64 - 1.0;
            let end = if t < 0.0 { BLUE } else { RED };
            for c in 0..3 {
                rgb.push((255.0 + (end[c] - 255.0) * t.abs()).round() as u8);
            }
        }
        rgb
    }

    /// The side of the picture in pixels.
    pub fn size(&self) -> u32 {
        self.size
    }

    /// The colour scale: values at or beyond `±scale` get the end colours.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The palette index (into [`FieldPainter::palette`]) of `value`; NaN is white.
    pub fn colour_index(&self, value: f64) -> u8 {
        let t = if value.is_nan() {
            0.0
        } else {
            (value / self.scale).clamp(-1.0, 1.0)
        };
        let level = ((t + 1.0) * 0.5 * (LEVELS - 1) as f64).round() as u8;
        FIRST_LEVEL + level
    }

    /// Renders `(position, value)` pairs; returns the palette indices row by row
    /// from the top (y up). Pixels no particle covers are the background (index 0),
    /// but for the gaps narrower than half a square between the squares of
    /// neighbouring particles (filled: see `fill_gaps`).
    pub fn render(&mut self, particles: impl Iterator<Item = ([f64; 2], f64)>) -> &[u8] {
        let size = self.size as usize;
        self.pixels.clear();
        self.pixels.resize(size * size, BACKGROUND);
        let per_unit = size as f64 / self.side;
        let half = 0.5 * self.spacing * per_unit;
        let span = |c: f64| {
            let lo = (c - half).round() as i64;
            let hi = ((c + half).round() as i64).max(lo + 1);
            if self.periodic {
                lo..hi
            } else {
                lo.max(0)..hi.min(size as i64)
            }
        };
        for (x, value) in particles {
            if !self.periodic && !x.iter().all(|c| c.is_finite()) {
                continue;
            }
            let colour = self.colour_index(value);
            let (cx, cy) = (
                (x[0] - self.lo[0]) * per_unit,
                (x[1] - self.lo[1]) * per_unit,
            );
            for py in span(cy) {
                let row = py.rem_euclid(size as i64) as usize;
                for px in span(cx) {
                    let column = px.rem_euclid(size as i64) as usize;
                    self.pixels[(size - 1 - row) * size + column] = colour;
                }
            }
        }
        self.fill_gaps((half as usize).max(1));
        &self.pixels
    }

    /// Fills the gaps between squares narrower than half a square: a square
    /// spans the pixels from `round(c - h/2)` to `round(c + h/2)`, so rounding
    /// can leave a column or row of pixels to neither of two neighbours on a
    /// lattice, and particles that the flow moves apart open gaps of a few
    /// pixels. Along each row, then each column (which also fills where a gap
    /// column and a gap row cross), a run of at most `widest` background pixels
    /// between two painted ones takes the colour of the nearer (the earlier on a
    /// tie). Wider gaps (a spacing without a particle) stay background; a
    /// periodic picture wraps.
    fn fill_gaps(&mut self, widest: usize) {
        let size = self.size as usize;
        for row in 0..size {
            fill_line(
                &mut self.pixels,
                |k| row * size + k,
                size,
                widest,
                self.periodic,
            );
        }
        for column in 0..size {
            fill_line(
                &mut self.pixels,
                |k| k * size + column,
                size,
                widest,
                self.periodic,
            );
        }
    }
}

/// Fills the runs of at most `widest` background pixels between two painted
/// ones on the line of `n` pixels whose `k`-th is `pixels[at(k)]`, each pixel
/// from the nearer end (the earlier on a tie); `periodic` lines wrap.
fn fill_line(
    pixels: &mut [u8],
    at: impl Fn(usize) -> usize,
    n: usize,
    widest: usize,
    periodic: bool,
) {
    let painted: Vec<usize> = (0..n).filter(|&k| pixels[at(k)] != BACKGROUND).collect();
    let pairs = painted.windows(2).map(|w| (w[0], w[1]));
    let wrapped = match (periodic, painted.first(), painted.last()) {
        (true, Some(&first), Some(&last)) if painted.len() > 1 => Some((last, first + n)),
        _ => None,
    };
    for (from, to) in pairs.chain(wrapped) {
        let gap = to - from - 1;
        if gap == 0 || gap > widest {
            continue;
        }
        let (before, after) = (pixels[at(from % n)], pixels[at(to % n)]);
        for k in from + 1..to {
            pixels[at(k % n)] = if k - from <= to - k { before } else { after };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lattice_fills_the_picture_in_its_colours() {
        let n = 8;
        let h = 1.0 / n as f64;
        let mut painter = FieldPainter::new(64, 1.0, h, 1.0);
        let particles = (0..n * n).map(|k| {
            let x = [((k % n) as f64 + 0.5) * h, ((k / n) as f64 + 0.5) * h];
            (x, if x[0] < 0.5 { -2.0 } else { 0.5 })
        });
        let pixels = painter.render(particles).to_vec();
        assert!(!pixels.contains(&BACKGROUND));
        // left half saturated blue, right half light red
        assert_eq!(pixels[10 * 64 + 3], FIRST_LEVEL);
        let right = pixels[10 * 64 + 60];
        assert!(right > FIRST_LEVEL + 127 && right < FIRST_LEVEL + 254);
        let palette = FieldPainter::palette();
        assert_eq!(palette.len(), 256 * 3);
        // zero is white
        assert_eq!(&palette[3 * (1 + 127)..3 * (1 + 127) + 3], &[255, 255, 255]);
    }

    #[test]
    fn a_lattice_leaves_no_seam_between_its_squares() {
        // the vortex pair's lattice (spacing 0.03 out to 0.45, seen with a
        // margin of two spacings) at every picture size from 300 to 560 pixels:
        // rounding put square edges on pixel centres at some sizes, leaving
        // unpainted lines through the field
        let (spacing, m) = (0.03, 15);
        let margin = 0.45 + 2.0 * spacing;
        let nodes = (-m..=m).map(|k| k as f64 * spacing);
        let particles: Vec<([f64; 2], f64)> = nodes
            .clone()
            .flat_map(|y| nodes.clone().map(move |x| ([x, y], x + y)))
            .collect();
        let mut seamed = Vec::new();
        for size in 300..=560u32 {
            let side = 2.0 * margin;
            let mut painter = FieldPainter::with_view(size, [-margin; 2], side, spacing, 1.0);
            let pixels = painter.render(particles.iter().copied()).to_vec();
            let n = size as usize;
            // pixels whose centre lies a pixel inside the lattice's squares
            let inside = |p: usize| {
                let c = -margin + (p as f64 + 0.5) * side / n as f64;
                c.abs() < (m as f64 + 0.5) * spacing - side / n as f64
            };
            let holes = (0..n * n)
                .filter(|&k| inside(k / n) && inside(k % n) && pixels[k] == BACKGROUND)
                .count();
            if holes > 0 {
                seamed.push((size, holes));
            }
        }
        assert!(seamed.is_empty(), "(size, unpainted pixels): {seamed:?}");
    }

    #[test]
    fn gaps_narrower_than_half_a_square_are_filled_and_wider_ones_stay() {
        // squares 4 pixels wide (half a square: 2 pixels) one, two and three
        // pixels apart
        let mut painter = FieldPainter::with_view(40, [0.0, 0.0], 40.0, 4.0, 1.0);
        let particles = [
            ([2.0, 2.0], 1.0),   // columns 0..4
            ([7.0, 2.0], -1.0),  // columns 5..9: column 4 is a seam
            ([13.0, 2.0], 1.0),  // columns 11..15: 9..11 is a gap of two
            ([20.0, 2.0], 1.0),  // columns 18..22
            ([27.0, 2.0], -1.0), // columns 25..29: 22..25 is a gap of three
        ];
        let pixels = painter.render(particles.into_iter()).to_vec();
        let at = |column: usize| pixels[(39 - 2) * 40 + column];
        let (red, blue) = (FIRST_LEVEL + 254, FIRST_LEVEL);
        assert_eq!([at(3), at(4), at(5)], [red, red, blue]);
        // each pixel of the gap of two from the nearer square
        assert_eq!([at(8), at(9), at(10), at(11)], [blue, blue, red, red]);
        assert_eq!([at(22), at(23), at(24)], [BACKGROUND; 3]);
        // below the squares nothing is painted
        assert_eq!(pixels[(39 - 10) * 40 + 4], BACKGROUND);
    }

    #[test]
    fn a_view_is_offset_and_clipped_not_wrapped() {
        // the view [10, 14) x [20, 24) on 40 pixels: 10 pixels per unit
        let mut painter = FieldPainter::with_view(40, [10.0, 20.0], 4.0, 1.0, 1.0);
        let particles = [
            ([10.2, 20.2], 1.0),     // bottom left corner, clipped at two edges
            ([13.9, 23.9], -1.0),    // top right corner
            ([12.0, 22.0], 0.0),     // the middle
            ([30.0, 30.0], 1.0),     // outside: nothing
            ([f64::NAN, 21.0], 1.0), // nowhere: nothing
        ];
        let pixels = painter.render(particles.into_iter()).to_vec();
        let at =
            |column: usize, row_from_bottom: usize| pixels[(39 - row_from_bottom) * 40 + column];
        let (red, blue, white) = (FIRST_LEVEL + 254, FIRST_LEVEL, FIRST_LEVEL + 127);
        // the first square covers x in [9.7, 10.7) -> columns 0..7, same rows
        assert_eq!(at(0, 0), red);
        assert_eq!(at(6, 6), red);
        assert_eq!(at(7, 0), BACKGROUND);
        assert_eq!(at(0, 7), BACKGROUND);
        // the second covers [13.4, 14.4) -> columns 34..40
        assert_eq!(at(39, 39), blue);
        assert_eq!(at(34, 34), blue);
        assert_eq!(at(33, 39), BACKGROUND);
        assert_eq!(at(15, 15), white);
        assert_eq!(at(25, 25), BACKGROUND);
        let painted = pixels.iter().filter(|&&p| p != BACKGROUND).count();
        assert_eq!(painted, 7 * 7 + 6 * 6 + 10 * 10);
        // the same particles in a periodic box wrap instead
        let mut periodic = FieldPainter::new(40, 4.0, 1.0, 1.0);
        let shifted = particles[..3]
            .iter()
            .map(|&(x, v)| ([x[0] - 10.0, x[1] - 20.0], v));
        let wrapped = periodic.render(shifted);
        let at =
            |column: usize, row_from_bottom: usize| wrapped[(39 - row_from_bottom) * 40 + column];
        assert_eq!(at(38, 5), red); // wrapped in x
        assert_eq!(at(5, 38), red); // wrapped in y
        assert_eq!(at(1, 1), blue); // wrapped in both, painted last
        assert_eq!(painter.colour_index(0.5), FIRST_LEVEL + 191);
        assert_eq!(painter.scale(), 1.0);
    }

    /// Pseudo-random particles straddling every periodic edge (and outside the box),
    /// with a spacing that is not a whole number of pixels and a NaN value.
    fn periodic_case() -> Vec<([f64; 2], f64)> {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut particles: Vec<([f64; 2], f64)> = (0..60)
            .map(|_| {
                let x = [3.4 * next() - 0.2, 3.4 * next() - 0.2];
                (x, 4.0 * next() - 2.0)
            })
            .collect();
        particles.push(([0.01, 2.99], f64::NAN));
        particles.push(([2.995, 0.003], 1e9));
        particles.push(([-0.05, 1.5], -1e9));
        particles
    }

    fn fnv1a(bytes: &[u8]) -> u64 {
        bytes.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, &b| {
            (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
        })
    }

    #[test]
    fn new_paints_the_periodic_box_as_recorded() {
        // Pixels recorded from the implementation (last when the gap fill came:
        // it painted 24 gap pixels of the first case and the 2 of the second):
        // a change here is a change to every periodic picture.
        let mut painter = FieldPainter::new(37, 3.0, 0.23, 1.5);
        let pixels = painter.render(periodic_case().into_iter()).to_vec();
        assert_eq!(pixels.len(), 37 * 37);
        let background = pixels.iter().filter(|&&p| p == BACKGROUND).count();
        let sum: u64 = pixels.iter().map(|&p| p as u64).sum();
        assert_eq!(
            (fnv1a(&pixels), background, sum),
            (0x0c6c_9a1c_dd50_0b40, 943, 56195)
        );
        // a size below the minimum, a box of side 1 and a spacing of ~5 pixels
        let mut small = FieldPainter::new(10, 1.0, 0.3, 0.7);
        assert_eq!(small.size(), 16);
        let scaled = periodic_case()
            .into_iter()
            .map(|(x, v)| ([x[0] / 3.0, x[1] / 3.0], v));
        let pixels = small.render(scaled).to_vec();
        let background = pixels.iter().filter(|&&p| p == BACKGROUND).count();
        let sum: u64 = pixels.iter().map(|&p| p as u64).sum();
        assert_eq!(
            (fnv1a(&pixels), background, sum),
            (0xc700_2ec8_0c83_027a, 0, 43261)
        );
    }
}
