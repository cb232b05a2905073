//! Checks shared by the inversion system tests: the service's answer against the offline solve.

/// The service's neighbour, Δχ² and covered covariance (`service`, report.json) are the offline
/// fit's (`offline`, inversion.json), to the bit; `mirror` is not among the neighbours.
pub fn assert_carries_the_offline_neighbours(
    service: &serde_json::Value,
    offline: &serde_json::Value,
    mirror: &serde_json::Value,
) {
    let neighbour = &offline["neighbours"][0];
    let at = |v: &serde_json::Value| -> Option<Vec<f64>> {
        let v = v.as_array()?;
        v.iter().map(|x| x.as_f64()).collect()
    };
    assert_eq!(
        service["neighbour_deg_per_frame"],
        neighbour["rate_deg_per_frame"]
    );
    assert_eq!(service["neighbour_delta_chi2"], neighbour["delta_chi2"]);
    if let Some(m) = at(mirror) {
        for n in offline["neighbours"].as_array().into_iter().flatten() {
            let q = at(&n["rate_deg_per_frame"]).unwrap();
            let d = (0..3).map(|i| (q[i] - m[i]).powi(2)).sum::<f64>().sqrt();
            assert!(d >= 1e-3, "the mirror among the neighbours: {n}");
        }
    }
    let rows = offline["covariance_deg2_per_frame2"].as_array().unwrap();
    let flat: Vec<serde_json::Value> = rows
        .iter()
        .flat_map(|r| r.as_array().unwrap().clone())
        .collect();
    assert_eq!(service["covariance"], serde_json::Value::from(flat));
}
