use super::*;

fn config(noise_dn: f64) -> EarthRenderConfig {
    EarthRenderConfig {
        width_px: 256,
        height_px: 256,
        camera: Fisheye::ideal(65.0, 127.5, 127.5),
        altitude_km: 950.0,
        image_circle_px: 127.0,
        earth_dn: 3000.0,
        space_dn: 200.0,
        psf_sigma_px: 1.2,
        noise_dn,
        saturation_dn: 65535,
        hazards: Default::default(),
    }
}

/// The profile against its closed form: at the limb ½ erfc(0) = ½ of the contrast, one σ
/// outside ½ erfc(1/√2), deep inside the Earth's level, outside the image circle 0.
#[test]
fn a_noise_free_frame_follows_the_limb_profile() {
    let r = EarthRenderer::new(config(0.0));
    let e = nadir(10.0, 0.0);
    let mut px = vec![0u16; 256 * 256];
    assert!(r.render(e, 1, 0, &mut px));
    let rho = earth_angular_radius_rad(950.0);
    let cam = r.config().camera;
    for (i, &v) in px.iter().enumerate() {
        let (x, y) = ((i % 256) as f64, (i / 256) as f64);
        if (x - cam.x0_px).hypot(y - cam.y0_px) > 127.0 {
            assert_eq!(v, 0, "({x}, {y}) outside the image circle");
            continue;
        }
        let u = cam.direction(x, y);
        let angle = (u[0] * e[0] + u[1] * e[1] + u[2] * e[2])
            .clamp(-1.0, 1.0)
            .acos();
        let d_px = (angle - rho) * cam.f_px;
        let expect = 200.0 + 2800.0 * 0.5 * libm::erfc(d_px / (1.2 * std::f64::consts::SQRT_2));
        // f32 directions and the table: within a DN and a half of the closed form.
        assert!(
            (f64::from(v) - expect).abs() <= 1.5,
            "({x}, {y}): {v} against {expect}"
        );
    }
    assert!(!r.render(e, 1, 0, &mut px[..10]));
}

#[test]
fn noise_has_the_asked_sigma_and_is_reproducible() {
    let (quiet, noisy) = (
        EarthRenderer::new(config(0.0)),
        EarthRenderer::new(config(20.0)),
    );
    let e = nadir(-4.0, 30.0);
    let (mut a, mut b, mut c) = (vec![0u16; 65536], vec![0u16; 65536], vec![0u16; 65536]);
    quiet.render(e, 7, 3, &mut a);
    noisy.render(e, 7, 3, &mut b);
    let d: Vec<f64> = (a.iter().zip(&b))
        .filter(|(q, _)| **q > 0)
        .map(|(q, n)| f64::from(*n) - f64::from(*q))
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!(mean.abs() < 0.3, "{mean}");
    // Rounding adds 1/12 DN² of variance.
    assert!((sd - (400.0f64 + 1.0 / 12.0).sqrt()).abs() < 0.4, "{sd}");
    noisy.render(e, 7, 3, &mut c);
    assert_eq!(b, c, "same seed and frame, same pixels");
    noisy.render(e, 7, 4, &mut c);
    assert_ne!(b, c, "another frame, other noise");
}

/// The frame read back by the [003] methods (glint-earth): the cross-product method gives the
/// nadir's tilt to a few hundredths of a degree through the noise.
#[test]
fn the_earth_core_reads_the_tilt_back() {
    let mut cfg = config(30.0);
    cfg.width_px = 512;
    cfg.height_px = 512;
    cfg.camera = Fisheye::ideal(130.0, 255.5, 255.5);
    cfg.image_circle_px = 255.0;
    let r = EarthRenderer::new(cfg.clone());
    let mut core = glint_earth::pipeline::EarthCore::new(glint_earth::pipeline::EarthConfig::new(
        cfg.camera, 950.0,
    ));
    let mut px = vec![0u16; 512 * 512];
    for tilt in [-7.0, 0.4, 25.0] {
        r.render(nadir(tilt, 0.0), 11, 0, &mut px);
        let out = core.process(&px, 512, 512).unwrap();
        let cp = out.cross_product.unwrap();
        assert!((cp.tilt_deg - tilt).abs() < 0.05, "{tilt}: {out:?}");
        assert!(
            (cp.beta_deg - f64::abs(tilt)).abs() < 0.05,
            "{tilt}: {cp:?}"
        );
    }
}

/// Through a Kannala–Brandt lens the limb at nadir images where the polynomial puts it: along
/// any radius the half-contrast crossing is at r = f θ_d(ρ_E), θ_d = θ (1 + k₁θ² + k₂θ⁴),
/// written out here — 5 % beyond the ideal lens's f ρ_E.
#[test]
fn a_distorted_lens_images_the_limb_where_its_polynomial_says() {
    let mut cfg = config(0.0);
    cfg.camera.k = [0.05, -0.01, 0.0, 0.0];
    let r = EarthRenderer::new(cfg);
    let mut px = vec![0u16; 256 * 256];
    assert!(r.render(nadir(0.0, 0.0), 1, 0, &mut px));
    let rho = earth_angular_radius_rad(950.0);
    let expect_px = 65.0 * rho * (1.0 + 0.05 * rho.powi(2) - 0.01 * rho.powi(4));
    assert!(expect_px > 1.04 * 65.0 * rho);
    // Along +x from the centre row (y = 127, 0.5 px off the axis), where the value crosses the
    // half level, linearly interpolated.
    let half = 200.0 + 1400.0;
    let row: Vec<f64> = (0..256).map(|x| f64::from(px[127 * 256 + x])).collect();
    let x = (128..255)
        .find(|&x| row[x] >= half && row[x + 1] < half)
        .expect("a limb along the row");
    let crossing = x as f64 + (row[x] - half) / (row[x] - row[x + 1]);
    let r_px = (crossing - 127.5).hypot(0.5);
    assert!((r_px - expect_px).abs() < 0.1, "{r_px} against {expect_px}");
}
