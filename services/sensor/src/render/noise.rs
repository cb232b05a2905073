//! Seedable noise: xoshiro256++ streams and a table-driven standard-normal sampler.
//!
//! - **PRNG.** xoshiro256++ (Blackman & Vigna 2019), 256-bit state, period 2^256 − 1. A stream is
//!   keyed by `(seed, stream)`: both words are mixed by the splitmix64 finaliser into one 64-bit
//!   key, and splitmix64 run from that key fills the state. The renderer uses
//!   `stream = frame_index`, so every frame has its own reproducible stream (docs/math.md §6.6,
//!   architecture.md §2: same scenario + seed ⇒ same frames). [`Xoshiro256pp::jump`] advances by
//!   2^128 draws, giving non-overlapping sub-streams (interleaved lanes) inside one frame.
//! - **Gaussian by lookup.** [`NormalTable`] holds N = 2^16 midpoint quantiles
//!   `z_i = Φ⁻¹((i + ½)/N)`; one 64-bit draw is four 16-bit indices, hence four deviates. The table
//!   is exactly antisymmetric (mean 0), has variance 0.99998 and kurtosis 2.9992 (the tails are cut
//!   at |z| = 4.3249), and its CDF is within 1/(2N) of Φ everywhere.
//! - **Quantiles.** Acklam's rational approximation (relative error ≤ 1.15e-9) refined by one
//!   Halley step (a Newton step with the second-order correction) on `Φ(z) − p`, where Φ uses
//!   [`erfc`] below: a positive-term series for x < 2.5, Lentz's continued fraction beyond.

/// Number of bits of one table index; four indices are cut from each 64-bit draw.
pub const TABLE_BITS: u32 = 16;
/// Number of entries of every lookup table indexed by a 16-bit draw.
pub const TABLE_LEN: usize = 1 << TABLE_BITS;

/// The splitmix64 output function (Steele, Lea & Flood 2014): a bijective 64-bit mixer.
pub fn splitmix64_mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// One step of the splitmix64 generator: advance `state` by the golden gamma, return its mix.
pub fn splitmix64_next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    splitmix64_mix(*state)
}

/// xoshiro256++ generator state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Xoshiro256pp {
    s: [u64; 4],
}

impl Xoshiro256pp {
    /// Generator from a raw state. An all-zero state (the one fixed point) is replaced by a
    /// splitmix64-filled one so the generator never degenerates.
    pub fn from_state(s: [u64; 4]) -> Self {
        if s == [0; 4] {
            return Self::new(0, 0);
        }
        Self { s }
    }

    /// Independent stream `stream` of master seed `seed`.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut key = splitmix64_mix(splitmix64_mix(seed) ^ stream.rotate_left(32));
        let s = [
            splitmix64_next(&mut key),
            splitmix64_next(&mut key),
            splitmix64_next(&mut key),
            splitmix64_next(&mut key),
        ];
        // splitmix64 is a bijection of a counter: four consecutive outputs are never all zero.
        Self { s }
    }

    /// Next 64 random bits.
    #[inline(always)]
    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform deviate in the open interval (0, 1), 53 bits.
    #[inline]
    pub fn next_open01(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
    }

    /// Advance by 2^128 draws (Vigna's jump polynomial): successive jumps give non-overlapping
    /// sub-streams of 2^128 draws each.
    pub fn jump(&mut self) {
        const JUMP: [u64; 4] = [
            0x180e_c6d3_3cfd_0aba,
            0xd5a6_1266_f0c9_392c,
            0xa958_2618_e03f_c9aa,
            0x39ab_dc45_29b1_661c,
        ];
        let mut acc = [0u64; 4];
        for word in JUMP {
            for bit in 0..64 {
                if word & (1u64 << bit) != 0 {
                    for (a, s) in acc.iter_mut().zip(self.s) {
                        *a ^= s;
                    }
                }
                self.next_u64();
            }
        }
        self.s = acc;
    }
}

/// Complementary error function, relative error ~1e-14 for all finite x (erfc(NaN) = NaN).
pub fn erfc(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    const FRAC_1_SQRT_PI: f64 = 0.564_189_583_547_756_3;
    if x < 2.5 {
        // erf x = (2/√π) e^{−x²} Σ_n (2x²)^n x / (1·3·…·(2n+1)): positive terms, no cancellation.
        let two_x2 = 2.0 * x * x;
        let (mut term, mut sum, mut n) = (x, x, 0.0);
        while term > sum * 1e-17 {
            n += 1.0;
            term *= two_x2 / (2.0 * n + 1.0);
            sum += term;
        }
        return 1.0 - 2.0 * FRAC_1_SQRT_PI * (-x * x).exp() * sum;
    }
    // erfc x = e^{−x²}/√π · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + …)))), modified Lentz.
    const TINY: f64 = 1e-300;
    let (mut f, mut c, mut d) = (x, x, 0.0);
    for n in 1..500 {
        let a = 0.5 * n as f64;
        d = x + a * d;
        d = if d == 0.0 { 1.0 / TINY } else { 1.0 / d };
        c = x + a / c;
        if c == 0.0 {
            c = TINY;
        }
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    FRAC_1_SQRT_PI * (-x * x).exp() / f
}

/// Standard normal CDF Φ(z) = ½ erfc(−z/√2).
pub fn normal_cdf(z: f64) -> f64 {
    0.5 * erfc(-z * std::f64::consts::FRAC_1_SQRT_2)
}

/// Standard normal quantile Φ⁻¹(p); −∞ / +∞ at p ≤ 0 / p ≥ 1, NaN for NaN.
pub fn inverse_normal_cdf(p: f64) -> f64 {
    if p.is_nan() {
        return f64::NAN;
    }
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    if p > 0.5 {
        // Symmetry keeps the relative accuracy of the upper tail (1 − p is exact for p ≥ ½).
        return -inverse_normal_cdf(1.0 - p);
    }
    let x = acklam(p);
    // One Halley step on f(x) = Φ(x) − p: with u = f/φ(x), x ← x − u/(1 + x u/2).
    let u = (normal_cdf(x) - p) * (2.0 * std::f64::consts::PI).sqrt() * (0.5 * x * x).exp();
    x - u / (1.0 + 0.5 * x * u)
}

/// Acklam's rational approximation of Φ⁻¹(p) for 0 < p ≤ ½.
fn acklam(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    if p < 0.02425 {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Build a boxed `[T; TABLE_LEN]` on the heap (no large stack temporary).
pub(crate) fn boxed_table<T>(f: impl FnMut(usize) -> T) -> Box<[T; TABLE_LEN]> {
    let v: Vec<T> = (0..TABLE_LEN).map(f).collect();
    match v.into_boxed_slice().try_into() {
        Ok(table) => table,
        Err(_) => unreachable!("the iterator yields exactly TABLE_LEN items"),
    }
}

/// Midpoint quantiles of the standard normal, `z_i = Φ⁻¹((i + ½)/TABLE_LEN)`.
pub struct NormalTable {
    z: Box<[f32; TABLE_LEN]>,
}

impl Default for NormalTable {
    fn default() -> Self {
        Self::new()
    }
}

impl NormalTable {
    /// Compute the table (about 65 k quantile evaluations; do it once).
    pub fn new() -> Self {
        let z = boxed_table(|i| inverse_normal_cdf((i as f64 + 0.5) / TABLE_LEN as f64) as f32);
        Self { z }
    }

    /// The deviate for a 16-bit index.
    #[inline(always)]
    pub fn get(&self, index: u16) -> f32 {
        self.z[index as usize]
    }

    /// All entries, ascending.
    pub fn as_slice(&self) -> &[f32] {
        &self.z[..]
    }

    /// Four standard-normal deviates from one 64-bit draw.
    #[inline(always)]
    pub fn sample4(&self, rng: &mut Xoshiro256pp) -> [f32; 4] {
        let r = rng.next_u64();
        [
            self.get(r as u16),
            self.get((r >> 16) as u16),
            self.get((r >> 32) as u16),
            self.get((r >> 48) as u16),
        ]
    }
}

/// Hands out 16-bit pieces of 64-bit draws, four per draw, in a fixed order.
pub struct Bits16<'a> {
    rng: &'a mut Xoshiro256pp,
    bits: u64,
    left: u32,
}

impl<'a> Bits16<'a> {
    /// Wrap a generator; draws happen lazily.
    pub fn new(rng: &'a mut Xoshiro256pp) -> Self {
        Self {
            rng,
            bits: 0,
            left: 0,
        }
    }

    /// The next 16 random bits.
    #[inline(always)]
    pub fn next_u16(&mut self) -> u16 {
        if self.left == 0 {
            self.bits = self.rng.next_u64();
            self.left = 4;
        }
        let out = self.bits as u16;
        self.bits >>= 16;
        self.left -= 1;
        out
    }
}

#[cfg(test)]
#[path = "noise_tests.rs"]
mod tests;
