//! PGM round trips and every error.

use super::*;

fn header_then(header: &str, raster: &[u8]) -> Vec<u8> {
    let mut bytes = header.as_bytes().to_vec();
    bytes.extend_from_slice(raster);
    bytes
}

#[test]
fn sixteen_bit_round_trip_in_memory_and_on_disk() {
    let image = PgmImage {
        width: 5,
        height: 3,
        maxval: 65_535,
        pixels: (0..15u16).map(|i| i * 4001 + 7).collect(),
    };
    let bytes = encode_pgm(&image).expect("valid image");
    assert!(bytes.starts_with(b"P5\n5 3\n65535\n"));
    assert_eq!(bytes.len(), 13 + 30);
    // Big-endian: the first sample 7 is [0, 7].
    assert_eq!(&bytes[13..15], &[0, 7]);
    assert_eq!(parse_pgm(&bytes).expect("parses"), image);
    let path = std::env::temp_dir().join(format!("glint-detector-pgm-{}.pgm", std::process::id()));
    write_pgm(&path, &image).expect("writes");
    let back = read_pgm(&path);
    let _ = std::fs::remove_file(&path);
    assert_eq!(back.expect("reads"), image);
}

#[test]
fn eight_bit_round_trip_and_widening() {
    let image = PgmImage {
        width: 4,
        height: 2,
        maxval: 255,
        pixels: vec![0, 1, 2, 3, 250, 251, 254, 255],
    };
    let bytes = encode_pgm(&image).expect("valid image");
    assert_eq!(bytes.len(), "P5\n4 2\n255\n".len() + 8);
    assert_eq!(parse_pgm(&bytes).expect("parses"), image);
    // maxval 1000 ≥ 256 ⇒ two bytes per sample even though values are small.
    let image = PgmImage {
        maxval: 1000,
        ..image
    };
    let bytes = encode_pgm(&image).expect("valid image");
    assert_eq!(bytes.len(), "P5\n4 2\n1000\n".len() + 16);
    assert_eq!(parse_pgm(&bytes).expect("parses"), image);
}

#[test]
fn comments_and_whitespace_in_the_header() {
    let bytes = header_then(
        "P5 # made by hand\r\n# a full-line comment\n\t3   # width\n2\n\n  # maxval next\n300# tail\n",
        &[0, 1, 0, 2, 0, 3, 1, 0, 1, 1, 1, 44],
    );
    let image = parse_pgm(&bytes).expect("parses");
    assert_eq!((image.width, image.height, image.maxval), (3, 2, 300));
    assert_eq!(image.pixels, vec![1, 2, 3, 256, 257, 300]);
    // Trailing bytes (a second image) are ignored; a raster byte that looks like whitespace is
    // data, not header.
    let bytes = header_then("P5\n2 1\n255\n", &[b'\n', b' ', 9, 9, 9]);
    assert_eq!(parse_pgm(&bytes).expect("parses").pixels, vec![10, 32]);
}

#[test]
fn every_error_has_a_clear_message() {
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b"P2\n2 2\n255\n1 2 3 4".to_vec(), "expected \"P5\""),
        (b"".to_vec(), "expected \"P5\""),
        (b"P6\n1 1\n255\n\0\0\0".to_vec(), "expected \"P5\""),
        (b"P5x\n1 1\n255\n\0".to_vec(), "expected \"P5\""),
        (b"P5\n2 2".to_vec(), "ends before the maxval"),
        (b"P5\n2".to_vec(), "ends before the height"),
        (b"P5 # only a comment".to_vec(), "ends before the width"),
        (b"P5\n2 2\n255".to_vec(), "ends before the raster"),
        (
            b"P5\n3 x2\n255\n".to_vec(),
            "height is not a decimal number: \"x2\"",
        ),
        (b"P5\n-3 2\n255\n".to_vec(), "width is not a decimal number"),
        (
            b"P5\n3 2\n99999999999999999999999\n".to_vec(),
            "maxval is not a decimal",
        ),
        (b"P5\n0 2\n255\n".to_vec(), "width is 0"),
        (
            b"P5\n2 2\n0\n\0\0\0\0".to_vec(),
            "maxval 0 is out of range 1..=65535",
        ),
        (b"P5\n2 2\n70000\n".to_vec(), "maxval 70000 is out of range"),
        (
            header_then("P5\n3 2\n65535\n", &[0; 11]),
            "needs 12 bytes after the header, found 11",
        ),
        (header_then("P5\n2 2\n255\n", &[1, 2]), "needs 4 bytes"),
        (
            header_then("P5\n2 1\n100\n", &[100, 101]),
            "sample 101 at pixel 1 exceeds maxval 100",
        ),
        (b"P5\n4294967296 4294967296\n65535\n".to_vec(), "too large"),
    ];
    for (bytes, want) in cases {
        match parse_pgm(&bytes) {
            Ok(image) => panic!("{want}: parsed {image:?}"),
            Err(e) => assert!(e.to_string().contains(want), "want {want:?}, got {e}"),
        }
    }
    let missing = Path::new("/nonexistent/glint/frame.pgm");
    let err = read_pgm(missing).expect_err("no such file");
    assert!(matches!(err, PgmError::Io { .. }));
    assert!(err
        .to_string()
        .starts_with("/nonexistent/glint/frame.pgm: "));
    let bad = PgmImage {
        width: 3,
        height: 2,
        maxval: 255,
        pixels: vec![0; 5],
    };
    assert!(matches!(
        encode_pgm(&bad),
        Err(PgmError::SizeMismatch { .. })
    ));
    let above = PgmImage {
        pixels: vec![0, 0, 0, 0, 0, 256],
        ..bad
    };
    assert!(matches!(
        encode_pgm(&above),
        Err(PgmError::SampleAboveMaxval { index: 5, .. })
    ));
}
