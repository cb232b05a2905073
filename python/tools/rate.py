"""Measures how fast a Python subscriber takes a deployment's frames, against the chain.

    python tools/rate.py GLINT_BIN [SCENARIO] [--seed N] [--no-checksum] [--runs K]

Starts ``glint run``, subscribes to ``frame`` as soon as the prefix is logged, and reports per
run: frames received / published, frames missed (seq gaps), the stream's rate (published frames
over the sensor's first-to-last send time, from the headers' ``send_mono_ns``: the rate the
detector, a lockstep consumer, takes them at), the Python rate (frames received over first
send to last receipt), and the send->receive latency. Every frame's pixel checksum is verified
unless ``--no-checksum``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from glint_client import Client, GlintRun


def one(glint: str, scenario: list[str], seed: int, checksum: bool) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as out:
        with GlintRun(glint, ["run", *scenario, "--out", out, "--force", "--seed", str(seed)]) as run:
            prefix = run.wait_prefix()
            sends: list[int] = []
            recvs: list[int] = []
            bad = 0
            with Client(prefix) as client:
                frames = client.frames()
                for f in frames.stream(idle_timeout=10):
                    recvs.append(time.monotonic_ns())
                    sends.append(int(f.header.meta.send_mono_ns))
                    if checksum and not f.checksum_ok():
                        bad += 1
                missed = frames.missed
            rc = run.wait()
            run.clean()  # glint's own files, left while this client still held the prefix
        report = json.loads((Path(out) / "report.json").read_text())
    published = report["topics"]["frame"]["published"]
    det = report["topics"]["frame"]["consumers"]["detector"]["received"]
    n = len(recvs)
    lat = sorted((r - s) / 1e3 for r, s in zip(recvs, sends))
    # The stream's span: first to last frame sent (the sensor waits on the detector's credit).
    stream_s = (max(sends) - min(sends)) / 1e9 if n > 1 else float("nan")
    py_s = (max(recvs) - min(sends)) / 1e9 if n > 1 else float("nan")
    return {
        "rc": rc, "published": published, "detector_received": det, "received": n,
        "missed": missed, "bad_checksums": bad,
        "stream_fps": (published - 1) / stream_s if n > 1 else float("nan"),
        "python_fps": (n - 1) / py_s if n > 1 else float("nan"),
        "latency_us_p50": lat[n // 2] if n else float("nan"),
        "latency_us_p99": lat[min(n - 1, int(n * 0.99))] if n else float("nan"),
        "glint_frames_per_s": report["timing"]["frames_per_s"],
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("glint")
    ap.add_argument("scenario", nargs="?")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--no-checksum", action="store_true")
    a = ap.parse_args()
    rows = [one(a.glint, [a.scenario] if a.scenario else [], a.seed + i, not a.no_checksum)
            for i in range(a.runs)]
    for r in rows:
        print(json.dumps({k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()}))
    frac = [r["received"] / r["published"] for r in rows]
    ratio = [r["python_fps"] / r["stream_fps"] for r in rows]
    print(f"received/published: min {min(frac):.3f} median {statistics.median(frac):.3f}; "
          f"python rate / stream rate: min {min(ratio):.3f} median {statistics.median(ratio):.3f}")


if __name__ == "__main__":
    main()
