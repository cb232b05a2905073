//! Binary PGM ("P5") images for the offline tool (architecture.md §5: `glint tool detect
//! FRAME.pgm`).
//!
//! Format (netpbm): the magic `P5`; then width, height and maxval as ASCII decimals separated by
//! whitespace, where a `#` starts a comment that runs to the end of the line; then exactly one
//! whitespace byte; then `width × height` samples in row-major order. maxval is 1..=65535;
//! samples are one byte if maxval < 256, else two bytes, big-endian (most significant first).
//! Samples must not exceed maxval. Bytes after the raster (a further image) are ignored.

use std::path::{Path, PathBuf};

/// A grey image with u16 samples (8-bit files are widened).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PgmImage {
    pub width: usize,
    pub height: usize,
    /// Largest sample value allowed by the file, 1..=65535.
    pub maxval: u16,
    /// Row-major samples, `width × height`.
    pub pixels: Vec<u16>,
}

/// Why a PGM could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum PgmError {
    #[error("not a binary PGM: the file starts with {found:?}, expected \"P5\"")]
    BadMagic { found: String },
    #[error("PGM header ends before the {field}")]
    UnexpectedEnd { field: &'static str },
    #[error("PGM {field} is not a decimal number: {text:?}")]
    BadNumber { field: &'static str, text: String },
    #[error("PGM {field} is 0; the image must not be empty")]
    ZeroDimension { field: &'static str },
    #[error("PGM maxval {maxval} is out of range 1..=65535")]
    MaxvalOutOfRange { maxval: u64 },
    #[error("PGM image of {width}×{height} px is too large")]
    TooLarge { width: u64, height: u64 },
    #[error(
        "PGM raster is short: {width}×{height} px at {bytes_per_sample} byte(s) per sample \
         needs {expected} bytes after the header, found {found}"
    )]
    ShortData {
        width: usize,
        height: usize,
        bytes_per_sample: usize,
        expected: usize,
        found: usize,
    },
    #[error("PGM sample {value} at pixel {index} exceeds maxval {maxval}")]
    SampleAboveMaxval {
        index: usize,
        value: u16,
        maxval: u16,
    },
    #[error("PGM pixel buffer has {len} samples for {width}×{height} px")]
    SizeMismatch {
        width: usize,
        height: usize,
        len: usize,
    },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Header cursor over the raw bytes.
struct Header<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Header<'_> {
    /// Skips whitespace and `#` comments.
    fn skip_blank(&mut self) {
        while let Some(&c) = self.bytes.get(self.pos) {
            if c == b'#' {
                while let Some(&c) = self.bytes.get(self.pos) {
                    if c == b'\n' || c == b'\r' {
                        break;
                    }
                    self.pos += 1;
                }
            } else if c.is_ascii_whitespace() {
                self.pos += 1;
            } else {
                break;
            }
        }
    }

    fn number(&mut self, field: &'static str) -> Result<u64, PgmError> {
        self.skip_blank();
        let start = self.pos;
        while self
            .bytes
            .get(self.pos)
            .is_some_and(|c| !c.is_ascii_whitespace() && *c != b'#')
        {
            self.pos += 1;
        }
        let token = &self.bytes[start..self.pos];
        if token.is_empty() {
            return Err(PgmError::UnexpectedEnd { field });
        }
        let bad = || PgmError::BadNumber {
            field,
            text: String::from_utf8_lossy(&token[..token.len().min(32)]).into_owned(),
        };
        if !token.iter().all(u8::is_ascii_digit) {
            return Err(bad());
        }
        std::str::from_utf8(token)
            .ok()
            .and_then(|s| s.parse::<u64>().ok())
            .ok_or_else(bad)
    }
}

/// Parses a binary PGM from memory.
pub fn parse_pgm(bytes: &[u8]) -> Result<PgmImage, PgmError> {
    if bytes.len() < 2 || &bytes[..2] != b"P5" {
        let found = String::from_utf8_lossy(&bytes[..bytes.len().min(2)]).into_owned();
        return Err(PgmError::BadMagic { found });
    }
    let mut h = Header { bytes, pos: 2 };
    if h.bytes
        .get(2)
        .is_some_and(|c| !c.is_ascii_whitespace() && *c != b'#')
    {
        let found = String::from_utf8_lossy(&bytes[..bytes.len().min(3)]).into_owned();
        return Err(PgmError::BadMagic { found });
    }
    let width = h.number("width")?;
    let height = h.number("height")?;
    let maxval = h.number("maxval")?;
    for (field, v) in [("width", width), ("height", height)] {
        if v == 0 {
            return Err(PgmError::ZeroDimension { field });
        }
    }
    if maxval == 0 || maxval > 65_535 {
        return Err(PgmError::MaxvalOutOfRange { maxval });
    }
    let maxval = maxval as u16;
    // Exactly one whitespace byte separates maxval from the raster; a comment may sit between
    // them, and the line end that closes it is the separator.
    if h.bytes.get(h.pos) == Some(&b'#') {
        while h
            .bytes
            .get(h.pos)
            .is_some_and(|c| *c != b'\n' && *c != b'\r')
        {
            h.pos += 1;
        }
    }
    match h.bytes.get(h.pos) {
        Some(c) if c.is_ascii_whitespace() => h.pos += 1,
        _ => return Err(PgmError::UnexpectedEnd { field: "raster" }),
    }
    let bytes_per_sample = if maxval < 256 { 1 } else { 2 };
    let too_large = PgmError::TooLarge { width, height };
    let (w, ht) = match (usize::try_from(width), usize::try_from(height)) {
        (Ok(w), Ok(ht)) => (w, ht),
        _ => return Err(too_large),
    };
    let n = w.checked_mul(ht).ok_or(too_large)?;
    let expected = n
        .checked_mul(bytes_per_sample)
        .ok_or(PgmError::TooLarge { width, height })?;
    let raster = &bytes[h.pos..];
    if raster.len() < expected {
        return Err(PgmError::ShortData {
            width: w,
            height: ht,
            bytes_per_sample,
            expected,
            found: raster.len(),
        });
    }
    let pixels: Vec<u16> = if bytes_per_sample == 1 {
        raster[..n].iter().map(|&b| u16::from(b)).collect()
    } else {
        raster[..expected]
            .chunks_exact(2)
            .map(|p| u16::from_be_bytes([p[0], p[1]]))
            .collect()
    };
    check_samples(&pixels, maxval)?;
    Ok(PgmImage {
        width: w,
        height: ht,
        maxval,
        pixels,
    })
}

fn check_samples(pixels: &[u16], maxval: u16) -> Result<(), PgmError> {
    match pixels.iter().position(|&v| v > maxval) {
        Some(index) => Err(PgmError::SampleAboveMaxval {
            index,
            value: pixels[index],
            maxval,
        }),
        None => Ok(()),
    }
}

/// Encodes an image as binary PGM (`P5\n<w> <h>\n<maxval>\n` + raster).
pub fn encode_pgm(image: &PgmImage) -> Result<Vec<u8>, PgmError> {
    let PgmImage {
        width,
        height,
        maxval,
        ref pixels,
    } = *image;
    if width == 0 || height == 0 {
        let field = if width == 0 { "width" } else { "height" };
        return Err(PgmError::ZeroDimension { field });
    }
    if maxval == 0 {
        return Err(PgmError::MaxvalOutOfRange { maxval: 0 });
    }
    if width.checked_mul(height) != Some(pixels.len()) {
        return Err(PgmError::SizeMismatch {
            width,
            height,
            len: pixels.len(),
        });
    }
    check_samples(pixels, maxval)?;
    let mut out = format!("P5\n{width} {height}\n{maxval}\n").into_bytes();
    if maxval < 256 {
        out.extend(pixels.iter().map(|&v| v as u8));
    } else {
        out.reserve(2 * pixels.len());
        for &v in pixels {
            out.extend_from_slice(&v.to_be_bytes());
        }
    }
    Ok(out)
}

/// Largest PGM file read \[bytes\]: a 8192² 16-bit frame and its header.
pub const MAX_PGM_FILE_BYTES: u64 = 8192 * 8192 * 2 + 4096;

/// Reads a binary PGM file (at most [`MAX_PGM_FILE_BYTES`]).
pub fn read_pgm(path: &Path) -> Result<PgmImage, PgmError> {
    let bytes = shared_types::input::read_capped(path, MAX_PGM_FILE_BYTES).map_err(|source| {
        PgmError::Io {
            path: path.to_path_buf(),
            source,
        }
    })?;
    parse_pgm(&bytes)
}

/// Writes a binary PGM file.
pub fn write_pgm(path: &Path, image: &PgmImage) -> Result<(), PgmError> {
    let bytes = encode_pgm(image)?;
    std::fs::write(path, bytes).map_err(|source| PgmError::Io {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests;
