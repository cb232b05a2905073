//! From the β_k samples to one angle (docs/math.md §4.5–4.6): the t location-scale fit with
//! the confidence-interval mean (eq 22), and the engineering version (eq 21) that replaces the
//! fit by a histogram mode and a calibrated σ(μ) table.
//!
//! **Unfolding.** β_k = ∠(n̂_k, Z_S) ≥ 0 folds at β = 0: near nadir the samples of a 0.05°
//! attitude scatter on both sides of the axis and their fold averages 0.17°. Each sample is
//! therefore signed by the side of the axis its normal leans to — positive toward the mean
//! normal's azimuth, negative away — the fit and the means run on the signed samples, and β is
//! the magnitude of the result. Away from nadir every sample is positive and nothing changes.

use crate::ring::RingSamples;
use crate::tfit::{self, TFit};

/// One angle estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// β̂ [deg], ≥ 0.
    pub beta_deg: f64,
    /// The signed tilt about Y_S [deg] from the tilt_k samples, same estimator.
    pub tilt_deg: f64,
    /// Location and scale used for the confidence interval of β [deg] (signed samples).
    pub mu_deg: f64,
    pub sigma_deg: f64,
    /// The fitted ν (cross-product method); None for the lookup version.
    pub nu: Option<f64>,
    /// Samples inside the interval (μ − σ, μ + σ).
    pub accepted: usize,
    pub samples: usize,
}

/// Why no estimate could be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EstimateError {
    #[error("{0} angle samples: at least 3 are needed (too few edge points on the limb)")]
    TooFewSamples(usize),
    #[error("the t fit failed: {0}")]
    Fit(#[from] tfit::TFitError),
    #[error("the σ table is empty")]
    EmptyTable,
}

/// The azimuth about Z_S the normals lean to [rad]: that of the component-wise medians of
/// their tilt vectors sin β_k (cos φ_k, sin φ_k). Medians, because edges that are not the limb
/// (the Sun, a field boundary) give normals that lean elsewhere, and a mean would follow them:
/// near nadir a few degrees of azimuth are all the true tilt leaves to go on. With no tilt at
/// all, the mean normal's.
pub fn tilt_azimuth_rad(s: &RingSamples) -> f64 {
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        match v.len() {
            0 => 0.0,
            n if n % 2 == 1 => v[n / 2],
            n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
        }
    };
    let lean = |f: fn(f64) -> f64| {
        median(
            (s.beta_deg.iter().zip(&s.azimuth_deg))
                .map(|(b, az)| b.to_radians().sin() * f(az.to_radians()))
                .collect(),
        )
    };
    let (x, y) = (lean(f64::cos), lean(f64::sin));
    if x == 0.0 && y == 0.0 {
        s.mean_normal[1].atan2(s.mean_normal[0])
    } else {
        y.atan2(x)
    }
}

/// β_k signed by the side of Z_S the normal leans to, as its tilt in the plane of Z_S and the
/// normals' azimuth ([`tilt_azimuth_rad`]): atan2(sin β_k cos Δφ_k, cos β_k), Δφ_k the
/// normal's azimuth from that one (see the module's notes). Away from nadir Δφ_k is tiny and
/// this is β_k; near it the normals scatter all round the axis, and a sample across the axis
/// counts by how far it leans along the common direction, not by its whole angle (whole
/// angles, signed, would leave a hole at 0 and two peaks at ± the scatter).
pub fn signed_beta(s: &RingSamples) -> Vec<f64> {
    let az_tilt = tilt_azimuth_rad(s);
    (s.beta_deg.iter().zip(&s.azimuth_deg))
        .map(|(b, az)| {
            let (sb, cb) = b.to_radians().sin_cos();
            (sb * (az.to_radians() - az_tilt).cos())
                .atan2(cb)
                .to_degrees()
        })
        .collect()
}

/// Eq 22: the mean of the samples within (μ − σ, μ + σ); μ if there are none. Returns the
/// mean and the count.
pub fn interval_mean(x: &[f64], mu: f64, sigma: f64) -> (f64, usize) {
    let (mut sum, mut m) = (0.0, 0usize);
    for v in x {
        if (v - mu).abs() < sigma {
            sum += v;
            m += 1;
        }
    }
    if m == 0 {
        (mu, 0)
    } else {
        (sum / m as f64, m)
    }
}

/// Eq 22 about its own result until it moves less than 1e-9° (at most 20 times).
fn mean_shift(x: &[f64], start: f64, sigma: f64) -> (f64, usize) {
    let (mut mu, mut m) = (start, 0);
    for _ in 0..20 {
        let (next, count) = interval_mean(x, mu, sigma);
        let moved = (next - mu).abs();
        (mu, m) = (next, count);
        if moved < 1e-9 {
            break;
        }
    }
    (mu, m)
}

/// The cross-product method: the t fit of the (signed) β_k and tilt_k, each followed by eq 22.
pub fn cross_product(s: &RingSamples) -> Result<(Estimate, TFit), EstimateError> {
    let n = s.beta_deg.len();
    if n < 3 {
        return Err(EstimateError::TooFewSamples(n));
    }
    let signed = signed_beta(s);
    let fit = tfit::fit(&signed)?;
    let (beta, accepted) = interval_mean(&signed, fit.mu, fit.sigma);
    let tilt_fit = tfit::fit(&s.tilt_deg)?;
    let (tilt, _) = interval_mean(&s.tilt_deg, tilt_fit.mu, tilt_fit.sigma);
    Ok((
        Estimate {
            beta_deg: beta.abs(),
            tilt_deg: tilt,
            mu_deg: fit.mu,
            sigma_deg: fit.sigma,
            nu: Some(fit.nu),
            accepted,
            samples: n,
        },
        fit,
    ))
}

/// σ(μ) calibrated per attitude angle (the paper's lost Table 1): points (μ [deg], σ [deg]),
/// ascending in μ, linearly interpolated and held constant beyond the ends.
#[derive(Clone, Debug, PartialEq)]
pub struct SigmaTable {
    pub points: Vec<(f64, f64)>,
}

/// What is wrong with a σ table file, with its line (1-based).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TableError {
    #[error("{file}:{line}: expected `mu_deg,sigma_deg` (two numbers), got `{text}`")]
    Row {
        file: String,
        line: usize,
        text: String,
    },
    #[error("{file}:{line}: σ = {sigma} must be finite and > 0, μ = {mu} finite in 0..=90")]
    Range {
        file: String,
        line: usize,
        mu: f64,
        sigma: f64,
    },
    #[error("{file}: no rows (a header `mu_deg,sigma_deg`, then one row per calibrated angle)")]
    Empty { file: String },
}

impl SigmaTable {
    /// The table as CSV: a `mu_deg,sigma_deg` header, one row per calibrated angle.
    pub fn to_csv(&self) -> String {
        let mut out = String::from("mu_deg,sigma_deg\n");
        for (mu, sigma) in &self.points {
            out.push_str(&format!("{mu},{sigma}\n"));
        }
        out
    }

    /// Reads [`SigmaTable::to_csv`]'s format (`#` comments and blank lines skipped; rows may
    /// come in any order); `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, TableError> {
        let mut points = vec![];
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() || (points.is_empty() && line.starts_with("mu_deg")) {
                continue;
            }
            let row = || TableError::Row {
                file: file.into(),
                line: i + 1,
                text: line.chars().take(60).collect(),
            };
            let (a, b) = line.split_once(',').ok_or_else(row)?;
            let (mu, sigma): (f64, f64) = (
                a.trim().parse().map_err(|_| row())?,
                b.trim().parse().map_err(|_| row())?,
            );
            if !(mu.is_finite() && (0.0..=90.0).contains(&mu) && sigma.is_finite() && sigma > 0.0) {
                return Err(TableError::Range {
                    file: file.into(),
                    line: i + 1,
                    mu,
                    sigma,
                });
            }
            points.push((mu, sigma));
        }
        if points.is_empty() {
            return Err(TableError::Empty { file: file.into() });
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(Self { points })
    }

    /// σ(μ) from calibration fits: one (|μ|, σ) per fit, the σ of fits at the same angle
    /// (to 1e-6°) averaged.
    pub fn from_fits(fits: &[(f64, f64)]) -> Self {
        let mut v: Vec<(f64, f64)> = fits.iter().map(|&(m, s)| (m.abs(), s)).collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut points: Vec<(f64, f64, usize)> = vec![];
        for (m, s) in v {
            match points.last_mut() {
                Some(last) if (m - last.0 / last.2 as f64).abs() < 1e-6 => {
                    last.0 += m;
                    last.1 += s;
                    last.2 += 1;
                }
                _ => points.push((m, s, 1)),
            }
        }
        Self {
            points: points
                .into_iter()
                .map(|(m, s, k)| (m / k as f64, s / k as f64))
                .collect(),
        }
    }

    pub fn sigma_at(&self, mu_deg: f64) -> Option<f64> {
        let p = &self.points;
        let first = p.first()?;
        let last = p[p.len() - 1];
        if mu_deg <= first.0 {
            return Some(first.1);
        }
        if mu_deg >= last.0 {
            return Some(last.1);
        }
        let i = p.partition_point(|q| q.0 <= mu_deg);
        let (a, b) = (p[i - 1], p[i]);
        Some(a.1 + (b.1 - a.1) * (mu_deg - a.0) / (b.0 - a.0))
    }
}

/// The engineering version (eq 21): the most populated of `bins` equal bins over
/// (−90°, 90°) of the signed β_k, μ̂ the mean of its samples, σ̂ = σ(μ̂) from the table, then
/// eq 22 repeated about its own result until it stops moving (at most 20 times): a 1° bin
/// cuts a 0.1°-wide cluster that straddles its edge and biases μ̂ by up to half its width,
/// and the repeated interval mean walks back to the cluster's peak.
pub fn lookup(s: &RingSamples, table: &SigmaTable, bins: usize) -> Result<Estimate, EstimateError> {
    let n = s.beta_deg.len();
    if n < 3 {
        return Err(EstimateError::TooFewSamples(n));
    }
    let signed = signed_beta(s);
    let bins = bins.max(1);
    let width = 180.0 / bins as f64;
    let bin_of = |v: f64| (((v + 90.0) / width) as usize).min(bins - 1);
    let mut counts = vec![0u32; bins];
    for &v in &signed {
        counts[bin_of(v)] += 1;
    }
    let mode = (0..bins)
        .max_by_key(|&i| (counts[i], std::cmp::Reverse(i)))
        .unwrap_or(0);
    let in_mode: Vec<f64> = signed
        .iter()
        .copied()
        .filter(|&v| bin_of(v) == mode)
        .collect();
    let mut mu = in_mode.iter().sum::<f64>() / in_mode.len().max(1) as f64;
    let sigma = table.sigma_at(mu.abs()).ok_or(EstimateError::EmptyTable)?;
    let accepted;
    (mu, accepted) = mean_shift(&signed, mu, sigma);
    let tilt_start = s.tilt_deg.iter().sum::<f64>() / n as f64;
    let (tilt, _) = mean_shift(&s.tilt_deg, tilt_start, sigma);
    Ok(Estimate {
        beta_deg: mu.abs(),
        tilt_deg: tilt,
        mu_deg: mu,
        sigma_deg: sigma,
        nu: None,
        accepted,
        samples: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples of a normal at `tilt` (about Y) with spread 0.1°, from a fixed sequence.
    fn ring(tilt: f64, n: usize) -> RingSamples {
        let mut s = RingSamples::default();
        let mut nx = 0.0;
        let mut nz = 0.0;
        for k in 0..n {
            // A deterministic, peaked spread: quantiles of a triangular density, ±0.2°.
            let p = (k as f64 + 0.5) / n as f64;
            let q = if p < 0.5 {
                (2.0 * p).sqrt() - 1.0
            } else {
                1.0 - (2.0 * (1.0 - p)).sqrt()
            };
            let d = 0.2 * q;
            let t = tilt + d;
            s.beta_deg.push(t.abs());
            s.tilt_deg.push(t);
            s.azimuth_deg.push(if t >= 0.0 { 0.0 } else { 180.0 });
            nx += t.to_radians().sin();
            nz += t.to_radians().cos();
        }
        let len = nx.hypot(nz);
        s.mean_normal = [nx / len, 0.0, nz / len];
        s
    }

    #[test]
    fn the_interval_mean_is_eq_22_of_math_md_7_4() {
        let x = [
            10.12, 9.87, 10.05, 9.96, 10.31, 9.74, 10.02, 10.08, 9.91, 10.44, 9.99, 10.15, 9.82,
            10.01, 9.58, 10.06, 9.95, 10.23, 9.89, 10.97,
        ];
        let f = tfit::fit(&x).unwrap();
        let (m, k) = interval_mean(&x, f.mu, f.sigma);
        assert_eq!(k, 13);
        assert!((m - 10.0046153846).abs() < 1e-9, "{m}");
        assert_eq!(interval_mean(&x, 100.0, 1.0), (100.0, 0));
    }

    #[test]
    fn near_nadir_the_signed_samples_undo_the_fold() {
        for tilt in [-0.04, 0.0, 0.05, 3.0, -7.5] {
            let s = ring(tilt, 300);
            let (e, _) = cross_product(&s).unwrap();
            assert!((e.beta_deg - f64::abs(tilt)).abs() < 0.01, "{tilt}: {e:?}");
            assert!((e.tilt_deg - tilt).abs() < 0.01, "{tilt}: {e:?}");
            // The folded samples alone are biased at nadir.
            let folded = tfit::fit(&s.beta_deg).unwrap();
            if tilt.abs() < 0.06 {
                assert!(folded.mu > f64::abs(tilt) + 0.02, "{tilt}: {folded:?}");
            }
        }
    }

    #[test]
    fn the_lookup_version_recovers_a_cluster_that_straddles_a_bin_edge() {
        let table = SigmaTable {
            points: vec![(0.0, 0.1), (50.0, 0.1)],
        };
        for tilt in [5.0, 5.02, 4.98, 12.5, -3.0] {
            let e = lookup(&ring(tilt, 300), &table, 180).unwrap();
            assert!((e.beta_deg - f64::abs(tilt)).abs() < 0.01, "{tilt}: {e:?}");
        }
    }

    #[test]
    fn the_sigma_table_interpolates_and_holds_its_ends() {
        let t = SigmaTable {
            points: vec![(0.0, 0.1), (10.0, 0.2), (40.0, 0.5)],
        };
        assert_eq!(t.sigma_at(-1.0), Some(0.1));
        assert!((t.sigma_at(5.0).unwrap() - 0.15).abs() < 1e-15);
        assert!((t.sigma_at(25.0).unwrap() - 0.35).abs() < 1e-15);
        assert_eq!(t.sigma_at(60.0), Some(0.5));
        assert_eq!(SigmaTable { points: vec![] }.sigma_at(1.0), None);
    }

    #[test]
    fn the_sigma_table_round_trips_through_its_file_and_names_bad_rows() {
        let t = SigmaTable::from_fits(&[(-5.0, 0.12), (5.0, 0.14), (0.5, 0.1), (30.0, 0.2)]);
        assert_eq!(t.points, vec![(0.5, 0.1), (5.0, 0.13), (30.0, 0.2)]);
        assert_eq!(SigmaTable::parse(&t.to_csv(), "t.csv").unwrap(), t);
        let e = SigmaTable::parse("mu_deg,sigma_deg\n1,0.1\n2;0.2\n", "t.csv").unwrap_err();
        assert_eq!(
            e.to_string(),
            "t.csv:3: expected `mu_deg,sigma_deg` (two numbers), got `2;0.2`"
        );
        let e = SigmaTable::parse("1,-0.1\n", "t.csv").unwrap_err();
        assert!(matches!(e, TableError::Range { line: 1, .. }), "{e}");
        assert!(matches!(
            SigmaTable::parse("# nothing\n", "t.csv"),
            Err(TableError::Empty { .. })
        ));
    }

    #[test]
    fn too_few_samples_are_an_error() {
        let s = ring(1.0, 2);
        assert_eq!(
            cross_product(&s).unwrap_err(),
            EstimateError::TooFewSamples(2)
        );
    }
}
