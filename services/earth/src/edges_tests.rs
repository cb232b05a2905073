use super::*;
use crate::ring::cross_product_samples;

const CAM: Fisheye = Fisheye::ideal(100.0, 127.5, 127.5);

fn no_masks() -> EdgeConfig {
    EdgeConfig {
        threshold_dn: None,
        blind_zone_half_deg: 0.0,
        image_circle_px: None,
        field_margin_px: 0.0,
    }
}

#[test]
fn sobel_of_a_ramp_is_eight_times_its_slope() {
    // I = 3x + 4y: gx = 8·3, gy = 8·4 (eq 3), |g| = 8·5 everywhere inside.
    let (w, h) = (9usize, 7usize);
    let px: Vec<u16> = (0..w * h)
        .map(|i| (3 * (i % w) + 4 * (i / w)) as u16)
        .collect();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            assert_eq!(sobel(&px, w, x, y), 40.0);
        }
    }
}

/// The kernel of eq 3 written out, on a 16-bit step whose squared gradient exceeds i32.
#[test]
fn sobel_matches_eq_3_on_a_full_range_step() {
    let (w, h) = (5usize, 5usize);
    let px: Vec<u16> = (0..w * h)
        .map(|i| if i % w >= 3 { 65535 } else { 0 })
        .collect();
    let z = |x: usize, y: usize| f64::from(px[y * w + x]);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let gy = (z(x - 1, y + 1) + 2.0 * z(x, y + 1) + z(x + 1, y + 1))
                - (z(x - 1, y - 1) + 2.0 * z(x, y - 1) + z(x + 1, y - 1));
            let gx = (z(x + 1, y - 1) + 2.0 * z(x + 1, y) + z(x + 1, y + 1))
                - (z(x - 1, y - 1) + 2.0 * z(x - 1, y) + z(x - 1, y + 1));
            let g = (gx * gx + gy * gy).sqrt();
            assert!(
                (f64::from(sobel(&px, w, x, y)) - g).abs() <= 1e-6 * g.max(1.0),
                "({x}, {y})"
            );
        }
    }
    assert_eq!(sobel(&px, w, 3, 2), 4.0 * 65535.0);
}

#[test]
fn otsu_splits_two_levels_between_them() {
    let values: Vec<f32> = [2.0f32; 300].into_iter().chain([90.0f32; 100]).collect();
    let t = otsu(&values);
    assert!(t > 2.0 && t <= 90.0, "{t}");
    assert_eq!(otsu(&[0.0f32; 5]), 0.0);
    // A large input is sampled, and the sample splits it the same way.
    let big: Vec<f32> = (0..100_000)
        .map(|i| {
            if i % 10 < 7 {
                2.0 + (i % 3) as f32
            } else {
                90.0 + (i % 5) as f32
            }
        })
        .collect();
    let t = otsu(&big);
    assert!(t > 4.0 && t <= 90.0, "{t}");
}

#[test]
fn erosion_shrinks_a_square_and_spares_a_thin_line() {
    let (w, h) = (16usize, 16usize);
    let mut ex = EdgeExtractor::default();
    let cam = Fisheye::ideal(10.0, 8.0, 8.0);
    // A bright block with 4-px ramps: its Sobel band is 5 px wide, and erosion keeps its middle.
    let ramp = |v: usize| ((v as f64 - 2.0).min(14.0 - v as f64) / 4.0).clamp(0.0, 1.0);
    let block: Vec<u16> = (0..w * h)
        .map(|i| (1000.0 * ramp(i % w) * ramp(i / w)) as u16)
        .collect();
    let cfg = EdgeConfig {
        threshold_dn: Some(1.0),
        ..no_masks()
    };
    let e = ex.extract(&block, w, h, &cam, &cfg).unwrap();
    assert!(e.eroded);
    let strong: Vec<(f64, f64)> = (1..h - 1)
        .flat_map(|y| (1..w - 1).map(move |x| (x, y)))
        .filter(|&(x, y)| sobel(&block, w, x, y) >= 1.0)
        .map(|(x, y)| (x as f64, y as f64))
        .collect();
    assert!(e.points_px.len() < strong.len());
    assert!(e.points_px.iter().all(|p| strong.contains(p)));
    // One bright pixel: its 3×3 Sobel ring has a hole in the middle, erosion empties it, and
    // the un-eroded map is used.
    let mut dot = vec![0u16; w * h];
    dot[8 * w + 8] = 1000;
    let e = ex.extract(&dot, w, h, &cam, &cfg).unwrap();
    assert!(!e.eroded);
    assert_eq!(e.points_px.len(), 8);
}

#[test]
fn masks_remove_the_blind_zone_and_outside_the_image_circle() {
    let (w, h) = (256usize, 256usize);
    let noise: Vec<u16> = (0..w * h).map(|i| ((i * 7919) % 251) as u16).collect();
    let cfg = EdgeConfig {
        threshold_dn: Some(0.0),
        blind_zone_half_deg: 30.0,
        image_circle_px: Some(110.0),
        field_margin_px: 4.0,
    };
    let e = EdgeExtractor::default()
        .extract(&noise, w, h, &CAM, &cfg)
        .unwrap();
    assert!(!e.points_px.is_empty());
    let r_blind = CAM.f_px * 30f64.to_radians();
    for &(x, y) in &e.points_px {
        let r = CAM.theta_rad(x, y) * CAM.f_px;
        assert!(
            r >= r_blind - 1e-9 && r <= 106.0 + 1e-9,
            "({x}, {y}) at r = {r}"
        );
    }
    // the margin keeps points off the circle, and the mask lets them come up to it
    assert!(e
        .points_px
        .iter()
        .any(|&(x, y)| CAM.theta_rad(x, y) * CAM.f_px > 104.0));
}

#[test]
fn the_edge_of_the_image_circle_is_not_a_limb() {
    // A uniformly bright field cut by the lens's circle: its only edge is the circle's.
    let (w, h) = (256usize, 256usize);
    let (cx, cy) = (CAM.x0_px, CAM.y0_px);
    let disk: Vec<u16> = (0..w * h)
        .map(|i| {
            let r = ((i % w) as f64 - cx).hypot((i / w) as f64 - cy);
            if r <= 100.0 {
                3000
            } else {
                0
            }
        })
        .collect();
    let mut cfg = EdgeConfig {
        image_circle_px: Some(100.0),
        field_margin_px: 0.0,
        ..EdgeConfig::default()
    };
    let mut ex = EdgeExtractor::default();
    let e = ex.extract(&disk, w, h, &CAM, &cfg).unwrap();
    assert!(
        !e.points_px.is_empty(),
        "without a margin the circle's edge is taken"
    );
    cfg.field_margin_px = 3.0;
    let e = ex.extract(&disk, w, h, &CAM, &cfg).unwrap();
    assert!(
        e.points_px.is_empty(),
        "{:?}",
        &e.points_px[..e.points_px.len().min(5)]
    );
}

#[test]
fn bad_frames_are_errors() {
    let mut ex = EdgeExtractor::default();
    let e = ex.extract(&[0; 10], 4, 4, &CAM, &no_masks()).unwrap_err();
    assert_eq!(
        e,
        EdgeError::Size {
            width: 4,
            height: 4,
            expected: 16,
            actual: 10
        }
    );
    assert!(matches!(
        ex.extract(&[0; 4], 2, 2, &CAM, &no_masks()),
        Err(EdgeError::TooSmall { .. })
    ));
}

/// The chain on a noise-free Earth disk with a blurred limb: edges → sphere → cross products. The
/// pixel grid quantises the limb, so β_k scatter; their median is β to a few hundredths of a
/// degree.
#[test]
fn a_rendered_disk_gives_beta_through_the_whole_chain() {
    let (w, h) = (256usize, 256usize);
    let mut ex = EdgeExtractor::default();
    for tilt in [-8.0f64, 3.0, 20.0] {
        let px = crate::synthetic::blurred_earth(w, h, &CAM, tilt);
        let edges = ex.extract(&px, w, h, &CAM, &EdgeConfig::default()).unwrap();
        assert!(edges.points_px.len() > 200, "{}", edges.points_px.len());
        let pts: Vec<[f64; 3]> = edges
            .points_px
            .iter()
            .map(|&(x, y)| CAM.direction(x, y))
            .collect();
        let s = cross_product_samples(&pts);
        let mut b = s.tilt_deg.clone();
        b.sort_by(f64::total_cmp);
        let median = b[b.len() / 2];
        assert!(
            (median - tilt).abs() < 0.05,
            "tilt {tilt}: median tilt_k {median}"
        );
    }
}
