//! Test-only synthetic frames: seeded Gaussian noise and Gaussian-profile line segments.

pub use glint_physics::rng::SeededRng as Rng;

/// A float image that is quantised to u16 at the end.
pub struct Canvas {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f64>,
}

impl Canvas {
    pub fn new(width: usize, height: usize, level_dn: f64) -> Self {
        Self {
            width,
            height,
            data: vec![level_dn; width * height],
        }
    }

    pub fn add_noise(&mut self, sigma_dn: f64, rng: &mut Rng) {
        for v in &mut self.data {
            *v += sigma_dn * rng.gaussian();
        }
    }

    /// Adds `peak_dn · exp(−d²/(2σ²))`, d = distance to the segment (x0, y0)–(x1, y1).
    pub fn add_segment(&mut self, p0: (f64, f64), p1: (f64, f64), peak_dn: f64, sigma_px: f64) {
        let (dx, dy) = (p1.0 - p0.0, p1.1 - p0.1);
        let len2 = dx * dx + dy * dy;
        let r = 4.0 * sigma_px + 1.0;
        let x_lo = (p0.0.min(p1.0) - r).floor().max(0.0) as usize;
        let x_hi = ((p0.0.max(p1.0) + r).ceil() as usize).min(self.width - 1);
        let y_lo = (p0.1.min(p1.1) - r).floor().max(0.0) as usize;
        let y_hi = ((p0.1.max(p1.1) + r).ceil() as usize).min(self.height - 1);
        for y in y_lo..=y_hi {
            for x in x_lo..=x_hi {
                let (px, py) = (x as f64 - p0.0, y as f64 - p0.1);
                let t = if len2 > 0.0 {
                    ((px * dx + py * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (ex, ey) = (px - t * dx, py - t * dy);
                let d2 = ex * ex + ey * ey;
                self.data[y * self.width + x] +=
                    peak_dn * (-0.5 * d2 / (sigma_px * sigma_px)).exp();
            }
        }
    }

    pub fn to_u16(&self) -> Vec<u16> {
        self.data
            .iter()
            .map(|v| v.round().clamp(0.0, 65535.0) as u16)
            .collect()
    }
}
