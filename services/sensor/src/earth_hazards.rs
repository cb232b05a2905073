//! What makes an Earth frame harder than the ideal one (all off by default): an oblate Earth,
//! a limb whose radiance changes with latitude (the seasonal hemispheres), and the Sun in the
//! field. Each breaks the limb's symmetry about nadir, so these frames are rendered pixel by
//! pixel from the geometry instead of from the symmetric profile table.
//!
//! The Earth's polar axis is taken as the sensor's Y_S made perpendicular to nadir (an
//! equatorial orbit with the turntable axis along the orbit normal). At a limb point whose
//! direction from nadir makes the angle χ with that axis, the figure's radius is that of the
//! meridian ellipse, `R(χ) = a b / √(a² cos²χ + b² sin²χ)` (b = a (1 − flattening)), and the
//! limb's angular radius is `asin((R(χ) + H(χ)) / (R_E + h))`, H the limb's height: the CO₂
//! layer's mean height, plus ½ S sin(lat) (S the summer pole's limb over the winter pole's)
//! plus ½ D cos(2 lat) (D the equator's over the poles'). The limb's tangent points lie
//! γ = arccos(R_E / (R_E + h)) from the sub-satellite point (29.5° at 950 km), so over the
//! equator the limb point at χ has sin(lat) = sin γ cos χ = cos ρ_E cos χ: from low orbit the
//! limb never reaches the poles, and S and D show only that far. The limb radiance is
//! `(earth − space) (1 + A cos χ)`. The Sun is a disk of 0.267° radius blurred by the same PSF,
//! hidden where the Earth is in front of it: a disk smaller than the PSF images as the PSF
//! holding its flux, `L (R² / 2σ²) exp(−d² / 2σ²)` at d px from its centre; a larger one as a
//! blurred edge. Distances are angles × f: exact along a radius of the ideal lens's image
//! (`r = f θ`), compressed by sin θ / θ across it.

/// The WGS 84 equatorial radius [km].
const EQUATORIAL_RADIUS_KM: f64 = 6378.137;
/// The mean radius the orbit is measured from [km] (as `earth_angular_radius_rad`).
const MEAN_RADIUS_KM: f64 = 6371.0;
/// The Sun's angular radius [rad].
const SUN_RADIUS_RAD: f64 = 0.267 * std::f64::consts::PI / 180.0;

/// The Sun in the field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunInField {
    /// Direction in the sensor frame (unit).
    pub direction: [f64; 3],
    /// Its recorded radiance [DN] (it saturates the detector in practice).
    pub radiance_dn: f64,
}

/// The harder conditions; the default is none of them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Hazards {
    /// Flattening of the Earth's figure, 0 (a sphere) to 0.01 (WGS 84: 1/298.257).
    pub flattening: f64,
    /// Relative amplitude A of the limb radiance's change from pole to pole, 0–0.9.
    pub limb_radiance_amplitude: f64,
    /// The limb's height [km]: mean, seasonal S and latitudinal D (the module's notes).
    pub limb_height_km: f64,
    pub limb_height_seasonal_km: f64,
    pub limb_height_latitude_km: f64,
    pub sun: Option<SunInField>,
}

impl Hazards {
    pub fn any(&self) -> bool {
        self.flattening > 0.0
            || self.limb_radiance_amplitude > 0.0
            || self.limb_height_km != 0.0
            || self.limb_varies()
            || self.sun.is_some()
    }

    fn limb_varies(&self) -> bool {
        self.limb_height_seasonal_km != 0.0 || self.limb_height_latitude_km != 0.0
    }

    /// H at the latitude whose sine is `sin_lat` [km] (cos(2 lat) = 1 − 2 sin²(lat)).
    fn limb_height_at(&self, sin_lat: f64) -> f64 {
        self.limb_height_km
            + 0.5 * self.limb_height_seasonal_km * sin_lat
            + 0.5 * self.limb_height_latitude_km * (1.0 - 2.0 * sin_lat * sin_lat)
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Per-frame geometry of the hazards: nadir, the polar axis, the limb's extreme radii.
pub struct HazardFrame {
    e: [f64; 3],
    pole: [f64; 3],
    orbit_km: f64,
    /// sin(lat) of the limb point at χ = 0: cos ρ_E.
    sin_lat_max: f64,
    a_km: f64,
    b_km: f64,
    /// Pixels with u·ê above this are inside the Earth beyond any limb blur; below `cos_out`,
    /// outside it.
    cos_in: f64,
    cos_out: f64,
    f_px: f64,
    sigma_sqrt2_px: f64,
    hazards: Hazards,
}

impl HazardFrame {
    pub fn new(h: Hazards, e: [f64; 3], altitude_km: f64, f_px: f64, psf_sigma_px: f64) -> Self {
        let y = [0.0, 1.0, 0.0];
        let along = dot(y, e);
        let p = [-along * e[0], 1.0 - along * e[1], -along * e[2]];
        let n = dot(p, p).sqrt();
        let pole = if n > 1e-9 {
            p.map(|v| v / n)
        } else {
            [1.0, 0.0, 0.0]
        };
        let orbit_km = MEAN_RADIUS_KM + altitude_km;
        let (a_km, b_km) = if h.flattening > 0.0 {
            (
                EQUATORIAL_RADIUS_KM,
                EQUATORIAL_RADIUS_KM * (1.0 - h.flattening),
            )
        } else {
            (MEAN_RADIUS_KM, MEAN_RADIUS_KM)
        };
        let band = 8.0 * psf_sigma_px / f_px;
        // H's extremes: at the poles, the equator, or where its derivative in cos χ vanishes.
        // sin(lat) of the limb points spans ±cos ρ_E (the module's notes).
        let sin_lat_max = (1.0 - (MEAN_RADIUS_KM / orbit_km).powi(2)).max(0.0).sqrt();
        let mut sin_lats = vec![-sin_lat_max, 0.0, sin_lat_max];
        if h.limb_height_latitude_km != 0.0 {
            let s = h.limb_height_seasonal_km / (4.0 * h.limb_height_latitude_km);
            if s.abs() <= sin_lat_max {
                sin_lats.push(s);
            }
        }
        let heights = sin_lats.iter().map(|&s| h.limb_height_at(s));
        let h_min = heights.clone().fold(f64::INFINITY, f64::min);
        let h_max = heights.fold(f64::NEG_INFINITY, f64::max);
        let rho_min = ((b_km + h_min) / orbit_km).min(1.0).asin();
        let rho_max = ((a_km + h_max) / orbit_km).min(1.0).asin();
        HazardFrame {
            e,
            pole,
            orbit_km,
            sin_lat_max,
            a_km,
            b_km,
            cos_in: (rho_min - band).max(0.0).cos(),
            cos_out: (rho_max + band).min(std::f64::consts::PI).cos(),
            f_px,
            sigma_sqrt2_px: psf_sigma_px * std::f64::consts::SQRT_2,
            hazards: h,
        }
    }

    /// ½ erfc(d / (σ√2)) for a pixel d px outside an edge.
    fn blurred(&self, d_px: f64) -> f64 {
        let t = d_px / self.sigma_sqrt2_px;
        if t > 6.0 {
            0.0
        } else if t < -6.0 {
            1.0
        } else {
            0.5 * libm::erfc(t)
        }
    }

    /// The noise-free value of a pixel of direction `u` [DN].
    pub fn value(&self, u: [f64; 3], earth_dn: f64, space_dn: f64) -> f64 {
        let c = dot(u, self.e);
        let h = &self.hazards;
        // cos χ: the angle of u about nadir from the polar axis.
        let cos_chi = || {
            let w = [
                u[0] - c * self.e[0],
                u[1] - c * self.e[1],
                u[2] - c * self.e[2],
            ];
            let n = dot(w, w).sqrt();
            if n > 1e-12 {
                dot(w, self.pole) / n
            } else {
                0.0
            }
        };
        let needs_chi = h.limb_radiance_amplitude > 0.0 || h.flattening > 0.0 || h.limb_varies();
        let chi = if needs_chi && c > self.cos_out {
            cos_chi()
        } else {
            0.0
        };
        let earth = if c >= self.cos_in {
            1.0
        } else if c <= self.cos_out {
            0.0
        } else {
            let (ca, sa2) = (chi, 1.0 - chi * chi);
            let r_km = self.a_km * self.b_km
                / (self.a_km * self.a_km * ca * ca + self.b_km * self.b_km * sa2).sqrt()
                + h.limb_height_at(self.sin_lat_max * chi);
            let rho = (r_km / self.orbit_km).min(1.0).asin();
            self.blurred((c.clamp(-1.0, 1.0).acos() - rho) * self.f_px)
        };
        let contrast = (earth_dn - space_dn) * (1.0 + h.limb_radiance_amplitude * chi);
        let mut v = space_dn + contrast * earth;
        if let Some(s) = &h.sun {
            let cs = dot(u, s.direction);
            let near = (SUN_RADIUS_RAD + 8.0 * self.sigma_sqrt2_px / self.f_px).cos();
            if cs > near {
                let d_px = cs.clamp(-1.0, 1.0).acos() * self.f_px;
                let (r_px, sigma_px) = (
                    SUN_RADIUS_RAD * self.f_px,
                    self.sigma_sqrt2_px / 2f64.sqrt(),
                );
                let share = if r_px < sigma_px {
                    let s2 = 2.0 * sigma_px * sigma_px;
                    r_px * r_px / s2 * (-d_px * d_px / s2).exp()
                } else {
                    self.blurred(d_px - r_px)
                };
                v += (s.radiance_dn - space_dn).max(0.0) * share * (1.0 - earth);
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const F: f64 = 130.0;

    fn frame(h: Hazards) -> HazardFrame {
        HazardFrame::new(h, [0.0, 0.0, 1.0], 950.0, F, 1.2)
    }

    /// The direction at angle `theta` from nadir (+Z), toward azimuth `phi` from +X.
    fn at(theta: f64, phi: f64) -> [f64; 3] {
        let (st, ct) = theta.sin_cos();
        [st * phi.cos(), st * phi.sin(), ct]
    }

    #[test]
    fn without_hazards_the_limb_is_at_the_spheres_angle_at_half_contrast() {
        let f = frame(Hazards::default());
        let rho = (MEAN_RADIUS_KM / (MEAN_RADIUS_KM + 950.0)).asin();
        for phi in [0.0, 1.0, 2.5] {
            let v = f.value(at(rho, phi), 3020.0, 20.0);
            assert!((v - 1520.0).abs() < 1e-9, "{v}");
        }
    }

    #[test]
    fn an_oblate_earth_is_narrower_toward_its_poles() {
        let f = frame(Hazards {
            flattening: 1.0 / 298.257,
            ..Default::default()
        });
        let orbit = MEAN_RADIUS_KM + 950.0;
        // Along the pole (+Y here) the limb is at asin(b / orbit); along the equator (+X) at
        // asin(a / orbit): half contrast at each.
        let b = EQUATORIAL_RADIUS_KM * (1.0 - 1.0 / 298.257);
        let pole = (b / orbit).asin();
        let equator = (EQUATORIAL_RADIUS_KM / orbit).asin();
        let v = f.value(at(pole, std::f64::consts::FRAC_PI_2), 3020.0, 20.0);
        assert!((v - 1520.0).abs() < 1e-6, "{v}");
        let v = f.value(at(equator, 0.0), 3020.0, 20.0);
        assert!((v - 1520.0).abs() < 1e-6, "{v}");
        assert!(equator - pole > 0.1f64.to_radians());
    }

    #[test]
    fn the_limb_is_at_its_height_by_latitude_and_season() {
        // mean 40 km, the summer (+Y) pole 6 km above the winter pole, the equator 8 km above
        // the poles; from 950 km the limb reaches sin(lat) = ±cos ρ_E = ±0.4927 (29.5°), so
        // along ±Y it is at 40 ± 3·0.4927 + 4·(1 − 2·0.4927²) km, across at 40 + 4 km.
        let f = frame(Hazards {
            limb_height_km: 40.0,
            limb_height_seasonal_km: 6.0,
            limb_height_latitude_km: 8.0,
            ..Default::default()
        });
        let orbit = MEAN_RADIUS_KM + 950.0;
        let s = (MEAN_RADIUS_KM / orbit).asin().cos();
        assert!((s - 0.4927).abs() < 1e-4, "{s}");
        let lat_term = 4.0 * (1.0 - 2.0 * s * s);
        let half = std::f64::consts::FRAC_PI_2;
        for (phi, height) in [
            (half, 40.0 + 3.0 * s + lat_term),
            (-half, 40.0 - 3.0 * s + lat_term),
            (0.0, 44.0),
            (std::f64::consts::PI, 44.0),
        ] {
            let rho = ((MEAN_RADIUS_KM + height) / orbit).asin();
            let v = f.value(at(rho, phi), 3020.0, 20.0);
            assert!((v - 1520.0).abs() < 1e-6, "φ {phi}: {v}");
        }
        assert!(Hazards {
            limb_height_km: 1.0,
            ..Default::default()
        }
        .any());
    }

    #[test]
    fn the_limb_radiance_changes_from_pole_to_pole() {
        let f = frame(Hazards {
            limb_radiance_amplitude: 0.2,
            ..Default::default()
        });
        let inside = 0.5;
        let north = f.value(at(inside, std::f64::consts::FRAC_PI_2), 3020.0, 20.0);
        let south = f.value(at(inside, -std::f64::consts::FRAC_PI_2), 3020.0, 20.0);
        let equator = f.value(at(inside, 0.0), 3020.0, 20.0);
        assert!((north - (20.0 + 3000.0 * 1.2)).abs() < 1e-9, "{north}");
        assert!((south - (20.0 + 3000.0 * 0.8)).abs() < 1e-9, "{south}");
        assert!((equator - 3020.0).abs() < 1e-9, "{equator}");
    }

    #[test]
    fn the_sun_is_a_blurred_disk_hidden_behind_the_earth() {
        let s = at(1.6, 0.3);
        let f = frame(Hazards {
            sun: Some(SunInField {
                direction: s,
                radiance_dn: 60000.0,
            }),
            ..Default::default()
        });
        // Smaller than the PSF (0.6 px against 1.2 px): the PSF with the disk's flux, πR²L.
        let (r, sigma) = (SUN_RADIUS_RAD * F, 1.2f64);
        let peak = 59980.0 * r * r / (2.0 * sigma * sigma);
        assert!((f.value(s, 3020.0, 20.0) - (20.0 + peak)).abs() < 1e-6);
        let two_sigma = at(1.6 + 2.0 * sigma / F, 0.3);
        let v = f.value(two_sigma, 3020.0, 20.0);
        assert!(
            (v - (20.0 + peak * (-2.0f64).exp())).abs() < 1e-3 * peak,
            "{v}"
        );
        assert_eq!(f.value(at(2.0, 0.3), 3020.0, 20.0), 20.0);
        // Behind the Earth, nothing of it.
        let hidden = frame(Hazards {
            sun: Some(SunInField {
                direction: at(0.2, 0.0),
                radiance_dn: 60000.0,
            }),
            ..Default::default()
        });
        assert_eq!(hidden.value(at(0.2, 0.0), 3020.0, 20.0), 3020.0);
    }
}
