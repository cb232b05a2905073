//! `glint bench ipc`: one-way latency and message rate between two processes, per transport and
//! payload size, all in one run. The sender writes every payload (its sequence number, then a
//! fill byte) and the receiver reads every byte (xxh3 of the payload, returned and checked), so
//! no transport skips touching the bytes. One message is in flight at a time (ping-pong): the
//! latency is the receiver's `CLOCK_MONOTONIC` at receipt minus the sender's just before it
//! sent, both on one host.
//!
//! Transports: iceoryx2 publish-subscribe woken by an event (how glint's services wait),
//! iceoryx2 with the receiver spinning on `receive()`, a Unix domain socket, TCP on loopback.

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use shared_types::topics::{Ipc, IpcNode};

use glint_runtime::mono_ns;

/// Payload sizes of the table [bytes].
pub const SIZES: [usize; 6] = [8, 4 << 10, 64 << 10, 1 << 20, 2 << 20, 4 << 20];
/// Round trips discarded before measuring.
const WARMUP: u64 = 50;
/// How long one side waits for the other before giving up.
const PEER_TIMEOUT: Duration = Duration::from_secs(10);

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Transport {
    /// iceoryx2, the receiver woken by an event.
    Iceoryx2,
    /// iceoryx2, the receiver spinning on `receive()`.
    Iceoryx2Spin,
    /// Unix domain socket (stream).
    Uds,
    /// TCP on 127.0.0.1, Nagle off.
    Tcp,
}

impl Transport {
    pub const ALL: [Transport; 4] = [
        Transport::Iceoryx2,
        Transport::Iceoryx2Spin,
        Transport::Uds,
        Transport::Tcp,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Transport::Iceoryx2 => "iceoryx2",
            Transport::Iceoryx2Spin => "iceoryx2-spin",
            Transport::Uds => "uds",
            Transport::Tcp => "tcp",
        }
    }
}

/// The ping's header: which message, and when it was sent.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[type_name("glint.bench.Ping")]
#[repr(C)]
pub struct Ping {
    pub seq: u64,
    pub send_mono_ns: u64,
}

/// The receiver's answer: the payload's checksum and the one-way latency it measured.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[type_name("glint.bench.Pong")]
#[repr(C)]
pub struct Pong {
    pub seq: u64,
    pub checksum: u64,
    pub latency_ns: u64,
}

/// Marks the receiver's "ready" pong.
const READY: u64 = u64::MAX;

/// One measured (transport, size).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Row {
    pub transport: &'static str,
    pub payload_bytes: usize,
    pub samples: usize,
    pub p50_us: f64,
    pub p90_us: f64,
    pub p99_us: f64,
    pub p999_us: f64,
    pub max_us: f64,
    /// Round trips per second (one message in flight at a time).
    pub msgs_per_s: f64,
    /// Latencies [µs], for the histograms (not in bench.json).
    #[serde(skip)]
    pub latencies_us: Vec<f64>,
}

/// Round trips measured for a payload: fewer for big ones (each costs ~1 ms to fill and read).
pub fn samples_for(bytes: usize, scale: f64) -> u64 {
    let base = match bytes {
        0..=65_536 => 5000.0,
        65_537..=1_048_576 => 1500.0,
        _ => 800.0,
    };
    ((base * scale).round() as u64).max(20)
}

/// Writes message `seq` into `payload` and returns its checksum.
fn fill(payload: &mut [u8], seq: u64) -> u64 {
    payload.fill(seq as u8);
    let head = payload.len().min(8);
    payload[..head].copy_from_slice(&seq.to_le_bytes()[..head]);
    xxhash_rust::xxh3::xxh3_64(payload)
}

/// Nearest-rank percentile of sorted values.
fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

fn row(transport: Transport, bytes: usize, mut lat_us: Vec<f64>, elapsed: Duration) -> Row {
    let n = lat_us.len();
    let unsorted = lat_us.clone();
    lat_us.sort_by(f64::total_cmp);
    Row {
        transport: transport.name(),
        payload_bytes: bytes,
        samples: n,
        p50_us: percentile(&lat_us, 0.50),
        p90_us: percentile(&lat_us, 0.90),
        p99_us: percentile(&lat_us, 0.99),
        p999_us: percentile(&lat_us, 0.999),
        max_us: lat_us.last().copied().unwrap_or(f64::NAN),
        msgs_per_s: n as f64 / elapsed.as_secs_f64().max(1e-9),
        latencies_us: unsorted,
    }
}

/// What the receiver process is told.
pub struct PeerArgs {
    pub transport: Transport,
    pub count: u64,
    /// iceoryx2 prefix, socket path or TCP address.
    pub address: String,
}

/// Measures one (transport, size): spawns the receiver (`glint bench-peer`), runs the round
/// trips, checks every checksum.
pub fn measure(transport: Transport, bytes: usize, samples: u64) -> Result<Row> {
    let count = WARMUP + samples;
    match transport {
        Transport::Iceoryx2 | Transport::Iceoryx2Spin => {
            let prefix = crate::run::run_prefix();
            let result = iceoryx2_sender(transport, bytes, count, &prefix);
            let _ = glint_runtime::remove_shm(&prefix);
            result
        }
        Transport::Uds => {
            let path = std::env::temp_dir().join(format!(
                "glint-bench-{}-{}.sock",
                std::process::id(),
                bytes
            ));
            let _ = std::fs::remove_file(&path);
            let listener = std::os::unix::net::UnixListener::bind(&path)
                .with_context(|| format!("binding {}", path.display()))?;
            let mut child = spawn_peer(transport, count, &path.display().to_string())?;
            let result = accept_with_timeout(&mut child, || {
                listener.set_nonblocking(true)?;
                let (s, _) = listener.accept()?;
                s.set_nonblocking(false)?;
                Ok(s)
            })
            .and_then(|mut s| stream_sender(transport, &mut s, bytes, count));
            let _ = std::fs::remove_file(&path);
            finish_peer(child, result)
        }
        Transport::Tcp => {
            let listener = std::net::TcpListener::bind("127.0.0.1:0")?;
            let addr = listener.local_addr()?.to_string();
            let mut child = spawn_peer(transport, count, &addr)?;
            let result = accept_with_timeout(&mut child, || {
                listener.set_nonblocking(true)?;
                let (s, _) = listener.accept()?;
                s.set_nonblocking(false)?;
                s.set_nodelay(true)?;
                Ok(s)
            })
            .and_then(|mut s| stream_sender(transport, &mut s, bytes, count));
            finish_peer(child, result)
        }
    }
}

fn spawn_peer(t: Transport, count: u64, address: &str) -> Result<std::process::Child> {
    let exe = std::env::current_exe().context("locating the glint binary")?;
    std::process::Command::new(exe)
        .arg("bench-peer")
        .args(["--transport", t.name()])
        .args(["--count", &count.to_string()])
        .args(["--address", address])
        .stdin(std::process::Stdio::null())
        .spawn()
        .context("starting the receiver process")
}

/// Waits for the receiver to connect (polling a non-blocking accept), or for it to die.
fn accept_with_timeout<S>(
    child: &mut std::process::Child,
    mut accept: impl FnMut() -> std::io::Result<S>,
) -> Result<S> {
    let t0 = Instant::now();
    loop {
        match accept() {
            Ok(s) => return Ok(s),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) => return Err(e.into()),
        }
        if let Some(status) = child.try_wait()? {
            bail!("the receiver exited before connecting ({status})");
        }
        if t0.elapsed() > PEER_TIMEOUT {
            bail!("the receiver did not connect within {PEER_TIMEOUT:?}");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn finish_peer(mut child: std::process::Child, result: Result<Row>) -> Result<Row> {
    if result.is_err() {
        let _ = child.kill();
    }
    let status = child.wait()?;
    let row = result?;
    if !status.success() {
        bail!("the receiver failed ({status})");
    }
    Ok(row)
}

fn stream_sender(
    t: Transport,
    s: &mut (impl Read + Write),
    bytes: usize,
    count: u64,
) -> Result<Row> {
    let mut payload = vec![0u8; bytes];
    let mut lat_us = Vec::with_capacity(count as usize);
    let mut t0 = Instant::now();
    for seq in 0..count {
        if seq == WARMUP {
            t0 = Instant::now();
        }
        let checksum = fill(&mut payload, seq);
        let mut header = [0u8; 24];
        header[..8].copy_from_slice(&seq.to_le_bytes());
        header[16..].copy_from_slice(&(bytes as u64).to_le_bytes());
        header[8..16].copy_from_slice(&mono_ns().to_le_bytes());
        s.write_all(&header)?;
        s.write_all(&payload)?;
        let mut pong = [0u8; 24];
        s.read_exact(&mut pong)?;
        let word = |i: usize| u64::from_le_bytes(pong[8 * i..8 * i + 8].try_into().unwrap());
        check_pong(seq, checksum, word(0), word(1))?;
        if seq >= WARMUP {
            lat_us.push(word(2) as f64 * 1e-3);
        }
    }
    Ok(row(t, bytes, lat_us, t0.elapsed()))
}

fn check_pong(seq: u64, checksum: u64, got_seq: u64, got_checksum: u64) -> Result<()> {
    if got_seq != seq {
        bail!("message {seq}: the receiver answered for message {got_seq}");
    }
    if got_checksum != checksum {
        bail!("message {seq}: the receiver read different bytes (checksum {got_checksum:016x}, sent {checksum:016x})");
    }
    Ok(())
}

/// The receiver's side of a stream transport.
fn stream_receiver(s: &mut (impl Read + Write), count: u64) -> Result<()> {
    let mut payload = vec![];
    for _ in 0..count {
        let mut header = [0u8; 24];
        s.read_exact(&mut header)?;
        let word = |i: usize| u64::from_le_bytes(header[8 * i..8 * i + 8].try_into().unwrap());
        let (seq, sent_ns, len) = (word(0), word(1), word(2) as usize);
        payload.resize(len, 0);
        s.read_exact(&mut payload)?;
        let latency_ns = mono_ns().saturating_sub(sent_ns);
        let checksum = xxhash_rust::xxh3::xxh3_64(&payload);
        let mut pong = [0u8; 24];
        pong[..8].copy_from_slice(&seq.to_le_bytes());
        pong[8..16].copy_from_slice(&checksum.to_le_bytes());
        pong[16..].copy_from_slice(&latency_ns.to_le_bytes());
        s.write_all(&pong)?;
    }
    Ok(())
}

type PingService = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Ipc, [u8], Ping>;
type PongService = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Ipc, Pong, ()>;

struct Channels {
    ping: PingService,
    pong: PongService,
    ping_event: iceoryx2::service::port_factory::event::PortFactory<Ipc>,
    pong_event: iceoryx2::service::port_factory::event::PortFactory<Ipc>,
}

fn channels(node: &IpcNode) -> Result<Channels> {
    let name = |s: &str| ServiceName::new(s).map_err(|e| anyhow!("{e:?}"));
    let ping = node
        .service_builder(&name("bench/ping")?)
        .publish_subscribe::<[u8]>()
        .user_header::<Ping>()
        .max_publishers(1)
        .max_subscribers(1)
        .subscriber_max_buffer_size(2)
        .history_size(0)
        .open_or_create()
        .map_err(|e| anyhow!("ping service: {e:?}"))?;
    let pong = node
        .service_builder(&name("bench/pong")?)
        .publish_subscribe::<Pong>()
        .max_publishers(1)
        .max_subscribers(1)
        .subscriber_max_buffer_size(2)
        .history_size(0)
        .open_or_create()
        .map_err(|e| anyhow!("pong service: {e:?}"))?;
    let ping_event = node
        .service_builder(&name("bench/ping-event")?)
        .event()
        .open_or_create()
        .map_err(|e| anyhow!("ping event: {e:?}"))?;
    let pong_event = node
        .service_builder(&name("bench/pong-event")?)
        .event()
        .open_or_create()
        .map_err(|e| anyhow!("pong event: {e:?}"))?;
    Ok(Channels {
        ping,
        pong,
        ping_event,
        pong_event,
    })
}

/// Waits for the next message of `receive`: on the listener (woken), or spinning.
fn wait_for<T>(
    listener: &Listener<Ipc>,
    spin: bool,
    mut receive: impl FnMut() -> Result<Option<T>>,
) -> Result<T> {
    let t0 = Instant::now();
    loop {
        if let Some(x) = receive()? {
            return Ok(x);
        }
        if t0.elapsed() > PEER_TIMEOUT {
            bail!("no message within {PEER_TIMEOUT:?}");
        }
        if glint_runtime::lifeline::end_requested().is_some() {
            bail!("asked to end");
        }
        if spin {
            std::hint::spin_loop();
        } else {
            listener
                .timed_wait(|_| {}, Duration::from_millis(100))
                .map_err(|e| anyhow!("wait: {e:?}"))?;
        }
    }
}

fn notify(n: &Notifier<Ipc>) -> Result<()> {
    n.notify().map_err(|e| anyhow!("notify: {e:?}"))?;
    Ok(())
}

fn iceoryx2_sender(t: Transport, bytes: usize, count: u64, prefix: &str) -> Result<Row> {
    let spin = t == Transport::Iceoryx2Spin;
    let node = glint_runtime::open_node(prefix, "bench-sender")?;
    let ch = channels(&node)?;
    let publisher = ch
        .ping
        .publisher_builder()
        .initial_max_slice_len(bytes)
        .allocation_strategy(AllocationStrategy::Static)
        .create()
        .map_err(|e| anyhow!("ping publisher: {e:?}"))?;
    let subscriber = ch
        .pong
        .subscriber_builder()
        .create()
        .map_err(|e| anyhow!("pong subscriber: {e:?}"))?;
    let notifier = ch
        .ping_event
        .notifier_builder()
        .create()
        .map_err(|e| anyhow!("ping notifier: {e:?}"))?;
    let listener = ch
        .pong_event
        .listener_builder()
        .create()
        .map_err(|e| anyhow!("pong listener: {e:?}"))?;
    let child = spawn_peer(t, count, prefix)?;
    let receive = || -> Result<Option<Pong>> {
        Ok(subscriber
            .receive()
            .map_err(|e| anyhow!("pong receive: {e:?}"))?
            .map(|s| *s.payload()))
    };
    let run = || -> Result<Row> {
        let ready = wait_for(&listener, false, receive)?;
        if ready.seq != READY {
            bail!("the receiver's first answer was not 'ready'");
        }
        let mut lat_us = Vec::with_capacity(count as usize);
        let mut t0 = Instant::now();
        for seq in 0..count {
            if seq == WARMUP {
                t0 = Instant::now();
            }
            let mut sample = publisher
                .loan_slice_uninit(bytes)
                .map_err(|e| anyhow!("loan: {e:?}"))?;
            // The payload is written in place in the loaned shared memory.
            let uninit = sample.payload_mut();
            // SAFETY: mapped shared memory is initialised at the OS level (fresh pages are
            // zero-filled, reused samples hold earlier pings) and every bit pattern is a valid
            // u8; `fill` then writes every byte before `assume_init`.
            let payload: &mut [u8] = unsafe {
                std::slice::from_raw_parts_mut(uninit.as_mut_ptr() as *mut u8, uninit.len())
            };
            let checksum = fill(payload, seq);
            // SAFETY: see above.
            let mut sample = unsafe { sample.assume_init() };
            *sample.user_header_mut() = Ping {
                seq,
                send_mono_ns: mono_ns(),
            };
            sample.send().map_err(|e| anyhow!("send: {e:?}"))?;
            if !spin {
                notify(&notifier)?;
            }
            let pong = wait_for(&listener, spin, receive)?;
            check_pong(seq, checksum, pong.seq, pong.checksum)?;
            if seq >= WARMUP {
                lat_us.push(pong.latency_ns as f64 * 1e-3);
            }
        }
        Ok(row(t, bytes, lat_us, t0.elapsed()))
    };
    let result = run();
    finish_peer(child, result)
}

fn iceoryx2_receiver(t: Transport, count: u64, prefix: &str) -> Result<()> {
    let spin = t == Transport::Iceoryx2Spin;
    let node = glint_runtime::open_node(prefix, "bench-receiver")?;
    let ch = channels(&node)?;
    let subscriber = ch
        .ping
        .subscriber_builder()
        .create()
        .map_err(|e| anyhow!("ping subscriber: {e:?}"))?;
    let publisher = ch
        .pong
        .publisher_builder()
        .create()
        .map_err(|e| anyhow!("pong publisher: {e:?}"))?;
    let notifier = ch
        .pong_event
        .notifier_builder()
        .create()
        .map_err(|e| anyhow!("pong notifier: {e:?}"))?;
    let listener = ch
        .ping_event
        .listener_builder()
        .create()
        .map_err(|e| anyhow!("ping listener: {e:?}"))?;
    let answer = |pong: Pong| -> Result<()> {
        publisher
            .send_copy(pong)
            .map_err(|e| anyhow!("pong send: {e:?}"))?;
        notify(&notifier)
    };
    answer(Pong {
        seq: READY,
        ..Default::default()
    })?;
    for _ in 0..count {
        let pong = wait_for(&listener, spin, || {
            let Some(sample) = subscriber
                .receive()
                .map_err(|e| anyhow!("ping receive: {e:?}"))?
            else {
                return Ok(None);
            };
            let latency_ns = mono_ns().saturating_sub(sample.user_header().send_mono_ns);
            // Read in place: every byte of the shared-memory sample.
            Ok(Some(Pong {
                seq: sample.user_header().seq,
                checksum: xxhash_rust::xxh3::xxh3_64(sample.payload()),
                latency_ns,
            }))
        })?;
        answer(pong)?;
    }
    Ok(())
}

/// `glint bench-peer`: the receiving process of one measurement.
pub fn peer(args: PeerArgs) -> Result<()> {
    match args.transport {
        Transport::Iceoryx2 | Transport::Iceoryx2Spin => {
            iceoryx2_receiver(args.transport, args.count, &args.address)
        }
        Transport::Uds => {
            let mut s = std::os::unix::net::UnixStream::connect(&args.address)
                .with_context(|| format!("connecting to {}", args.address))?;
            stream_receiver(&mut s, args.count)
        }
        Transport::Tcp => {
            let mut s = std::net::TcpStream::connect(&args.address)
                .with_context(|| format!("connecting to {}", args.address))?;
            s.set_nodelay(true)?;
            stream_receiver(&mut s, args.count)
        }
    }
}

/// `glint bench-peer` (started by `glint bench ipc`).
pub(crate) fn peer_command(args: crate::cli::PeerArgs) -> std::process::ExitCode {
    use std::process::ExitCode;
    let crate::cli::PeerArgs {
        transport,
        count,
        address,
    } = args;
    glint_runtime::lifeline::watch_parent();
    let args = PeerArgs {
        transport,
        count,
        address,
    };
    match peer(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: bench receiver: {e:#}");
            ExitCode::from(1)
        }
    }
}
