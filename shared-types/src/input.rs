//! Reading a user's file with a size limit: `/dev/zero` or a wrong path to a disk image must
//! give an error, not read until memory runs out.

use std::io::Read;
use std::path::Path;

/// Largest scenario or settings file read \[bytes\].
pub const MAX_TEXT_FILE_BYTES: u64 = 1 << 20;

/// The whole file, or an `InvalidData` error when it holds more than `max_bytes` (checked on
/// what is read, so it holds for pipes and devices whose size the file system does not know).
pub fn read_capped(path: &Path, max_bytes: u64) -> std::io::Result<Vec<u8>> {
    let mut bytes = vec![];
    std::fs::File::open(path)?
        .take(max_bytes + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "larger than the {} MiB glint reads from such a file",
                max_bytes >> 20
            ),
        ));
    }
    Ok(bytes)
}

/// [`read_capped`] as UTF-8 text.
pub fn read_text_capped(path: &Path, max_bytes: u64) -> std::io::Result<String> {
    String::from_utf8(read_capped(path, max_bytes)?).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (at byte {})", e.utf8_error().valid_up_to()),
        )
    })
}
