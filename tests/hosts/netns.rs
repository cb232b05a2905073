//! Two network namespaces joined by a veth pair: the hosts of the link-cut and slow-link tests.

use std::path::{Path, PathBuf};

use super::common::procs::*;
use super::{small_frames, split};

/// Two network namespaces joined by a veth pair (`ip netns`, as root): the two hosts of a
/// split deployment on one machine, each with only its own address, and a link that can be
/// cut. `None` where this machine cannot make them (no root, no iproute2).
pub struct Namespaces {
    pub names: [String; 2],
    addrs: [String; 2],
    /// `board`'s end of the link.
    pub veth: String,
}

fn ip(args: &[&str]) -> bool {
    std::process::Command::new("ip")
        .args(args)
        .status()
        .is_ok_and(|s| s.success())
}

impl Namespaces {
    /// The pair numbered `k` (one per test of this process).
    pub fn new(k: u32) -> Option<Self> {
        let id = std::process::id() % 100_000;
        let names = [format!("glint-a{id}-{k}"), format!("glint-b{id}-{k}")];
        let veth = [format!("gla{id}-{k}"), format!("glb{id}-{k}")];
        let net = 10 + id % 200;
        let addrs = [format!("10.{net}.{k}.1"), format!("10.{net}.{k}.2")];
        let ns = Namespaces {
            names: names.clone(),
            addrs: addrs.clone(),
            veth: veth[0].clone(),
        };
        let made = ip(&["netns", "add", &names[0]])
            && ip(&["netns", "add", &names[1]])
            && ip(&[
                "link", "add", &veth[0], "type", "veth", "peer", "name", &veth[1],
            ])
            && (0..2).all(|i| {
                ip(&["link", "set", &veth[i], "netns", &names[i]])
                    && ip(&[
                        "-n",
                        &names[i],
                        "addr",
                        "add",
                        &format!("{}/24", addrs[i]),
                        "dev",
                        &veth[i],
                    ])
                    && ip(&["-n", &names[i], "link", "set", &veth[i], "up"])
                    && ip(&["-n", &names[i], "link", "set", "lo", "up"])
            });
        made.then_some(ns)
    }

    /// `glint run FILE --out OUT --host HOST` inside namespace `i`.
    pub fn run(&self, i: usize, file: &Path, out: &Path, host: &str) -> KillOnDrop {
        let stderr = std::fs::File::create(stderr_path(out)).unwrap();
        KillOnDrop(
            std::process::Command::new("ip")
                .args([
                    "netns",
                    "exec",
                    &self.names[i],
                    env!("CARGO_BIN_EXE_glint"),
                    "run",
                ])
                .arg(file)
                .arg("--out")
                .arg(out)
                .args(["--host", host])
                .stdout(std::process::Stdio::null())
                .stderr(stderr)
                .spawn()
                .expect("ip netns exec glint run"),
        )
    }

    /// Takes `board`'s end of the link down (`up` false) or up again; the wall clock then.
    /// The split scenario of `frames` 256² frames, its hosts at the namespaces' addresses.
    pub fn scenario(&self, dir: &Path, frames: u32) -> PathBuf {
        let file = split(dir, frames, "");
        small_frames(&file);
        let mut text = std::fs::read_to_string(&file).unwrap();
        // board's endpoint comes first in the file, ground's second
        text = text.replacen("127.0.0.1", &self.addrs[0], 1);
        text = text.replacen("127.0.0.1", &self.addrs[1], 1);
        std::fs::write(&file, &text).unwrap();
        file
    }

    pub fn link(&self, up: bool) -> u64 {
        let state = if up { "up" } else { "down" };
        assert!(ip(&[
            "-n",
            &self.names[0],
            "link",
            "set",
            &self.veth,
            state
        ]));
        unix_ms()
    }
}

impl Drop for Namespaces {
    fn drop(&mut self) {
        for n in &self.names {
            ip(&["netns", "del", n]);
        }
    }
}

pub fn unix_ms() -> u64 {
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH);
    now.unwrap().as_millis() as u64
}

/// `tc ARGS…` (iproute2's traffic control).
pub fn tc(args: &[&str]) -> bool {
    std::process::Command::new("tc")
        .args(args)
        .status()
        .is_ok_and(|s| s.success())
}
