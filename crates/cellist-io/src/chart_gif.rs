//! Annotated charts (RGB, from [`crate::FieldChart`] and [`crate::BodyChart`]) as
//! frames of an indexed GIF: a fixed 256-colour palette holds the picture's own
//! colours (a field's or a speed scale's palette) and a ramp of greys for the
//! text, axes and their anti-aliasing. Each pixel is looked up exactly; a colour
//! that is not in the palette (anti-aliased text) takes the grey of its
//! luminance. The palette depends on the picture's palette only, so that a
//! resumed animation continues with the very same colours.

use std::collections::HashMap;

/// Greys in the palette, from black to white.
pub const GREYS: usize = 48;

/// The 256 colours of annotated GIF frames and the conversion of RGB charts to
/// them.
#[derive(Clone, Debug)]
pub struct ChartPalette {
    rgb: Vec<u8>,
    exact: HashMap<[u8; 3], u8>,
    grey: [u8; 256],
}

impl ChartPalette {
    /// The palette of charts painted in the colours `data` (RGB triples): all of
    /// them if they fit in the `256 - GREYS` places, else that many evenly spaced
    /// ones (the ends included; the others are drawn in the nearest kept colour),
    /// then [`GREYS`] greys from black to white.
    pub fn new(data: &[u8]) -> Self {
        let colours: Vec<[u8; 3]> = data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let slots = 256 - GREYS;
        let kept: Vec<[u8; 3]> = if colours.len() <= slots {
            colours.clone()
        } else {
            let n = colours.len() - 1;
            (0..slots)
                .map(|k| colours[(k * n + (slots - 1) / 2) / (slots - 1)])
                .collect()
        };
        let first_grey = kept.len();
        let mut rgb: Vec<u8> = kept.iter().flatten().copied().collect();
        let greys = 256 - first_grey;
        for g in 0..greys {
            let v = (255.0 * g as f64 / (greys - 1) as f64).round() as u8;
            rgb.extend_from_slice(&[v, v, v]);
        }
        let entry = |k: usize| [rgb[3 * k], rgb[3 * k + 1], rgb[3 * k + 2]];
        // exact colours: the greys, then the kept colours (which win a tie)
        let mut exact = HashMap::new();
        for k in (first_grey..256).chain(0..first_grey) {
            exact.insert(entry(k), k as u8);
        }
        // the picture's colours that were not kept: the nearest entry
        for c in &colours {
            if !exact.contains_key(c) {
                let distance = |k: usize| {
                    let e = entry(k);
                    (0..3)
                        .map(|i| (e[i] as i32 - c[i] as i32).pow(2))
                        .sum::<i32>()
                };
                let nearest = (0..256).min_by_key(|&k| distance(k)).expect("256 entries");
                exact.insert(*c, nearest as u8);
            }
        }
        // other colours: the grey nearest in luminance
        let mut grey = [0u8; 256];
        for (l, g) in grey.iter_mut().enumerate() {
            let step = 255.0 / (greys - 1) as f64;
            *g = (first_grey + (l as f64 / step).round() as usize) as u8;
        }
        ChartPalette { rgb, exact, grey }
    }

    /// The 256 colours as RGB triples (768 bytes), for the GIF's global palette.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    /// The palette index of the RGB colour `c`: exact when the palette holds it
    /// (or it is one of the picture's colours), else the grey of its luminance.
    pub fn index(&self, c: [u8; 3]) -> u8 {
        match self.exact.get(&c) {
            Some(&k) => k,
            None => {
                let [r, g, b] = c.map(u32::from);
                self.grey[((299 * r + 587 * g + 114 * b + 500) / 1000) as usize]
            }
        }
    }

    /// The RGB `pixels` (3 bytes each) as palette indices, into `out` (cleared
    /// first).
    pub fn indices_into(&self, pixels: &[u8], out: &mut Vec<u8>) {
        out.clear();
        out.reserve(pixels.len() / 3);
        // charts are mostly runs of one colour: look a colour up once per run
        let mut last: Option<([u8; 3], u8)> = None;
        for p in pixels.chunks_exact(3) {
            let c = [p[0], p[1], p[2]];
            let k = match last {
                Some((l, k)) if l == c => k,
                _ => {
                    let k = self.index(c);
                    last = Some((c, k));
                    k
                }
            };
            out.push(k);
        }
    }

    /// The RGB `pixels` as palette indices.
    pub fn indices(&self, pixels: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        self.indices_into(pixels, &mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DiscPainter, FieldPainter};

    fn entry(p: &ChartPalette, k: u8) -> [u8; 3] {
        let r = p.rgb();
        let k = 3 * k as usize;
        [r[k], r[k + 1], r[k + 2]]
    }

    #[test]
    fn a_small_palette_is_kept_whole_and_other_colours_become_greys() {
        let data = [10, 200, 30, 250, 0, 0];
        let p = ChartPalette::new(&data);
        assert_eq!(p.rgb().len(), 768);
        assert_eq!(p.index([10, 200, 30]), 0);
        assert_eq!(p.index([250, 0, 0]), 1);
        assert_eq!(entry(&p, p.index([255, 255, 255])), [255, 255, 255]);
        assert_eq!(entry(&p, p.index([0, 0, 0])), [0, 0, 0]);
        // an anti-aliased grey: the nearest grey of 254
        let g = entry(&p, p.index([100, 100, 100]));
        assert!(g[0] == g[1] && g[1] == g[2] && (g[0] as i32 - 100).abs() <= 1);
        // a colour that is neither: a grey of its luminance
        let g = entry(&p, p.index([0, 0, 255]));
        assert!(g[0] == g[1] && (g[0] as i32 - 29).abs() <= 3, "{g:?}");
    }

    #[test]
    fn a_large_palette_keeps_its_ends_and_maps_every_colour_near() {
        for data in [FieldPainter::palette(), DiscPainter::palette()] {
            let p = ChartPalette::new(&data);
            assert_eq!(p.rgb().len(), 768);
            let first = [data[0], data[1], data[2]];
            assert_eq!(entry(&p, p.index(first)), first);
            let n = data.len() / 3;
            for k in 0..n {
                let c = [data[3 * k], data[3 * k + 1], data[3 * k + 2]];
                let e = entry(&p, p.index(c));
                let d: i32 = (0..3)
                    .map(|i| (e[i] as i32 - c[i] as i32).abs())
                    .max()
                    .unwrap();
                assert!(d <= 12, "colour {k} {c:?} drawn as {e:?}");
            }
            // the same palette every time (a resumed animation relies on it)
            assert_eq!(ChartPalette::new(&data).rgb(), p.rgb());
        }
    }

    #[test]
    fn pixels_convert_in_order() {
        let p = ChartPalette::new(&[1, 2, 3]);
        let pixels = [1, 2, 3, 1, 2, 3, 255, 255, 255, 1, 2, 3];
        let k = p.indices(&pixels);
        assert_eq!(k.len(), 4);
        assert_eq!(k[0], 0);
        assert_eq!(k[1], 0);
        assert_eq!(entry(&p, k[2]), [255, 255, 255]);
        assert_eq!(k[3], 0);
    }
}
