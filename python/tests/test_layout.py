"""Layouts -> numpy dtypes and ctypes structures (no glint needed)."""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from glint_client.layout import Layouts, LayoutError, View, decode, parse_type


def test_parse_type() -> None:
    assert parse_type("u64") == ("u64", ())
    assert parse_type("[f64; 3]") == ("f64", (3,))
    assert parse_type("[[f64; 6]; 16]") == ("f64", (16, 6))
    assert parse_type("[Detection; 32]") == ("Detection", (32,))


def test_every_bundled_layout_builds_and_agrees() -> None:
    lay = Layouts.bundled()
    names = {t.name for t in lay}
    assert {"FrameHeader", "Meta", "Detections", "Detection", "Tracks"} <= names
    for t in lay:
        dt = lay.dtype(t.name)
        ct = lay.ctype(t.name)
        assert dt.itemsize == t.size == ctypes.sizeof(ct)
        assert ctypes.alignment(ct) == t.align
        assert ct.type_name() == t.contract_name
        for f in t.fields:
            assert dt.fields[f.name][1] == f.offset
            assert getattr(ct, f.name).offset == f.offset
            assert dt.fields[f.name][0].itemsize == f.size


def test_topic_types() -> None:
    lay = Layouts.bundled()
    assert lay.topic_type("frame").contract_name == "glint.v8.FrameHeader"
    assert lay.topic_type("detections").contract_name == "glint.v8.Detections"
    with pytest.raises(LayoutError):
        lay.topic_type("nope")


def test_frame_header_and_detections_shape() -> None:
    lay = Layouts.bundled()
    assert lay.get("glint.v8.FrameHeader").size == 80
    dt = lay.dtype("Detections")
    assert dt["items"].shape == (32,)
    assert dt["items"].base.names[:4] == ("track_id", "flags", "x_px", "y_px")


def test_decode_view_nested_access() -> None:
    lay = Layouts.bundled()
    dt = lay.dtype("Detections")
    a = np.zeros(1, dt)
    a["meta"]["seq"] = 41
    a["n"] = 2
    a["items"]["x_px"][0, :3] = [1.5, 2.5, 3.5]
    a["items"]["track_id"][0, :3] = [7, 8, 9]
    v = decode(lay, "Detections", a.tobytes())
    assert v.meta.seq == 41
    assert list(v.items[: v.n].x_px) == [1.5, 2.5]
    assert list(v.items[: v.n].track_id) == [7, 8]
    assert v.asdict()["meta"]["seq"] == 41
    with pytest.raises(AttributeError):
        v.nope  # noqa: B018
    with pytest.raises(AttributeError):
        v.n = 3  # type: ignore[misc]


def test_ctype_fills_like_rust_bytes() -> None:
    lay = Layouts.bundled()
    hdr = lay.ctype("FrameHeader")()
    hdr.meta.seq = 5
    hdr.width_px, hdr.height_px = 640, 480
    hdr.pixels_xxh3 = 0x1122334455667788
    v = decode(lay, "FrameHeader", bytes(hdr))
    assert (v.meta.seq, v.width_px, v.height_px, v.pixels_xxh3) == (5, 640, 480,
                                                                    0x1122334455667788)


def test_nested_arrays_and_size_mismatch() -> None:
    good = {"types": [
        {"name": "P", "contract_name": "x.P", "size": 16, "align": 8,
         "fields": [{"name": "a", "offset": 0, "size": 4, "type": "u32"},
                    {"name": "b", "offset": 4, "size": 4, "type": "f32"},
                    {"name": "c", "offset": 8, "size": 8, "type": "u64"}]},
        {"name": "Q", "contract_name": "x.Q", "size": 112, "align": 8,
         "fields": [{"name": "m", "offset": 0, "size": 48, "type": "[[f64; 2]; 3]"},
                    {"name": "p", "offset": 48, "size": 64, "type": "[P; 4]"}]},
    ]}
    lay = Layouts.from_json(good)
    assert lay.dtype("Q")["m"].shape == (3, 2)
    assert lay.dtype("Q")["p"].shape == (4,)
    assert ctypes.sizeof(lay.ctype("x.Q")) == 112
    bad = {"types": [{"name": "R", "contract_name": "x.R", "size": 8, "align": 8,
                      "fields": [{"name": "a", "offset": 0, "size": 8, "type": "u32"}]}]}
    with pytest.raises(LayoutError):
        Layouts.from_json(bad).dtype("R")
    with pytest.raises(LayoutError):
        Layouts.from_json({"type": "x"})
