//! System tests: the real `glint` binary deploys real service processes that exchange frames
//! and spectra through iceoryx2 shared memory. No transport is mocked.

mod common;

use common::*;

#[test]
fn default_run_accounts_for_every_message_across_processes() {
    let dir = temp_dir("default");
    let r = run_ok(None, &dir, &[]);
    assert!(
        r.output.status.success(),
        "glint run failed: {}\n{}",
        String::from_utf8_lossy(&r.output.stderr),
        std::fs::read_to_string(dir.join("summary.md")).unwrap_or_default()
    );
    let rep = &r.typed;
    assert!(rep.results.success);
    assert!(rep.results.accounting.invariant_held);

    // Distinct OS processes: the sensor is neither this test nor the orchestrator.
    let services = &rep.results.services;
    assert!(!services.is_empty());
    for s in services {
        let pid = rep.run.pids[&s.name];
        assert_ne!(pid, std::process::id());
        assert_ne!(pid, 0);
        assert_eq!(s.ending, "shutdown", "{s:?}");
    }

    // Every published frame and spectrum received intact (checksums verified on receipt).
    for (topic, expected) in [("frame", 50), ("spectrum", 480), ("truth", 530)] {
        let t = &rep.results.topics[topic];
        assert_eq!(t.published, Some(expected), "{topic}");
        let orchestrator = &t.consumers["orchestrator"];
        assert_eq!(orchestrator.received, Some(expected), "{topic}");
        assert_eq!(orchestrator.dropped, Some(0), "{topic}");
    }

    // Nothing left in shared memory.
    let prefix = &rep.run.prefix;
    assert!(prefix.starts_with("glint_"));
    assert!(shm_left(prefix).is_empty(), "{:?}", shm_left(prefix));
    assert!(rep.results.shared_memory.leftover.is_empty());
    assert!(dir.join("summary.md").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn same_seed_gives_identical_results_and_another_seed_differs() {
    let dirs = [temp_dir("det-a"), temp_dir("det-b"), temp_dir("det-c")];
    let a = run(None, &dirs[0], &["--seed", "7"]);
    let b = run(None, &dirs[1], &["--seed", "7"]);
    let c = run(None, &dirs[2], &["--seed", "8"]);
    for r in [&a, &b, &c] {
        assert!(
            r.output.status.success(),
            "{}",
            String::from_utf8_lossy(&r.output.stderr)
        );
    }
    assert_eq!(deterministic_part(&a.typed), deterministic_part(&b.typed));
    let ja = serde_json::to_string_pretty(&deterministic_part(&a.typed)).unwrap();
    let jb = serde_json::to_string_pretty(&deterministic_part(&b.typed)).unwrap();
    assert_eq!(ja.as_bytes(), jb.as_bytes());
    let digest = |r: &RunResult, t: &str| r.typed.results.topics[t].digest_xxh3.clone().unwrap();
    // Another seed: different noise in frames and spectra, same truth (truth has no noise).
    assert_ne!(digest(&a, "frame"), digest(&c, "frame"));
    assert_eq!(digest(&a, "truth"), digest(&c, "truth"));
    // The resolved scenario is written into the run directory and carries the seed.
    let resolved = std::fs::read_to_string(dirs[0].join("scenario.toml")).unwrap();
    assert!(resolved.contains("seed = 7"));
    for d in dirs {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn realtime_clock_accounts_for_every_frame() {
    let dir = temp_dir("realtime");
    let file = scenario_variant(
        "debris-geo.toml",
        &[
            ("seed = 2016", "seed = 2016\nclock = \"realtime\""),
            ("frames = 50", "frames = 25"),
        ],
        &dir,
    );
    // The run must succeed (every message accounted for), and every consumer of the frames —
    // the detector too, not only the orchestrator — received or dropped each one with a reason.
    let r = run_ok(Some(&file), &dir.join("out"), &[]);
    assert!(r.typed.results.success);
    assert_eq!(r.typed.results.scenario.clock, "realtime");
    let f = &r.typed.results.topics["frame"];
    assert_eq!(f.published, Some(25));
    for name in ["orchestrator", "detector"] {
        let c = &f.consumers[name];
        assert!(c.accounted, "{name}: {c:?}");
        assert_eq!(
            c.received.unwrap() + c.dropped.unwrap(),
            25,
            "{name}: {c:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs started in the same second never share a directory: two default runs started
/// together each get their own, and each report is of its own scenario (the seed each was
/// given). Before, both wrote `runs/<name>-<second>/` and one run read the other's scenario.
#[test]
fn runs_started_together_get_their_own_directories() {
    let dir = temp_dir("same-second");
    let start = |seed: &str| {
        glint()
            .current_dir(&dir)
            .args(["run", "--seed", seed])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (start("11"), start("12"));
    let mut seen = vec![];
    for (child, seed) in [(a, 11), (b, 12)] {
        let out = child.wait_with_output().unwrap();
        assert_success(&out);
        let summary = String::from_utf8_lossy(&out.stdout).trim().to_string();
        let run_dir = dir.join(std::path::Path::new(&summary).parent().unwrap());
        let report = read_report(&run_dir.join("report.json"));
        assert_eq!(report.results.seed, seed, "{}", run_dir.display());
        seen.push(run_dir);
    }
    assert_ne!(seen[0], seen[1]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--out` into a directory that holds files is refused (exit 2) unless `--force`, which
/// replaces a previous run and leaves none of its files; `--force` never clears a directory
/// that is not a run's.
#[test]
fn out_into_a_previous_run_needs_force_and_leaves_nothing_of_it() {
    let dir = temp_dir("out-reuse");
    let out = dir.join("run");
    run_ok(None, &out, &[]);
    std::fs::write(out.join("stale.txt"), "from before").unwrap();
    let again = glint().arg("run").arg("--out").arg(&out).output().unwrap();
    let err = String::from_utf8_lossy(&again.stderr);
    assert_eq!(again.status.code(), Some(2), "{err}");
    assert!(
        err.contains("already holds files") && err.contains("--force"),
        "{err}"
    );
    assert!(
        out.join("stale.txt").exists(),
        "a refused run touches nothing"
    );
    let r = run_ok(None, &out, &["--force"]);
    assert!(
        !out.join("stale.txt").exists(),
        "the previous run's files are gone"
    );
    assert!(r.typed.results.success);
    let other = dir.join("not-a-run");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "mine").unwrap();
    let refused = glint()
        .arg("run")
        .arg("--out")
        .arg(&other)
        .arg("--force")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{err}");
    assert!(err.contains("not a glint run directory"), "{err}");
    assert!(other.join("notes.txt").exists());
    let file = other.join("notes.txt");
    let onto_file = glint().arg("run").arg("--out").arg(&file).output().unwrap();
    let err = String::from_utf8_lossy(&onto_file.stderr);
    assert_eq!(onto_file.status.code(), Some(2), "{err}");
    assert!(err.contains("is a file, not a directory"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// No shared-memory file of a deployment is readable or writable by other users (iceoryx2
/// creates its global management segment 0666; glint restricts it to the owner).
#[test]
fn no_file_of_a_deployment_is_open_to_other_users() {
    use std::os::unix::fs::PermissionsExt;
    let prefix = "glint_0a11ce55_";
    let node = glint_runtime::open_node(prefix, "probe").expect("node");
    let files = glint_runtime::shm_entries(prefix);
    let in_shm: Vec<_> = files.iter().filter(|p| p.starts_with("/dev/shm")).collect();
    assert!(!in_shm.is_empty(), "{files:?}");
    for p in in_shm {
        let mode = std::fs::metadata(p).unwrap().permissions().mode();
        assert_eq!(mode & 0o077, 0, "{} is {:o}", p.display(), mode & 0o777);
    }
    drop(node);
    glint_runtime::remove_shm(prefix);
    assert!(glint_runtime::shm_entries(prefix).is_empty());
}

/// `[services.<name>] cpu`: the service runs on that CPU (its affinity read back in its log,
/// every frame accounted for, the science as unpinned); a CPU the host does not give glint is
/// refused before anything is deployed, naming the field and the CPUs there are.
#[test]
fn a_service_pinned_to_a_cpu_runs_there_and_a_missing_cpu_is_refused() {
    let dir = temp_dir("placement");
    let base = run_ok(Some(&scenario("debris-geo.toml")), &dir.join("base"), &[]);
    let pinned = dir.join("pinned.toml");
    let text = std::fs::read_to_string(scenario("debris-geo.toml")).unwrap();
    let cpu = first_allowed_cpu();
    std::fs::write(
        &pinned,
        format!("{text}\n[services.detector]\ncpu = {cpu}\n"),
    )
    .unwrap();
    let r = run_ok(Some(&pinned), &dir.join("pinned"), &[]);
    assert!(r.typed.results.success, "{:?}", r.typed.results.failure);
    let log = std::fs::read_to_string(r.dir.join("logs/detector.log")).unwrap();
    assert!(
        log.contains(&format!("detector pinned to CPU {cpu} cpus=[{cpu}]")),
        "{log}"
    );
    let sensor = std::fs::read_to_string(r.dir.join("logs/sensor.log")).unwrap();
    assert!(!sensor.contains("pinned"), "{sensor}");
    assert_eq!(
        r.typed.results.science.digest_xxh3,
        base.typed.results.science.digest_xxh3
    );

    std::fs::write(
        &pinned,
        format!("{text}\n[services.detector]\ncpu = 1023\n"),
    )
    .unwrap();
    let o = glint()
        .arg("run")
        .arg(&pinned)
        .arg("--out")
        .arg(dir.join("missing"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("services.detector.cpu") && stderr.contains("CPU 1023 is not one"),
        "{stderr}"
    );
    assert!(!dir.join("missing").join("report.json").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
