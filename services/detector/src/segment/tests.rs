//! Segmenter tests: a flood-fill reference with per-pixel moments, connectivity, filters.

use super::*;
use proptest::prelude::*;

/// Reference component: flood fill (8-neighbourhood) and direct per-pixel sums.
#[derive(Debug)]
struct Reference {
    pixels: Vec<(usize, usize, u16)>,
}

fn flood_fill(frame: &[u16], w: usize, h: usize, t: u16) -> Vec<Reference> {
    let mut seen = vec![false; w * h];
    let mut out = Vec::new();
    for start in 0..w * h {
        if seen[start] || frame[start] <= t {
            continue;
        }
        seen[start] = true;
        let mut stack = vec![start];
        let mut pixels = Vec::new();
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            pixels.push((x, y, frame[i]));
            for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    let j = ny * w + nx;
                    if !seen[j] && frame[j] > t {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        out.push(Reference { pixels });
    }
    out
}

fn direct_moments(r: &Reference, ox: f64, oy: f64, weight: impl Fn(u16) -> f64) -> RawMoments {
    let mut m = RawMoments::default();
    for &(x, y, v) in &r.pixels {
        let (dx, dy, f) = (x as f64 - ox, y as f64 - oy, weight(v));
        m.m00 += f;
        m.m10 += f * dx;
        m.m01 += f * dy;
        m.m20 += f * dx * dx;
        m.m02 += f * dy * dy;
        m.m11 += f * dx * dy;
    }
    m
}

fn assert_moments_close(got: &RawMoments, want: &RawMoments, what: &str) {
    let pairs = [
        (got.m00, want.m00),
        (got.m10, want.m10),
        (got.m01, want.m01),
        (got.m20, want.m20),
        (got.m02, want.m02),
        (got.m11, want.m11),
    ];
    let scale = pairs.iter().map(|p| p.1.abs()).fold(1.0, f64::max);
    for (i, (g, w)) in pairs.into_iter().enumerate() {
        assert!(
            (g - w).abs() <= 1e-9 * scale,
            "{what} moment {i}: got {g}, want {w}"
        );
    }
}

fn params(threshold_dn: u16, background_dn: f64, min_area_px: u32) -> SegmentParams {
    SegmentParams {
        threshold_dn,
        background_dn,
        min_area_px,
        saturation_dn: 60_000,
    }
}

/// Runs the segmenter and checks every component against the reference.
fn check_against_reference(frame: &[u16], w: usize, h: usize, p: &SegmentParams) -> usize {
    let mut seg = Segmenter::new();
    let got = seg.segment(frame, w, h, p).expect("valid frame").to_vec();
    let want: Vec<Reference> = flood_fill(frame, w, h, p.threshold_dn)
        .into_iter()
        .filter(|r| r.pixels.len() >= p.min_area_px as usize)
        .collect();
    assert_eq!(got.len(), want.len(), "component count");
    for (c, r) in got.iter().zip(&want) {
        let xs = r.pixels.iter().map(|q| q.0 as u32);
        let ys = r.pixels.iter().map(|q| q.1 as u32);
        let bbox = BoundingBox {
            x_min_px: xs.clone().min().unwrap_or(0),
            y_min_px: ys.clone().min().unwrap_or(0),
            x_max_px: xs.max().unwrap_or(0),
            y_max_px: ys.max().unwrap_or(0),
        };
        assert_eq!(c.bbox, bbox);
        assert_eq!(c.area_px as usize, r.pixels.len());
        assert_eq!(c.peak_dn, r.pixels.iter().map(|q| q.2).max().unwrap_or(0));
        let sat = r.pixels.iter().filter(|q| q.2 >= p.saturation_dn).count();
        assert_eq!(c.saturated_px as usize, sat);
        let border = bbox.x_min_px == 0
            || bbox.y_min_px == 0
            || bbox.x_max_px as usize == w - 1
            || bbox.y_max_px as usize == h - 1;
        assert_eq!(c.touches_border, border);
        let (ox, oy) = (f64::from(c.origin_x_px), f64::from(c.origin_y_px));
        assert_moments_close(&c.binary, &direct_moments(r, ox, oy, |_| 1.0), "binary");
        let b = p.background_dn;
        let weighted = direct_moments(r, ox, oy, |v| f64::from(v) - b);
        assert_moments_close(&c.weighted, &weighted, "weighted");
    }
    got.len()
}

#[test]
fn diagonal_pixels_join_and_gaps_do_not() {
    #[rustfmt::skip]
    let frame: Vec<u16> = vec![
        9, 0, 0, 0, 0, 9,
        0, 9, 0, 0, 0, 0,
        0, 0, 9, 0, 0, 9,
        0, 0, 0, 0, 0, 9,
    ];
    let mut seg = Segmenter::new();
    let comps = seg
        .segment(&frame, 6, 4, &params(5, 0.0, 1))
        .expect("valid frame");
    assert_eq!(comps.len(), 3, "{comps:?}");
    assert_eq!(comps[0].area_px, 3, "the diagonal chain is one component");
    assert_eq!(comps[1].area_px, 1);
    assert_eq!(comps[2].area_px, 2);
    // Anti-diagonal too.
    #[rustfmt::skip]
    let anti: Vec<u16> = vec![
        0, 0, 9,
        0, 9, 0,
        9, 0, 0,
    ];
    let comps = seg
        .segment(&anti, 3, 3, &params(5, 0.0, 1))
        .expect("valid frame");
    assert_eq!(comps.len(), 1);
    assert_eq!(comps[0].area_px, 3);
}

#[test]
fn late_unions_merge_moments_exactly() {
    // A "W": three prongs that only join at the bottom row, and a spiral-ish shape.
    #[rustfmt::skip]
    let frame: Vec<u16> = vec![
        7, 0, 8, 0, 9, 0, 0, 0,
        7, 0, 8, 0, 9, 0, 5, 5,
        7, 0, 8, 0, 9, 0, 0, 5,
        7, 7, 7, 7, 7, 0, 5, 0,
        0, 0, 0, 0, 0, 5, 0, 0,
    ];
    let n = check_against_reference(&frame, 8, 5, &params(4, 2.5, 1));
    assert_eq!(
        n, 1,
        "everything is 8-connected through the bottom-right diagonal"
    );
    let n = check_against_reference(&frame, 8, 5, &params(6, 2.5, 1));
    assert_eq!(n, 1);
}

#[test]
fn min_area_and_border_flag() {
    let mut frame = vec![0u16; 10 * 10];
    frame[5 * 10 + 5] = 100; // single pixel
    for x in 0..4 {
        frame[9 * 10 + x] = 100; // 4 px on the bottom border
    }
    let mut seg = Segmenter::new();
    let comps = seg
        .segment(&frame, 10, 10, &params(50, 0.0, 3))
        .expect("valid frame");
    assert_eq!(comps.len(), 1);
    assert!(comps[0].touches_border);
    assert_eq!(comps[0].area_px, 4);
    let comps = seg
        .segment(&frame, 10, 10, &params(50, 0.0, 1))
        .expect("valid frame");
    assert_eq!(comps.len(), 2);
    assert!(!comps[0].touches_border);
}

#[test]
fn full_frame_component_and_run_across_blocks() {
    // A frame wider than two blocks, all foreground: one component, exact moments.
    let (w, h) = (70, 5);
    let frame: Vec<u16> = (0..w * h).map(|i| 100 + (i % 13) as u16).collect();
    assert_eq!(
        check_against_reference(&frame, w, h, &params(10, 3.25, 1)),
        1
    );
}

#[test]
fn saturation_count_and_reuse_does_not_leak() {
    let mut frame = vec![0u16; 40 * 40];
    for x in 10..20 {
        frame[20 * 40 + x] = if x % 2 == 0 { 65_535 } else { 1000 };
    }
    let mut seg = Segmenter::new();
    let p = SegmentParams {
        saturation_dn: 65_535,
        ..params(10, 0.0, 1)
    };
    let first = seg
        .segment(&frame, 40, 40, &p)
        .expect("valid frame")
        .to_vec();
    assert_eq!(first.len(), 1);
    assert_eq!(first[0].saturated_px, 5);
    assert_eq!(first[0].peak_dn, 65_535);
    let empty = vec![0u16; 40 * 40];
    assert!(seg.segment(&empty, 40, 40, &p).expect("valid").is_empty());
    let again = seg
        .segment(&frame, 40, 40, &p)
        .expect("valid frame")
        .to_vec();
    assert_eq!(first, again);
}

#[test]
fn size_errors() {
    let mut seg = Segmenter::new();
    let p = params(10, 0.0, 1);
    assert!(matches!(
        seg.segment(&[0; 5], 2, 2, &p),
        Err(FrameError::SizeMismatch { .. })
    ));
    assert!(matches!(
        seg.segment(&[], 0, 3, &p),
        Err(FrameError::Empty { .. })
    ));
    assert!(matches!(
        seg.segment(&[], MAX_SIDE_PX + 1, 0, &p),
        Err(FrameError::Empty { .. }) | Err(FrameError::TooLarge { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 200,
        // Deterministic suite: the same cases on every run (shrunk failures are kept in the
        // proptest-regressions files).
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x0067_6c69_6e74),
        ..ProptestConfig::default()
    })]

    /// Random sparse frames: components, moments (both sets), bbox, peak and flags equal the
    /// flood-fill reference; moments to 1e-9 relative.
    #[test]
    fn matches_flood_fill_reference(
        w in 1usize..80,
        h in 1usize..24,
        density in 0.05f64..0.7,
        seed in any::<u64>(),
        background in 0.0f64..50.0,
    ) {
        let mut rng = crate::synth::Rng::new(seed);
        let frame: Vec<u16> = (0..w * h)
            .map(|_| {
                if rng.uniform() < density {
                    100 + (rng.next_u64() % 65_000) as u16
                } else {
                    (rng.next_u64() % 100) as u16
                }
            })
            .collect();
        check_against_reference(&frame, w, h, &params(99, background, 1));
        check_against_reference(&frame, w, h, &params(99, background, 3));
    }
}
