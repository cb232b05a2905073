//! `glint bench ipc`'s run: every transport at every payload size, the ratios that answer
//! what zero-copy buys, the table, `bench.json`, the CSV and the latency plot.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::json;

use super::ipc::{self, Row, Transport};
use super::{host, merge_bench_json};
use crate::plots::{self, Series};

/// Options of `glint bench ipc`.
pub struct IpcOptions {
    pub out: PathBuf,
    pub transports: Vec<Transport>,
    pub sizes: Vec<usize>,
    /// Multiplies the number of round trips per size.
    pub scale: f64,
}

/// Runs every (transport, size), writes `bench.json`, `ipc.csv` and the plots, prints the table.
pub fn run_ipc(o: &IpcOptions) -> Result<()> {
    std::fs::create_dir_all(&o.out).with_context(|| format!("creating {}", o.out.display()))?;
    let cases: Vec<(Transport, usize)> = o
        .transports
        .iter()
        .flat_map(|t| o.sizes.iter().map(move |s| (*t, *s)))
        .collect();
    let bar = crate::progress::bar(cases.len() as u64);
    bar.set_message("transports × sizes");
    let mut rows = vec![];
    for (t, bytes) in &cases {
        let samples = ipc::samples_for(*bytes, o.scale);
        let row = ipc::measure(*t, *bytes, samples)
            .with_context(|| format!("{} with {} payloads", t.name(), size_label(*bytes)))?;
        rows.push(row);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let ratios = ratios(&rows);
    print_table(&rows, &ratios);
    write_outputs(&o.out, &rows, &ratios)?;
    println!("\n{}", o.out.join("bench.json").display());
    Ok(())
}

fn size_label(bytes: usize) -> String {
    match bytes {
        b if b >= 1 << 20 && b % (1 << 20) == 0 => format!("{} MiB", b >> 20),
        b if b >= 1 << 10 && b % (1 << 10) == 0 => format!("{} KiB", b >> 10),
        b => format!("{b} B"),
    }
}

fn find(rows: &[Row], t: Transport, bytes: usize) -> Option<&Row> {
    rows.iter()
        .find(|r| r.transport == t.name() && r.payload_bytes == bytes)
}

/// What zero-copy buys, as ratios of medians in this run.
#[derive(Debug, Default, serde::Serialize)]
pub struct Ratios {
    /// iceoryx2 (woken): p50 of the 2 MiB hop / p50 of the 8-byte hop.
    pub iceoryx2_2mib_over_8b: Option<f64>,
    /// p50 of the 2 MiB hop: Unix socket / iceoryx2 (woken).
    pub uds_over_iceoryx2_2mib: Option<f64>,
    /// p50 of the 2 MiB hop: Unix socket / iceoryx2 (spinning).
    pub uds_over_iceoryx2_spin_2mib: Option<f64>,
    /// p50 of the 2 MiB hop: TCP / iceoryx2 (woken).
    pub tcp_over_iceoryx2_2mib: Option<f64>,
}

fn ratios(rows: &[Row]) -> Ratios {
    let p50 = |t, b| find(rows, t, b).map(|r| r.p50_us);
    let ratio = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) if b > 0.0 => Some(a / b),
        _ => None,
    };
    let mib2 = 2 << 20;
    Ratios {
        iceoryx2_2mib_over_8b: ratio(p50(Transport::Iceoryx2, mib2), p50(Transport::Iceoryx2, 8)),
        uds_over_iceoryx2_2mib: ratio(p50(Transport::Uds, mib2), p50(Transport::Iceoryx2, mib2)),
        uds_over_iceoryx2_spin_2mib: ratio(
            p50(Transport::Uds, mib2),
            p50(Transport::Iceoryx2Spin, mib2),
        ),
        tcp_over_iceoryx2_2mib: ratio(p50(Transport::Tcp, mib2), p50(Transport::Iceoryx2, mib2)),
    }
}

fn print_table(rows: &[Row], r: &Ratios) {
    let x = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.1}×"));
    println!(
        "2 MiB hop: iceoryx2 {} faster than a Unix socket ({} spinning), {} faster than TCP; \
         its 2 MiB hop costs {} its 8-byte hop",
        x(r.uds_over_iceoryx2_2mib),
        x(r.uds_over_iceoryx2_spin_2mib),
        x(r.tcp_over_iceoryx2_2mib),
        x(r.iceoryx2_2mib_over_8b),
    );
    println!("\none-way latency [µs], one message in flight; payload written by the sender, read by the receiver\n");
    println!(
        "{:<14} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>9} {:>11}",
        "transport", "payload", "samples", "p50", "p90", "p99", "p99.9", "max", "msgs/s"
    );
    for row in rows {
        println!(
            "{:<14} {:>8} {:>8} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>11.0}",
            row.transport,
            size_label(row.payload_bytes),
            row.samples,
            row.p50_us,
            row.p90_us,
            row.p99_us,
            row.p999_us,
            row.max_us,
            row.msgs_per_s
        );
    }
}

fn write_outputs(dir: &Path, rows: &[Row], r: &Ratios) -> Result<()> {
    let doc = json!({
        "glint_version": env!("CARGO_PKG_VERSION"),
        "host": host(),
        "ipc": {
            "method": "ping-pong between two processes, one message in flight; one-way latency = receiver's CLOCK_MONOTONIC at receipt − sender's just before send; msgs_per_s = round trips per second",
            "rows": rows,
            "ratios": r,
        }
    });
    merge_bench_json(dir, doc)?;
    let mut csv = csv::Writer::from_path(dir.join("ipc.csv"))?;
    for row in rows {
        csv.serialize(row)?;
    }
    csv.flush()?;
    plot_latency(dir, rows)?;
    for row in rows {
        let size = size_label(row.payload_bytes);
        plots::log_histogram(
            &dir.join(format!(
                "ipc-hist-{}-{}.svg",
                row.transport,
                size.replace(' ', "")
            )),
            &format!("{} one-way latency, {size} payloads", row.transport),
            "log10 latency [µs]",
            &(row.latencies_us.iter())
                .map(|v| (*v, 1))
                .collect::<Vec<_>>(),
        )?;
    }
    Ok(())
}

fn plot_latency(dir: &Path, rows: &[Row]) -> Result<()> {
    let colors = [plots::BLUE, plots::GREEN, plots::RED, plots::ORANGE];
    let mut series = vec![];
    for (t, color) in Transport::ALL.iter().zip(colors) {
        let points: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.transport == t.name())
            .map(|r| ((r.payload_bytes as f64).log10(), r.p50_us.log10()))
            .collect();
        if !points.is_empty() {
            series.push(Series {
                label: t.name(),
                points,
                color,
                markers: false,
            });
        }
    }
    plots::line_chart(
        &dir.join("ipc-latency.svg"),
        "one-way latency (median) against payload size",
        "log10 payload [bytes]",
        "log10 p50 latency [µs]",
        &series,
    )
}
