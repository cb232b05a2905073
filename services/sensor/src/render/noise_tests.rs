//! Tests of the keyed streams, the special functions (statrs) and the normal lookup table.
use super::*;

#[test]
fn xoshiro_matches_reference_first_output() {
    // Reference C code: s = {1, 2, 3, 4} → rotl(1 + 4, 23) + 1.
    let seed: Vec<u8> = [1u64, 2, 3, 4]
        .iter()
        .flat_map(|w| w.to_le_bytes())
        .collect();
    let mut rng = Xoshiro256PlusPlus::from_seed(seed.try_into().unwrap());
    assert_eq!(rng.next_u64(), 41_943_041);
}

#[test]
fn keyed_stream_is_splitmix64_seeded_xoshiro() {
    // The state is four consecutive splitmix64 outputs from the key (Vigna's recommended seeding).
    let key = splitmix64_mix(splitmix64_mix(7) ^ 3u64.rotate_left(32));
    let mut sm = rand_xoshiro::SplitMix64::seed_from_u64(key);
    let seed: Vec<u8> = (0..4).flat_map(|_| sm.next_u64().to_le_bytes()).collect();
    let mut want = Xoshiro256PlusPlus::from_seed(seed.try_into().unwrap());
    let mut got = Xoshiro256pp::new(7, 3);
    for _ in 0..4 {
        assert_eq!(got.next_u64(), want.next_u64());
    }
}

#[test]
fn streams_are_deterministic_and_distinct() {
    let draw = |seed, stream| {
        let mut rng = Xoshiro256pp::new(seed, stream);
        (0..8).map(|_| rng.next_u64()).collect::<Vec<_>>()
    };
    assert_eq!(draw(7, 3), draw(7, 3));
    assert_ne!(draw(7, 3), draw(7, 4));
    assert_ne!(draw(7, 3), draw(8, 3));
    // Swapping the roles of seed and stream must not alias.
    assert_ne!(draw(3, 7), draw(7, 3));
    let mut jumped = Xoshiro256pp::new(7, 3);
    jumped.jump();
    assert_ne!(jumped, Xoshiro256pp::new(7, 3));
    let mut again = Xoshiro256pp::new(7, 3);
    again.jump();
    assert_eq!(jumped, again);
}

#[test]
fn open01_stays_open() {
    let mut rng = Xoshiro256pp::new(1, 1);
    assert!((0..100_000).all(|_| {
        let u = rng.next_open01();
        u > 0.0 && u < 1.0
    }));
}

#[test]
fn erfc_matches_reference_values() {
    // Python math.erfc.
    let cases = [
        (0.0, 1.0),
        (0.5, 0.479_500_122_186_953_5),
        (1.0, 0.157_299_207_050_285_13),
        (2.0, 0.004_677_734_981_047_265),
        (2.5, 0.000_406_952_017_444_958_9),
        (3.0, 2.209_049_699_858_543_8e-5),
        (5.0, 1.537_459_794_428_035_1e-12),
        (-1.0, 1.842_700_792_949_715),
    ];
    for (x, want) in cases {
        let got = erfc(x);
        assert!(
            ((got - want) / want).abs() < 1e-13,
            "erfc({x}) = {got}, want {want}"
        );
    }
    assert!(erfc(f64::NAN).is_nan());
    assert_eq!(erfc(40.0), 0.0);
    assert_eq!(erfc(-40.0), 2.0);
}

#[test]
fn inverse_normal_matches_reference_values() {
    // Python statistics.NormalDist().inv_cdf.
    let cases = [
        (0.975, 1.959_963_984_540_053_6),
        (0.001, -3.090_232_306_167_813),
        (1e-9, -5.997_807_015_007_686_5),
        (0.5 / 65_536.0, -4.324_919_040_826_044),
        (0.5, 0.0),
    ];
    for (p, want) in cases {
        let got = inverse_normal_cdf(p);
        assert!(
            (got - want).abs() < 1e-12 * want.abs().max(1.0),
            "Φ⁻¹({p}) = {got}"
        );
    }
    assert_eq!(inverse_normal_cdf(0.0), f64::NEG_INFINITY);
    assert_eq!(inverse_normal_cdf(1.0), f64::INFINITY);
    assert!(inverse_normal_cdf(f64::NAN).is_nan());
    for k in 1..1000 {
        let p = k as f64 / 1000.0;
        assert!((normal_cdf(inverse_normal_cdf(p)) - p).abs() < 1e-14);
    }
}

#[test]
fn table_is_antisymmetric_with_known_moments() {
    let t = NormalTable::new();
    let z = t.as_slice();
    for i in 0..TABLE_LEN / 2 {
        assert_eq!(z[i], -z[TABLE_LEN - 1 - i]);
    }
    assert!(z.windows(2).all(|w| w[0] < w[1]));
    let n = TABLE_LEN as f64;
    let var = z.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / n;
    let m4 = z.iter().map(|&v| (v as f64).powi(4)).sum::<f64>() / n;
    // numpy/scipy on the same midpoints: 0.9999797, kurtosis 2.999247.
    assert!((var - 0.999_979_7).abs() < 1e-6, "var {var}");
    assert!((m4 / (var * var) - 2.999_247).abs() < 1e-5);
}

/// Moments of 10^6 table draws: the standard errors are 1e-3 (mean), 1.4e-3 (variance),
/// 4.9e-3 (kurtosis); the tolerances are ≥ 5σ, and the seed is fixed so the test is exact.
#[test]
fn table_draws_have_normal_moments() {
    let t = NormalTable::new();
    let mut rng = Xoshiro256pp::new(0x5eed, 1);
    let n = 1_000_000usize;
    let (mut s1, mut s2, mut s4) = (0.0f64, 0.0f64, 0.0f64);
    for _ in 0..n / 4 {
        for z in t.sample4(&mut rng) {
            let z = z as f64;
            s1 += z;
            s2 += z * z;
            s4 += z * z * z * z;
        }
    }
    let nf = n as f64;
    let mean = s1 / nf;
    let var = s2 / nf - mean * mean;
    let kurt = (s4 / nf) / (var * var);
    assert!(mean.abs() < 5e-3, "mean {mean}");
    assert!((var - 1.0).abs() < 7e-3, "var {var}");
    assert!((kurt - 3.0).abs() < 0.03, "kurtosis {kurt}");
}

/// Kolmogorov–Smirnov distance of 10^6 draws to Φ. The 0.1 % critical value is 1.95/√n; the
/// table's own discretisation adds at most 1/(2·2^16).
#[test]
fn table_draws_pass_kolmogorov_smirnov() {
    let t = NormalTable::new();
    let mut rng = Xoshiro256pp::new(42, 0);
    let n = 1_000_000usize;
    let mut xs: Vec<f32> = Vec::with_capacity(n);
    for _ in 0..n / 4 {
        xs.extend_from_slice(&t.sample4(&mut rng));
    }
    xs.sort_unstable_by(f32::total_cmp);
    let nf = n as f64;
    let d = xs
        .iter()
        .enumerate()
        .map(|(i, &x)| {
            let cdf = normal_cdf(x as f64);
            ((i + 1) as f64 / nf - cdf).max(cdf - i as f64 / nf)
        })
        .fold(0.0f64, f64::max);
    let bound = 1.95 / nf.sqrt() + 0.5 / TABLE_LEN as f64;
    assert!(d < bound, "KS distance {d} ≥ {bound}");
}

#[test]
fn bits16_cuts_draws_low_half_first() {
    let mut a = Xoshiro256pp::new(1, 2);
    let mut b = a.clone();
    let r = b.next_u64();
    let mut bits = Bits16::new(&mut a);
    let got: Vec<u16> = (0..4).map(|_| bits.next_u16()).collect();
    assert_eq!(
        got,
        [
            r as u16,
            (r >> 16) as u16,
            (r >> 32) as u16,
            (r >> 48) as u16
        ]
    );
}
