//! The laser rangefinder served by a real sensor process over iceoryx2 request/response: this
//! test plays the orchestrator (creates the services, spawns `glint service sensor`) and the
//! tracker (sends range requests), and checks the answers against the CW truth.

mod common;

use std::process::Stdio;
use std::time::{Duration, Instant};

use common::*;
use glint_physics::camera::angles_from_position;
use glint_physics::cw::propagate_lvlhn;
use glint_physics::orbit::MU_EARTH_M3_S2;
use glint_runtime::ports::Inbox;
use glint_runtime::rpc::{CallOutcome, RangeClient};
use glint_runtime::{open_node, remove_shm, shm_entries};
use nalgebra::{Vector3, Vector6};
use rustix::process::{kill_process, Pid, Signal};
use shared_types::topics::create_all;
use shared_types::{Heartbeat, RangeRequest, RangeStatus, Scenario, ServiceId, TopicId};

struct KillOnDrop(std::process::Child);
impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn sensor_answers_range_requests_against_truth() {
    let prefix = format!("glt{}l_", std::process::id() % 100_000);
    let file = scenario("debris-geo.toml");
    let sc = Scenario::from_file(&file).unwrap();
    let cam = sc.camera.as_ref().unwrap();
    {
        let node = open_node(&prefix, "test-orchestrator").unwrap();
        let _services = create_all(&node, &sc).unwrap();
        let (mut hb, _l) = Inbox::<Heartbeat>::open(&node, TopicId::Heartbeat).unwrap();
        let mut sensor = KillOnDrop(
            glint()
                .args(["service", "sensor", "--prefix", &prefix, "--scenario"])
                .arg(&file)
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        );
        // Ready = a heartbeat from the sensor process.
        let t0 = Instant::now();
        let mut ready = false;
        while !ready && t0.elapsed() < Duration::from_secs(20) {
            hb.drain(|r| {
                ready |= r.msg.meta.producer == ServiceId::Sensor as u32
                    && r.msg.state >= Heartbeat::READY;
                Ok(())
            })
            .unwrap();
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(ready, "sensor never became ready");

        let mut client = RangeClient::open(&node, ServiceId::Tracker).unwrap();
        let a_m = cam.orbit_semi_major_axis_km * 1e3;
        let n = (MU_EARTH_M3_S2 / (a_m * a_m * a_m)).sqrt();
        let d = &cam.debris[3];
        let x0 = Vector6::new(d.x_m, d.y_m, d.z_m, d.vx_mps, d.vy_mps, d.vz_mps);
        let t_ns = 400_000_000u64; // fire at 0.4 s
        let echo_s = 0.4 + cam.laser.delay_s;
        let truth = propagate_lvlhn(x0, n, echo_s);
        let r = Vector3::new(truth[0], truth[1], truth[2]);
        let (az, el) = angles_from_position(r);
        let mut hits = vec![];
        for _ in 0..20 {
            let req = RangeRequest {
                azimuth_rad: az,
                elevation_rad: el,
                track_id: 4,
                ..Default::default()
            };
            match client
                .call(&node, req, t_ns, Duration::from_secs(5))
                .unwrap()
            {
                CallOutcome::Answered(resp) => {
                    assert_eq!(resp.status, RangeStatus::Hit as u32);
                    assert_eq!(resp.track_id, 4);
                    assert_eq!(
                        resp.meta.t_ns,
                        t_ns + (cam.laser.delay_s * 1e9).round() as u64
                    );
                    hits.push(resp.range_m - r.norm());
                }
                other => panic!("no answer: {other:?}"),
            }
        }
        // Errors are the rangefinder noise: zero mean, σ = 0.1/3 m.
        let sigma = cam.laser.range_sigma_m;
        let mean = hits.iter().sum::<f64>() / hits.len() as f64;
        assert!(hits.iter().all(|e| e.abs() < 5.0 * sigma), "{hits:?}");
        assert!(
            mean.abs() < 4.0 * sigma / (hits.len() as f64).sqrt(),
            "mean error {mean}"
        );
        // Pointing 1° off every debris: a miss.
        let req = RangeRequest {
            azimuth_rad: az + 1f64.to_radians(),
            elevation_rad: el + 1f64.to_radians(),
            ..Default::default()
        };
        match client
            .call(&node, req, t_ns, Duration::from_secs(5))
            .unwrap()
        {
            CallOutcome::Answered(resp) => assert_eq!(resp.status, RangeStatus::Miss as u32),
            other => panic!("no answer: {other:?}"),
        }
        // A malformed request is rejected, not trusted.
        let req = RangeRequest {
            azimuth_rad: f64::NAN,
            elevation_rad: 0.0,
            ..Default::default()
        };
        match client
            .call(&node, req, t_ns, Duration::from_secs(5))
            .unwrap()
        {
            CallOutcome::Answered(resp) => assert_eq!(resp.status, RangeStatus::Rejected as u32),
            other => panic!("no answer: {other:?}"),
        }
        // SIGTERM ends the service cleanly.
        kill_process(Pid::from_child(&sensor.0), Signal::TERM).expect("SIGTERM");
        let status = sensor.0.wait().unwrap();
        assert!(status.success(), "{status}");
    }
    remove_shm(&prefix);
    assert!(shm_entries(&prefix).is_empty());
}
