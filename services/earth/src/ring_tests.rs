use super::*;

const F_PX: f64 = 150.0;
const CAM: Fisheye = Fisheye::ideal(F_PX, 255.5, 255.5);

/// N limb directions of an Earth whose nadir is β from Z_S, tilted about Y_S by `tilt_deg`
/// (β = |tilt|), angular radius ρ.
fn limb(tilt_deg: f64, rho_rad: f64, n: usize) -> Vec<[f64; 3]> {
    let t = tilt_deg.to_radians();
    let e = [t.sin(), 0.0, t.cos()];
    // An orthonormal pair ⊥ e.
    let a = [t.cos(), 0.0, -t.sin()];
    let b = [0.0, 1.0, 0.0];
    (0..n)
        .map(|i| {
            let s = 2.0 * PI * (i as f64 + 0.37) / n as f64;
            let (ss, cs) = s.sin_cos();
            std::array::from_fn(|k| rho_rad.cos() * e[k] + rho_rad.sin() * (cs * a[k] + ss * b[k]))
        })
        .collect()
}

/// math.md §4.1: a ring of exact limb points gives β exactly, with the tilt's sign, through
/// the pixels and back onto the sphere.
#[test]
fn an_exact_ring_gives_beta_exactly() {
    let rho = earth_angular_radius_rad(950.0);
    for tilt in [-50.0, -10.0, -0.3, 0.0, 0.1, 5.0, 30.0, 45.0] {
        let pts: Vec<[f64; 3]> = limb(tilt, rho, 600)
            .into_iter()
            .map(|u| {
                let (x, y) = CAM.pixel(u);
                CAM.direction(x, y)
            })
            .collect();
        let s = cross_product_samples(&pts);
        assert_eq!(s.beta_deg.len(), 200);
        for (b, t) in s.beta_deg.iter().zip(&s.tilt_deg) {
            assert!((b - f64::abs(tilt)).abs() < 1e-9, "tilt {tilt}: β_k {b}");
            assert!((t - tilt).abs() < 1e-9, "tilt {tilt}: tilt_k {t}");
        }
        let expect = [tilt.to_radians().sin(), 0.0, tilt.to_radians().cos()];
        assert!((dot(s.mean_normal, expect) - 1.0).abs() < 1e-12);
    }
}

/// A partial arc (the 60° blind zone takes the near side at large β) still gives β exactly.
#[test]
fn a_partial_arc_gives_beta_exactly() {
    let rho = earth_angular_radius_rad(950.0);
    let tilt = 45.0;
    let pts: Vec<[f64; 3]> = (limb(tilt, rho, 900).into_iter())
        .filter(|u| u[2] < 30f64.to_radians().cos())
        .collect();
    assert!(pts.len() < 900 && pts.len() > 300, "{}", pts.len());
    let s = cross_product_samples(&pts);
    assert!(!s.beta_deg.is_empty());
    for b in &s.beta_deg {
        assert!((b - tilt).abs() < 1e-9, "{b}");
    }
}

#[test]
fn too_few_points_give_no_samples() {
    assert!(cross_product_samples(&[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
        .beta_deg
        .is_empty());
    // Three identical points: a degenerate triple, dropped.
    assert!(cross_product_samples(&[[0.0, 0.6, 0.8]; 3])
        .beta_deg
        .is_empty());
}
