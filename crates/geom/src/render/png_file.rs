//! Storing and loading [`Image`]s as PNG.

use super::Image;
use crate::{GeomError, Location};
use std::path::Path;

/// Write `image` as an 8-bit RGB PNG, atomically (a failed write leaves no
/// partial file and keeps any previous one).
pub fn write_png(path: impl AsRef<Path>, image: &Image) -> Result<(), GeomError> {
    let expected = 3 * image.width as usize * image.height as usize;
    if image.width == 0 || image.height == 0 || image.pixels.len() != expected {
        return Err(GeomError::InvalidInput(format!(
            "image of {}x{} pixels has {} bytes, expected {expected} (and a non-empty size)",
            image.width,
            image.height,
            image.pixels.len()
        )));
    }
    crate::io::write_atomic(path, |w| {
        let mut encoder = png::Encoder::new(w, image.width, image.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        // Per-row filter choice: shaded pictures compress far better.
        encoder.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
        writer
            .write_image_data(&image.pixels)
            .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)
    })
}

/// Read a PNG of any colour type and bit depth as 8-bit RGB (grey is
/// replicated, alpha dropped).
pub fn read_png(path: impl AsRef<Path>) -> Result<Image, GeomError> {
    let path = path.as_ref();
    let parse_err = |message: String| GeomError::Parse {
        path: path.to_path_buf(),
        location: Location::File,
        message,
    };
    let file = std::fs::File::open(path).map_err(|source| GeomError::Io {
        path: path.to_path_buf(),
        error: source,
    })?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder
        .read_info()
        .map_err(|e| parse_err(format!("not a readable PNG: {e}")))?;
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader
        .next_frame(&mut buffer)
        .map_err(|e| parse_err(format!("PNG image data: {e}")))?;
    buffer.truncate(info.buffer_size());
    let channels = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err(parse_err("palette PNG was not expanded".into())),
    };
    let pixels = buffer
        .chunks_exact(channels)
        .flat_map(|p| {
            if channels < 3 {
                [p[0]; 3]
            } else {
                [p[0], p[1], p[2]]
            }
        })
        .collect();
    Ok(Image {
        width: info.width,
        height: info.height,
        pixels,
    })
}
