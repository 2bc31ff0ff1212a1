"""`agrinav scenario` killed at several moments: ``--out`` is afterwards absent, the
complete old folder, or the complete new one — never partial — and the next run to the same
``--out`` removes whatever the dead run left. Two concurrent runs: one is refused."""

import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from baselines.cli import main
from scenario_gen import load

SMALL = ["--set", "field.width=10", "--set", "field.length=14", "--set", "layout.headland=2"]
FILES = {"scenario.json", "terrain.npz", "plants.csv", "route.csv", "field.geojson"}


def _start(out: Path, *extra: str) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "baselines.cli", "scenario", "--out", str(out), *extra]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _temps(out: Path) -> list[Path]:
    return sorted(out.parent.glob(f".{out.name}.tmp-*"))


def _when(cond: Callable[[], bool], proc: subprocess.Popen[bytes], timeout: float = 90) -> bool:
    """Poll ``cond`` every 2 ms until it holds (True) or the process ends first (False)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.002)
    return False


def _has(out: Path, name: str) -> Callable[[], bool]:
    return lambda: any((t / name).exists() for t in _temps(out))


MOMENTS: dict[str, tuple[list[str], Callable[[Path], Callable[[], bool]]]] = {
    # one scenario: as soon as its temporary folder exists, with some files written, while the
    # preview renders (every data file written); a bank: after its first member is complete
    "temp-made": ([], lambda out: lambda: bool(_temps(out))),
    "half-written": ([], lambda out: _has(out, "terrain.npz")),
    "preview": ([], lambda out: _has(out, "scenario.json")),
    "bank-member": (
        ["--count", "4"],
        lambda out: lambda: any(any(t.glob("seed-*")) for t in _temps(out)),
    ),
}


def _absent_or_whole(out: Path, seed: int) -> bool:
    """True if ``out`` is absent; if present it must be the complete scenario of ``seed``."""
    if not out.exists():
        return True
    assert FILES | {"preview.png"} <= {p.name for p in out.iterdir()}
    assert load(out).seed == seed
    return False


def _next_run_cleans(out: Path, force: bool) -> None:
    argv = ["scenario", "--out", str(out), *SMALL, "--no-preview", "--seed", "9"]
    assert main(argv + (["--force"] if force else [])) == 0
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]  # nothing stale
    assert load(out).seed == 9


def _slow_unless(*fast: str) -> list:
    """The moments as parameters, all but ``fast`` marked slow (a subprocess each, 2-10 s)."""
    return [pytest.param(m, marks=() if m in fast else pytest.mark.slow) for m in MOMENTS]


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["kill-9", "sigterm"])
@pytest.mark.parametrize("moment", _slow_unless("half-written"))
def test_killed_run_leaves_nothing_partial(tmp_path: Path, moment: str, sig: int) -> None:
    extra, when = MOMENTS[moment]
    out = tmp_path / "scn"
    proc = _start(out, *SMALL, "--seed", "1", *extra)
    try:
        caught = _when(when(out), proc)
        proc.send_signal(sig)
        proc.wait(timeout=60)
    finally:
        proc.kill()
    assert caught, f"the run ended before the moment {moment!r}"
    assert _absent_or_whole(out, 1)  # killed before its rename: no folder at all
    if sig == signal.SIGTERM:  # unwinds: its temporaries and its lock are gone already
        assert sorted(p.name for p in tmp_path.iterdir()) == []
    _next_run_cleans(out, force=False)


@pytest.mark.parametrize(
    "moment",
    [
        "preview",
        pytest.param("temp-made", marks=pytest.mark.slow),
        pytest.param("bank-member", marks=pytest.mark.slow),
    ],
)
def test_killed_force_replacement_keeps_the_old_folder_whole(tmp_path: Path, moment: str) -> None:
    out = tmp_path / "scn"
    extra, when = MOMENTS[moment]
    assert main(["scenario", "--out", str(out), *SMALL, "--seed", "1", "--no-preview"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    proc = _start(out, *SMALL, "--seed", "2", "--force", *extra)
    try:
        caught = _when(when(out), proc)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        proc.kill()
    assert caught, f"the run ended before the moment {moment!r}"
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # the old one, untouched
    _next_run_cleans(out, force=True)


def test_a_run_to_an_out_being_written_is_refused(tmp_path: Path) -> None:
    from scenario_gen.atomic import output_dir

    out = tmp_path / "scn"
    with output_dir(out) as tmp:  # another run, mid-write
        (tmp / "scenario.json").write_text("{}")
        proc = subprocess.run(
            [sys.executable, "-m", "baselines.cli", "scenario", "--out", str(out), *SMALL],
            capture_output=True,
            text=True,
            timeout=120,
        )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "out" in lines[0] and "being written by another run" in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scn"]
    assert (out / "scenario.json").read_text() == "{}"  # the other run's result, untouched


@pytest.mark.slow
def test_two_concurrent_runs_to_one_out(tmp_path: Path) -> None:
    out = tmp_path / "scn"
    first = _start(out, *SMALL, "--seed", "1")
    try:
        assert _when(lambda: bool(_temps(out)), first)  # the first holds the lock
        second = subprocess.run(
            [sys.executable, "-m", "baselines.cli", "scenario", "--out", str(out), *SMALL],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert first.wait(timeout=120) == 0
    finally:
        first.kill()
    lines = second.stderr.strip().splitlines()
    assert second.returncode == 2 and len(lines) == 1, second.stderr
    assert "being written by another run" in lines[0] or "already exists" in lines[0]
    assert load(out).seed == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scn"]
