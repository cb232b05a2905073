//! Streak signal: exposure smear sampled along the segment, PSF, shot noise, saturating add.
//!
//! docs/math.md §3.2 (gray levels): over the exposure the image point moves uniformly from
//! p₀ = (x0, y0) to p₁ = (x1, y1). The segment is first clipped (Liang–Barsky) to the frame grown
//! by the PSF reach, keeping the signal of the clipped part, `E·(t_out − t_in)`. It is then cut
//! into chunks of ≤ 32 px; a chunk of length ℓ gets K = max(1, ⌈substeps_per_px·ℓ⌉) sub-steps at
//! the midpoints τ_k = (k + ½)/K, each depositing E_chunk/K by bilinear weights into the 4 nearest
//! pixels of an f32 tile (this keeps the centroid exact). The tile is blurred by the PSF
//! (`psf.rs`), then each tile pixel with signal s > 0 is added to the frame as
//! `⌊s + √(s/g)·z + u⌋`, z ~ N(0, 1) from the lookup table (shot noise, Gaussian approximation,
//! g = gain in e⁻/DN) and u ~ U[0, 1) (dithered rounding: the expected added DN is exactly s, even
//! in the faint PSF wings), clamped to [0, saturation_dn].

use super::noise::{Bits16, NormalTable};
use super::psf::blur_separable;
use super::{RenderReport, Streak};

/// Longest chunk rendered in one tile, px.
pub(crate) const CHUNK_PX: f64 = 32.0;

/// Offset that makes the noisy per-pixel increment positive before truncation.
const FLOOR_OFFSET: f32 = 16.0;

/// A segment after clipping, with the signal of the part kept.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Segment {
    pub x0_px: f64,
    pub y0_px: f64,
    pub x1_px: f64,
    pub y1_px: f64,
    pub signal_dn: f64,
}

/// Result of clipping one streak against a rectangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Clip {
    /// Non-finite numbers, negative signal, or a length that overflows.
    Invalid,
    /// Nothing of the streak reaches the rectangle (or it carries no signal).
    Outside,
    Inside(Segment),
}

/// Clip `s` to the closed rectangle `[x_min, x_max] × [y_min, y_max]` (Liang–Barsky).
pub(crate) fn clip_streak(s: &Streak, x_min: f64, y_min: f64, x_max: f64, y_max: f64) -> Clip {
    let values = [s.x0_px, s.y0_px, s.x1_px, s.y1_px, s.total_signal_dn];
    if values.iter().any(|v| !v.is_finite()) || s.total_signal_dn < 0.0 {
        return Clip::Invalid;
    }
    let (dx, dy) = (s.x1_px - s.x0_px, s.y1_px - s.y0_px);
    if !dx.is_finite() || !dy.is_finite() || !dx.hypot(dy).is_finite() {
        return Clip::Invalid;
    }
    if s.total_signal_dn == 0.0 {
        return Clip::Outside;
    }
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let edges = [
        (-dx, s.x0_px - x_min),
        (dx, x_max - s.x0_px),
        (-dy, s.y0_px - y_min),
        (dy, y_max - s.y0_px),
    ];
    for (p, q) in edges {
        if p == 0.0 {
            if q < 0.0 {
                return Clip::Outside;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if t0 > t1 {
        return Clip::Outside;
    }
    let fraction = if dx == 0.0 && dy == 0.0 { 1.0 } else { t1 - t0 };
    Clip::Inside(Segment {
        x0_px: s.x0_px + t0 * dx,
        y0_px: s.y0_px + t0 * dy,
        x1_px: s.x0_px + t1 * dx,
        y1_px: s.y0_px + t1 * dy,
        signal_dn: s.total_signal_dn * fraction,
    })
}

/// Everything the streak pass reads, borrowed from the renderer.
pub(crate) struct StreakPass<'a> {
    pub width_px: usize,
    pub height_px: usize,
    pub saturation_dn: u16,
    pub inv_gain_dn_per_e: f32,
    pub substeps_per_px: f64,
    pub kernel: &'a [f32],
    pub normal: &'a NormalTable,
}

/// Caller-owned tile buffers, grown on demand and reused across chunks and streaks.
#[derive(Default)]
pub(crate) struct TileScratch {
    tile: Vec<f32>,
    tmp: Vec<f32>,
}

impl StreakPass<'_> {
    /// PSF reach beyond the segment: bilinear (1 px) plus the kernel radius.
    pub fn reach_px(&self) -> f64 {
        (self.kernel.len() / 2 + 1) as f64
    }

    /// Render every streak on top of `out`, counting what happened in `report`.
    pub fn add_all(
        &self,
        streaks: &[Streak],
        bits: &mut Bits16<'_>,
        scratch: &mut TileScratch,
        out: &mut [u16],
        report: &mut RenderReport,
    ) {
        let m = self.reach_px();
        let (x_max, y_max) = (
            (self.width_px - 1) as f64 + m,
            (self.height_px - 1) as f64 + m,
        );
        for s in streaks {
            match clip_streak(s, -m, -m, x_max, y_max) {
                Clip::Invalid => report.streaks_invalid += 1,
                Clip::Outside => report.streaks_outside += 1,
                Clip::Inside(seg) => {
                    self.add_segment(&seg, bits, scratch, out, report);
                    report.streaks_rendered += 1;
                }
            }
        }
    }

    fn add_segment(
        &self,
        seg: &Segment,
        bits: &mut Bits16<'_>,
        scratch: &mut TileScratch,
        out: &mut [u16],
        report: &mut RenderReport,
    ) {
        let (dx, dy) = (seg.x1_px - seg.x0_px, seg.y1_px - seg.y0_px);
        let length_px = dx.hypot(dy);
        let n_chunks = (length_px / CHUNK_PX).ceil().max(1.0);
        let chunk_len_px = length_px / n_chunks;
        let substeps = (self.substeps_per_px * chunk_len_px).ceil().max(1.0);
        let dn_per_substep = (seg.signal_dn / n_chunks / substeps) as f32;
        let r = (self.kernel.len() / 2) as i64;
        for c in 0..n_chunks as usize {
            let (ta, tb) = (c as f64 / n_chunks, (c + 1) as f64 / n_chunks);
            let (ax, ay) = (seg.x0_px + ta * dx, seg.y0_px + ta * dy);
            let (bx, by) = (seg.x0_px + tb * dx, seg.y0_px + tb * dy);
            // Tile: whole-pixel box of the chunk, +1 px for the bilinear neighbour, +1 px slack
            // for rounding of the interpolated positions, + R px PSF margin on each side.
            let ox = ax.min(bx).floor() as i64 - r;
            let oy = ay.min(by).floor() as i64 - r;
            let tw = (ax.max(bx).floor() as i64 - ox + 3 + r) as usize;
            let th = (ay.max(by).floor() as i64 - oy + 3 + r) as usize;
            let n = tw * th;
            if scratch.tile.len() < n {
                scratch.tile.resize(n, 0.0);
                scratch.tmp.resize(n, 0.0);
            }
            let tile = &mut scratch.tile[..n];
            tile.fill(0.0);
            for k in 0..substeps as usize {
                let t = ta + (tb - ta) * ((k as f64 + 0.5) / substeps);
                let lx = seg.x0_px + t * dx - ox as f64;
                let ly = seg.y0_px + t * dy - oy as f64;
                // lx, ly ≥ R ≥ 0 by construction of the tile, so truncation is floor (and
                // avoids a libm call on baseline x86-64); the clamps only guard rounding.
                let (ix, iy) = ((lx as usize).min(tw - 2), (ly as usize).min(th - 2));
                let fx = ((lx - ix as f64) as f32).clamp(0.0, 1.0);
                let fy = ((ly - iy as f64) as f32).clamp(0.0, 1.0);
                let i = iy * tw + ix;
                tile[i] += dn_per_substep * (1.0 - fx) * (1.0 - fy);
                tile[i + 1] += dn_per_substep * fx * (1.0 - fy);
                tile[i + tw] += dn_per_substep * (1.0 - fx) * fy;
                tile[i + tw + 1] += dn_per_substep * fx * fy;
            }
            blur_separable(tile, &mut scratch.tmp, tw, th, self.kernel);
            self.add_tile(&scratch.tile[..n], ox, oy, tw, bits, out, report);
        }
    }

    /// Add a tile whose pixel (0, 0) sits at frame pixel (ox, oy), with shot noise and dithered
    /// rounding; pixels outside the frame are skipped.
    #[allow(clippy::too_many_arguments)]
    fn add_tile(
        &self,
        tile: &[f32],
        ox: i64,
        oy: i64,
        tw: usize,
        bits: &mut Bits16<'_>,
        out: &mut [u16],
        report: &mut RenderReport,
    ) {
        let (w, h) = (self.width_px as i64, self.height_px as i64);
        let x_lo = (-ox).clamp(0, tw as i64) as usize;
        let x_hi = (w - ox).clamp(0, tw as i64) as usize;
        let sat = i64::from(self.saturation_dn);
        for (ty, row) in tile.chunks_exact(tw).enumerate() {
            let gy = oy + ty as i64;
            if gy < 0 || gy >= h || x_lo >= x_hi {
                continue;
            }
            // Frame pixels (ox + x_lo ..< ox + x_hi) of row gy; all indices are ≥ 0 here.
            let first = (gy * w + ox + x_lo as i64) as usize;
            let dst = &mut out[first..first + (x_hi - x_lo)];
            for (px, &s) in dst.iter_mut().zip(&row[x_lo..x_hi]) {
                if s <= 0.0 {
                    continue;
                }
                let z = self.normal.get(bits.next_u16());
                let u = f32::from(bits.next_u16()) * (1.0 / 65_536.0);
                // ⌊x⌋ as trunc(x + 16) − 16: x ≥ s − 4.33√s ≥ −4.7 for every table deviate.
                let x = s + (s * self.inv_gain_dn_per_e).sqrt() * z + u;
                let dn = (x + FLOOR_OFFSET) as i64 - FLOOR_OFFSET as i64;
                let v = i64::from(*px) + dn;
                if v > sat {
                    report.saturated_px += 1;
                }
                *px = v.clamp(0, sat) as u16;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn streak(x0: f64, y0: f64, x1: f64, y1: f64) -> Streak {
        Streak {
            x0_px: x0,
            y0_px: y0,
            x1_px: x1,
            y1_px: y1,
            total_signal_dn: 100.0,
        }
    }

    #[test]
    fn clipping_keeps_the_inside_part_and_its_signal() {
        let Clip::Inside(s) = clip_streak(&streak(-10.0, 5.0, 10.0, 5.0), 0.0, 0.0, 20.0, 20.0)
        else {
            panic!("expected Inside");
        };
        assert_eq!((s.x0_px, s.x1_px, s.y0_px, s.y1_px), (0.0, 10.0, 5.0, 5.0));
        assert!((s.signal_dn - 50.0).abs() < 1e-12);
        // Reversed direction, diagonal exit through a corner region.
        let Clip::Inside(s) = clip_streak(&streak(30.0, 30.0, 10.0, 10.0), 0.0, 0.0, 20.0, 20.0)
        else {
            panic!("expected Inside");
        };
        assert_eq!(
            (s.x0_px, s.y0_px, s.x1_px, s.y1_px),
            (20.0, 20.0, 10.0, 10.0)
        );
        assert!((s.signal_dn - 50.0).abs() < 1e-12);
    }

    #[test]
    fn clipping_rejects_outside_and_invalid() {
        let r = |s: Streak| clip_streak(&s, 0.0, 0.0, 20.0, 20.0);
        assert_eq!(r(streak(-10.0, -1.0, 30.0, -1.0)), Clip::Outside);
        assert_eq!(r(streak(25.0, 5.0, 25.0, 5.0)), Clip::Outside);
        assert_eq!(r(streak(-5.0, 30.0, 30.0, 24.0)), Clip::Outside);
        assert_eq!(r(streak(f64::NAN, 1.0, 2.0, 3.0)), Clip::Invalid);
        assert_eq!(r(streak(-1e308, 1.0, 1e308, 3.0)), Clip::Invalid);
        let mut neg = streak(1.0, 1.0, 2.0, 2.0);
        neg.total_signal_dn = -1.0;
        assert_eq!(r(neg), Clip::Invalid);
        let Clip::Inside(p) = r(streak(3.0, 4.0, 3.0, 4.0)) else {
            panic!("point inside");
        };
        assert_eq!(p.signal_dn, 100.0);
    }
}
