//! The baseline the paper improves on (docs/math.md §4.7): the limb fitted as a circle in the
//! image — a Hough transform for the centre and radius, then the Kåsa algebraic fit of the
//! inliers — and β = ‖centre − principal point‖ / f.
//!
//! The Hough stage is the gradient-directed form (as OpenCV's `HOUGH_GRADIENT`): each edge
//! point votes for centres along its Sobel gradient, toward the warm side (the Earth is
//! brighter than space, so its centre lies up the gradient), at every radius of the range,
//! into a 1-px centre accumulator; the radius is then the most common distance from the best
//! centre. Under `r = f θ` the limb is not exactly a circle, so the baseline carries a model
//! bias that grows with β (math.md §4.7 tabulates it; the tests check it).

use crate::ring::Fisheye;

/// A circle in the image [px].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    pub x_px: f64,
    pub y_px: f64,
    pub r_px: f64,
}

/// The baseline's answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HoughEstimate {
    pub circle: Circle,
    /// β = ‖centre − principal point‖ / f [deg].
    pub beta_deg: f64,
    /// The centre's offset along x over f [deg]: the tilt about Y_S.
    pub tilt_deg: f64,
    pub inliers: usize,
    /// The accumulator's peak cell, the centre before the Kåsa refinement [px].
    pub peak_px: (f64, f64),
}

/// The Kåsa fit: min Σ (X² + Y² + D X + E Y + F)², centre (−D/2, −E/2), r = √(a² + b² − F);
/// None for fewer than 3 points or collinear ones. Solved about the points' mean (the normal
/// equations of raw pixel coordinates lose ~8 digits).
pub fn kasa_fit(points: &[(f64, f64)]) -> Option<Circle> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = (
        points.iter().map(|p| p.0).sum::<f64>() / n,
        points.iter().map(|p| p.1).sum::<f64>() / n,
    );
    // Rows [x, y, 1], right-hand side −(x² + y²), in centred coordinates.
    let mut a = [[0.0f64; 3]; 3];
    let mut rhs = [0.0f64; 3];
    for &(px, py) in points {
        let (x, y) = (px - mx, py - my);
        let row = [x, y, 1.0];
        let t = -(x * x + y * y);
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] += row[i] * row[j];
            }
            rhs[i] += row[i] * t;
        }
    }
    let [d, e, f] = solve3(a, rhs)?;
    let (cx, cy) = (-d / 2.0, -e / 2.0);
    let r2 = cx * cx + cy * cy - f;
    (r2 > 0.0).then(|| Circle {
        x_px: cx + mx,
        y_px: cy + my,
        r_px: r2.sqrt(),
    })
}

/// Gaussian elimination with partial pivoting; None if singular.
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    for col in 0..3 {
        let piv = (col..3).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() <= 1e-12 * scale {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..3 {
            let f = a[row][col] / a[col][col];
            let pivot_row = a[col];
            for (v, p) in a[row].iter_mut().zip(pivot_row).skip(col) {
                *v -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 3];
    for i in (0..3).rev() {
        x[i] = (b[i] - (i + 1..3).map(|k| a[i][k] * x[k]).sum::<f64>()) / a[i][i];
    }
    Some(x)
}

/// Reusable accumulator of the Hough stage.
#[derive(Default)]
pub struct Hough {
    /// Zero between frames: only the cells a frame voted for are reset.
    votes: Vec<u32>,
    touched: Vec<u32>,
    /// The frame's edge points in the ideal lens's image.
    undistorted: Vec<(f64, f64)>,
    radii: Vec<u32>,
}

/// Inliers of the Kåsa fit: within this of the Hough circle [px] (math.md §4.7).
const INLIER_PX: f64 = 2.0;

impl Hough {
    /// The baseline on edge points of a `width`×`height` frame `px`, for limb radii in
    /// [r_min_px, r_max_px]; None if nothing was found.
    #[allow(clippy::too_many_arguments)]
    pub fn estimate(
        &mut self,
        px: &[u16],
        width: usize,
        height: usize,
        edges_px: &[(f64, f64)],
        cam: &Fisheye,
        r_min_px: f64,
        r_max_px: f64,
    ) -> Option<HoughEstimate> {
        let (w, h) = (width, height);
        if w < 3
            || h < 3
            || px.len() != w * h
            || edges_px.len() < 3
            || r_max_px.is_nan()
            || r_max_px < r_min_px
        {
            return None;
        }
        if self.votes.len() != w * h {
            self.votes.clear();
            self.votes.resize(w * h, 0);
        }
        self.touched.clear();
        let (r0, r1) = (r_min_px.max(1.0).round() as i64, r_max_px.round() as i64);
        // Through a distorted lens the votes, the radius and the fit are cast in the ideal
        // lens's image (`r = f θ`), where the limb is the circle math.md §4.7 fits.
        self.undistorted.clear();
        (self.undistorted).extend(edges_px.iter().map(|&(x, y)| cam.to_equidistant(x, y)));
        for (&(x, y), &(xe, ye)) in edges_px.iter().zip(&self.undistorted) {
            let (xi, yi) = (x as usize, y as usize);
            if xi == 0 || yi == 0 || xi >= w - 1 || yi >= h - 1 {
                continue;
            }
            let z = |dx: usize, dy: usize| f64::from(px[(yi + dy - 1) * w + xi + dx - 1]);
            let gy = (z(0, 2) + 2.0 * z(1, 2) + z(2, 2)) - (z(0, 0) + 2.0 * z(1, 0) + z(2, 0));
            let gx = (z(2, 0) + 2.0 * z(2, 1) + z(2, 2)) - (z(0, 0) + 2.0 * z(0, 1) + z(0, 2));
            let g = gx.hypot(gy);
            if g == 0.0 {
                continue;
            }
            // The Earth is the warm side: its centre lies up the gradient.
            let (ux, uy) = cam.normal_to_equidistant(x, y, (gx / g, gy / g));
            for r in r0..=r1 {
                let cx = (xe + r as f64 * ux).round();
                let cy = (ye + r as f64 * uy).round();
                if cx >= 0.0 && cy >= 0.0 && (cx as usize) < w && (cy as usize) < h {
                    let i = cy as usize * w + cx as usize;
                    if self.votes[i] == 0 {
                        self.touched.push(i as u32);
                    }
                    self.votes[i] += 1;
                }
            }
        }
        // The best centre, its votes summed over its 3×3 neighbourhood (rounding spreads them),
        // looked for among the cells with at least a third of the busiest cell's votes.
        let peak = (self.touched.iter())
            .map(|&i| self.votes[i as usize])
            .max()
            .unwrap_or(0);
        let mut best = (0u32, 0usize);
        for &i in &self.touched {
            let i = i as usize;
            let (x, y) = (i % w, i / w);
            if 3 * self.votes[i] < peak || x == 0 || y == 0 || x == w - 1 || y == h - 1 {
                continue;
            }
            let s: u32 = (0..3)
                .map(|dy| {
                    let row = (y + dy - 1) * w + x - 1;
                    self.votes[row..row + 3].iter().sum::<u32>()
                })
                .sum();
            if s > best.0 || (s == best.0 && i < best.1) {
                best = (s, i);
            }
        }
        for &i in &self.touched {
            self.votes[i as usize] = 0;
        }
        if best.0 == 0 {
            return None;
        }
        let (cx, cy) = ((best.1 % w) as f64, (best.1 / w) as f64);
        // The radius: the most common distance, 1-px bins.
        self.radii.clear();
        self.radii.resize((r1 - r0 + 1) as usize, 0);
        for &(x, y) in &self.undistorted {
            let d = (x - cx).hypot(y - cy).round() as i64;
            if (r0..=r1).contains(&d) {
                self.radii[(d - r0) as usize] += 1;
            }
        }
        let (k, _) =
            (self.radii.iter().enumerate()).max_by_key(|(k, c)| (**c, std::cmp::Reverse(*k)))?;
        let r = (r0 + k as i64) as f64;
        let inliers: Vec<(f64, f64)> = (self.undistorted.iter())
            .filter(|&&(x, y)| ((x - cx).hypot(y - cy) - r).abs() <= INLIER_PX)
            .copied()
            .collect();
        let circle = kasa_fit(&inliers)?;
        Some(HoughEstimate {
            peak_px: (cx, cy),
            ..estimate_of(circle, cam, inliers.len())
        })
    }
}

/// β and tilt of a limb circle fitted in the ideal lens's image (math.md §4.7 step 5:
/// β = ‖centre − principal point‖ / f).
pub fn estimate_of(circle: Circle, cam: &Fisheye, inliers: usize) -> HoughEstimate {
    let (dx, dy) = (circle.x_px - cam.x0_px, circle.y_px - cam.y0_px);
    HoughEstimate {
        circle,
        beta_deg: (dx.hypot(dy) / cam.f_px).to_degrees(),
        tilt_deg: (dx / cam.f_px).to_degrees(),
        inliers,
        peak_px: (circle.x_px, circle.y_px),
    }
}

#[cfg(test)]
#[path = "hough_tests.rs"]
mod tests;
