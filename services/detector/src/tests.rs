//! End-to-end detector tests on rendered frames.

use super::*;
use crate::synth::{Canvas, Rng};

/// A 256² frame with background 100 DN, noise 5 DN, two streaks and a point.
fn scene() -> Vec<u16> {
    let mut c = Canvas::new(256, 256, 100.0);
    c.add_noise(5.0, &mut Rng::new(11));
    c.add_segment((40.0, 50.0), (60.0, 60.0), 400.0, 0.8); // 22.4 px at 26.57°
    c.add_segment((200.0, 200.0), (200.0, 170.0), 300.0, 0.8); // vertical, up
    c.add_segment((120.0, 140.0), (120.0, 140.0), 2000.0, 0.8); // point
    c.to_u16()
}

#[test]
fn detects_streaks_and_point_with_features() {
    let frame = scene();
    let blobs = detect(&frame, 256, 256, &DetectorConfig::default()).expect("valid");
    assert_eq!(blobs.len(), 3, "{blobs:#?}");
    // Raster order of the first pixel: the diagonal streak (row ≈ 48), the point (≈ 137), the
    // vertical streak (≈ 167).
    let (d, p, v) = (blobs[0], blobs[1], blobs[2]);
    assert!((d.weighted.x_px - 50.0).abs() < 0.1 && (d.weighted.y_px - 55.0).abs() < 0.1);
    assert!(
        (d.theta_rad - 0.5f64.atan()).abs() < 2f64.to_radians(),
        "{d:?}"
    );
    assert!(d.eccentricity > 0.95);
    assert!((v.weighted.x_px - 200.0).abs() < 0.1 && (v.weighted.y_px - 185.0).abs() < 0.1);
    assert!(
        (v.theta_rad.abs() - std::f64::consts::FRAC_PI_2).abs() < 1e-2,
        "{v:?}"
    );
    assert!((p.weighted.x_px - 120.0).abs() < 0.05 && (p.weighted.y_px - 140.0).abs() < 0.05);
    assert!(p.eccentricity < 0.5);
    // The weighted m00 is the flux: ≈ peak · 2πσ² for the point.
    let flux = 2000.0 * std::f64::consts::TAU * 0.64;
    assert!(
        (p.flux_dn / flux - 1.0).abs() < 0.05,
        "{} vs {flux}",
        p.flux_dn
    );
    assert!(blobs
        .iter()
        .all(|b| !b.touches_border && b.saturated_px == 0));
}

#[test]
fn detector_reuse_is_deterministic_and_reports_the_threshold() {
    let frame = scene();
    let mut det = Detector::new(DetectorConfig::default()).expect("default config");
    let first = det.detect(&frame, 256, 256).expect("valid").blobs.to_vec();
    let empty = vec![100u16; 256 * 256];
    assert!(det
        .detect(&empty, 256, 256)
        .expect("valid")
        .blobs
        .is_empty());
    let again = det.detect(&frame, 256, 256).expect("valid");
    assert_eq!(again.blobs, &first[..]);
    let bg = again.background;
    assert!((bg.background_dn - 100.0).abs() < 0.3 && (bg.sigma_dn - 5.0).abs() < 0.3);
    let t = (bg.background_dn + 5.0 * bg.sigma_dn).floor() as u16;
    assert_eq!(again.threshold_dn, t);
}

#[test]
fn absolute_threshold_and_min_area() {
    let frame = scene();
    let cfg = DetectorConfig {
        threshold: Threshold::AbsoluteDn { threshold_dn: 1000 },
        ..DetectorConfig::default()
    };
    let blobs = detect(&frame, 256, 256, &cfg).expect("valid");
    assert_eq!(blobs.len(), 1, "only the point peaks above 1000 DN");
    let cfg = DetectorConfig {
        min_area_px: 10_000,
        ..DetectorConfig::default()
    };
    assert!(detect(&frame, 256, 256, &cfg).expect("valid").is_empty());
}

#[test]
fn config_validation_names_the_field() {
    let bad = [
        (
            DetectorConfig {
                threshold: Threshold::Sigma { k: f64::NAN },
                ..DetectorConfig::default()
            },
            "threshold.k",
        ),
        (
            DetectorConfig {
                min_area_px: 0,
                ..DetectorConfig::default()
            },
            "min_area_px",
        ),
        (
            DetectorConfig {
                background_step_px: 0,
                ..DetectorConfig::default()
            },
            "background_step_px",
        ),
        (
            DetectorConfig {
                saturation_dn: 0,
                ..DetectorConfig::default()
            },
            "saturation_dn",
        ),
    ];
    for (cfg, field) in bad {
        let err = cfg.validate().expect_err(field);
        assert_eq!(err.field, field);
        assert!(matches!(
            detect(&[0; 4], 2, 2, &cfg),
            Err(DetectError::Config(_))
        ));
    }
    assert!(matches!(
        detect(&[0; 4], 3, 2, &DetectorConfig::default()),
        Err(DetectError::Frame(FrameError::SizeMismatch { .. }))
    ));
}

#[test]
fn config_and_blobs_serialise() {
    let cfg = DetectorConfig::default();
    let json = serde_json::to_string(&cfg).expect("serialises");
    assert!(json.contains("\"mode\":\"sigma\""), "{json}");
    let back: DetectorConfig = serde_json::from_str(&json).expect("parses");
    assert_eq!(back, cfg);
    let partial: DetectorConfig = serde_json::from_str(r#"{"min_area_px": 5}"#).expect("parses");
    assert_eq!(partial.min_area_px, 5);
    assert!(serde_json::from_str::<DetectorConfig>(r#"{"min_area": 5}"#).is_err());
    let blobs = detect(&scene(), 256, 256, &cfg).expect("valid");
    let json = serde_json::to_string(&blobs).expect("serialises");
    assert!(json.contains("\"weighted\"") && json.contains("\"theta_rad\""));
}
