//! The spin rate from a light curve (docs/math.md §2.6, eq 9): the angular frequency of its
//! dominant line. Uniformly sampled: the mean removed, a Hann window, zero-padding to at least
//! 8N (a power of two), the largest bin above 0 refined by a parabola through its neighbours.
//! With gaps (samples in the Earth's shadow or below the horizon are absent): the
//! Lomb–Scargle periodogram on a grid 8 times finer than 1/T, refined the same way.

use rustfft::{num_complex::Complex, FftPlanner};
use std::f64::consts::PI;

/// Sampling counts as uniform when every interval is within this fraction of the first.
const UNIFORM: f64 = 1e-6;
/// Most samples, and most Lomb–Scargle frequencies (span over median interval × 4): a curve
/// beyond either gives no rate rather than hours of work.
pub const MAX_SAMPLES: usize = 1 << 20;
pub const MAX_FREQUENCIES: usize = 1 << 20;

/// ω = 2π f [rad/s] of the light curve's dominant line; `None` with fewer than 8 samples or a
/// flat curve.
pub fn dominant_angular_frequency(t_s: &[f64], y: &[f64]) -> Option<f64> {
    if t_s.len() < 8 || t_s.len() != y.len() || t_s.len() > MAX_SAMPLES {
        return None;
    }
    let dt = t_s[1] - t_s[0];
    let uniform = dt > 0.0
        && t_s
            .windows(2)
            .all(|w| ((w[1] - w[0]) - dt).abs() <= UNIFORM * dt);
    let f = if uniform {
        fft_peak(y, 1.0 / dt)?
    } else {
        lomb_scargle_peak(t_s, y)?
    };
    Some(2.0 * PI * f)
}

/// The vertex of the parabola through (−1, a), (0, b), (1, c), as an offset from 0.
fn parabolic_offset(a: f64, b: f64, c: f64) -> f64 {
    let d = a - 2.0 * b + c;
    if d.abs() > 0.0 {
        (0.5 * (a - c) / d).clamp(-0.5, 0.5)
    } else {
        0.0
    }
}

fn fft_peak(y: &[f64], fs_hz: f64) -> Option<f64> {
    let n = y.len();
    let mean = y.iter().sum::<f64>() / n as f64;
    let n_fft = (64 * n).next_power_of_two();
    let mut buf: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); n_fft];
    for (k, (b, v)) in buf.iter_mut().zip(y).enumerate() {
        let hann = 0.5 * (1.0 - (2.0 * PI * k as f64 / (n - 1) as f64).cos());
        *b = Complex::new((v - mean) * hann, 0.0);
    }
    FftPlanner::new().plan_fft_forward(n_fft).process(&mut buf);
    let mag: Vec<f64> = buf[..n_fft / 2].iter().map(|c| c.norm()).collect();
    let (k, &peak) = mag
        .iter()
        .enumerate()
        .skip(1)
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    if peak <= 0.0 || k + 1 >= mag.len() {
        return None;
    }
    let k_star = k as f64 + parabolic_offset(mag[k - 1], mag[k], mag[k + 1]);
    Some(k_star * fs_hz / n_fft as f64)
}

/// The normalised Lomb–Scargle power at frequency `f_hz`.
fn lomb_scargle(t: &[f64], y: &[f64], f_hz: f64) -> f64 {
    let w = 2.0 * PI * f_hz;
    let (s2, c2) = t.iter().fold((0.0, 0.0), |(s, c), &ti| {
        (s + (2.0 * w * ti).sin(), c + (2.0 * w * ti).cos())
    });
    let tau = s2.atan2(c2) / (2.0 * w);
    let (mut yc, mut ys, mut cc, mut ss) = (0.0, 0.0, 0.0, 0.0);
    for (&ti, &yi) in t.iter().zip(y) {
        let (s, c) = (w * (ti - tau)).sin_cos();
        yc += yi * c;
        ys += yi * s;
        cc += c * c;
        ss += s * s;
    }
    0.5 * (yc * yc / cc.max(1e-300) + ys * ys / ss.max(1e-300))
}

fn lomb_scargle_peak(t: &[f64], y: &[f64]) -> Option<f64> {
    let n = t.len();
    let span = t[n - 1] - t[0];
    if span <= 0.0 {
        return None;
    }
    let mean = y.iter().sum::<f64>() / n as f64;
    let yc: Vec<f64> = y.iter().map(|v| v - mean).collect();
    // Up to the Nyquist frequency of the median interval.
    let mut dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let f_max = 0.5 / dts[dts.len() / 2].max(1e-12);
    let df = 1.0 / (8.0 * span);
    let bins = (f_max / df).floor();
    if !(1.0..=MAX_FREQUENCIES as f64).contains(&bins) {
        return None;
    }
    // power[i] at frequency (i + 1) df: from the lowest frequency the span resolves
    let power: Vec<f64> = (1..=bins as usize)
        .map(|k| lomb_scargle(t, &yc, k as f64 * df))
        .collect();
    let (i, &peak) = power.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    if peak <= 0.0 {
        return None;
    }
    // refined by the parabola only between two neighbours
    let offset = if i > 0 && i + 1 < power.len() {
        parabolic_offset(power[i - 1], power[i], power[i + 1])
    } else {
        0.0
    };
    Some((i as f64 + 1.0 + offset) * df)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sinusoid at 0.0137 Hz plus its harmonic, 1 s cadence for 20 minutes.
    fn curve(t: &[f64]) -> Vec<f64> {
        t.iter()
            .map(|t| {
                5.0 + 2.0 * (2.0 * PI * 0.0137 * t + 0.3).sin()
                    + 0.5 * (4.0 * PI * 0.0137 * t).cos()
            })
            .collect()
    }

    #[test]
    fn a_sinusoids_frequency_by_fft() {
        let t: Vec<f64> = (0..1200).map(|k| k as f64).collect();
        let w = dominant_angular_frequency(&t, &curve(&t)).unwrap();
        let truth = 2.0 * PI * 0.0137;
        assert!((w / truth - 1.0).abs() < 1e-3, "{w} vs {truth}");
    }

    #[test]
    fn with_gaps_by_lomb_scargle() {
        // the same curve with two stretches missing (shadow, horizon) and a jittered cadence
        let t: Vec<f64> = (0..1200)
            .filter(|k| !(200..320).contains(k) && !(700..760).contains(k))
            .map(|k| k as f64 + 0.2 * ((k * 7919 % 13) as f64 / 13.0))
            .collect();
        let w = dominant_angular_frequency(&t, &curve(&t)).unwrap();
        let truth = 2.0 * PI * 0.0137;
        assert!((w / truth - 1.0).abs() < 1e-3, "{w} vs {truth}");
    }

    #[test]
    fn too_short_or_flat_gives_nothing() {
        let t: Vec<f64> = (0..5).map(|k| k as f64).collect();
        assert_eq!(dominant_angular_frequency(&t, &[1.0; 5]), None);
    }
}
