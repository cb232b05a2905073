"""Finding a deployment: its iceoryx2 prefix ``glint_<hex>_``.

Every service of a deployment opens its iceoryx2 node with ``global.prefix = glint_<hex>_``
(one prefix per run), and names its services ``glint/<topic>``. A client finds the prefix in:

- the orchestrator's log (stderr), ``INFO deployed prefix="glint_c9222f1e_" services=4``, the
  first line of a run, printed before any frame is sent (``GlintRun`` reads it);
- ``report.json``'s ``run.prefix``, written when the run has ended (``prefix_from_report``);
- ``/dev/shm``: every file of a deployment starts with its prefix (``prefixes_in_shm``), and
  iceoryx2 lists the live nodes under a prefix (``live_nodes``).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

PREFIX = re.compile(r"glint_[0-9a-f]+_")
_DEPLOYED = re.compile(r'deployed prefix="(?P<prefix>glint_[0-9a-f]+_)"')
SHM_DIR = Path("/dev/shm")


class DiscoveryError(RuntimeError):
    """No deployment prefix where one was looked for."""


def is_prefix(s: str) -> bool:
    """Whether ``s`` is a whole deployment prefix, ``glint_<hex>_``."""
    return PREFIX.fullmatch(s) is not None


def prefix_from_log_line(line: str) -> str | None:
    """The prefix of an orchestrator's ``deployed prefix="…"`` log line, else None."""
    m = _DEPLOYED.search(line)
    return m["prefix"] if m else None


def prefix_from_report(path: str | os.PathLike[str]) -> str:
    """``run.prefix`` of a ``report.json`` (or of the run directory holding it)."""
    p = Path(path)
    if p.is_dir():
        p = p / "report.json"
    prefix = json.loads(p.read_text())["run"]["prefix"]
    if not is_prefix(prefix):
        raise DiscoveryError(f"{p}: run.prefix {prefix!r} is not a glint prefix")
    return str(prefix)


def prefixes_in_shm(shm_dir: Path = SHM_DIR) -> set[str]:
    """Every deployment prefix that has a file in ``/dev/shm`` (live or left behind)."""
    out: set[str] = set()
    for name in os.listdir(shm_dir):
        m = PREFIX.match(name)
        if m:
            out.add(m.group(0))
    return out


@dataclass(frozen=True)
class NodeInfo:
    name: str
    pid: int
    executable: str


def live_nodes(prefix: str) -> list[NodeInfo]:
    """The live iceoryx2 nodes under ``prefix``: a deployment's services, its orchestrator and
    any observer (this client's node is named ``glint-py`` by default)."""
    import iceoryx2 as iox

    cfg = iox.config.default()
    cfg.global_cfg.prefix = iox.FileName.new(prefix)
    out: list[NodeInfo] = []
    for state in iox.Node.list(iox.ServiceType.Ipc, cfg):
        if not isinstance(state, iox.NodeState.Alive):
            continue
        details = state._0.details  # NodeState.Alive(AliveNodeView)
        if details is None:
            continue
        out.append(NodeInfo(details.name.as_str(), int(details.process_id),
                            details.executable.to_string()))
    return out


def wait_for_new_prefix(before: set[str], timeout: float = 10.0,
                        shm_dir: Path = SHM_DIR) -> str:
    """The first prefix to appear in ``/dev/shm`` that was not in ``before`` (a deployment
    started after ``before`` was taken, when its log cannot be read)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        new = prefixes_in_shm(shm_dir) - before
        if len(new) == 1:
            return new.pop()
        if len(new) > 1:
            raise DiscoveryError(f"several new deployments: {sorted(new)}")
        time.sleep(0.002)
    raise DiscoveryError(f"no new deployment in {shm_dir} within {timeout} s")


class GlintRun:
    """``glint run …`` as a child process whose prefix is read from its log as soon as it is
    printed. The log (stderr) is drained by a thread so that the child never blocks on it.

    >>> with GlintRun(glint_bin, ["run", "scenario.toml", "--out", out]) as run:
    ...     prefix = run.wait_prefix()
    ...     ...
    ...     rc = run.wait()
    """

    def __init__(self, glint_bin: str | os.PathLike[str], args: Sequence[str],
                 env: dict[str, str] | None = None):
        self.args = [os.fspath(glint_bin), *args]
        self.process = subprocess.Popen(
            self.args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env=env, bufsize=1,
        )
        self.stderr_lines: list[str] = []
        self.stdout_lines: list[str] = []
        self._prefix: str | None = None
        self._found = threading.Event()
        self._threads = [
            threading.Thread(target=self._drain, args=(self.process.stderr, self.stderr_lines,
                                                       True), daemon=True),
            threading.Thread(target=self._drain, args=(self.process.stdout, self.stdout_lines,
                                                       False), daemon=True),
        ]
        for t in self._threads:
            t.start()

    def _drain(self, stream: Any, into: list[str], look: bool) -> None:
        for line in stream:
            into.append(line)
            if look and self._prefix is None:
                p = prefix_from_log_line(line)
                if p is not None:
                    self._prefix = p
                    self._found.set()
        if look:
            self._found.set()  # ended without a prefix: unblock the waiter

    def wait_prefix(self, timeout: float = 30.0) -> str:
        """The deployment's prefix, as soon as the orchestrator logged it."""
        self._found.wait(timeout)
        if self._prefix is None:
            raise DiscoveryError(
                f"`{' '.join(self.args)}` logged no prefix within {timeout} s "
                f"(exit code {self.process.poll()}); its log:\n{''.join(self.stderr_lines)}")
        return self._prefix

    @property
    def prefix(self) -> str | None:
        return self._prefix

    def running(self) -> bool:
        return self.process.poll() is None

    def wait(self, timeout: float | None = None) -> int:
        rc = self.process.wait(timeout)
        for t in self._threads:
            t.join(5)
        return rc

    def stop(self) -> None:
        """SIGTERM (the orchestrator shuts its deployment down), then the exit."""
        if self.running():
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
        self.wait()

    def clean(self) -> None:
        """``glint clean --prefix P``: what the run left once every node has gone (glint's own
        files stay while an observer, such as this client, still held the prefix at its end)."""
        if self._prefix is not None:
            subprocess.run([self.args[0], "clean", "--prefix", self._prefix],
                           capture_output=True, timeout=60)

    def __enter__(self) -> GlintRun:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
