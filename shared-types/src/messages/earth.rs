//! The [003] Earth sensor's answer per frame: β and the signed tilt from each method, and what
//! each took.

use iceoryx2::prelude::ZeroCopySend;

use super::*;

/// One method's answer on one frame.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.EarthMethod")]
#[repr(C)]
pub struct EarthMethod {
    /// β, the angle between the optical axis and nadir [deg], ≥ 0.
    pub beta_deg: f64,
    /// The nadir's signed tilt about Y_S [deg].
    pub tilt_deg: f64,
    /// Compute time, the shared edge extraction included [µs]. A timing: never part of a
    /// result's digest.
    pub time_us: f64,
    /// 1 when the method answers on this frame, 0 when the frame does not determine it (the
    /// numbers are then 0).
    pub valid: u32,
    /// Why not, when `valid` is 0 ([`EarthMethod::UNDETERMINED_NAMES`]); 0 when valid.
    pub undetermined: u32,
}

impl Default for EarthMethod {
    /// No answer: the frame gave no limb (a valid message, unlike the zeroed one).
    fn default() -> Self {
        EarthMethod {
            beta_deg: 0.0,
            tilt_deg: 0.0,
            time_us: 0.0,
            valid: 0,
            undetermined: 1,
        }
    }
}

impl EarthMethod {
    /// Names of the `undetermined` codes: no limb (too few edge points or samples), imprecise
    /// (the samples fix β only loosely), off the limb (the edges are not the answer's limb),
    /// circle model bias (the baseline's circle is not the fisheye's limb at this β), mode off
    /// the location (the lookup's histogram mode is not the samples' centre).
    pub const UNDETERMINED_NAMES: [&'static str; 6] = [
        "determined",
        "no_limb",
        "imprecise",
        "off_the_limb",
        "circle_model_bias",
        "mode_off_location",
    ];

    /// The name of this answer's `undetermined` code.
    pub fn undetermined_name(&self) -> &'static str {
        (Self::UNDETERMINED_NAMES.get(self.undetermined as usize)).unwrap_or(&"unknown")
    }
}

/// β and tilt of one Earth frame by every method (math.md §4.4–4.7).
#[derive(
    Debug, Default, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.EarthAttitude")]
#[repr(C)]
pub struct EarthAttitude {
    pub meta: Meta,
    /// Index of the Earth frame answered.
    pub frame_index: u64,
    /// Edge points after masks and erosion.
    pub edge_points: u32,
    /// β_k samples of the interval cross products.
    pub samples: u32,
    /// The t location-scale fit of the signed β_k [deg, deg, 1] (0 without a fit).
    pub fit_mu_deg: f64,
    pub fit_sigma_deg: f64,
    pub fit_nu: f64,
    /// Indexed by [`EarthAttitude::CROSS_PRODUCT`], [`EarthAttitude::LOOKUP`],
    /// [`EarthAttitude::HOUGH`].
    pub methods: [EarthMethod; 3],
    /// The signed β_k samples about the fit: counts in [`EarthAttitude::SAMPLE_BINS`] equal
    /// bins over μ ± [`EarthAttitude::SAMPLE_SPAN_SIGMA`]·σ (all 0 without a fit). What the
    /// fit was made from, so a reader can judge it (the report draws it beside the t density).
    pub samples_hist: [u16; EarthAttitude::SAMPLE_BINS],
}

impl EarthAttitude {
    /// The interval cross product with the t location-scale MLE (eqs 10–19, 22).
    pub const CROSS_PRODUCT: usize = 0;
    /// Its engineering version: a histogram mode and the σ(μ) table (eq 21).
    pub const LOOKUP: usize = 1;
    /// The baseline: Hough circle and Kåsa fit (§4.7).
    pub const HOUGH: usize = 2;
    /// Report names of the methods, in index order.
    pub const METHOD_NAMES: [&'static str; 3] = ["cross_product", "lookup", "hough"];
    /// Bins of [`EarthAttitude::samples_hist`].
    pub const SAMPLE_BINS: usize = 32;
    /// Half the width of the histogram, in units of the fit's σ.
    pub const SAMPLE_SPAN_SIGMA: f64 = 6.0;

    /// The histogram of `samples_deg` about the fit (μ, σ) [deg]: each sample in its bin,
    /// those outside μ ± span·σ left out, counts saturating.
    pub fn histogram(samples_deg: &[f64], mu_deg: f64, sigma_deg: f64) -> [u16; Self::SAMPLE_BINS] {
        let mut hist = [0u16; Self::SAMPLE_BINS];
        if !(sigma_deg > 0.0 && sigma_deg.is_finite() && mu_deg.is_finite()) {
            return hist;
        }
        let half = Self::SAMPLE_SPAN_SIGMA * sigma_deg;
        let width = 2.0 * half / Self::SAMPLE_BINS as f64;
        for &b in samples_deg {
            let k = ((b - mu_deg + half) / width).floor();
            if (0.0..Self::SAMPLE_BINS as f64).contains(&k) {
                let c = &mut hist[k as usize];
                *c = c.saturating_add(1);
            }
        }
        hist
    }

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        for v in [self.fit_mu_deg, self.fit_sigma_deg, self.fit_nu] {
            finite(v, "earth_attitude.fit")?;
        }
        for m in &self.methods {
            if m.valid > 1 {
                return Err(Reject::new("earth_attitude.methods.valid", "not 0 or 1"));
            }
            let reasons = EarthMethod::UNDETERMINED_NAMES.len() as u32;
            if (m.valid == 1) != (m.undetermined == 0) || m.undetermined >= reasons {
                return Err(Reject::new(
                    "earth_attitude.methods.undetermined",
                    "0 when valid, else a reason 1..=5",
                ));
            }
            for v in [m.beta_deg, m.tilt_deg, m.time_us] {
                finite(v, "earth_attitude.methods")?;
            }
            if m.valid == 1 && !(0.0..=180.0).contains(&m.beta_deg) {
                return Err(Reject::new(
                    "earth_attitude.methods.beta_deg",
                    "out of range 0..=180",
                ));
            }
        }
        Ok(())
    }
}
