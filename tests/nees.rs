//! EKF consistency over a seeded Monte Carlo: 50 runs of the [002] scenario across real sensor,
//! detector and tracker processes; the final-time NEES averaged over the runs must lie in the
//! 95 % band of χ²(6·50)/50 for every debris.

mod common;

use common::*;

#[test]
fn ekf_nees_is_consistent_over_50_seeded_runs() {
    const RUNS: u64 = 50;
    let root = temp_dir("nees");
    let results: Vec<glint::report::Report> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..2u64)
            .map(|lane| {
                let root = &root;
                s.spawn(move || {
                    (1..=RUNS)
                        .filter(|seed| seed % 2 == lane)
                        .map(|seed| {
                            let dir = root.join(seed.to_string());
                            let r = run(
                                Some(&scenario("debris-geo.toml")),
                                &dir,
                                &["--seed", &seed.to_string()],
                            );
                            assert!(
                                r.output.status.success(),
                                "seed {seed}: {}",
                                String::from_utf8_lossy(&r.output.stderr)
                            );
                            r.typed
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    assert_eq!(results.len() as u64, RUNS);
    // χ²(300)/50: 95 % interval [253.9, 349.9]/50.
    let (lo, hi) = (5.078, 6.998);
    for id in 1..=4u32 {
        let nees: Vec<f64> = results
            .iter()
            .map(|r| {
                let tracking = r.results.tracking.as_ref().expect("a tracking score");
                let t = tracking.targets.iter().find(|t| t.id == id).unwrap();
                assert!(!t.nees_final.is_nan(), "debris {id}: no final NEES: {t:?}");
                t.nees_final
            })
            .collect();
        let mean = nees.iter().sum::<f64>() / nees.len() as f64;
        assert!(
            (lo..=hi).contains(&mean),
            "debris {id}: mean final NEES {mean:.2} outside [{lo}, {hi}]"
        );
    }
    let _ = std::fs::remove_dir_all(&root);
}
