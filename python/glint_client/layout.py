"""glint's wire-type layouts as data, turned into numpy dtypes and ctypes structures.

A layout (``TypeLayout``) is what ``glint run --record`` writes into each MCAP channel's schema
(``shared-types/src/messages/layout.rs``): the Rust name, the contract type name
(``glint.v8.Detections``), size, alignment and each field's name, offset, size and Rust type
(``u64``, ``[f64; 3]``, ``Meta``, ``[Detection; 32]``). Nothing here hard-codes an offset: the
numpy dtypes and ctypes structures are built from the layouts and checked against them.

The same layouts ship with this package (``layouts/glint_v8.json``, extracted from recordings)
for the live client, which has no recording to read them from. Regenerate that file with::

    python -m glint_client.layout RUN.mcap [RUN.mcap ...] > glint_client/layouts/glint_v8.json
"""

from __future__ import annotations

import ctypes
import json
import re
import sys
from dataclasses import dataclass
from functools import cached_property
from importlib import resources
from typing import Any, Iterable, Iterator, Mapping

import numpy as np

#: The wire contract this package was written against (``glint.contract`` attribute).
CONTRACT_VERSION = 8

_PRIMITIVES: dict[str, tuple[str, type[ctypes._SimpleCData[Any]]]] = {
    "u8": ("<u1", ctypes.c_uint8),
    "u16": ("<u2", ctypes.c_uint16),
    "u32": ("<u4", ctypes.c_uint32),
    "u64": ("<u8", ctypes.c_uint64),
    "usize": ("<u8", ctypes.c_uint64),
    "i8": ("<i1", ctypes.c_int8),
    "i16": ("<i2", ctypes.c_int16),
    "i32": ("<i4", ctypes.c_int32),
    "i64": ("<i8", ctypes.c_int64),
    "isize": ("<i8", ctypes.c_int64),
    "f32": ("<f4", ctypes.c_float),
    "f64": ("<f8", ctypes.c_double),
    "bool": ("?", ctypes.c_bool),
}

_ARRAY = re.compile(r"^\[(?P<inner>.+);\s*(?P<n>\d+)\]$")


class LayoutError(ValueError):
    """A layout that is malformed, names an unknown type, or disagrees with what was built."""


@dataclass(frozen=True)
class FieldLayout:
    name: str
    offset: int
    size: int
    type: str


@dataclass(frozen=True)
class TypeLayout:
    name: str
    contract_name: str
    size: int
    align: int
    fields: tuple[FieldLayout, ...]

    @staticmethod
    def from_json(obj: Mapping[str, Any]) -> TypeLayout:
        try:
            return TypeLayout(
                name=obj["name"],
                contract_name=obj["contract_name"],
                size=int(obj["size"]),
                align=int(obj["align"]),
                fields=tuple(
                    FieldLayout(f["name"], int(f["offset"]), int(f["size"]), f["type"])
                    for f in obj["fields"]
                ),
            )
        except (KeyError, TypeError) as e:
            raise LayoutError(f"not a type layout: {e!r} in {obj!r:.200}") from e

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "contract_name": self.contract_name,
            "size": self.size,
            "align": self.align,
            "fields": [
                {"name": f.name, "offset": f.offset, "size": f.size, "type": f.type}
                for f in self.fields
            ],
        }


def parse_type(expr: str) -> tuple[str, tuple[int, ...]]:
    """``[[f64; 6]; 16]`` -> ``("f64", (16, 6))``; ``Meta`` -> ``("Meta", ())``."""
    shape: list[int] = []
    s = expr.strip()
    while m := _ARRAY.match(s):
        shape.append(int(m["n"]))
        s = m["inner"].strip()
    return s, tuple(shape)


class Layouts:
    """A set of type layouts, by Rust name and by contract name, and what is built from them."""

    def __init__(self, types: Iterable[TypeLayout], topics: Mapping[str, str] | None = None):
        self._by_name: dict[str, TypeLayout] = {}
        for t in types:
            old = self._by_name.get(t.name)
            if old is not None and old != t:
                raise LayoutError(f"two different layouts of {t.name}")
            self._by_name[t.name] = t
        self._by_contract = {t.contract_name: t for t in self._by_name.values()}
        #: topic name -> contract type name of its payload (a frame topic: its header).
        self.topics: dict[str, str] = dict(topics or {})
        self._dtypes: dict[str, np.dtype] = {}
        self._ctypes: dict[str, type[ctypes.Structure]] = {}

    # -- construction -----------------------------------------------------------------------
    @staticmethod
    def from_json(obj: Mapping[str, Any]) -> Layouts:
        """From ``{"types": [...], "topics": {...}}`` (a schema's data or the bundled file)."""
        types = obj.get("types")
        if not isinstance(types, list):
            raise LayoutError("no `types` list: a recording from a glint without layouts")
        return Layouts((TypeLayout.from_json(t) for t in types), obj.get("topics"))

    @staticmethod
    def bundled() -> Layouts:
        """The layouts shipped with this package (contract ``CONTRACT_VERSION``)."""
        return _bundled()

    def merged(self, other: Layouts) -> Layouts:
        return Layouts([*self._by_name.values(), *other._by_name.values()],
                       {**self.topics, **other.topics})

    # -- lookup -----------------------------------------------------------------------------
    def __contains__(self, name: str) -> bool:
        return name in self._by_name or name in self._by_contract

    def __iter__(self) -> Iterator[TypeLayout]:
        return iter(self._by_name.values())

    def get(self, name: str) -> TypeLayout:
        """The layout of ``name``: a Rust name (``Detections``) or a contract name."""
        t = self._by_name.get(name) or self._by_contract.get(name)
        if t is None:
            raise LayoutError(f"no layout of type `{name}`")
        return t

    def topic_type(self, topic: str) -> TypeLayout:
        """The payload layout of a topic (``detections`` -> ``glint.v8.Detections``)."""
        if topic not in self.topics:
            raise LayoutError(f"unknown topic `{topic}`; known: {sorted(self.topics)}")
        return self.get(self.topics[topic])

    # -- numpy ------------------------------------------------------------------------------
    def dtype(self, name: str) -> np.dtype:
        """A little-endian structured dtype of ``name``, nested types and arrays included,
        with the layout's offsets and size."""
        t = self.get(name)
        if t.name not in self._dtypes:
            names, formats, offsets = [], [], []
            for f in t.fields:
                base, shape = parse_type(f.type)
                inner = np.dtype(_PRIMITIVES[base][0]) if base in _PRIMITIVES else self.dtype(base)
                fmt: Any = (inner, shape) if shape else inner
                if np.dtype(fmt).itemsize != f.size:
                    raise LayoutError(f"{t.name}.{f.name}: `{f.type}` is "
                                      f"{np.dtype(fmt).itemsize} bytes, the layout says {f.size}")
                names.append(f.name)
                formats.append(fmt)
                offsets.append(f.offset)
            self._dtypes[t.name] = np.dtype(
                {"names": names, "formats": formats, "offsets": offsets, "itemsize": t.size}
            )
        return self._dtypes[t.name]

    # -- ctypes -----------------------------------------------------------------------------
    def ctype(self, name: str) -> type[ctypes.Structure]:
        """A ctypes structure of ``name`` whose ``type_name()`` is the contract name: what the
        iceoryx2 Python binding takes as a payload or user-header type. Its size, alignment and
        every offset are checked against the layout."""
        t = self.get(name)
        if t.name not in self._ctypes:
            fields: list[tuple[str, Any]] = []
            at = 0
            for f in t.fields:
                if f.offset > at:  # explicit padding, should the layout ever have a gap
                    fields.append((f"_gap{at}", ctypes.c_uint8 * (f.offset - at)))
                base, shape = parse_type(f.type)
                c: Any = _PRIMITIVES[base][1] if base in _PRIMITIVES else self.ctype(base)
                for n in reversed(shape):
                    c = c * n
                fields.append((f.name, c))
                at = f.offset + f.size
            if t.size > at:
                fields.append((f"_gap{at}", ctypes.c_uint8 * (t.size - at)))
            contract = t.contract_name
            cls = type(t.name, (ctypes.LittleEndianStructure,), {
                "_fields_": fields,
                "type_name": staticmethod(lambda: contract),
                "__doc__": f"`{contract}` ({t.size} bytes, align {t.align}), from its layout.",
            })
            _check_ctype(cls, t)
            self._ctypes[t.name] = cls
        return self._ctypes[t.name]


def _check_ctype(cls: type[ctypes.Structure], t: TypeLayout) -> None:
    if ctypes.sizeof(cls) != t.size or ctypes.alignment(cls) != t.align:
        raise LayoutError(f"{t.name}: ctypes gives size {ctypes.sizeof(cls)} align "
                          f"{ctypes.alignment(cls)}, the layout {t.size}/{t.align}")
    for f in t.fields:
        off = getattr(cls, f.name).offset
        if off != f.offset:
            raise LayoutError(f"{t.name}.{f.name}: ctypes offset {off}, layout {f.offset}")


_BUNDLED: Layouts | None = None


def _bundled() -> Layouts:
    global _BUNDLED
    if _BUNDLED is None:
        text = resources.files(__package__).joinpath("layouts/glint_v8.json").read_text()
        obj = json.loads(text)
        if obj.get("contract_version") != CONTRACT_VERSION:
            raise LayoutError("bundled layouts are of another contract version")
        _BUNDLED = Layouts.from_json(obj)
    return _BUNDLED


# -- a decoded message ----------------------------------------------------------------------
class View:
    """Attribute access over a numpy structured scalar or array: ``d.meta.seq``,
    ``d.items[:d.n].x_px``. Nested structures come back as ``View``; anything else as the numpy
    value itself. ``.value`` is the underlying numpy object."""

    __slots__ = ("value",)

    def __init__(self, value: np.void | np.ndarray):
        object.__setattr__(self, "value", value)

    def __getattr__(self, name: str) -> Any:
        try:
            return _wrap(self.value[name])
        except (ValueError, KeyError, IndexError) as e:
            raise AttributeError(name) from e

    def __getitem__(self, key: Any) -> Any:
        return _wrap(self.value[key])

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("a decoded message is read-only")

    def __len__(self) -> int:
        return len(self.value)

    def __iter__(self) -> Iterator[Any]:
        return (_wrap(v) for v in self.value)

    def __dir__(self) -> list[str]:
        return list(self.value.dtype.names or ())

    def __repr__(self) -> str:
        return f"View({self.asdict()!r})" if self.value.ndim == 0 else f"View({self.value!r})"

    def asdict(self) -> Any:
        """Plain Python: dicts, lists and scalars (for JSON or printing)."""
        return _plain(self.value)


def _wrap(v: Any) -> Any:
    if isinstance(v, (np.void, np.ndarray)) and v.dtype.names:
        return View(v)
    return v


def _plain(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        if v.dtype.names:
            return [_plain(x) for x in v]
        return v.tolist()
    if isinstance(v, np.void) and v.dtype.names:
        return {n: _plain(v[n]) for n in v.dtype.names}
    return v.item() if isinstance(v, np.generic) else v


def decode(layouts: Layouts, name: str, data: bytes | memoryview, offset: int = 0) -> View:
    """One message of type ``name`` from its bytes (a read-only view on ``data``, no copy)."""
    dt = layouts.dtype(name)
    return View(np.frombuffer(data, dtype=dt, count=1, offset=offset)[0])


# -- regenerating the bundled file ----------------------------------------------------------
def extract(paths: Iterable[str]) -> dict[str, Any]:
    """The layouts and topic types of every channel of the given recordings."""
    from mcap.reader import make_reader

    types: dict[str, dict[str, Any]] = {}
    topics: dict[str, str] = {}
    for p in paths:
        with open(p, "rb") as f:
            summary = make_reader(f).get_summary()
        if summary is None:
            raise LayoutError(f"{p}: no summary section")
        for ch in sorted(summary.channels.values(), key=lambda c: c.id):
            data = json.loads(summary.schemas[ch.schema_id].data)
            topics[ch.topic] = data["type"]
            for t in Layouts.from_json(data):
                types[t.name] = t.to_json()
    return {
        "about": "glint's wire-type layouts as `glint run --record` writes them in each MCAP "
                 "channel's schema; regenerate with `python -m glint_client.layout RUN.mcap...`",
        "contract_version": CONTRACT_VERSION,
        "topics": topics,
        "types": sorted(types.values(), key=lambda t: t["name"]),
    }


if __name__ == "__main__":
    json.dump(extract(sys.argv[1:]), sys.stdout, indent=1)
    sys.stdout.write("\n")
