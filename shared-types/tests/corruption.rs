//! Every message type of the contract, corrupted in every way a fault can corrupt it — a
//! non-finite value, a count past its capacity (a frame: a size that disagrees with its
//! pixels), a wrong contract version — is rejected by its own check, so a consumer counts it
//! `malformed` and never trusts it. A type with no field of a kind is corrupted in its version
//! instead: every mode must still be rejected. The table's visitor names every topic's types,
//! so a new topic is checked without a line here.

use shared_types::scenario::Corruption;
use shared_types::table::{visit, PayloadVisitor, TopicSpec, TOPICS};
use shared_types::{
    Command, Control, EarthAttitude, EarthMethod, FrameHeader, Message, PhotometrySample,
    SolveRequest, SolveResponse, Spectrum, CONTRACT_VERSION,
};

/// A zeroed message of the current contract with what its type needs set, sealed.
fn valid<T: Message>() -> T {
    let mut m: T = bytemuck::Zeroable::zeroed();
    m.meta_mut().contract_version = CONTRACT_VERSION;
    let any = &mut m as &mut dyn std::any::Any;
    if let Some(s) = any.downcast_mut::<Spectrum>() {
        s.n_bands = 1;
        s.sun_body = [1.0, 0.0, 0.0];
        s.observer_body = [0.0, 1.0, 0.0];
        s.range_m = 1.0;
    } else if let Some(p) = any.downcast_mut::<PhotometrySample>() {
        p.sigma_mag = 0.05;
        p.sun = [1.0, 0.0, 0.0];
        p.obs = [0.0, 1.0, 0.0];
        p.range_m = 3.6e7;
    } else if let Some(e) = any.downcast_mut::<EarthAttitude>() {
        // each method without an answer says why (a zeroed method has no reason)
        e.methods = [EarthMethod::default(); 3];
    } else if let Some(c) = any.downcast_mut::<Control>() {
        c.command = Command::Shutdown as u32;
    } else if let Some(r) = any.downcast_mut::<SolveRequest>() {
        r.stage = 1;
    } else if let Some(r) = any.downcast_mut::<SolveResponse>() {
        r.stage = 1;
    }
    m.seal();
    m
}

/// The header of a valid 4 × 2 frame (8 pixels).
fn valid_frame() -> FrameHeader {
    let mut h = FrameHeader {
        width_px: 4,
        height_px: 2,
        exposure_ns: 1,
        ..Default::default()
    };
    h.meta.contract_version = CONTRACT_VERSION;
    h
}

/// What is wrong with `T`'s checks (empty: every corruption rejected).
fn check_type<T: Message>(topic: &str) -> Vec<String> {
    let name = std::any::type_name::<T>();
    let m = valid::<T>();
    if let Err(r) = m.check() {
        return vec![format!(
            "{topic} ({name}): the valid message is rejected: {r:?}"
        )];
    }
    (Corruption::ALL.into_iter())
        .filter_map(|how| {
            let mut c = m;
            c.corrupt(how);
            c.check()
                .is_ok()
                .then(|| format!("{topic} ({name}): corrupted by {how:?}, accepted"))
        })
        .collect()
}

struct Check;

impl PayloadVisitor for Check {
    type Out = Vec<String>;
    fn frames(self, spec: &'static TopicSpec) -> Vec<String> {
        let h = valid_frame();
        if let Err(r) = h.validate(8) {
            return vec![format!("{}: the valid frame is rejected: {r:?}", spec.name)];
        }
        (Corruption::ALL.into_iter())
            .filter_map(|how| {
                let mut c = h;
                c.corrupt(how);
                (c.validate(8).is_ok())
                    .then(|| format!("{}: corrupted by {how:?}, accepted", spec.name))
            })
            .collect()
    }
    fn messages<T: Message>(self, spec: &'static TopicSpec) -> Vec<String> {
        check_type::<T>(spec.name)
    }
    fn calls<Req: Message, Resp: Message>(self, spec: &'static TopicSpec) -> Vec<String> {
        let mut v = check_type::<Req>(spec.name);
        v.extend(check_type::<Resp>(spec.name));
        v
    }
}

#[test]
fn every_message_type_corrupted_in_every_mode_is_rejected_by_its_check() {
    let failures: Vec<String> = TOPICS.iter().flat_map(|t| visit(t.id, Check)).collect();
    assert!(failures.is_empty(), "{failures:#?}");
    assert!(TOPICS.len() >= 16, "every topic of the table was visited");
}

#[test]
fn a_wrong_length_or_a_size_out_of_range_is_rejected_in_a_frame() {
    let h = valid_frame();
    assert!(h.validate(8).is_ok());
    assert!(h.validate(7).is_err(), "a payload one pixel short");
    assert!(h.validate(9).is_err(), "a payload one pixel long");
    let mut wide = h;
    wide.width_px = 16385;
    assert!(wide.validate(16385 * 2).is_err(), "past 16384 px");
    let mut empty = h;
    empty.height_px = 0;
    assert!(empty.validate(0).is_err());
}
