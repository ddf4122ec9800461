//! Writing RGB frames as one looping animated GIF: a fixed 256-colour palette (the
//! drawing's own colours exactly, a grey ramp and a 6×6×6 cube), and each frame stored as
//! the rectangle that changed since the one before, so the file stays small.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use gif::{DisposalMethod, Encoder, Frame, Repeat};

/// Entries of the colour cube per channel.
const CUBE: usize = 6;

/// An animated GIF being written, frame by frame.
pub(super) struct GifWriter {
    encoder: Encoder<BufWriter<File>>,
    size: (u16, u16),
    /// Delay after each frame \[1/100 s\].
    delay: u16,
    /// Palette index of each colour with 5 bits per channel (`r << 10 | g << 5 | b`).
    lookup: Vec<u8>,
    /// Palette indices of the frame before.
    previous: Option<Vec<u8>>,
    /// Indices of the frame being written.
    current: Vec<u8>,
}

/// The palette: `exact` first (at most 40 colours kept), then a grey ramp filling up to
/// 40, then the colour cube.
fn palette(exact: &[[u8; 3]]) -> Vec<[u8; 3]> {
    let mut colours: Vec<[u8; 3]> = Vec::with_capacity(256);
    for c in exact.iter().take(40) {
        if !colours.contains(c) {
            colours.push(*c);
        }
    }
    let greys = 256 - CUBE * CUBE * CUBE - colours.len();
    for k in 0..greys {
        let v = (255 * (k + 1) / (greys + 1)) as u8;
        colours.push([v, v, v]);
    }
    let level = |k: usize| (255 * k / (CUBE - 1)) as u8;
    for r in 0..CUBE {
        for g in 0..CUBE {
            for b in 0..CUBE {
                colours.push([level(r), level(g), level(b)]);
            }
        }
    }
    colours
}

/// The nearest palette entry of every 15-bit colour.
fn lookup_table(palette: &[[u8; 3]]) -> Vec<u8> {
    (0..1usize << 15)
        .map(|key| {
            let channel = |shift: usize| (((key >> shift) & 31) << 3 | 4) as i32;
            let (r, g, b) = (channel(10), channel(5), channel(0));
            let mut best = (i32::MAX, 0u8);
            for (k, c) in palette.iter().enumerate() {
                let (dr, dg, db) = (r - c[0] as i32, g - c[1] as i32, b - c[2] as i32);
                // Weighted toward green, as the eye is.
                let distance = 2 * dr * dr + 4 * dg * dg + 3 * db * db;
                if distance < best.0 {
                    best = (distance, k as u8);
                }
            }
            best.1
        })
        .collect()
}

impl GifWriter {
    /// Starts `path` for frames of `size` pixels shown `delay` hundredths of a second each,
    /// with `exact` colours reproduced exactly.
    pub(super) fn create(
        path: &Path,
        size: (u16, u16),
        delay: u16,
        exact: &[[u8; 3]],
    ) -> Result<GifWriter, String> {
        if size.0 == 0 || size.1 == 0 {
            return Err(format!("frame size {}×{} has no pixels", size.0, size.1));
        }
        let colours = palette(exact);
        let flat: Vec<u8> = colours.iter().flatten().copied().collect();
        let file = File::create(path).map_err(|e| e.to_string())?;
        let mut encoder =
            Encoder::new(BufWriter::new(file), size.0, size.1, &flat).map_err(|e| e.to_string())?;
        encoder
            .set_repeat(Repeat::Infinite)
            .map_err(|e| e.to_string())?;
        Ok(GifWriter {
            encoder,
            size,
            delay,
            lookup: lookup_table(&colours),
            previous: None,
            current: vec![0; size.0 as usize * size.1 as usize],
        })
    }

    /// Appends a frame of 8-bit RGB pixels, row-major, of the size given to
    /// [`GifWriter::create`].
    pub(super) fn push(&mut self, rgb: &[u8]) -> Result<(), String> {
        let (width, height) = (self.size.0 as usize, self.size.1 as usize);
        if rgb.len() != 3 * width * height {
            return Err(format!(
                "frame of {} bytes, expected {}",
                rgb.len(),
                3 * width * height
            ));
        }
        for (index, pixel) in self.current.iter_mut().zip(rgb.chunks_exact(3)) {
            let key = (pixel[0] as usize >> 3) << 10
                | (pixel[1] as usize >> 3) << 5
                | pixel[2] as usize >> 3;
            *index = self.lookup[key];
        }
        // The rectangle that changed (the whole frame the first time; one pixel if none).
        let (mut x0, mut y0, mut x1, mut y1) = (0, 0, width, height);
        if let Some(previous) = &self.previous {
            let row_changed = |y: usize| {
                previous[y * width..(y + 1) * width] != self.current[y * width..(y + 1) * width]
            };
            match (0..height).find(|&y| row_changed(y)) {
                None => (x0, y0, x1, y1) = (0, 0, 1, 1),
                Some(top) => {
                    let bottom = (top..height).rev().find(|&y| row_changed(y)).unwrap_or(top);
                    let column_changed = |x: usize| {
                        (top..=bottom)
                            .any(|y| previous[y * width + x] != self.current[y * width + x])
                    };
                    let left = (0..width).find(|&x| column_changed(x)).unwrap_or(0);
                    let right = (left..width)
                        .rev()
                        .find(|&x| column_changed(x))
                        .unwrap_or(left);
                    (x0, y0, x1, y1) = (left, top, right + 1, bottom + 1);
                }
            }
        }
        let mut buffer = Vec::with_capacity((x1 - x0) * (y1 - y0));
        for y in y0..y1 {
            buffer.extend_from_slice(&self.current[y * width + x0..y * width + x1]);
        }
        let frame = Frame {
            delay: self.delay,
            dispose: DisposalMethod::Keep,
            left: x0 as u16,
            top: y0 as u16,
            width: (x1 - x0) as u16,
            height: (y1 - y0) as u16,
            buffer: buffer.into(),
            ..Frame::default()
        };
        self.encoder
            .write_frame(&frame)
            .map_err(|e| e.to_string())?;
        match &mut self.previous {
            Some(previous) => previous.copy_from_slice(&self.current),
            None => self.previous = Some(self.current.clone()),
        }
        Ok(())
    }

    /// Writes the trailer and flushes the file.
    pub(super) fn finish(self) -> Result<(), String> {
        use std::io::Write;
        let mut file = self.encoder.into_inner().map_err(|e| e.to_string())?;
        file.flush().map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palette_keeps_exact_colours_and_has_256_entries() {
        let exact = [[255, 255, 255], [0, 0, 0], [230, 145, 0], [230, 145, 0]];
        let colours = palette(&exact);
        assert_eq!(colours.len(), 256);
        assert_eq!(colours[2], [230, 145, 0]);
        let lookup = lookup_table(&colours);
        let key = |c: [u8; 3]| {
            (c[0] as usize >> 3) << 10 | (c[1] as usize >> 3) << 5 | c[2] as usize >> 3
        };
        assert_eq!(lookup[key([230, 145, 0])], 2);
        assert_eq!(
            colours[lookup[key([255, 255, 255])] as usize],
            [255, 255, 255]
        );
    }
}
