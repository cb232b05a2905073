//! A solve response from a peer is checked before it is trusted: codes outside their tables,
//! band indices outside the bands and a rate reported ok that is not a number are rejected with
//! the field named.

use shared_types::*;

fn ok(stage: u32) -> SolveResponse {
    SolveResponse {
        meta: Meta::new(0, 0, 0, ServiceId::Inversion),
        stage,
        status: SolveStatus::Ok as u32,
        n_bands: 8,
        ..Default::default()
    }
}

fn answered() -> SolveResponse {
    SolveResponse {
        rate_deg_per_frame: [0.0, 0.25, 0.0],
        covariance: [0.0; 9],
        ..ok(3)
    }
}

fn field(r: &SolveResponse) -> &'static str {
    r.validate().unwrap_err().field
}

#[test]
fn codes_outside_their_tables_are_rejected_with_the_field_named() {
    let mut r = ok(1);
    assert!(r.validate().is_ok());
    // Every reason code in the table is valid, the next one is not.
    r.unobservable_reason = SolveResponse::REASON_NAMES.len() as u32 - 1;
    assert!(r.validate().is_ok());
    r.unobservable_reason += 1;
    assert_eq!(field(&r), "solve_response.unobservable_reason");
    let mut r = ok(1);
    r.band_unobservable_reason = SolveResponse::REASON_NAMES.len() as u32;
    assert_eq!(field(&r), "solve_response.unobservable_reason");
    // The held axes: bits x, y, z and "other".
    let mut r = ok(1);
    r.held_axes = 0b1111;
    assert!(r.validate().is_ok());
    r.held_axes = 0b1_0000;
    assert_eq!(field(&r), "solve_response.held_axes");
    // The flags: the three defined bits, no others.
    let mut r = ok(1);
    r.flags = SolveResponse::FLAGS_KNOWN;
    assert!(r.validate().is_ok());
    r.flags = 0b1000;
    assert_eq!(field(&r), "solve_response.flags");
    // Three Fisher directions.
    let mut r = ok(1);
    r.observable_mask = 0b111;
    assert!(r.validate().is_ok());
    r.observable_mask = 0b1000;
    assert_eq!(field(&r), "solve_response.observable_mask");
    // Status and stage.
    let mut r = ok(1);
    r.status = 99;
    assert_eq!(field(&r), "solve_response.status");
    let mut r = ok(1);
    r.stage = 4;
    assert_eq!(field(&r), "solve_response.stage");
    let mut r = ok(1);
    r.band_status = 99;
    assert_eq!(field(&r), "solve_response.band_status");
}

#[test]
fn band_indices_must_lie_within_the_bands() {
    let mut r = ok(2);
    r.chosen_band = 7;
    assert!(r.validate().is_ok());
    r.chosen_band = 8;
    assert_eq!(field(&r), "solve_response.n_bands/chosen_band");
    let mut r = ok(2);
    r.n_bands = MAX_BANDS as u32 + 1;
    assert_eq!(field(&r), "solve_response.n_bands/chosen_band");
}

#[test]
fn a_rate_reported_ok_must_be_a_number_with_a_covariance() {
    assert!(answered().validate().is_ok());
    let mut r = answered();
    r.rate_deg_per_frame[1] = f64::NAN;
    assert_eq!(field(&r), "solve_response.rate_deg_per_frame");
    let mut r = answered();
    r.covariance[4] = f64::INFINITY;
    assert_eq!(field(&r), "solve_response.rate_deg_per_frame");
    // An unobservable answer carries no rate: NaN is its value.
    let mut r = answered();
    r.status = SolveStatus::Unobservable as u32;
    r.rate_deg_per_frame = [f64::NAN; 3];
    assert!(r.validate().is_ok());
}
