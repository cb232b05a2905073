"""Where an address of this process lies: the shared-memory mappings of ``/proc/self/maps``
(to show that an array is a view on a deployment's shared memory, not a copy)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Mapping:
    start: int
    end: int
    perms: str
    path: str


def mappings(pid: int | str = "self") -> list[Mapping]:
    out = []
    with open(f"/proc/{pid}/maps") as f:
        for line in f:
            parts = line.split(maxsplit=5)
            lo, hi = parts[0].split("-")
            path = parts[5].strip() if len(parts) > 5 else ""
            out.append(Mapping(int(lo, 16), int(hi, 16), parts[1], path))
    return out


def mapping_of(address: int, pid: int | str = "self",
               maps: list[Mapping] | None = None) -> Mapping | None:
    """The mapping holding ``address``, if any (in ``maps`` when given: reading
    ``/proc/self/maps`` costs about a millisecond)."""
    for m in maps if maps is not None else mappings(pid):
        if m.start <= address < m.end:
            return m
    return None


class ShmChecker:
    """Whether addresses lie in a deployment's ``/dev/shm`` files; re-reads the maps only for
    an address its copy does not hold (a segment mapped since)."""

    def __init__(self, prefix: str):
        self.prefix = prefix
        self._maps = mappings()

    def mapping(self, address: int) -> Mapping | None:
        m = mapping_of(address, maps=self._maps)
        if m is None:
            self._maps = mappings()
            m = mapping_of(address, maps=self._maps)
        return m

    def __call__(self, address: int) -> bool:
        m = self.mapping(address)
        return m is not None and m.path.startswith("/dev/shm/") and self.prefix in m.path


def in_deployment_shm(address: int, prefix: str) -> bool:
    """Whether ``address`` lies in a ``/dev/shm`` file of the deployment ``prefix``."""
    return ShmChecker(prefix)(address)
