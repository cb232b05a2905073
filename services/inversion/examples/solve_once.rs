//! The bench's three-stage solve (8 bands, stable window 720 samples, motion window 360
//! frames, rotation 0.25 deg/frame about Y), run a given number of times: a fixed amount of
//! work for an instruction count, which unlike wall-clock time does not depend on how busy
//! the machine is.
//!
//! ```sh
//! cargo build --release -p glint-inversion --example solve_once
//! valgrind --tool=callgrind target/release/examples/solve_once           # 8 bands, once
//! valgrind --tool=callgrind target/release/examples/solve_once joint     # with the joint fit
//! target/release/examples/solve_once joint 20                            # mean wall-clock
//! ```

#[path = "../tests/common/mod.rs"]
mod common;

use glint_inversion::{solve_three_stage, InversionConfig};
use std::hint::black_box;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let joint_fit = args.next().is_some_and(|a| a == "joint");
    let runs: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(1).max(1);
    let set = common::scenario(720, 360, [0.0, 0.25, 0.0]);
    let config = InversionConfig {
        joint_fit,
        ..InversionConfig::default()
    };
    let started = Instant::now();
    for _ in 0..runs {
        if let Err(e) = solve_three_stage(black_box(&set), black_box(&config)) {
            eprintln!("solve failed: {e}");
            std::process::exit(1);
        }
    }
    let ms = started.elapsed().as_secs_f64() * 1e3 / runs as f64;
    println!("{ms:.2} ms per solve over {runs} (joint fit: {joint_fit})");
}
