"""The per-topic digests of ``report.json`` (``topics.<name>.digest_xxh3``), recomputed by a
client from the messages it saw: equal digests, the same messages in the same order.

As the orchestrator's taps compute them (``orchestrator/run/taps.rs``):

- a frame topic: one streaming xxh3-64 over, per frame, ``meta.seq`` then ``pixels_xxh3`` (each
  u64 little-endian): the headers, not the pixels (each header's checksum covers them);
- a message topic: one streaming xxh3-64 over each message's bytes with ``meta.send_mono_ns``
  and ``meta.contract_version`` zeroed (the send time is the only field that differs between
  two runs of the same scenario and seed). Spectra fold their ``content_xxh3`` instead, and
  truth its own subset: those two are not reproduced here.
"""

from __future__ import annotations

import struct

import numpy as np
import xxhash

from .layout import Layouts


class FrameDigest:
    def __init__(self) -> None:
        self._h = xxhash.xxh3_64()
        self.count = 0

    def add(self, seq: int, pixels_xxh3: int) -> None:
        self._h.update(struct.pack("<QQ", seq, pixels_xxh3))
        self.count += 1

    def hexdigest(self) -> str:
        """As the report writes it: 16 lower-case hex digits."""
        return f"{self._h.intdigest():016x}"


class MessageDigest:
    def __init__(self, layouts: Layouts, type_name: str) -> None:
        self._dtype = layouts.dtype(type_name)
        self._h = xxhash.xxh3_64()
        self.count = 0

    def add(self, raw: bytes) -> None:
        rec = np.frombuffer(raw, dtype=self._dtype, count=1).copy()
        rec["meta"]["send_mono_ns"] = 0
        rec["meta"]["contract_version"] = 0
        self._h.update(rec.tobytes())
        self.count += 1

    def hexdigest(self) -> str:
        return f"{self._h.intdigest():016x}"
