//! Pins the wire layout: size, alignment and every field offset of every message, and the
//! versioned type names. A change here is a contract change: bump `CONTRACT_VERSION`.

use std::mem::{align_of, offset_of, size_of};

use iceoryx2::prelude::ZeroCopySend;
use shared_types::*;

#[test]
fn meta_layout() {
    assert_eq!((size_of::<Meta>(), align_of::<Meta>()), (32, 8));
    assert_eq!(offset_of!(Meta, seq), 0);
    assert_eq!(offset_of!(Meta, t_ns), 8);
    assert_eq!(offset_of!(Meta, send_mono_ns), 16);
    assert_eq!(offset_of!(Meta, contract_version), 24);
    assert_eq!(offset_of!(Meta, producer), 28);
}

#[test]
fn frame_header_layout() {
    assert_eq!(
        (size_of::<FrameHeader>(), align_of::<FrameHeader>()),
        (80, 8)
    );
    assert_eq!(offset_of!(FrameHeader, frame_index), 32);
    assert_eq!(offset_of!(FrameHeader, exposure_start_ns), 40);
    assert_eq!(offset_of!(FrameHeader, exposure_ns), 48);
    assert_eq!(offset_of!(FrameHeader, interval_ns), 56);
    assert_eq!(offset_of!(FrameHeader, pixels_xxh3), 64);
    assert_eq!(offset_of!(FrameHeader, width_px), 72);
    assert_eq!(offset_of!(FrameHeader, height_px), 76);
}

#[test]
fn spectrum_layout() {
    assert_eq!((size_of::<Spectrum>(), align_of::<Spectrum>()), (1656, 8));
    assert_eq!(offset_of!(Spectrum, frame_index), 32);
    assert_eq!(offset_of!(Spectrum, window), 40);
    assert_eq!(offset_of!(Spectrum, n_bands), 44);
    assert_eq!(offset_of!(Spectrum, sun_body), 48);
    assert_eq!(offset_of!(Spectrum, observer_body), 72);
    assert_eq!(offset_of!(Spectrum, range_m), 96);
    assert_eq!(offset_of!(Spectrum, phase_rad), 104);
    assert_eq!(offset_of!(Spectrum, wavelength_nm), 112);
    assert_eq!(offset_of!(Spectrum, flux_w), 112 + 512);
    assert_eq!(offset_of!(Spectrum, sigma_w), 112 + 1024);
    assert_eq!(offset_of!(Spectrum, content_xxh3), 112 + 1536);
}

#[test]
fn truth_layout() {
    assert_eq!(
        (size_of::<Truth>(), align_of::<Truth>()),
        (1192 + 15 * 8, 8)
    );
    assert_eq!(offset_of!(Truth, kind), 32);
    assert_eq!(offset_of!(Truth, n_debris), 36);
    assert_eq!(offset_of!(Truth, frame_index), 40);
    assert_eq!(offset_of!(Truth, debris_state_lvlh), 48);
    assert_eq!(offset_of!(Truth, attitude_body_rest), 48 + 768);
    assert_eq!(offset_of!(Truth, rate_deg_per_frame), 888);
    assert_eq!(offset_of!(Truth, window), 912);
    assert_eq!(offset_of!(Truth, n_false), 916);
    assert_eq!(offset_of!(Truth, false_targets_px), 920);
    assert_eq!(offset_of!(Truth, earth_beta_deg), 1176);
    assert_eq!(offset_of!(Truth, earth_tilt_deg), 1184);
    assert_eq!(offset_of!(Truth, target_state), 1192);
}

#[test]
fn earth_attitude_layout() {
    assert_eq!(
        (size_of::<EarthMethod>(), align_of::<EarthMethod>()),
        (32, 8)
    );
    assert_eq!(offset_of!(EarthMethod, time_us), 16);
    assert_eq!(offset_of!(EarthMethod, valid), 24);
    assert_eq!(
        (size_of::<EarthAttitude>(), align_of::<EarthAttitude>()),
        (72 + 3 * 32 + 2 * 32, 8)
    );
    assert_eq!(offset_of!(EarthAttitude, frame_index), 32);
    assert_eq!(offset_of!(EarthAttitude, edge_points), 40);
    assert_eq!(offset_of!(EarthAttitude, samples), 44);
    assert_eq!(offset_of!(EarthAttitude, fit_mu_deg), 48);
    assert_eq!(offset_of!(EarthAttitude, methods), 72);
    assert_eq!(offset_of!(EarthAttitude, samples_hist), 72 + 3 * 32);
}

#[test]
fn stereo_and_relnav_layout() {
    assert_eq!(
        (size_of::<StereoFeature>(), align_of::<StereoFeature>()),
        (40, 8)
    );
    assert_eq!(offset_of!(StereoFeature, z), 8);
    assert_eq!(
        (size_of::<Stereo>(), align_of::<Stereo>()),
        (48 + 16 * 40, 8)
    );
    assert_eq!(offset_of!(Stereo, epoch_index), 32);
    assert_eq!(offset_of!(Stereo, n_features), 40);
    assert_eq!(offset_of!(Stereo, features), 48);
    assert_eq!(
        (size_of::<RelNavEstimate>(), align_of::<RelNavEstimate>()),
        (64 + 15 * 8 + 105 * 8 + 16, 8)
    );
    assert_eq!(offset_of!(RelNavEstimate, epoch_index), 32);
    assert_eq!(offset_of!(RelNavEstimate, status), 40);
    assert_eq!(offset_of!(RelNavEstimate, nis), 56);
    assert_eq!(offset_of!(RelNavEstimate, q_ct), 64);
    assert_eq!(offset_of!(RelNavEstimate, covariance), 64 + 15 * 8);
    assert_eq!(offset_of!(RelNavEstimate, starts), 64 + 120 + 840);
}

#[test]
fn photometry_layout() {
    assert_eq!(
        (
            size_of::<PhotometrySample>(),
            align_of::<PhotometrySample>()
        ),
        (120, 8)
    );
    assert_eq!(offset_of!(PhotometrySample, sample_index), 32);
    assert_eq!(offset_of!(PhotometrySample, status), 40);
    assert_eq!(offset_of!(PhotometrySample, mag), 48);
    assert_eq!(offset_of!(PhotometrySample, sun), 64);
    assert_eq!(offset_of!(PhotometrySample, obs), 88);
    assert_eq!(offset_of!(PhotometrySample, range_m), 112);
    assert_eq!(
        (size_of::<PhotometryMatch>(), align_of::<PhotometryMatch>()),
        (72, 8)
    );
    assert_eq!(offset_of!(PhotometryMatch, score), 8);
    assert_eq!(offset_of!(PhotometryMatch, axis), 32);
    assert_eq!(offset_of!(PhotometryMatch, t0_s), 64);
    assert_eq!(
        (
            size_of::<PhotometryEstimate>(),
            align_of::<PhotometryEstimate>()
        ),
        (864, 8)
    );
    assert_eq!(offset_of!(PhotometryEstimate, status), 40);
    assert_eq!(offset_of!(PhotometryEstimate, matching), 48);
    assert_eq!(offset_of!(PhotometryEstimate, q_ib), 48 + 8 * 72);
    assert_eq!(offset_of!(PhotometryEstimate, covariance), 48 + 576 + 56);
    assert_eq!(offset_of!(PhotometryEstimate, updated), 680 + 168);
}

#[test]
fn detections_and_tracks_layout() {
    assert_eq!((size_of::<Detection>(), align_of::<Detection>()), (112, 8));
    assert_eq!(offset_of!(Detection, x_px), 8);
    assert_eq!(offset_of!(Detection, end_x_px), 24);
    assert_eq!(offset_of!(Detection, area_px), 40);
    assert_eq!(offset_of!(Detection, azimuth_rad), 88);
    assert_eq!(offset_of!(Detection, sigma_rad), 104);
    assert_eq!(
        (size_of::<Detections>(), align_of::<Detections>()),
        (64 + 32 * 112, 8)
    );
    assert_eq!(offset_of!(Detections, frame_index), 32);
    assert_eq!(offset_of!(Detections, exposure_end_ns), 40);
    assert_eq!(offset_of!(Detections, n), 48);
    assert_eq!(offset_of!(Detections, items), 64);
    assert_eq!(
        (size_of::<TrackEstimate>(), align_of::<TrackEstimate>()),
        (448, 8)
    );
    assert_eq!(offset_of!(TrackEstimate, azimuth_meas_rad), 16);
    assert_eq!(offset_of!(TrackEstimate, range_meas_m), 48);
    assert_eq!(offset_of!(TrackEstimate, state_lvlh), 72);
    assert_eq!(offset_of!(TrackEstimate, covariance), 120);
    assert_eq!(offset_of!(TrackEstimate, direct_position_m), 408);
    assert_eq!(offset_of!(TrackEstimate, ekf_valid), 432);
    assert_eq!(offset_of!(TrackEstimate, state_t_ns), 440);
    assert_eq!(
        (size_of::<Tracks>(), align_of::<Tracks>()),
        (48 + 16 * 448, 8)
    );
    assert_eq!(offset_of!(Tracks, items), 48);
}

#[test]
fn range_layout() {
    assert_eq!(
        (size_of::<RangeRequest>(), align_of::<RangeRequest>()),
        (64, 8)
    );
    assert_eq!(offset_of!(RangeRequest, request_id), 32);
    assert_eq!(offset_of!(RangeRequest, azimuth_rad), 40);
    assert_eq!(offset_of!(RangeRequest, elevation_rad), 48);
    assert_eq!(offset_of!(RangeRequest, track_id), 56);
    assert_eq!(
        (size_of::<RangeResponse>(), align_of::<RangeResponse>()),
        (56, 8)
    );
    assert_eq!(offset_of!(RangeResponse, request_id), 32);
    assert_eq!(offset_of!(RangeResponse, range_m), 40);
    assert_eq!(offset_of!(RangeResponse, status), 48);
    assert_eq!(offset_of!(RangeResponse, track_id), 52);
}

#[test]
fn housekeeping_layout() {
    assert_eq!(
        (size_of::<TopicCounters>(), align_of::<TopicCounters>()),
        (96, 8)
    );
    assert_eq!(offset_of!(TopicCounters, published), 8);
    assert_eq!(offset_of!(TopicCounters, received), 16);
    assert_eq!(offset_of!(TopicCounters, dropped), 24);
    assert_eq!(offset_of!(TopicCounters, next_seq), 88);
    assert_eq!((size_of::<Heartbeat>(), align_of::<Heartbeat>()), (880, 8));
    assert_eq!(offset_of!(Heartbeat, time), 816);
    assert_eq!(offset_of!(Heartbeat, faults_obeyed), 864);
    assert_eq!(offset_of!(Heartbeat, delaying), 872);
    assert_eq!(
        (size_of::<ServiceTime>(), align_of::<ServiceTime>()),
        (48, 8)
    );
    assert_eq!(offset_of!(ServiceTime, credit_wait_ns), 8);
    assert_eq!(offset_of!(ServiceTime, rpc_wait_ns), 40);
    assert_eq!(offset_of!(Heartbeat, pid), 32);
    assert_eq!(offset_of!(Heartbeat, state), 36);
    assert_eq!(offset_of!(Heartbeat, last_latency_ns), 40);
    assert_eq!(offset_of!(Heartbeat, topics), 48);
    assert_eq!((size_of::<Ack>(), align_of::<Ack>()), (56, 8));
    assert_eq!(offset_of!(Ack, checkpoint_seq), 48);
    assert_eq!(offset_of!(Ack, topic), 32);
    assert_eq!(offset_of!(Ack, consumer), 36);
    assert_eq!(offset_of!(Ack, next_seq), 40);
    assert_eq!((size_of::<Control>(), align_of::<Control>()), (56, 8));
    assert_eq!(offset_of!(Control, command), 32);
    assert_eq!(offset_of!(Control, target), 36);
    assert_eq!(offset_of!(Control, arg), 40);
}

#[test]
fn type_names_carry_the_contract_version() {
    let v = format!("glint.v{CONTRACT_VERSION}.");
    // SAFETY: `type_name` only returns the static name given by the derive macro.
    let names = unsafe {
        [
            <Meta as ZeroCopySend>::type_name(),
            <FrameHeader as ZeroCopySend>::type_name(),
            <Spectrum as ZeroCopySend>::type_name(),
            <Truth as ZeroCopySend>::type_name(),
            <RangeRequest as ZeroCopySend>::type_name(),
            <RangeResponse as ZeroCopySend>::type_name(),
            <Heartbeat as ZeroCopySend>::type_name(),
            <TopicCounters as ZeroCopySend>::type_name(),
            <ServiceTime as ZeroCopySend>::type_name(),
            <Ack as ZeroCopySend>::type_name(),
            <Control as ZeroCopySend>::type_name(),
            <Detection as ZeroCopySend>::type_name(),
            <Detections as ZeroCopySend>::type_name(),
            <TrackEstimate as ZeroCopySend>::type_name(),
            <Tracks as ZeroCopySend>::type_name(),
            <SolveRequest as ZeroCopySend>::type_name(),
            <SolveResponse as ZeroCopySend>::type_name(),
            <EarthMethod as ZeroCopySend>::type_name(),
            <EarthAttitude as ZeroCopySend>::type_name(),
            <StereoFeature as ZeroCopySend>::type_name(),
            <Stereo as ZeroCopySend>::type_name(),
            <RelNavEstimate as ZeroCopySend>::type_name(),
            <PhotometrySample as ZeroCopySend>::type_name(),
            <PhotometryMatch as ZeroCopySend>::type_name(),
            <PhotometryEstimate as ZeroCopySend>::type_name(),
        ]
    };
    for name in names {
        assert!(name.starts_with(&v), "{name} does not start with {v}");
    }
}

#[test]
fn spectrum_validation_rejects_corruption() {
    let mut s = Spectrum {
        meta: Meta::new(0, 0, 0, ServiceId::Sensor),
        n_bands: 2,
        sun_body: [1.0, 0.0, 0.0],
        observer_body: [0.0, 0.0, 1.0],
        range_m: 2.1e6,
        ..Default::default()
    };
    s.wavelength_nm[..2].copy_from_slice(&[650.0, 660.0]);
    s.flux_w[..2].copy_from_slice(&[1e-14, 2e-14]);
    s.seal();
    assert_eq!(s.check(), Ok(()));
    let mut bad = s;
    bad.flux_w[1] = f64::NAN;
    assert_eq!(bad.check().unwrap_err().field, "spectrum.flux_w");
    let mut bad = s;
    bad.flux_w[0] *= 1.0 + 1e-12; // a flipped bit, hash no longer matches
    assert_eq!(bad.check().unwrap_err().field, "spectrum.content_xxh3");
    let mut bad = s;
    bad.n_bands = 65;
    assert_eq!(bad.check().unwrap_err().field, "spectrum.n_bands");
    let mut bad = s;
    bad.meta.contract_version = 99;
    assert_eq!(bad.check().unwrap_err().field, "meta.contract_version");
}

#[test]
fn frame_header_validation_checks_payload_length() {
    let h = FrameHeader {
        meta: Meta::new(0, 0, 0, ServiceId::Sensor),
        width_px: 32,
        height_px: 16,
        exposure_ns: 1,
        ..Default::default()
    };
    assert!(h.validate(512).is_ok());
    assert_eq!(h.validate(511).unwrap_err().field, "frame.payload");
}

#[test]
fn solve_layout() {
    assert_eq!(
        (size_of::<SolveRequest>(), align_of::<SolveRequest>()),
        (48, 8)
    );
    assert_eq!(offset_of!(SolveRequest, request_id), 32);
    assert_eq!(offset_of!(SolveRequest, stage), 40);
    assert_eq!(offset_of!(SolveRequest, flags), 44);
    // The answer, ≤ 1.25 KiB: no lab notes on the wire (ADR 0035).
    assert_eq!(
        (size_of::<SolveResponse>(), align_of::<SolveResponse>()),
        (1208, 8)
    );
    assert!(size_of::<SolveResponse>() <= 1280);
    assert_eq!(offset_of!(SolveResponse, request_id), 32);
    assert_eq!(offset_of!(SolveResponse, stage), 40);
    assert_eq!(offset_of!(SolveResponse, status), 44);
    assert_eq!(offset_of!(SolveResponse, n_bands), 48);
    assert_eq!(offset_of!(SolveResponse, chosen_band), 52);
    assert_eq!(offset_of!(SolveResponse, stable_samples), 56);
    assert_eq!(offset_of!(SolveResponse, motion_samples), 60);
    assert_eq!(offset_of!(SolveResponse, recon_err), 64);
    assert_eq!(offset_of!(SolveResponse, separation), 320);
    assert_eq!(offset_of!(SolveResponse, flags), 576);
    assert_eq!(offset_of!(SolveResponse, unobservable_reason), 580);
    assert_eq!(offset_of!(SolveResponse, held_axes), 584);
    assert_eq!(offset_of!(SolveResponse, observable_mask), 588);
    assert_eq!(offset_of!(SolveResponse, fitted_frames), 592);
    assert_eq!(offset_of!(SolveResponse, iterations), 596);
    assert_eq!(offset_of!(SolveResponse, rate_deg_per_frame), 600);
    assert_eq!(offset_of!(SolveResponse, covariance), 624);
    assert_eq!(offset_of!(SolveResponse, fisher_eigenvectors), 696);
    assert_eq!(offset_of!(SolveResponse, bound_1sigma_deg_per_frame), 768);
    assert_eq!(offset_of!(SolveResponse, mirror_deg_per_frame), 792);
    assert_eq!(offset_of!(SolveResponse, band_status), 816);
    assert_eq!(offset_of!(SolveResponse, band_unobservable_reason), 820);
    assert_eq!(offset_of!(SolveResponse, band_rate_deg_per_frame), 824);
    assert_eq!(offset_of!(SolveResponse, recon_coefficients), 848);
    assert_eq!(offset_of!(SolveResponse, rate_coefficients), 1024);
    assert_eq!(offset_of!(SolveResponse, refit_lobes), 1200);
}
