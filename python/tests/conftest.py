"""Shared fixtures: the glint binary (``GLINT_BIN``), small scenarios, cleanup of a run's
prefix."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Callable

import pytest

#: The repository's debug build (the Rust test that runs these sets ``GLINT_BIN``).
DEFAULT_GLINT = str(Path(__file__).resolve().parents[2] / "target" / "debug" / "glint")

#: 256² frames, 2 debris, sim clock (lockstep): a second or two even in a debug build.
SMALL = """\
name = "py-small"
description = "glint_client tests: small camera-only run"
seed = 7
{clock}

[camera]
width_px = {w}
height_px = {h}
fov_deg = 10.0
exposure_s = 0.02
interval_s = 0.02
frames = {frames}

[[camera.debris]]
x_m = 9000.0
y_m = 600.0
z_m = -500.0
vx_mps = -100.0
vy_mps = -600.0
vz_mps = 400.0
size_m = 0.1

[[camera.debris]]
x_m = 6000.0
y_m = 300.0
z_m = 400.0
vx_mps = -80.0
vy_mps = -100.0
vz_mps = -150.0
size_m = 0.08
"""


@pytest.fixture(scope="session")
def glint_bin() -> str:
    path = os.environ.get("GLINT_BIN", DEFAULT_GLINT)
    if not Path(path).is_file():
        pytest.skip(f"no glint binary at {path} (set GLINT_BIN)")
    return path


@pytest.fixture(scope="session")
def make_scenario(tmp_path_factory: pytest.TempPathFactory, glint_bin: str
                  ) -> Callable[..., Path]:
    """Writes a small scenario, checked by ``glint validate``."""

    def make(frames: int = 40, w: int = 256, h: int = 256, realtime: bool = False) -> Path:
        clock = 'clock = "realtime"' if realtime else 'clock = "sim"'
        p = tmp_path_factory.mktemp("scenario") / f"small-{w}x{h}-{frames}.toml"
        p.write_text(SMALL.format(clock=clock, w=w, h=h, frames=frames))
        subprocess.run([glint_bin, "validate", str(p)], check=True, capture_output=True)
        return p

    return make


def clean_prefix(glint_bin: str, prefix: str) -> None:
    """Removes what a run of ``prefix`` left (its own files, once every node has gone)."""
    subprocess.run([glint_bin, "clean", "--prefix", prefix], capture_output=True, timeout=30)
