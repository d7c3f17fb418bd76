//! Pictures of discs in a square box, coloured by speed: frames of a GIF animation
//! and a PNG of one frame. Indexed colour: white background, the box outline in
//! grey, and a blue-to-red scale of 250 colours from speed 0 to the scale's top.

use crate::output::{AtomicFile, StreamFile};
use std::io;
use std::path::Path;

const BACKGROUND: u8 = 0;
const OUTLINE: u8 = 1;
const FIRST_SPEED: u8 = 2;
const SPEEDS: usize = 250;

/// Draws discs of radius `radius` in the box `[0, side]^2` (with a margin of 5% of
/// the side around it) on `size` x `size` pixels.
#[derive(Clone, Debug)]
pub struct DiscPainter {
    size: u32,
    side: f64,
    radius: f64,
    top_speed: f64,
    pixels: Vec<u8>,
}

impl DiscPainter {
    /// The colours of [`DiscPainter::palette`] in use (background, outline and
    /// the speeds); the rest pads it to 256.
    pub const COLOURS: usize = FIRST_SPEED as usize + SPEEDS;

    /// A painter whose colour scale ends at `top_speed` (faster discs are drawn in
    /// the top colour).
    pub fn new(size: u32, side: f64, radius: f64, top_speed: f64) -> Self {
        DiscPainter {
            size: size.max(16),
            side,
            radius,
            top_speed: if top_speed > 0.0 { top_speed } else { 1.0 },
            pixels: Vec::new(),
        }
    }

    /// The palette as RGB triples (index 0 background, 1 outline, then speeds).
    pub fn palette() -> Vec<u8> {
        let mut rgb = vec![255, 255, 255, 120, 120, 120];
        // blue -> cyan -> yellow -> red
        const STOPS: [[f64; 3]; 4] = [
            [40.0, 60.0, 200.0],
            [30.0, 190.0, 200.0],
            [240.0, 210.0, 40.0],
            [210.0, 40.0, 30.0],
        ];
        for k in 0..SPEEDS {
            let t = k as f64 / (SPEEDS - 1) as f64 * (STOPS.len() - 1) as f64;
            let i = (t.floor() as usize).min(STOPS.len() - 2);
            let f = t - i as f64;
            for c in 0..3 {
                rgb.push((STOPS[i][c] + (STOPS[i + 1][c] - STOPS[i][c]) * f).round() as u8);
            }
        }
        rgb.resize(256 * 3, 0);
        rgb
    }

    /// The side of the picture in pixels.
    pub fn size(&self) -> u32 {
        self.size
    }

    /// The top of the colour scale.
    pub fn top_speed(&self) -> f64 {
        self.top_speed
    }

    /// The square a picture shows, `(lower corner, side)`: the box `[0, side]^2`
    /// with a margin of 5% of its side around it.
    pub fn view(&self) -> ([f64; 2], f64) {
        let margin = 0.05 * self.side;
        ([-margin, -margin], self.side + 2.0 * margin)
    }

    /// The palette index of a disc moving at `speed`: 250 levels from 0 to the top
    /// speed (faster discs get the top colour).
    pub fn speed_index(&self, speed: f64) -> u8 {
        Self::speed_colour(speed, self.top_speed)
    }

    /// The palette index of `speed` on a scale from 0 to `top_speed` (250 levels;
    /// faster, and NaN, get the top colour): the colours of every picture coloured
    /// by speed.
    pub fn speed_colour(speed: f64, top_speed: f64) -> u8 {
        let t = (speed / top_speed).min(1.0);
        let t = if t.is_nan() { 1.0 } else { t.max(0.0) };
        FIRST_SPEED + (t * (SPEEDS - 1) as f64) as u8
    }

    /// Renders one frame; returns its palette indices, row by row from the top.
    pub fn render(&mut self, x: &[f64], y: &[f64], v: &[[f64; 2]]) -> &[u8] {
        let size = self.size as usize;
        self.pixels.clear();
        self.pixels.resize(size * size, BACKGROUND);
        let margin = 0.05 * self.side;
        let scale = size as f64 / (self.side + 2.0 * margin);
        let to_px = |c: f64| (c + margin) * scale;
        // the box outline
        let (lo, hi) = (
            to_px(0.0) as usize,
            (to_px(self.side) as usize).min(size - 1),
        );
        for k in lo..=hi {
            for (px, py) in [(k, lo), (k, hi), (lo, k), (hi, k)] {
                self.pixels[(size - 1 - py) * size + px] = OUTLINE;
            }
        }
        let r_px = (self.radius * scale).max(0.5);
        for k in 0..x.len() {
            let colour = self.speed_index((v[k][0] * v[k][0] + v[k][1] * v[k][1]).sqrt());
            let (cx, cy) = (to_px(x[k]), to_px(y[k]));
            let span = |c: f64| {
                (
                    (c - r_px).floor().max(0.0) as usize,
                    ((c + r_px).ceil().min(size as f64 - 1.0)).max(-1.0),
                )
            };
            let ((x0, x1), (y0, y1)) = (span(cx), span(cy));
            if x1 < 0.0 || y1 < 0.0 {
                continue;
            }
            for py in y0..=y1 as usize {
                for px in x0..=x1 as usize {
                    let (dx, dy) = (px as f64 + 0.5 - cx, py as f64 + 0.5 - cy);
                    if dx * dx + dy * dy <= r_px * r_px || (px == cx as usize && py == cy as usize)
                    {
                        self.pixels[(size - 1 - py) * size + px] = colour;
                    }
                }
            }
        }
        &self.pixels
    }
}

/// A GIF animation written frame by frame to its file as the run goes; a restart
/// continues it ([`GifAnimation::resume`]).
pub struct GifAnimation {
    encoder: gif::Encoder<GifSink>,
    width: u16,
    height: u16,
}

/// The animation's file, which drops the first `skip` bytes written to it: a
/// resumed animation's encoder writes the header again, and the file has it.
struct GifSink {
    file: StreamFile,
    skip: usize,
}

impl io::Write for GifSink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let dropped = self.skip.min(buf.len());
        self.skip -= dropped;
        self.file.write_all(&buf[dropped..])?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

impl GifAnimation {
    /// Starts an animation of `width` x `height` frames at `path` in `palette` (RGB
    /// triples), looping forever.
    pub fn create(path: &Path, width: u32, height: u32, palette: &[u8]) -> io::Result<Self> {
        Self::start(StreamFile::create(path)?, 0, [width, height], palette)
    }

    /// Continues the animation at `path` from its first `length` bytes (the header
    /// and the frames a checkpoint counted); the frame size and palette must be
    /// those it was created with.
    pub fn resume(
        path: &Path,
        length: u64,
        width: u32,
        height: u32,
        palette: &[u8],
    ) -> io::Result<Self> {
        let header = Self::start_encoder(Vec::new(), [width, height], palette)?
            .get_ref()
            .len();
        if length < header as u64 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{} is shorter than a GIF header", path.display()),
            ));
        }
        Self::start(
            StreamFile::resume(path, length)?,
            header,
            [width, height],
            palette,
        )
    }

    fn start_encoder<W: io::Write>(
        w: W,
        size: [u32; 2],
        palette: &[u8],
    ) -> io::Result<gif::Encoder<W>> {
        let [width, height] = size.map(|s| {
            u16::try_from(s)
                .map_err(|_| io::Error::other("a GIF frame is at most 65535 pixels wide and high"))
        });
        let mut encoder =
            gif::Encoder::new(w, width?, height?, palette).map_err(io::Error::other)?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(io::Error::other)?;
        Ok(encoder)
    }

    fn start(file: StreamFile, skip: usize, size: [u32; 2], palette: &[u8]) -> io::Result<Self> {
        let encoder = Self::start_encoder(GifSink { file, skip }, size, palette)?;
        Ok(GifAnimation {
            encoder,
            width: size[0] as u16,
            height: size[1] as u16,
        })
    }

    /// The frame size in pixels, `[width, height]`.
    pub fn frame_size(&self) -> [u32; 2] {
        [self.width as u32, self.height as u32]
    }

    /// Appends a frame (palette indices, `width * height`, rows from the top)
    /// shown for `delay` hundredths of a second.
    pub fn add_frame(&mut self, pixels: &[u8], delay: u16) -> io::Result<()> {
        if pixels.len() != self.width as usize * self.height as usize {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "a GIF frame of {} pixels, expected {} x {}",
                    pixels.len(),
                    self.width,
                    self.height
                ),
            ));
        }
        let mut frame = gif::Frame::from_indexed_pixels(self.width, self.height, pixels, None);
        frame.delay = delay;
        self.encoder.write_frame(&frame).map_err(io::Error::other)
    }

    /// Flushes the frames so far and returns the file's length (without the
    /// trailer that [`GifAnimation::finish`] adds).
    pub fn sync(&mut self) -> io::Result<u64> {
        self.encoder.get_mut().file.sync()
    }

    /// Ends the animation (writes the trailer) and flushes the file.
    pub fn finish(self) -> io::Result<()> {
        let mut sink = self.encoder.into_inner()?;
        sink.file.sync().map(drop)
    }
}

impl io::Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer().write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer().flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_a_disc_in_its_speed_colour_and_animates_it() {
        let mut painter = DiscPainter::new(100, 10.0, 1.0, 2.0);
        let pixels = painter.render(&[5.0], &[5.0], &[[2.0, 0.0]]).to_vec();
        let centre = 50 * 100 + 50;
        assert_eq!(pixels[centre], FIRST_SPEED + (SPEEDS - 1) as u8);
        assert_eq!(pixels[0], BACKGROUND);
        assert!(pixels.contains(&OUTLINE));
        // a disc far outside the view is skipped, not drawn at the edge
        let far = painter.render(&[-1e9], &[5.0], &[[0.0, 0.0]]).to_vec();
        assert!(!far.iter().any(|&p| p >= FIRST_SPEED));

        let dir = tempfile::tempdir().unwrap();
        let gif_path = dir.path().join("a.gif");
        let mut gif = GifAnimation::create(&gif_path, 100, 100, &DiscPainter::palette()).unwrap();
        gif.add_frame(&pixels, 5).unwrap();
        gif.add_frame(&far, 5).unwrap();
        gif.finish().unwrap();
        assert_eq!(&std::fs::read(&gif_path).unwrap()[..6], b"GIF89a");
        assert_eq!(DiscPainter::palette().len(), 768);
    }
}
