//! A solve response from a peer is checked before it is trusted: codes outside their tables are
//! rejected with the field named.

use shared_types::*;

fn ok() -> SolveResponse {
    SolveResponse {
        meta: Meta::new(0, 0, 0, ServiceId::Inversion),
        status: SolveStatus::Ok as u32,
        ..Default::default()
    }
}

#[test]
fn codes_outside_their_tables_are_rejected_with_the_field_named() {
    let mut r = ok();
    assert!(r.validate().is_ok());
    // Every reason code in the table is valid, the next one is not.
    r.unobservable_reason = SolveResponse::REASON_NAMES.len() as u32 - 1;
    assert!(r.validate().is_ok());
    r.unobservable_reason += 1;
    assert_eq!(
        r.validate().unwrap_err().field,
        "solve_response.unobservable_reason"
    );
    // The held axes: bits x, y, z and "other".
    let mut r = ok();
    r.stage3_held_axes = 0b1111;
    assert!(r.validate().is_ok());
    r.stage3_held_axes = 0b1_0000;
    assert_eq!(
        r.validate().unwrap_err().field,
        "solve_response.stage3_held_axes"
    );
    // The stage-3 flags: the eight defined bits, no others.
    let mut r = ok();
    r.stage3_flags = 0b1111_1111;
    assert!(r.validate().is_ok());
    r.stage3_flags = 0b1_0000_0000;
    assert_eq!(
        r.validate().unwrap_err().field,
        "solve_response.stage3_flags"
    );
    // The covariance's noise source.
    let mut r = ok();
    r.stage3_covariance_source = SolveResponse::COVARIANCE_SOURCE_NAMES.len() as u32 - 1;
    assert!(r.validate().is_ok());
    r.stage3_covariance_source += 1;
    assert_eq!(
        r.validate().unwrap_err().field,
        "solve_response.stage3_covariance_source"
    );
}
