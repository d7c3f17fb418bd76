//! Pictures of a scalar field carried by particles: each particle paints the square
//! of one lattice spacing around it in a blue-white-red colour for its value (blue
//! negative, white zero, red positive, saturating at a fixed scale, so that frames
//! of one run compare). The frames go to [`crate::GifAnimation`] and
//! [`crate::write_png`] with [`FieldPainter::palette`].

const BACKGROUND: u8 = 0;
const FIRST_LEVEL: u8 = 1;
const LEVELS: usize = 255;

/// Paints the box `[0, side)^2` on `size` x `size` pixels.
#[derive(Clone, Debug)]
pub struct FieldPainter {
    size: u32,
    side: f64,
    spacing: f64,
    scale: f64,
    pixels: Vec<u8>,
}

impl FieldPainter {
    /// A painter for particles `spacing` apart whose colours saturate at
    /// `|value| = scale`.
    pub fn new(size: u32, side: f64, spacing: f64, scale: f64) -> Self {
        FieldPainter {
            size: size.max(16),
            side,
            spacing,
            scale: if scale > 0.0 && scale.is_finite() {
                scale
            } else {
                1.0
            },
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

    /// Renders `(position, value)` pairs; returns the palette indices row by row
    /// from the top (y up). Squares wrap across the periodic edges.
    pub fn render(&mut self, particles: impl Iterator<Item = ([f64; 2], f64)>) -> &[u8] {
        let size = self.size as usize;
        self.pixels.clear();
        self.pixels.resize(size * size, BACKGROUND);
        let per_unit = size as f64 / self.side;
        let half = 0.5 * self.spacing * per_unit;
        for (x, value) in particles {
            let t = if value.is_nan() {
                0.0
            } else {
                (value / self.scale).clamp(-1.0, 1.0)
            };
            let level = ((t + 1.0) * 0.5 * (LEVELS - 1) as f64).round() as u8;
            let colour = FIRST_LEVEL + level;
            let (cx, cy) = (x[0] * per_unit, x[1] * per_unit);
            let span = |c: f64| {
                let lo = (c - half).round() as i64;
                let hi = ((c + half).round() as i64).max(lo + 1);
                lo..hi
            };
            for py in span(cy) {
                let row = py.rem_euclid(size as i64) as usize;
                for px in span(cx) {
                    let column = px.rem_euclid(size as i64) as usize;
                    self.pixels[(size - 1 - row) * size + column] = colour;
                }
            }
        }
        &self.pixels
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
}
