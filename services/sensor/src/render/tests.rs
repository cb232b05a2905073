//! Frame renderer tests: validation, determinism, clipping, and agreement of the fast renderer
//! with the reference and with the model (background moments, deposited signal, centroid).
//! Seeds are fixed, so every statistical tolerance (≥ 5σ) is also an exact regression check.
use super::*;

fn config(width_px: usize, height_px: usize) -> RenderConfig {
    RenderConfig {
        width_px,
        height_px,
        background_dn: 100.0,
        read_noise_dn: 5.0,
        gain_e_per_dn: 2.0,
        saturation_dn: 65_535,
        psf_sigma_px: 1.0,
        substeps_per_px: 10.0,
    }
}

fn renderer(c: RenderConfig) -> FrameRenderer {
    FrameRenderer::new(c).expect("valid test config")
}

fn mean_std(v: &[u16]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().map(|&x| f64::from(x)).sum::<f64>() / n;
    let var = v
        .iter()
        .map(|&x| (f64::from(x) - mean).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    (mean, var.sqrt())
}

/// Background-subtracted sum, centroid and pixel count over the window [x0, x1] × [y0, y1].
fn window_stats(frame: &[u16], width: usize, bg: f64, win: [usize; 4]) -> (f64, f64, f64, usize) {
    let (mut sum, mut sx, mut sy, mut n) = (0.0, 0.0, 0.0, 0);
    for y in win[2]..=win[3] {
        for x in win[0]..=win[1] {
            let s = f64::from(frame[y * width + x]) - bg;
            sum += s;
            sx += s * x as f64;
            sy += s * y as f64;
            n += 1;
        }
    }
    (sum, sx / sum, sy / sum, n)
}

#[test]
fn config_validation_names_the_field() {
    assert!(FrameRenderer::new(RenderConfig::default()).is_ok());
    let bad = |f: fn(&mut RenderConfig)| {
        let mut c = RenderConfig::default();
        f(&mut c);
        FrameRenderer::new(c).err().expect("must be rejected")
    };
    assert!(matches!(
        bad(|c| c.background_dn = f64::NAN),
        RenderConfigError::NotFinite {
            field: "background_dn",
            ..
        }
    ));
    assert!(matches!(
        bad(|c| c.read_noise_dn = -1.0),
        RenderConfigError::OutOfRange {
            field: "read_noise_dn",
            ..
        }
    ));
    assert!(matches!(
        bad(|c| c.background_dn = 300.0),
        RenderConfigError::OutOfRange {
            field: "background_dn",
            ..
        }
    ));
    assert!(matches!(
        bad(|c| c.width_px = 0),
        RenderConfigError::OutOfRange {
            field: "width_px",
            ..
        }
    ));
    assert!(matches!(
        bad(|c| c.saturation_dn = 0),
        RenderConfigError::OutOfRange { .. }
    ));
    assert!(matches!(
        bad(|c| c.gain_e_per_dn = 0.0),
        RenderConfigError::OutOfRange { .. }
    ));
    assert!(matches!(
        bad(|c| c.psf_sigma_px = f64::INFINITY),
        RenderConfigError::NotFinite { .. }
    ));
    assert!(matches!(
        bad(|c| c.substeps_per_px = 0.5),
        RenderConfigError::OutOfRange { .. }
    ));
    assert!(bad(|c| c.psf_sigma_px = 9.0)
        .to_string()
        .contains("psf_sigma_px"));
}

#[test]
fn wrong_output_length_is_an_error_and_writes_nothing() {
    let r = renderer(config(16, 8));
    let mut out = vec![7u16; 127];
    let err = r.render(&[], 1, 0, &mut out).unwrap_err();
    assert_eq!(
        err,
        RenderError::OutputLength {
            expected_px: 128,
            actual_px: 127
        }
    );
    assert!(out.iter().all(|&v| v == 7));
    assert!(r.render_reference(&[], 1, 0, &mut out).is_err());
}

#[test]
fn every_pixel_is_written_whatever_out_held() {
    // 37 × 23 = 851 px: 106 blocks of 8 and a tail of 3.
    let r = renderer(RenderConfig {
        saturation_dn: 1000,
        ..config(37, 23)
    });
    let streaks = [Streak {
        x0_px: 3.0,
        y0_px: 4.0,
        x1_px: 30.0,
        y1_px: 19.0,
        total_signal_dn: 5e3,
    }];
    let mut a = vec![u16::MAX; 37 * 23];
    let mut b = vec![0u16; 37 * 23];
    r.render(&streaks, 9, 2, &mut a).unwrap();
    r.render(&streaks, 9, 2, &mut b).unwrap();
    assert_eq!(a, b);
    assert!(a.iter().all(|&v| v <= 1000));
}

#[test]
fn same_seed_and_frame_is_byte_identical_others_differ() {
    let r = renderer(config(128, 96));
    let streaks = [
        Streak {
            x0_px: 10.5,
            y0_px: 20.2,
            x1_px: 40.1,
            y1_px: 30.9,
            total_signal_dn: 2e4,
        },
        Streak::point(90.0, 70.0, 5e3),
    ];
    let frame = |seed, idx| {
        let mut out = vec![0u16; 128 * 96];
        r.render(&streaks, seed, idx, &mut out).unwrap();
        out
    };
    assert_eq!(frame(5, 11), frame(5, 11));
    assert_ne!(frame(5, 11), frame(5, 12));
    assert_ne!(frame(5, 11), frame(6, 11));
}

#[test]
fn background_moments_match_model_and_reference() {
    let c = config(512, 512);
    let r = renderer(c);
    let mut fast = vec![0u16; 512 * 512];
    let mut slow = vec![0u16; 512 * 512];
    r.render(&[], 3, 0, &mut fast).unwrap();
    r.render_reference(&[], 3, 0, &mut slow).unwrap();
    // σ² = b/g + read² + 1/12 (rounding to integer DN) = 50 + 25 + 1/12.
    let sigma = (75.0f64 + 1.0 / 12.0).sqrt();
    let se_mean = sigma / 512.0;
    for (name, v) in [("fast", &fast), ("reference", &slow)] {
        let (m, s) = mean_std(v);
        assert!((m - 100.0).abs() < 5.0 * se_mean, "{name} mean {m}");
        assert!((s / sigma - 1.0).abs() < 0.01, "{name} std {s} vs {sigma}");
    }
    let ((mf, sf), (ms, ss)) = (mean_std(&fast), mean_std(&slow));
    assert!((mf - ms).abs() < 7.0 * se_mean);
    assert!((sf / ss - 1.0).abs() < 0.015);
}

#[test]
fn background_is_clipped_to_saturation_and_zero() {
    let c = RenderConfig {
        background_dn: 250.0,
        read_noise_dn: 10.0,
        saturation_dn: 255,
        ..config(64, 64)
    };
    let mut out = vec![0u16; 64 * 64];
    renderer(c).render(&[], 1, 1, &mut out).unwrap();
    assert!(out.iter().all(|&v| v <= 255) && out.contains(&255));
    let c = RenderConfig {
        background_dn: 1.0,
        read_noise_dn: 10.0,
        ..config(64, 64)
    };
    renderer(c).render(&[], 1, 1, &mut out).unwrap();
    assert!(out.contains(&0));
}

/// A bright streak (and a bright point): the integrated signal matches total_signal_dn within
/// 5σ of background + shot noise, and the centroid is the segment midpoint to < 0.05 px, for
/// both renderers.
#[test]
fn integrated_signal_and_centroid_match_the_segment() {
    let c = config(256, 256);
    let r = renderer(c);
    let cases = [
        (
            Streak {
                x0_px: 100.3,
                y0_px: 120.7,
                x1_px: 125.9,
                y1_px: 131.2,
                total_signal_dn: 1e6,
            },
            1,
        ),
        (
            Streak {
                x0_px: 60.0,
                y0_px: 40.0,
                x1_px: 40.0,
                y1_px: 160.0,
                total_signal_dn: 3e6,
            },
            2,
        ),
        (Streak::point(200.37, 30.81, 2e5), 3),
    ];
    for (s, frame_index) in cases {
        let win = [
            (s.x0_px.min(s.x1_px) - 8.0) as usize,
            (s.x0_px.max(s.x1_px) + 8.0) as usize,
            (s.y0_px.min(s.y1_px) - 8.0) as usize,
            (s.y0_px.max(s.y1_px) + 8.0) as usize,
        ];
        let (mid_x, mid_y) = (0.5 * (s.x0_px + s.x1_px), 0.5 * (s.y0_px + s.y1_px));
        let mut out = vec![0u16; 256 * 256];
        for fast in [true, false] {
            let report = if fast {
                r.render(&[s], 77, frame_index, &mut out).unwrap()
            } else {
                r.render_reference(&[s], 77, frame_index, &mut out).unwrap()
            };
            assert_eq!(report.streaks_rendered, 1);
            let (sum, cx, cy, n) = window_stats(&out, 256, c.background_dn, win);
            let sigma_sum = (n as f64 * 75.1 + s.total_signal_dn / c.gain_e_per_dn).sqrt();
            assert!(
                (sum - s.total_signal_dn).abs() < 5.0 * sigma_sum,
                "fast={fast} {s:?}: {sum}"
            );
            assert!(
                (cx - mid_x).abs() < 0.05 && (cy - mid_y).abs() < 0.05,
                "fast={fast} {s:?}: centroid ({cx}, {cy}) vs ({mid_x}, {mid_y})"
            );
        }
    }
}

#[test]
fn fast_and_reference_agree_on_a_faint_streak() {
    let c = config(128, 128);
    let r = renderer(c);
    let s = Streak {
        x0_px: 30.2,
        y0_px: 50.5,
        x1_px: 58.8,
        y1_px: 60.1,
        total_signal_dn: 2e4,
    };
    let win = [20, 68, 40, 70];
    let (mut fast, mut slow) = (vec![0u16; 128 * 128], vec![0u16; 128 * 128]);
    let n = (49 * 31) as f64;
    let sigma_sum = (n * 75.1 + s.total_signal_dn / c.gain_e_per_dn).sqrt();
    for frame_index in 0..4 {
        r.render(&[s], 5, frame_index, &mut fast).unwrap();
        r.render_reference(&[s], 5, frame_index, &mut slow).unwrap();
        let (sf, ..) = window_stats(&fast, 128, 100.0, win);
        let (ss, ..) = window_stats(&slow, 128, 100.0, win);
        assert!(
            (sf - ss).abs() < 5.0 * 2f64.sqrt() * sigma_sum,
            "{sf} vs {ss}"
        );
        assert!((sf - s.total_signal_dn).abs() < 5.0 * sigma_sum);
    }
}

#[test]
fn out_of_frame_streaks_are_clipped_never_panic() {
    let c = config(128, 128);
    let r = renderer(c);
    let mut base = vec![0u16; 128 * 128];
    r.render(&[], 4, 4, &mut base).unwrap();
    // Wholly outside (beyond the PSF reach): the frame is the background-only frame.
    let outside = [
        Streak {
            x0_px: -50.0,
            y0_px: -30.0,
            x1_px: -10.0,
            y1_px: -6.0,
            total_signal_dn: 1e6,
        },
        Streak::point(140.0, 60.0, 1e6),
        Streak {
            x0_px: 1e300,
            y0_px: 0.0,
            x1_px: 2e300,
            y1_px: 5.0,
            total_signal_dn: 1e6,
        },
    ];
    let mut out = vec![0u16; 128 * 128];
    let report = r.render(&outside, 4, 4, &mut out).unwrap();
    assert_eq!(out, base);
    assert_eq!(report.streaks_outside, 3);
    // Invalid input is counted and skipped.
    let invalid = [
        Streak {
            x0_px: f64::NAN,
            y0_px: 0.0,
            x1_px: 1.0,
            y1_px: 1.0,
            total_signal_dn: 1.0,
        },
        Streak {
            x0_px: -1e308,
            y0_px: 9.0,
            x1_px: 1e308,
            y1_px: 9.0,
            total_signal_dn: 1.0,
        },
        Streak::point(5.0, 5.0, -3.0),
        Streak::point(5.0, 5.0, f64::INFINITY),
    ];
    let report = r.render(&invalid, 4, 4, &mut out).unwrap();
    assert_eq!((report.streaks_invalid, report.streaks_rendered), (4, 0));
    assert_eq!(out, base);
    // Half in: a horizontal streak from x = −100 to 100 on row 64 keeps the part x ≥ −½,
    // i.e. 100.5/200 of its signal, on the frame; a huge diagonal crossing the frame is clipped.
    let half = Streak {
        x0_px: -100.0,
        y0_px: 64.0,
        x1_px: 100.0,
        y1_px: 64.0,
        total_signal_dn: 4e5,
    };
    let report = r.render(&[half], 4, 4, &mut out).unwrap();
    assert_eq!(report.streaks_rendered, 1);
    let (sum, ..) = window_stats(&out, 128, 100.0, [0, 110, 54, 74]);
    let want: f64 = 4e5 * 100.5 / 200.0;
    let sigma_sum = (111.0 * 21.0 * 75.1 + want / 2.0).sqrt();
    assert!((sum - want).abs() < 5.0 * sigma_sum, "{sum} vs {want}");
    let huge = Streak {
        x0_px: -1e9,
        y0_px: -1e9,
        x1_px: 1e9,
        y1_px: 1e9,
        total_signal_dn: 1e12,
    };
    let report = r.render(&[huge], 4, 4, &mut out).unwrap();
    assert_eq!(report.streaks_rendered, 1);
}

#[test]
fn bright_sources_saturate() {
    let c = RenderConfig {
        saturation_dn: 4095,
        ..config(64, 64)
    };
    let r = renderer(c);
    let mut out = vec![0u16; 64 * 64];
    let report = r
        .render(&[Streak::point(32.0, 32.0, 1e6)], 1, 0, &mut out)
        .unwrap();
    assert!(report.saturated_px > 0);
    assert_eq!(out.iter().copied().max(), Some(4095));
    assert_eq!(out[32 * 64 + 32], 4095);
}

#[test]
fn zero_psf_width_still_conserves_signal() {
    let c = RenderConfig {
        psf_sigma_px: 0.0,
        ..config(64, 64)
    };
    let r = renderer(c);
    let s = Streak {
        x0_px: 10.25,
        y0_px: 10.5,
        x1_px: 50.0,
        y1_px: 30.0,
        total_signal_dn: 1e6,
    };
    let mut out = vec![0u16; 64 * 64];
    r.render(&[s], 2, 2, &mut out).unwrap();
    let (sum, cx, cy, n) = window_stats(&out, 64, 100.0, [5, 55, 5, 35]);
    let sigma_sum = (n as f64 * 75.1 + 5e5).sqrt();
    assert!((sum - 1e6).abs() < 5.0 * sigma_sum);
    assert!(
        (cx - 30.125).abs() < 0.05 && (cy - 20.25).abs() < 0.05,
        "({cx}, {cy})"
    );
}
