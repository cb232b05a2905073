//! Ellipse-feature tests: the §7.2 reference blob, a dense ellipse, degenerate blobs, and
//! translation invariance.

use super::*;
use crate::segment::{SegmentParams, Segmenter};
use proptest::prelude::*;

fn blobs_of(frame: &[u16], w: usize, h: usize, background_dn: f64) -> Vec<Blob> {
    let p = SegmentParams {
        threshold_dn: 0,
        background_dn,
        min_area_px: 1,
        saturation_dn: u16::MAX,
    };
    Segmenter::new()
        .segment(frame, w, h, &p)
        .expect("valid frame")
        .iter()
        .filter_map(Blob::from_component)
        .collect()
}

/// Angle difference modulo π, in [0, π/2].
fn axis_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

#[test]
fn reference_blob_of_section_7_2() {
    // 1-based (u, v) from docs/math.md §7.2; stored 0-based (u − 1, v − 1).
    let pixels = [
        (2, 2),
        (3, 2),
        (3, 3),
        (4, 3),
        (4, 4),
        (5, 3),
        (5, 4),
        (6, 4),
        (6, 5),
        (7, 5),
        (4, 2),
        (5, 5),
    ];
    let (w, h) = (9, 7);
    let mut frame = vec![0u16; w * h];
    for (u, v) in pixels {
        frame[(v - 1) * w + (u - 1)] = 1;
    }
    let blobs = blobs_of(&frame, w, h, 0.0);
    assert_eq!(blobs.len(), 1);
    let b = blobs[0];
    assert_eq!(b.area_px, 12);
    // Centroid (4.5, 3.5) 1-based = (3.5, 2.5) 0-based.
    assert!((b.x_px - 3.5).abs() < 1e-12 && (b.y_px - 2.5).abs() < 1e-12);
    assert!((b.a_px - 3.39235290500).abs() < 1e-10, "a = {}", b.a_px);
    assert!((b.b_px - 1.07638674954).abs() < 1e-10, "b = {}", b.b_px);
    assert!(
        (b.theta_rad - 0.655096967524).abs() < 1e-11,
        "θ = {}",
        b.theta_rad
    );
    assert!((b.theta_rad.to_degrees() - 37.5342914109).abs() < 1e-9);
    assert!((b.eccentricity - 0.948325886575).abs() < 1e-11);
    // Central moments μ20 = 23, μ02 = 15, μ11 = 15 (about the bbox origin (1, 1)).
    let c = CentralMoments::from_raw(
        &RawMoments {
            m00: 12.0,
            m10: 54.0,
            m01: 42.0,
            m20: 266.0,
            m02: 162.0,
            m11: 204.0,
        },
        0.0,
        0.0,
    )
    .expect("m00 > 0");
    assert_eq!((c.mu20, c.mu02, c.mu11), (23.0, 15.0, 15.0));
    // Unit pixel values with background 0: the weighted ellipse equals the binary one.
    assert!((b.weighted.a_px - b.a_px).abs() < 1e-12);
    assert_eq!(b.flux_dn, 12.0);
}

/// Rasterises a filled ellipse with semi-axes (a, b) rotated by θ, centred in the frame.
fn filled_ellipse(a: f64, b: f64, theta: f64) -> (Vec<u16>, usize, (f64, f64)) {
    let n = (2.0 * a + 8.0).ceil() as usize;
    let c = ((n as f64 - 1.0) / 2.0 + 0.3, (n as f64 - 1.0) / 2.0 - 0.2);
    let (s, co) = theta.sin_cos();
    let mut frame = vec![0u16; n * n];
    for y in 0..n {
        for x in 0..n {
            let (dx, dy) = (x as f64 - c.0, y as f64 - c.1);
            let (p, q) = (dx * co + dy * s, -dx * s + dy * co);
            if (p / a).powi(2) + (q / b).powi(2) <= 1.0 {
                frame[y * n + x] = 1;
            }
        }
    }
    (frame, n, c)
}

#[test]
fn filled_ellipse_recovers_its_axes_and_angle() {
    let theta = 30f64.to_radians();
    // Pixel-scale raster: a few per cent.
    let (frame, n, c) = filled_ellipse(10.0, 4.0, theta);
    let b = blobs_of(&frame, n, n, 0.0)[0];
    assert!((b.a_px - 10.0).abs() < 0.1, "{b:?}");
    assert!((b.b_px - 4.0).abs() < 0.1, "{b:?}");
    assert!(axis_diff(b.theta_rad, theta) < 0.5f64.to_radians(), "{b:?}");
    assert!(
        (b.x_px - c.0).abs() < 0.1 && (b.y_px - c.1).abs() < 0.1,
        "{b:?} vs {c:?}"
    );
    // Dense (×20) raster, scaled back: ≈ 10.0002, 3.9998, 30.002° (docs/math.md §3.3).
    let k = 20.0;
    let (frame, n, _) = filled_ellipse(10.0 * k, 4.0 * k, theta);
    let b = blobs_of(&frame, n, n, 0.0)[0];
    assert!((b.a_px / k - 10.0).abs() < 2e-3, "{b:?}");
    assert!((b.b_px / k - 4.0).abs() < 2e-3, "{b:?}");
    assert!(
        axis_diff(b.theta_rad, theta) < 0.01f64.to_radians(),
        "{b:?}"
    );
    let e = (1.0f64 - 0.16).sqrt();
    assert!((b.eccentricity - e).abs() < 1e-3);
}

#[test]
fn degenerate_blobs() {
    let single = Ellipse::from_raw(
        &RawMoments {
            m00: 1.0,
            ..RawMoments::default()
        },
        4.0,
        5.0,
    )
    .expect("m00 > 0");
    assert_eq!(
        (single.a_px, single.b_px, single.eccentricity),
        (0.0, 0.0, 0.0)
    );
    assert_eq!((single.x_px, single.y_px), (4.0, 5.0));
    // A horizontal line: θ = 0, b = 0, e = 1. A vertical one: θ = π/2.
    let mut frame = vec![0u16; 5 * 5];
    frame[10..15].fill(1);
    let h = blobs_of(&frame, 5, 5, 0.0)[0];
    assert_eq!((h.theta_rad, h.b_px, h.eccentricity), (0.0, 0.0, 1.0));
    // 5 pixels at spacing 1: variance 2 ⇒ a = 2√2.
    assert!((h.a_px - 8f64.sqrt()).abs() < 1e-12);
    let mut frame = vec![0u16; 5 * 5];
    for y in 0..5 {
        frame[y * 5 + 2] = 1;
    }
    let v = blobs_of(&frame, 5, 5, 0.0)[0];
    assert!((v.theta_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert!(Ellipse::from_raw(&RawMoments::default(), 0.0, 0.0).is_none());
    let nan = RawMoments {
        m00: 1.0,
        m20: f64::NAN,
        ..RawMoments::default()
    };
    assert!(Ellipse::from_raw(&nan, 0.0, 0.0).is_none());
}

#[test]
fn theta_is_measured_toward_plus_y() {
    // Pixels along the main diagonal (x = y) go toward +x and +y (down): θ = +45°.
    let mut frame = vec![0u16; 6 * 6];
    for i in 0..6 {
        frame[i * 6 + i] = 1;
    }
    let b = blobs_of(&frame, 6, 6, 0.0)[0];
    assert!((b.theta_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
}

/// A connected random pattern: a random 8-neighbour walk with random values.
fn random_walk_pattern(seed: u64, steps: usize) -> Vec<(i64, i64, u16)> {
    let mut rng = crate::synth::Rng::new(seed);
    let (mut x, mut y) = (0i64, 0i64);
    let mut out = vec![(0, 0, 1000)];
    for _ in 0..steps {
        x = (x + (rng.next_u64() % 3) as i64 - 1).clamp(-12, 12);
        y = (y + (rng.next_u64() % 3) as i64 - 1).clamp(-12, 12);
        if !out.iter().any(|p| (p.0, p.1) == (x, y)) {
            out.push((x, y, 200 + (rng.next_u64() % 60_000) as u16));
        }
    }
    out
}

fn frame_with(pattern: &[(i64, i64, u16)], off: (i64, i64), n: usize) -> Vec<u16> {
    let mut frame = vec![0u16; n * n];
    for &(x, y, v) in pattern {
        frame[((y + off.1) as usize) * n + (x + off.0) as usize] = v;
    }
    frame
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 64,
        // Deterministic suite: the same cases on every run (shrunk failures are kept in the
        // proptest-regressions files).
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x0067_6c69_6e74),
        ..ProptestConfig::default()
    })]

    /// Features do not change under translation; the centroid moves by the offset.
    #[test]
    fn features_are_translation_invariant(
        seed in any::<u64>(),
        steps in 2usize..60,
        ox in 13i64..200,
        oy in 13i64..200,
        background in 0.0f64..150.0,
    ) {
        let pattern = random_walk_pattern(seed, steps);
        let n = 230;
        let b0 = blobs_of(&frame_with(&pattern, (13, 13), n), n, n, background);
        let b1 = blobs_of(&frame_with(&pattern, (ox, oy), n), n, n, background);
        prop_assert_eq!(b0.len(), 1);
        prop_assert_eq!(b1.len(), 1);
        let (s, t) = ((ox - 13) as f64, (oy - 13) as f64);
        for set in [FeatureSet::Binary, FeatureSet::Weighted] {
            let (e0, e1) = (b0[0].ellipse(set), b1[0].ellipse(set));
            prop_assert!((e1.x_px - e0.x_px - s).abs() < 1e-9);
            prop_assert!((e1.y_px - e0.y_px - t).abs() < 1e-9);
            prop_assert!((e1.a_px - e0.a_px).abs() < 1e-9);
            prop_assert!((e1.b_px - e0.b_px).abs() < 1e-9);
            prop_assert!((e1.eccentricity - e0.eccentricity).abs() < 1e-9);
            prop_assert!(axis_diff(e1.theta_rad, e0.theta_rad) < 1e-9);
        }
        // The same features from moments about a far origin (f64 path, not the exact one).
        let c = b1[0].binary();
        let mut far = RawMoments::default();
        for &(x, y, _) in &pattern {
            let (dx, dy) = ((x + ox) as f64 + 500.0, (y + oy) as f64 + 500.0);
            far.m00 += 1.0;
            far.m10 += dx;
            far.m01 += dy;
            far.m20 += dx * dx;
            far.m02 += dy * dy;
            far.m11 += dx * dy;
        }
        let e = Ellipse::from_raw(&far, -500.0, -500.0).expect("m00 > 0");
        prop_assert!((e.x_px - c.x_px).abs() < 1e-9 && (e.y_px - c.y_px).abs() < 1e-9);
        prop_assert!((e.a_px - c.a_px).abs() < 1e-6);
        // b² (not b): b = sqrt(det…) amplifies rounding near b = 0.
        prop_assert!((e.b_px.powi(2) - c.b_px.powi(2)).abs() < 1e-6);
    }
}
