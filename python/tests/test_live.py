"""Live: a running deployment's frames and detections, zero-copy, checked against its report."""

from __future__ import annotations

import gc
import json
import os
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest
import xxhash

from glint_client import (
    Client,
    FrameDigest,
    FramesHeldError,
    GlintRun,
    LiveError,
    MessageDigest,
    live_nodes,
    prefix_from_log_line,
    prefix_from_report,
)
from glint_client.shm import ShmChecker

from .conftest import clean_prefix

# Frames large enough that the chain, not this client, sets the pace even in a release build:
# an observer is not in the sim-clock lockstep, and one slower than the chain misses frames
# (256² frames at ~9000 frames/s: 1.5 % missed). At 1024x768 it takes every frame.
W, H, FRAMES = 1024, 768, 60


def _shm_files(prefix: str) -> list[str]:
    return [e for e in os.listdir("/dev/shm") if e.startswith(prefix)]


@pytest.fixture(scope="module")
def live_run(glint_bin: str, make_scenario: Callable[..., Path],
             tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One sim-clock run, subscribed to from its first frame; what the client saw."""
    out = tmp_path_factory.mktemp("live") / "run"
    scen = make_scenario(frames=FRAMES, w=W, h=H)
    seen: dict[str, Any] = {"frames": [], "detections": [], "in_shm": [], "read_only": [],
                            "checksum_ok": [], "shape_ok": []}
    with GlintRun(glint_bin, ["run", str(scen), "--seed", "5", "--out", str(out)]) as run:
        prefix = run.wait_prefix(timeout=30)
        client = Client(prefix)
        frames = client.frames()
        dets = client.messages("detections")
        seen["nodes"] = {n.name for n in live_nodes(prefix)}
        seen["qos"] = frames.qos
        layouts = client.layouts
        fdig, ddig = FrameDigest(), MessageDigest(layouts, "Detections")
        in_shm = ShmChecker(prefix)
        deadline = time.monotonic() + 60
        # Take whatever is queued on either topic, then wait on both at once: waiting on one
        # topic only would let the other's queue (16 deep) overflow meanwhile.
        while (frames.received < FRAMES or dets.received < FRAMES) \
                and time.monotonic() < deadline:
            while (f := frames.receive()) is not None:
                with f:
                    a = f.pixels
                    addr = a.__array_interface__["data"][0]
                    seen["in_shm"].append(in_shm(addr))
                    seen["read_only"].append(not a.flags.writeable)
                    seen["shape_ok"].append(a.shape == (H, W) and a.dtype == np.uint16)
                    seen["checksum_ok"].append(
                        xxhash.xxh3_64_intdigest(a) == int(f.header.pixels_xxh3))
                    seen["frames"].append(f.header)  # decoded after the run: no garbage now
                    fdig.add(f.seq, int(f.header.pixels_xxh3))
                    if len(seen["frames"]) == 1:
                        seen["mapping"] = in_shm.mapping(addr)
                    del a
            for m in dets.drain():
                seen["detections"].append(m)
                ddig.add(m.raw)
            if not run.running() and not frames.has_samples() and not dets.has_samples():
                break  # the run ended and nothing is left queued
            client.wait(0.05)
        seen["missed"] = frames.missed
        seen["frames"] = [h.asdict() for h in seen["frames"]]
        seen["detections"] = [m.value.asdict() for m in seen["detections"]]
        client.close()
        seen["closed_at"] = time.monotonic()
        rc = run.wait(timeout=60)
        seen["log_prefixes"] = {p for p in map(prefix_from_log_line, run.stderr_lines) if p}
    report = json.loads((out / "report.json").read_text())
    seen.update(rc=rc, report=report, prefix=prefix, out=out, frame_digest=fdig.hexdigest(),
                detections_digest=ddig.hexdigest())
    seen["nodes_after"] = live_nodes(prefix)
    clean_prefix(glint_bin, prefix)
    seen["shm_after_clean"] = _shm_files(prefix)
    return seen


def test_run_passed_and_prefix_found(live_run: dict[str, Any]) -> None:
    assert live_run["rc"] == 0, live_run["report"].get("failure")
    assert live_run["report"]["success"]
    assert prefix_from_report(live_run["out"]) == live_run["prefix"]
    assert live_run["log_prefixes"] == {live_run["prefix"]}
    assert {"glint-py", "sensor", "detector"} <= live_run["nodes"]
    # The orchestrator looks for strangers every 250 ms: a short run may end before it sees us.
    strangers = live_run["report"]["membership"]["strangers"]
    assert all((s["name"], s["role"]) == ("glint-py", "observer") for s in strangers)


def test_service_qos_as_the_rust_side_creates_it(live_run: dict[str, Any]) -> None:
    q = live_run["qos"]
    assert (q.max_publishers, q.max_subscribers, q.subscriber_max_borrowed_samples) == (2, 4, 2)
    assert q.history_size == q.subscriber_max_buffer_size == 16 and q.safe_overflow


def test_every_frame_received_zero_copy_and_checked(live_run: dict[str, Any]) -> None:
    published = live_run["report"]["topics"]["frame"]["published"]
    assert published == FRAMES
    assert live_run["missed"] == 0
    assert [f["meta"]["seq"] for f in live_run["frames"]] == list(range(published))
    assert all(live_run["checksum_ok"]) and all(live_run["shape_ok"])
    assert all(live_run["read_only"])
    assert all(live_run["in_shm"]), live_run.get("mapping")
    assert live_run["mapping"].path.startswith(f"/dev/shm/{live_run['prefix']}")
    h = live_run["frames"][0]
    assert (h["width_px"], h["height_px"], h["meta"]["contract_version"]) == (W, H, 8)


def test_frame_digest_equals_the_report(live_run: dict[str, Any]) -> None:
    assert live_run["frame_digest"] == live_run["report"]["topics"]["frame"]["digest_xxh3"]


def test_detections_decoded_and_digest_equals_the_report(live_run: dict[str, Any]) -> None:
    dets = live_run["detections"]
    topic = live_run["report"]["topics"]["detections"]
    missing = sorted(set(range(FRAMES)) - {d["meta"]["seq"] for d in dets})
    assert len(dets) == topic["published"] == FRAMES, f"missing {missing}"
    assert [d["meta"]["seq"] for d in dets] == list(range(FRAMES))
    assert [d["frame_index"] for d in dets] == list(range(FRAMES))
    assert sum(d["n"] for d in dets) > 0
    for d in dets:
        assert 0 <= d["n"] <= 32
        for it in d["items"][: d["n"]]:
            assert 0 <= it["x_px"] < W and 0 <= it["y_px"] < H and it["track_id"] > 0
    assert live_run["detections_digest"] == topic["digest_xxh3"]


def test_client_left_cleanly(live_run: dict[str, Any]) -> None:
    # Our node is gone (no live or dead node left under the prefix) and, once glint's own
    # files are cleaned, nothing of the prefix remains.
    assert live_run["nodes_after"] == []
    assert live_run["shm_after_clean"] == []


def test_frame_lifetime_and_borrow_limit(glint_bin: str, make_scenario: Callable[..., Path],
                                         tmp_path: Path) -> None:
    """The arrays own the loans: valid after release and after close; the borrow limit."""
    scen = make_scenario(frames=60, w=128, h=96, realtime=True)  # 25 frames/s, 2.4 s
    with GlintRun(glint_bin, ["run", str(scen), "--out", str(tmp_path / "run")]) as run:
        prefix = run.wait_prefix(timeout=30)
        client = Client(prefix)
        frames = client.frames()
        f1 = frames.wait(10)
        f2 = frames.wait(10)
        assert f1 is not None and f2 is not None
        a1, a2 = f1.pixels, f2.pixels[10:20]  # a view of a view keeps it too
        h1, h2 = int(f1.header.pixels_xxh3), int(f2.header.pixels_xxh3)
        full2 = f2.pixels
        f1.release()
        f2.release()
        with pytest.raises(LiveError):
            f1.pixels  # noqa: B018
        assert frames.held() == 2
        with pytest.raises(ValueError):
            a1.flags.writeable = True
        with pytest.raises(FramesHeldError):
            deadline = time.monotonic() + 5
            while time.monotonic() < deadline:
                frames.wait(0.1)
        assert xxhash.xxh3_64_intdigest(a1) == h1  # still the frame it was
        del a1
        gc.collect()
        assert frames.held() == 1
        f3 = frames.wait(5)  # one loan free again
        assert f3 is not None and f3.checksum_ok()
        del f3
        del full2
        gc.collect()
        with pytest.warns(ResourceWarning):
            client.close()  # a2 (a view) still holds frame 2
        assert a2.shape == (10, 128)
        a2_bytes = a2.tobytes()  # readable after the node closed
        assert len(a2_bytes) == 10 * 128 * 2
        del a2
        gc.collect()
        assert frames.held() == 0
        run.stop()
    clean_prefix(glint_bin, prefix)
    assert h2 != 0


def test_a_prefix_without_deployment_is_refused(glint_bin: str) -> None:
    with pytest.raises(ValueError):
        Client("not_a_prefix")
    prefix = "glint_00000000f_"
    with Client(prefix) as c:
        with pytest.raises(LiveError):
            c.frames()
    # iceoryx2 keeps a prefix's global management segment after its last node: glint cleans it
    assert all(e.endswith(".global_mgmt") for e in _shm_files(prefix))
    clean_prefix(glint_bin, prefix)
    assert not _shm_files(prefix)


def test_client_stream_takes_every_topic(glint_bin: str, make_scenario: Callable[..., Path],
                                         tmp_path: Path) -> None:
    """``Client.stream()``: frames and detections interleaved, until the producers end."""
    scen = make_scenario(frames=30, w=1024, h=768)
    with GlintRun(glint_bin, ["run", str(scen), "--out", str(tmp_path / "run")]) as run:
        prefix = run.wait_prefix(timeout=30)
        with Client(prefix) as client:
            frames = client.frames()
            dets = client.messages("detections")
            kinds: dict[str, int] = {}
            for item in client.stream(idle_timeout=20):
                kinds[item.topic if hasattr(item, "topic") else "frame"] = \
                    kinds.get(item.topic if hasattr(item, "topic") else "frame", 0) + 1
            assert frames.held() == 0  # each frame released as the next item was asked for
        assert run.wait(60) == 0
    clean_prefix(glint_bin, prefix)
    assert kinds == {"frame": 30, "detections": 30}
    assert frames.missed == 0 and dets.received == 30
