"""Real tools the export tests check against: libsdformat (via tools/sdf_check) and GDAL.

Locally a missing tool skips the test with the install line; in CI (``CI=true``) it fails,
because there the tools are installed by .ci/run and their absence is a broken setup.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import NoReturn

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]
SOURCE = REPO / "tools" / "sdf_check" / "sdf_check.cc"
BUILD = REPO / "build" / "sdf_check"  # gitignored; the binary is cached across sessions
APT = "apt-get install -y g++ pkg-config libsdformat-dev gdal-bin"


def in_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")


def missing(what: str) -> NoReturn:
    msg = f"{what} not found (install: {APT})"
    if in_ci():
        pytest.fail(f"{msg}; CI must run this test", pytrace=False)
    pytest.skip(msg)


def build_sdf_check() -> Path:
    """Compile tools/sdf_check once (keyed by source and flags) and return the binary."""
    gxx, pkg = shutil.which("g++"), shutil.which("pkg-config")
    if gxx is None or pkg is None:
        missing("g++ or pkg-config")
    flags = subprocess.run(
        [pkg, "--cflags", "--libs", "sdformat12"], capture_output=True, text=True, check=False
    )
    if flags.returncode != 0:
        missing("SDFormat 12 (libsdformat-dev)")
    key = hashlib.sha256(SOURCE.read_bytes() + flags.stdout.encode()).hexdigest()[:12]
    exe = BUILD / f"sdf_check-{key}"
    BUILD.mkdir(parents=True, exist_ok=True)
    with open(BUILD / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # xdist workers wait for the one that compiles
        if not exe.is_file():
            tmp = exe.with_name(f"{exe.name}.tmp-{os.getpid()}")
            cmd = [gxx, "-O1", "-o", str(tmp), str(SOURCE), *flags.stdout.split()]
            r = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if r.returncode != 0:
                pytest.fail(f"sdf_check does not compile:\n{r.stderr[-3000:]}", pytrace=False)
            os.replace(tmp, exe)
            for old in BUILD.glob("sdf_check-*"):
                if old != exe:
                    old.unlink(missing_ok=True)  # builds of an older source
    return exe


def gdal(tool: str) -> str:
    path = shutil.which(tool)
    if path is None:
        missing(f"GDAL's {tool} (gdal-bin)")
    return path


@dataclass
class Check:
    """What sdf_check printed: the world as libsdformat and ignition-math see it."""

    returncode: int
    stderr: str
    spherical: tuple[float, ...] = ()
    models: dict[str, np.ndarray] = field(default_factory=dict)  # name -> 13 numbers
    collisions: dict[str, np.ndarray] = field(default_factory=dict)  # "model/col" -> 9 numbers
    meshes: list[str] = field(default_factory=list)
    valid: bool = False


def run_check(exe: Path, world: Path, models: Path) -> Check:
    return run_checks(exe, [world], models)[0]


def run_checks(exe: Path, worlds: list[Path], models: Path) -> list[Check]:
    """Check several worlds in parallel processes (each include costs libsdformat ≈60 ms)."""
    procs = [
        subprocess.Popen(
            [str(exe), str(w), "-m", str(models)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for w in worlds
    ]
    results = []
    for proc in procs:
        stdout, stderr = proc.communicate()
        results.append(_parse(proc.returncode, stdout, stderr))
    return results


def _parse(returncode: int, stdout: str, stderr: str) -> Check:
    out = Check(returncode, stderr)
    for line in stdout.splitlines():
        kind, *rest = line.split()
        if kind == "spherical":
            out.spherical = tuple(map(float, rest))
        elif kind == "model":
            out.models[rest[0]] = np.array(rest[1:], float)
        elif kind == "collision":
            out.collisions[f"{rest[0]}/{rest[2]}"] = np.array(rest[3:], float)
        elif kind == "mesh":
            out.meshes.append(rest[2])
        elif kind == "Valid.":
            out.valid = True
    return out


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(n, 4) quaternions w, x, y, z -> (n, 3, 3) rotation matrices."""
    w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def ground_metres(lat0: float, dlat: np.ndarray, dlon: np.ndarray) -> np.ndarray:
    """Horizontal distance (m) of small lat/lon differences (degrees) near ``lat0``."""
    m_per_deg = 111_320.0
    return np.hypot(dlat * m_per_deg, dlon * m_per_deg * np.cos(np.radians(lat0)))
