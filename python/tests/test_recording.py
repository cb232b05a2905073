"""Reading ``run.mcap``: a real recording (``glint run --record``) and synthetic files."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest
import xxhash
from mcap.writer import Writer

from glint_client import FrameDigest, Layouts, MessageDigest, Recording, RecordingError

from .conftest import clean_prefix


@pytest.fixture(scope="module")
def recorded(glint_bin: str, make_scenario: Callable[..., Path],
             tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    out = tmp_path_factory.mktemp("rec") / "run"
    scen = make_scenario(frames=30, w=256, h=192)
    p = subprocess.run([glint_bin, "run", str(scen), "--record", "--seed", "11", "--out", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    report = json.loads((out / "report.json").read_text())
    clean_prefix(glint_bin, report["run"]["prefix"])
    return out / "run.mcap", report


def test_channels_and_counts_match_the_report(recorded: tuple[Path, dict[str, Any]]) -> None:
    path, report = recorded
    with Recording(path) as rec:
        counts = rec.counts()
        written = report["run"]["recording"]["messages"]
        assert report["run"]["recording"]["not_written"] == {}
        # every topic the report says was written is a channel, with that many messages
        assert {t: counts.get(t) for t in written} == written
        for topic, t in report["topics"].items():  # every tapped data topic
            assert counts[topic] == t["published"], topic
        # any other channel (e.g. `faults` of a newer glint, none injected here) is empty
        assert all(n == 0 for t, n in counts.items() if t not in written), counts
        assert rec.channels["frame"].is_frame
        assert rec.channels["detections"].type_name == "glint.v8.Detections"
        # the messages themselves, not only the summary
        seen: dict[str, int] = {}
        for m in rec.messages():
            seen[m.topic] = seen.get(m.topic, 0) + 1
        assert seen == {t: n for t, n in counts.items() if n}


def test_json_channels_and_report_attachment(recorded: tuple[Path, dict[str, Any]]) -> None:
    """A newer glint adds a JSON `faults` channel and `report.json` as an attachment."""
    path, report = recorded
    with Recording(path) as rec:
        if "faults" in rec.channels:
            assert rec.channels["faults"].message_encoding == "json"
            assert [m.value for m in rec.messages(["faults"])] == report["faults"]
        attached = rec.report
        if attached is not None:
            assert attached["run"]["prefix"] == report["run"]["prefix"]
            assert attached["topics"]["frame"] == report["topics"]["frame"]


def test_scenario_metadata(recorded: tuple[Path, dict[str, Any]]) -> None:
    path, report = recorded
    with Recording(path) as rec:
        sc = rec.scenario
        assert sc["name"] == "py-small"
        assert int(sc["seed"]) == 11 == report["seed"]
        assert sc["resolved"]["camera"]["frames"] == 30


def test_frames_decode_and_checksums(recorded: tuple[Path, dict[str, Any]]) -> None:
    path, report = recorded
    digest = FrameDigest()
    with Recording(path) as rec:
        n = 0
        for f in rec.frames():
            assert f.pixels.shape == (192, 256) and f.pixels.dtype == np.uint16
            assert not f.pixels.flags.writeable
            assert xxhash.xxh3_64_intdigest(f.pixels.tobytes()) == int(f.header.pixels_xxh3)
            assert f.sequence == int(f.header.meta.seq) & 0xFFFFFFFF
            assert f.header.frame_index == f.header.meta.seq == n
            digest.add(int(f.header.meta.seq), int(f.header.pixels_xxh3))
            n += 1
        assert n == report["topics"]["frame"]["published"]
    assert digest.hexdigest() == report["topics"]["frame"]["digest_xxh3"]


def test_detections_decode(recorded: tuple[Path, dict[str, Any]]) -> None:
    path, report = recorded
    with Recording(path) as rec:
        digest = MessageDigest(rec.layouts, "glint.v8.Detections")
        found = 0
        for i, d in enumerate(rec.messages(["detections"])):
            assert d.meta.seq == i == d.sequence and d.frame_index == i
            assert 0 <= d.n <= 32
            items = d.items[: d.n]
            assert np.all((items.x_px >= 0) & (items.x_px < 256))
            assert np.all((items.y_px >= 0) & (items.y_px < 192))
            found += int(d.n)
            digest.add(d.data)
        assert found > 0
        table = rec.table("detections")
        assert len(table) == report["topics"]["detections"]["published"]
        assert int(table["n"].sum()) == found
    assert digest.hexdigest() == report["topics"]["detections"]["digest_xxh3"]


# -- synthetic files: no glint needed -------------------------------------------------------
def _write(path: Path, schema: dict[str, Any], frames: list[tuple[int, np.ndarray]]) -> None:
    lay = Layouts.bundled()
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("glint.v8.FrameHeader", "glint.repr-c", json.dumps(schema).encode())
        cid = w.register_channel("frame", "glint.repr-c", sid, {"producer": "sensor"})
        for seq, px in frames:
            h = lay.ctype("FrameHeader")()
            h.meta.seq, h.frame_index = seq, seq
            h.height_px, h.width_px = px.shape
            h.pixels_xxh3 = xxhash.xxh3_64_intdigest(px.astype("<u2").tobytes())
            w.add_message(cid, log_time=seq, publish_time=seq, sequence=seq,
                          data=bytes(h) + px.astype("<u2").tobytes())
        w.add_metadata("scenario", {"name": "synthetic", "seed": "1", "toml": "name = 'synthetic'"})
        w.finish()


def _frames() -> list[tuple[int, np.ndarray]]:
    rng = np.random.default_rng(0)
    return [(i, rng.integers(0, 4096, size=(3, 5), dtype=np.uint16)) for i in range(4)]


def test_synthetic_with_layouts(tmp_path: Path) -> None:
    lay = Layouts.bundled()
    schema = {"type": "glint.v8.FrameHeader", "contract_version": 8, "repr": "C",
              "frame": "the header, then the pixels",
              "types": [lay.get("FrameHeader").to_json(), lay.get("Meta").to_json()]}
    frames = _frames()
    _write(tmp_path / "a.mcap", schema, frames)
    with Recording(tmp_path / "a.mcap") as rec:
        got = list(rec.frames())
        assert [f.header.meta.seq for f in got] == [0, 1, 2, 3]
        for f, (_, px) in zip(got, frames):
            assert np.array_equal(f.pixels, px) and f.checksum_ok()
        assert rec.scenario["resolved"] == {"name": "synthetic"}


def test_synthetic_without_layouts_uses_bundled(tmp_path: Path) -> None:
    """A recording by a glint from before layouts were recorded: size_bytes only."""
    schema = {"type": "glint.v8.FrameHeader", "contract_version": 8, "size_bytes": 80,
              "align_bytes": 8, "frame": "the header, then the pixels"}
    _write(tmp_path / "b.mcap", schema, _frames())
    with Recording(tmp_path / "b.mcap") as rec:
        assert all(f.checksum_ok() for f in rec.frames())


def test_synthetic_other_contract_is_refused(tmp_path: Path) -> None:
    schema = {"type": "glint.v9.FrameHeader", "contract_version": 9, "frame": "x", "types": []}
    _write(tmp_path / "c.mcap", schema, _frames())
    with pytest.raises(RecordingError):
        Recording(tmp_path / "c.mcap")
