//! PNG output for 8-bit grayscale images (the annotated frame in the report), through the `png`
//! crate: deflate-compressed, viewable anywhere.

use anyhow::Context as _;

/// Encodes a `width × height` row-major 8-bit grayscale image (`pixels` holds exactly
/// `width·height` bytes).
pub fn encode_gray8(width: usize, height: usize, pixels: &[u8]) -> anyhow::Result<Vec<u8>> {
    let w = u32::try_from(width).context("PNG width")?;
    let h = u32::try_from(height).context("PNG height")?;
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, w, h);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(pixels)?;
    writer.finish()?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_the_decoder() {
        let img: Vec<u8> = (0..70_000u32).map(|i| (i % 251) as u8).collect();
        let bytes = encode_gray8(350, 200, &img).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let mut reader = png::Decoder::new(std::io::Cursor::new(&bytes))
            .read_info()
            .unwrap();
        let info = reader.info();
        assert_eq!((info.width, info.height), (350, 200));
        assert_eq!(info.color_type, png::ColorType::Grayscale);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let frame = reader.next_frame(&mut buf).unwrap();
        assert_eq!(&buf[..frame.buffer_size()], &img[..]);
    }

    #[test]
    fn a_short_buffer_is_an_error_not_a_corrupt_file() {
        assert!(encode_gray8(10, 10, &[0u8; 50]).is_err());
    }
}
