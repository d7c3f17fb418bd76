//! PNG reading for the picture tests.

use std::path::Path;

/// Decodes an 8-bit RGB PNG into (width, height, RGB pixels).
pub fn decode(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// The colour of pixel `(x, y)` of an RGB picture `width` pixels wide.
pub fn pixel(rgb: &[u8], width: u32, [x, y]: [u32; 2]) -> [u8; 3] {
    let k = 3 * (y * width + x) as usize;
    [rgb[k], rgb[k + 1], rgb[k + 2]]
}

/// The pixels darker than 100 in every channel (text, axes) in the rectangle
/// `xs` x `ys`.
pub fn dark_pixels(
    rgb: &[u8],
    width: u32,
    xs: std::ops::Range<u32>,
    ys: std::ops::Range<u32>,
) -> usize {
    ys.flat_map(|y| xs.clone().map(move |x| [x, y]))
        .filter(|&p| pixel(rgb, width, p).iter().all(|&c| c < 100))
        .count()
}
