//! Images: 8-bit RGB PNGs and the false-colour heatmap of nodes visited per ray.

use super::file::write_file;
use crate::commands::Result;
use std::io::Write;
use std::path::Path;

/// Writes an 8-bit RGB image.
pub(crate) fn write_png(path: &Path, w: u32, h: u32, rgb: &[[u8; 3]]) -> Result<()> {
    let width = w as usize;
    write_png_rows(path, w, h, |y, row| {
        row.copy_from_slice(rgb[y * width..(y + 1) * width].as_flattened())
    })
}

/// Writes an 8-bit RGB image whose row `y` `fill(y, row)` writes into `row` (3 bytes a pixel),
/// streamed: the encoder holds a row and a chunk of compressed data, not the image (which
/// `write_image_data` would compress into memory whole).
fn write_png_rows(
    path: &Path,
    w: u32,
    h: u32,
    mut fill: impl FnMut(usize, &mut [u8]),
) -> Result<()> {
    write_file(path, |out| {
        let mut enc = png::Encoder::new(out, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header()?;
        let mut stream = writer.stream_writer()?;
        let mut row = vec![0u8; 3 * w as usize];
        for y in 0..h as usize {
            fill(y, &mut row);
            stream.write_all(&row)?;
        }
        stream.finish()?;
        Ok(())
    })
}

/// Writes a false-colour picture of per-ray node counts, `width` a row: dark blue (few)
/// through green and yellow to red (the most, at the 99th percentile so a few outliers do not
/// wash out the image). Streamed row by row; the percentile comes from a histogram of the
/// counts, so nothing of the picture's size is held but the counts.
pub(crate) fn write_heatmap(path: &Path, counts: &[u32], width: usize) -> Result<()> {
    let top = percentile_99(counts).max(1) as f32;
    let height = counts.len() / width.max(1);
    write_png_rows(path, width as u32, height as u32, |y, row| {
        for (px, &c) in row
            .chunks_exact_mut(3)
            .zip(&counts[y * width..(y + 1) * width])
        {
            px.copy_from_slice(&heat(c as f32 / top));
        }
    })
}

/// The element at index `len * 99 / 100` of `counts` sorted (0 for none).
fn percentile_99(counts: &[u32]) -> u32 {
    let Some(&max) = counts.iter().max() else {
        return 0;
    };
    let rank = counts.len() * 99 / 100;
    if max as usize <= 1 << 22 {
        // A histogram: 4 bytes per distinct value up to the largest, not per count.
        let mut histogram = vec![0u32; max as usize + 1];
        for &c in counts {
            histogram[c as usize] += 1;
        }
        let mut seen = 0usize;
        for (value, &n) in histogram.iter().enumerate() {
            seen += n as usize;
            if seen > rank {
                return value as u32;
            }
        }
        max
    } else {
        let mut copy = counts.to_vec();
        *copy.select_nth_unstable(rank).1
    }
}

/// The heatmap's colour at `x` (0 few, 1 the 99th percentile and above).
fn heat(x: f32) -> [u8; 3] {
    let x = x.min(1.0);
    let ramp = [
        (0.0, [0.0, 0.0, 0.3]),
        (0.33, [0.0, 0.6, 1.0]),
        (0.66, [1.0, 1.0, 0.0]),
        (1.0, [1.0, 0.0, 0.0]),
    ];
    let k = ramp.windows(2).position(|w| x <= w[1].0).unwrap_or(2);
    let (a, b) = (ramp[k], ramp[k + 1]);
    let f = (x - a.0) / (b.0 - a.0);
    let ch = |i: usize| ((a.1[i] + (b.1[i] - a.1[i]) * f) * 255.0 + 0.5) as u8;
    [ch(0), ch(1), ch(2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histogram percentile is the sorted array's element.
    #[test]
    fn percentile_is_the_sorted_element() {
        let mut seed = 5u64;
        for len in [0usize, 1, 2, 99, 100, 101, 1000, 4097] {
            for spread in [1u32, 7, 1000, u32::MAX] {
                let counts: Vec<u32> = (0..len)
                    .map(|_| {
                        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                        ((seed >> 33) as u32) % spread.max(1)
                    })
                    .collect();
                let mut sorted = counts.clone();
                sorted.sort_unstable();
                let want = sorted.get(len * 99 / 100).copied().unwrap_or(0);
                assert_eq!(percentile_99(&counts), want, "{len} {spread}");
            }
        }
    }
}
