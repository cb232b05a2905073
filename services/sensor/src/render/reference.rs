//! Slow, direct rendering of the same model, for tests and as the benchmark baseline.
//!
//! Per pixel: `clamp(round(b + σ_b z₁ + s + √(s/g) z₂), 0, sat)` with (z₁, z₂) from one Box–Muller
//! pair, where s is the streak signal of the pixel. s is accumulated in f64 by evaluating, at each
//! sub-step position p, the Gaussian PSF integrated exactly over every pixel within ⌈5σ⌉ + 1 px
//! (`[Φ((i + ½ − p_x)/σ) − Φ((i − ½ − p_x)/σ)]·[same in y]`), with no tables, tiles or bilinear
//! splat; σ = 0 puts each sub-step into the pixel that contains it. Sub-steps are the midpoints of
//! K = max(1, ⌈substeps_per_px·L⌉) equal parts of the (clipped) path of length L. Statistically
//! it agrees with [`FrameRenderer::render`]; bit for bit it does not.

use super::noise::{normal_cdf, Xoshiro256pp};
use super::streak::{clip_streak, Clip};
use super::{background_sigma_dn, check_len, FrameRenderer, RenderError, RenderReport, Streak};

impl FrameRenderer {
    /// Reference rendering (Box–Muller per pixel, exact PSF integrals). Slow: tests only.
    pub fn render_reference(
        &self,
        streaks: &[Streak],
        seed: u64,
        frame_index: u64,
        out: &mut [u16],
    ) -> Result<RenderReport, RenderError> {
        let c = self.config();
        check_len(c, out)?;
        let (w, h) = (c.width_px, c.height_px);
        let sigma_psf = c.psf_sigma_px;
        let reach = (5.0 * sigma_psf).ceil() + 1.0;
        let mut report = RenderReport::default();
        let mut signal: Vec<f64> = Vec::new();
        for s in streaks {
            let seg = match clip_streak(
                s,
                -reach,
                -reach,
                (w - 1) as f64 + reach,
                (h - 1) as f64 + reach,
            ) {
                Clip::Invalid => {
                    report.streaks_invalid += 1;
                    continue;
                }
                Clip::Outside => {
                    report.streaks_outside += 1;
                    continue;
                }
                Clip::Inside(seg) => seg,
            };
            report.streaks_rendered += 1;
            if signal.is_empty() {
                signal = vec![0.0; w * h];
            }
            let (dx, dy) = (seg.x1_px - seg.x0_px, seg.y1_px - seg.y0_px);
            let k_total = (c.substeps_per_px * dx.hypot(dy)).ceil().max(1.0);
            let dn = seg.signal_dn / k_total;
            for k in 0..k_total as usize {
                let t = (k as f64 + 0.5) / k_total;
                let (px, py) = (seg.x0_px + t * dx, seg.y0_px + t * dy);
                let (cx, cy) = (px.round() as i64, py.round() as i64);
                let r = reach as i64;
                for gy in (cy - r).max(0)..=(cy + r).min(h as i64 - 1) {
                    let wy = pixel_weight(gy as f64 - py, sigma_psf);
                    for gx in (cx - r).max(0)..=(cx + r).min(w as i64 - 1) {
                        let wx = pixel_weight(gx as f64 - px, sigma_psf);
                        signal[gy as usize * w + gx as usize] += dn * wx * wy;
                    }
                }
            }
        }
        let mut rng = Xoshiro256pp::new(seed, frame_index);
        let sigma_bg = background_sigma_dn(c);
        let sat = f64::from(c.saturation_dn);
        for (i, px) in out.iter_mut().enumerate() {
            // Box–Muller: one pair of uniforms per pixel gives both of its deviates.
            let radius = (-2.0 * rng.next_open01().ln()).sqrt();
            let angle = 2.0 * std::f64::consts::PI * rng.next_open01();
            let (z2, z1) = angle.sin_cos();
            let s = signal.get(i).copied().unwrap_or(0.0);
            let mut v = c.background_dn + sigma_bg * radius * z1;
            if s > 0.0 {
                v += s + (s / c.gain_e_per_dn).sqrt() * radius * z2;
                if v.round() > sat {
                    report.saturated_px += 1;
                }
            }
            *px = v.round().clamp(0.0, sat) as u16;
        }
        Ok(report)
    }
}

/// Fraction of a 1-D Gaussian of std `sigma` centred 0 that falls in the pixel [d − ½, d + ½].
fn pixel_weight(d: f64, sigma: f64) -> f64 {
    if sigma > 0.0 {
        normal_cdf((d + 0.5) / sigma) - normal_cdf((d - 0.5) / sigma)
    } else if (-0.5..0.5).contains(&d) {
        1.0
    } else {
        0.0
    }
}
