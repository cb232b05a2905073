//! Threshold and 8-connected components in one streaming pass, with exact moments
//! (docs/math.md §3.3, eqs 3–4 with the FIX that includes f(u, v)).
//!
//! A pixel is foreground when `v > threshold_dn`. Rows are scanned once, top to bottom; the hot
//! loop tests 32 pixels at a time with one saturating subtraction each (`Σ sat(v − t) = 0` ⇔ no
//! pixel above t), so background-only stretches cost one compare per pixel and only runs of
//! foreground pixels are touched further. Each run `[x_s, x_e)` of row y joins the runs
//! `[p_s, p_e)` of row y − 1 with `p_s ≤ x_e` and `p_e ≥ x_s` (8-connectivity: diagonal
//! neighbours join), by union–find on run labels.
//!
//! Every label carries raw moments about its own integer origin `(o_x, o_y)`, for two weights:
//! binary `f = 1` and pixel value `f = v` (DN):
//! `S_pq = Σ f · (x − o_x)^p (y − o_y)^q`, p + q ≤ 2.
//! A run adds closed-form sums (`Σ i`, `Σ i²` over the run for f = 1; `Σ v`, `Σ v i`, `Σ v i²`
//! for f = v); a union shifts the absorbed label's sums to the survivor's origin with the
//! binomial identity `Σ f (d + s)² = S₂ + 2 s S₁ + s² S₀`. All sums are exact integers (i128),
//! so the moments equal a direct per-pixel computation to the last bit of the final f64.
//! The intensity-weighted moments of §3.3 use `f = v − b` (b = background): `S^w = S^v − b S^1`.
//!
//! Scratch (runs of two rows, labels, accumulators, output) lives in [`Segmenter`] and is reused,
//! so a steady stream of frames does not allocate.

use crate::FrameError;

/// Pixels tested per block in the hot loop.
const BLOCK: usize = 32;
/// Largest accepted width or height: keeps the per-run `Σ v i²` inside u64.
pub const MAX_SIDE_PX: usize = 1 << 14;

/// Segmentation parameters for one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentParams {
    /// A pixel is foreground when its value is strictly greater than this \[DN\].
    pub threshold_dn: u16,
    /// Background b subtracted for the intensity-weighted moments \[DN\].
    pub background_dn: f64,
    /// Components with fewer pixels are dropped \[px\].
    pub min_area_px: u32,
    /// Pixels at or above this value count as saturated \[DN\].
    pub saturation_dn: u16,
}

/// Inclusive pixel bounding box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BoundingBox {
    pub x_min_px: u32,
    pub y_min_px: u32,
    pub x_max_px: u32,
    pub y_max_px: u32,
}

/// Raw moments `m_pq = Σ f (x − o_x)^p (y − o_y)^q` about an origin (o_x, o_y).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct RawMoments {
    pub m00: f64,
    pub m10: f64,
    pub m01: f64,
    pub m20: f64,
    pub m02: f64,
    pub m11: f64,
}

/// One connected component.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Component {
    /// Moments are taken about (origin_x_px, origin_y_px) = the bounding box's top-left pixel.
    pub origin_x_px: u32,
    pub origin_y_px: u32,
    /// Binary moments (f = 1); `m00` is the pixel count.
    pub binary: RawMoments,
    /// Intensity-weighted moments (f = v − background); `m00` is the flux above background.
    pub weighted: RawMoments,
    pub area_px: u32,
    pub bbox: BoundingBox,
    /// Largest pixel value \[DN\].
    pub peak_dn: u16,
    /// Pixels at or above the saturation level.
    pub saturated_px: u32,
    /// The component has a pixel in the first or last row or column.
    pub touches_border: bool,
}

#[derive(Debug, Clone, Copy)]
struct Run {
    xs: u32,
    xe: u32,
    label: u32,
}

/// Exact moment sums about an integer origin: index 0..6 = (S00, S10, S01, S20, S02, S11).
#[derive(Debug, Clone, Copy)]
struct Acc {
    ox: i64,
    oy: i64,
    one: [i128; 6],
    val: [i128; 6],
    x_min: u32,
    x_max: u32,
    y_min: u32,
    y_max: u32,
    peak: u16,
    saturated: u32,
}

/// Shifts sums about origin o to sums about o − (s, t), i.e. coordinates d → d + (s, t).
fn shift(m: [i128; 6], s: i128, t: i128) -> [i128; 6] {
    let [n, sx, sy, sxx, syy, sxy] = m;
    [
        n,
        sx + s * n,
        sy + t * n,
        sxx + 2 * s * sx + s * s * n,
        syy + 2 * t * sy + t * t * n,
        sxy + t * sx + s * sy + s * t * n,
    ]
}

fn add(a: &mut [i128; 6], b: [i128; 6]) {
    for (x, y) in a.iter_mut().zip(b) {
        *x += y;
    }
}

impl Acc {
    fn new(x: u32, y: u32) -> Self {
        Self {
            ox: i64::from(x),
            oy: i64::from(y),
            one: [0; 6],
            val: [0; 6],
            x_min: x,
            x_max: x,
            y_min: y,
            y_max: y,
            peak: 0,
            saturated: 0,
        }
    }

    /// Adds the run `row[xs..xe]` of row y.
    fn add_run(&mut self, row: &[u16], xs: u32, xe: u32, y: u32, saturation_dn: u16) {
        let (mut s0, mut s1, mut s2) = (0u64, 0u64, 0u64);
        let mut peak = self.peak;
        let mut saturated = 0u32;
        for (i, &v) in (0u64..).zip(&row[xs as usize..xe as usize]) {
            let v64 = u64::from(v);
            s0 += v64;
            s1 += v64 * i;
            s2 += v64 * i * i;
            peak = peak.max(v);
            saturated += u32::from(v >= saturation_dn);
        }
        let len = i128::from(xe - xs);
        let (si, sii) = (len * (len - 1) / 2, (len - 1) * len * (2 * len - 1) / 6);
        let d0 = i128::from(i64::from(xs) - self.ox);
        let dy = i128::from(i64::from(y) - self.oy);
        // Sums over the run with coordinates relative to its first pixel, then shifted by d0.
        let one = shift([len, si, 0, sii, 0, 0], d0, dy);
        let val = shift(
            [i128::from(s0), i128::from(s1), 0, i128::from(s2), 0, 0],
            d0,
            dy,
        );
        add(&mut self.one, one);
        add(&mut self.val, val);
        self.x_min = self.x_min.min(xs);
        self.x_max = self.x_max.max(xe - 1);
        self.y_min = self.y_min.min(y);
        self.y_max = self.y_max.max(y);
        self.peak = peak;
        self.saturated += saturated;
    }

    /// Merges `other` (any origin) into self.
    fn absorb(&mut self, other: &Acc) {
        let s = i128::from(other.ox - self.ox);
        let t = i128::from(other.oy - self.oy);
        add(&mut self.one, shift(other.one, s, t));
        add(&mut self.val, shift(other.val, s, t));
        self.x_min = self.x_min.min(other.x_min);
        self.x_max = self.x_max.max(other.x_max);
        self.y_min = self.y_min.min(other.y_min);
        self.y_max = self.y_max.max(other.y_max);
        self.peak = self.peak.max(other.peak);
        self.saturated += other.saturated;
    }

    fn component(&self, width: u32, height: u32, background_dn: f64) -> Component {
        let s = i128::from(self.ox - i64::from(self.x_min));
        let t = i128::from(self.oy - i64::from(self.y_min));
        let one = shift(self.one, s, t);
        let val = shift(self.val, s, t);
        let f = |k: usize| one[k] as f64;
        let w = |k: usize| val[k] as f64 - background_dn * one[k] as f64;
        let moments = |g: &dyn Fn(usize) -> f64| RawMoments {
            m00: g(0),
            m10: g(1),
            m01: g(2),
            m20: g(3),
            m02: g(4),
            m11: g(5),
        };
        Component {
            origin_x_px: self.x_min,
            origin_y_px: self.y_min,
            binary: moments(&f),
            weighted: moments(&w),
            area_px: u32::try_from(one[0]).unwrap_or(u32::MAX),
            bbox: BoundingBox {
                x_min_px: self.x_min,
                y_min_px: self.y_min,
                x_max_px: self.x_max,
                y_max_px: self.y_max,
            },
            peak_dn: self.peak,
            saturated_px: self.saturated,
            touches_border: self.x_min == 0
                || self.y_min == 0
                || self.x_max + 1 == width
                || self.y_max + 1 == height,
        }
    }
}

/// Appends the foreground runs of `row` (pixels with `v > threshold`) to `out`.
fn find_runs(row: &[u16], threshold: u16, out: &mut Vec<Run>) {
    const NONE: usize = usize::MAX;
    let mut start = NONE;
    let mut x = 0;
    let mut blocks = row.chunks_exact(BLOCK);
    for block in blocks.by_ref() {
        let any = block
            .iter()
            .fold(0u16, |acc, &v| acc | v.saturating_sub(threshold));
        if any != 0 || start != NONE {
            for (i, &v) in block.iter().enumerate() {
                scan_pixel(v > threshold, x + i, &mut start, out);
            }
        }
        x += BLOCK;
    }
    for (i, &v) in blocks.remainder().iter().enumerate() {
        scan_pixel(v > threshold, x + i, &mut start, out);
    }
    if start != NONE {
        push_run(out, start, row.len());
    }
}

#[inline(always)]
fn scan_pixel(above: bool, x: usize, start: &mut usize, out: &mut Vec<Run>) {
    if above {
        if *start == usize::MAX {
            *start = x;
        }
    } else if *start != usize::MAX {
        push_run(out, *start, x);
        *start = usize::MAX;
    }
}

#[inline(always)]
fn push_run(out: &mut Vec<Run>, xs: usize, xe: usize) {
    // Widths are bounded by MAX_SIDE_PX, so the casts are lossless; the label is set later.
    out.push(Run {
        xs: xs as u32,
        xe: xe as u32,
        label: u32::MAX,
    });
}

/// Streaming 8-connected labelling with reusable scratch.
#[derive(Debug, Default)]
pub struct Segmenter {
    prev: Vec<Run>,
    cur: Vec<Run>,
    parent: Vec<u32>,
    acc: Vec<Acc>,
    components: Vec<Component>,
}

impl Segmenter {
    pub fn new() -> Self {
        Self::default()
    }

    /// Labels `frame` (row-major, `width × height`) and returns its components with at least
    /// `min_area_px` pixels, in raster order of their first pixel.
    pub fn segment(
        &mut self,
        frame: &[u16],
        width: usize,
        height: usize,
        params: &SegmentParams,
    ) -> Result<&[Component], FrameError> {
        crate::check_frame(frame, width, height)?;
        self.prev.clear();
        self.parent.clear();
        self.acc.clear();
        self.components.clear();
        for (y, row) in (0u32..).zip(frame.chunks_exact(width)) {
            self.cur.clear();
            find_runs(row, params.threshold_dn, &mut self.cur);
            self.connect_row(row, y, params.saturation_dn);
            std::mem::swap(&mut self.prev, &mut self.cur);
        }
        let (w, h) = (width as u32, height as u32);
        for (label, acc) in self.acc.iter().enumerate() {
            if self.parent[label] as usize == label && acc.one[0] >= i128::from(params.min_area_px)
            {
                self.components
                    .push(acc.component(w, h, params.background_dn));
            }
        }
        Ok(&self.components)
    }

    /// Labels the runs in `self.cur` (row y) against `self.prev` and accumulates them.
    fn connect_row(&mut self, row: &[u16], y: u32, saturation_dn: u16) {
        let mut j = 0;
        for r in 0..self.cur.len() {
            let Run { xs, xe, .. } = self.cur[r];
            while j < self.prev.len() && self.prev[j].xe < xs {
                j += 1;
            }
            let mut label = u32::MAX;
            let mut k = j;
            while k < self.prev.len() && self.prev[k].xs <= xe {
                let root = self.find(self.prev[k].label);
                label = if label == u32::MAX {
                    root
                } else {
                    self.union(label, root)
                };
                k += 1;
            }
            if label == u32::MAX {
                label = self.acc.len() as u32;
                self.parent.push(label);
                self.acc.push(Acc::new(xs, y));
            }
            self.acc[label as usize].add_run(row, xs, xe, y, saturation_dn);
            self.cur[r].label = label;
        }
    }

    fn find(&mut self, mut l: u32) -> u32 {
        while self.parent[l as usize] != l {
            let p = self.parent[l as usize];
            self.parent[l as usize] = self.parent[p as usize];
            l = p;
        }
        l
    }

    /// Joins two roots; the older (smaller) label survives and absorbs the other's sums.
    fn union(&mut self, a: u32, b: u32) -> u32 {
        if a == b {
            return a;
        }
        let (keep, gone) = if a < b { (a, b) } else { (b, a) };
        let other = self.acc[gone as usize];
        self.acc[keep as usize].absorb(&other);
        self.parent[gone as usize] = keep;
        keep
    }
}

#[cfg(test)]
mod tests;
