//! Every wire type's layout as data: its contract type name, size, alignment, and each
//! field's name, offset, size and Rust type (nested types by their own name). A recording
//! (`glint run --record`) carries it in each channel's schema so that a reader without glint
//! decodes the bytes; the test below holds every description to the type itself (the fields
//! cover every byte, in order: the types have no implicit padding).

use std::mem::{align_of, offset_of, size_of};

use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

use super::*;

/// One field of a wire type.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FieldLayout {
    pub name: String,
    pub offset: usize,
    pub size: usize,
    /// The Rust type without paths: `u64`, `[f64; 3]`, `Meta`, `[Detection; 32]`.
    #[serde(rename = "type")]
    pub ty: String,
}

/// One wire type: `#[repr(C)]`, little-endian, explicit padding.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TypeLayout {
    /// The Rust name (what a field's `type` names) and the contract type name.
    pub name: String,
    pub contract_name: String,
    pub size: usize,
    pub align: usize,
    pub fields: Vec<FieldLayout>,
}

/// A Rust type name without its paths.
fn short(mut s: String) -> String {
    while let Some(i) = s.find("::") {
        let start = s[..i]
            .rfind(|c: char| !(c.is_alphanumeric() || c == '_'))
            .map_or(0, |j| j + 1);
        s.replace_range(start..i + 2, "");
    }
    s
}

fn type_of<F>(_: &F) -> String {
    short(std::any::type_name::<F>().to_string())
}

macro_rules! layout {
    ($t:ident { $($f:ident),* $(,)? }) => {{
        let z: $t = bytemuck::Zeroable::zeroed();
        TypeLayout {
            name: stringify!($t).to_string(),
            // SAFETY: `type_name` only returns the `#[type_name]` string.
            contract_name: unsafe { <$t as ZeroCopySend>::type_name() }.to_string(),
            size: size_of::<$t>(),
            align: align_of::<$t>(),
            fields: vec![$(FieldLayout {
                name: stringify!($f).to_string(),
                offset: offset_of!($t, $f),
                size: std::mem::size_of_val(&z.$f),
                ty: type_of(&z.$f),
            }),*],
        }
    }};
}

/// Every wire type's layout.
pub fn layouts() -> Vec<TypeLayout> {
    vec![
        layout!(FrameHeader {
            meta,
            frame_index,
            exposure_start_ns,
            exposure_ns,
            interval_ns,
            pixels_xxh3,
            width_px,
            height_px
        }),
        layout!(Detection {
            track_id,
            flags,
            x_px,
            y_px,
            end_x_px,
            end_y_px,
            area_px,
            a_px,
            b_px,
            theta_rad,
            eccentricity,
            flux_dn,
            azimuth_rad,
            elevation_rad,
            sigma_rad
        }),
        layout!(Detections {
            meta,
            frame_index,
            exposure_end_ns,
            n,
            blobs_found,
            rejected,
            _pad,
            items
        }),
        layout!(TrackEstimate {
            track_id,
            status,
            range_status,
            angles_valid,
            azimuth_meas_rad,
            elevation_meas_rad,
            azimuth_filt_rad,
            elevation_filt_rad,
            range_meas_m,
            pointing_azimuth_rad,
            pointing_elevation_rad,
            state_lvlh,
            covariance,
            direct_position_m,
            ekf_valid,
            _pad2,
            state_t_ns
        }),
        layout!(Tracks {
            meta,
            frame_index,
            n,
            range_timeouts,
            items
        }),
        layout!(EarthMethod {
            beta_deg,
            tilt_deg,
            time_us,
            valid,
            undetermined
        }),
        layout!(EarthAttitude {
            meta,
            frame_index,
            edge_points,
            samples,
            fit_mu_deg,
            fit_sigma_deg,
            fit_nu,
            methods,
            samples_hist
        }),
        layout!(TopicCounters {
            topic,
            duplicates,
            published,
            received,
            dropped,
            next_seq
        }),
        layout!(ServiceTime {
            busy_ns,
            credit_wait_ns,
            idle_ns,
            publish_ns,
            checksum_ns,
            rpc_wait_ns
        }),
        layout!(Heartbeat {
            meta,
            pid,
            state,
            last_latency_ns,
            topics,
            time,
            faults_obeyed,
            faults_refused,
            delaying,
            _reserved
        }),
        layout!(Ack {
            meta,
            topic,
            consumer,
            next_seq,
            checkpoint_seq
        }),
        layout!(Control {
            meta,
            command,
            target,
            arg
        }),
        layout!(Meta {
            seq,
            t_ns,
            send_mono_ns,
            contract_version,
            producer
        }),
        layout!(PhotometrySample {
            meta,
            sample_index,
            status,
            _pad,
            mag,
            sigma_mag,
            sun,
            obs,
            range_m
        }),
        layout!(PhotometryMatch {
            geometry,
            _pad,
            score,
            area_scale,
            area_m2,
            axis,
            spin_rad_s,
            t0_s
        }),
        layout!(PhotometryEstimate {
            meta,
            sample_index,
            status,
            n_matching,
            matching,
            q_ib,
            w_body_rad_s,
            covariance,
            updated,
            fallbacks,
            restarts,
            _pad
        }),
        layout!(RangeRequest {
            meta,
            request_id,
            azimuth_rad,
            elevation_rad,
            track_id,
            _pad
        }),
        layout!(RangeResponse {
            meta,
            request_id,
            range_m,
            status,
            track_id
        }),
        layout!(Spectrum {
            meta,
            frame_index,
            window,
            n_bands,
            sun_body,
            observer_body,
            range_m,
            phase_rad,
            wavelength_nm,
            flux_w,
            sigma_w,
            content_xxh3
        }),
        layout!(SolveRequest {
            meta,
            request_id,
            stage,
            flags
        }),
        layout!(SolveResponse {
            meta,
            request_id,
            stage,
            status,
            n_bands,
            chosen_band,
            stable_samples,
            motion_samples,
            recon_err,
            separation,
            flags,
            unobservable_reason,
            held_axes,
            observable_mask,
            fitted_frames,
            iterations,
            rate_deg_per_frame,
            covariance,
            fisher_eigenvectors,
            bound_1sigma_deg_per_frame,
            mirror_deg_per_frame,
            band_status,
            band_unobservable_reason,
            band_rate_deg_per_frame,
            recon_coefficients,
            rate_coefficients,
            refit_lobes
        }),
        layout!(StereoFeature { feature, _pad, z }),
        layout!(Stereo {
            meta,
            epoch_index,
            n_features,
            _pad,
            features
        }),
        layout!(RelNavEstimate {
            meta,
            epoch_index,
            status,
            used,
            rejected,
            dof,
            nis,
            q_ct,
            w_t_rad_s,
            k,
            rho_o_m,
            v_o_m_s,
            covariance,
            starts,
            diverged,
            numerical_failures,
            _pad
        }),
        layout!(Truth {
            meta,
            kind,
            n_debris,
            frame_index,
            debris_state_lvlh,
            attitude_body_rest,
            rate_deg_per_frame,
            window,
            n_false,
            false_targets_px,
            earth_beta_deg,
            earth_tilt_deg,
            target_state
        }),
    ]
}

/// The layout of the type named `name` (Rust or contract name) and of every type its fields
/// name, itself first.
pub fn layout_with_nested(name: &str) -> Vec<TypeLayout> {
    let all = layouts();
    let mut out: Vec<TypeLayout> = vec![];
    let mut todo: Vec<String> = vec![name.to_string()];
    while let Some(n) = todo.pop() {
        let Some(t) = all.iter().find(|t| t.name == n || t.contract_name == n) else {
            continue;
        };
        if out.iter().any(|o| o.name == t.name) {
            continue;
        }
        for f in &t.fields {
            let inner = f.ty.trim_start_matches('[').split(';').next().unwrap_or("");
            todo.push(inner.trim_end_matches(']').to_string());
        }
        out.push(t.clone());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each description covers its type's every byte, field after field, and names its nested
    /// types by descriptions that exist.
    #[test]
    fn every_layout_covers_its_type() {
        let all = layouts();
        for t in &all {
            let mut at = 0;
            for f in &t.fields {
                assert_eq!(
                    f.offset, at,
                    "{}.{}: a gap or a field out of order",
                    t.name, f.name
                );
                at += f.size;
            }
            assert_eq!(
                at, t.size,
                "{}: fields end at {at} of {} bytes",
                t.name, t.size
            );
            assert!(
                t.contract_name.starts_with("glint.v"),
                "{}",
                t.contract_name
            );
        }
        let spectrum = layout_with_nested("glint.v8.Detections");
        let names: Vec<&str> = spectrum.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names[0], "Detections");
        assert!(
            names.contains(&"Meta") && names.contains(&"Detection"),
            "{names:?}"
        );
        let d = &spectrum[0]
            .fields
            .iter()
            .find(|f| f.name == "items")
            .unwrap()
            .ty;
        assert_eq!(d, &format!("[Detection; {MAX_DETECTIONS}]"));
    }
}
