"""``agrinav bench`` and ``agrinav tune`` spread over workers (``baselines.parallel``) and
resumed after a kill (``baselines.journal``): the same records as one serial run."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

import baselines.bench as bench_module
from baselines.cli import main

SMOKE = ["bench", "--suite", "smoke", "--policies", "rpp,dwb", "--seeds", "2"]


def _records(out: Path, seconds: bool = False) -> list[dict[str, Any]]:
    records = json.loads((out / "results.json").read_text())
    if not seconds:  # each episode's wall time: the one field no two runs share
        for r in records:
            r.pop("seconds")
    return records


@pytest.fixture(scope="module")
def serial(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("serial") / "bench"
    assert main([*SMOKE, "--out", str(out)]) == 0
    return out


def test_bench_with_two_workers_writes_the_serial_runs_records(
    serial: Path, tmp_path: Path
) -> None:
    out = tmp_path / "bench"
    assert main([*SMOKE, "--workers", "2", "--out", str(out)]) == 0
    assert _records(out) == _records(serial)
    figures = sorted(p.name for p in serial.glob("traj_*.png"))
    assert figures and figures == sorted(p.name for p in out.glob("traj_*.png"))  # every episode
    for name in figures:
        assert (out / name).read_bytes() == (serial / name).read_bytes()
    assert not list(tmp_path.glob(".bench.partial"))  # the journal goes with a finished run


def test_a_bench_interrupted_mid_run_resumes_without_running_its_episodes_again(
    serial: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "bench"
    real = bench_module.episode_task
    ran: list[str] = []

    def dies_after_two(job: Any) -> Any:
        if len(ran) == 2:
            raise KeyboardInterrupt  # Ctrl-C (or a kill) mid-run
        ran.append(job.key)
        return real(job)

    monkeypatch.setattr(bench_module, "episode_task", dies_after_two)
    assert main([*SMOKE, "--out", str(out)]) == 130  # interrupted
    assert not out.exists()
    assert (
        f"bench: stopped; 2 of 4 episodes are kept in {tmp_path / '.bench.partial'}: rerun the "
        "same command to resume"
    ) in capsys.readouterr().err
    kept = {
        f.stem: json.loads(f.read_text()) for f in (tmp_path / ".bench.partial").glob("c*.json")
    }
    assert sorted(k for k in kept) == sorted(ran)

    def counts(job: Any) -> Any:
        ran.append(job.key)
        return real(job)

    monkeypatch.setattr(bench_module, "episode_task", counts)
    ran.clear()
    assert main([*SMOKE, "--out", str(out)]) == 0
    assert len(ran) == 4 - 2 and not set(ran) & set(kept)
    assert _records(out) == _records(serial)
    with_seconds = _records(out, seconds=True)
    for k, record in kept.items():  # the kept episodes as they were (their own wall time)
        assert record in with_seconds, k
    assert not (tmp_path / ".bench.partial").exists()


def test_a_resume_reads_the_same_files_or_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A parameter file edited between the interrupted run and its rerun: the rerun is
    refused, naming the file (it used to average episodes of both settings in one cell). A
    run stopped before any episode finished keeps no journal to block another command."""
    params = tmp_path / "slow.yaml"
    params.write_text("desired_linear_vel: 0.3\n")
    out = tmp_path / "bench"
    argv = ["bench", "--suite", "smoke", "--policies", f"rpp:{params}", "--seeds", "2"]
    argv += ["--out", str(out)]
    real = bench_module.episode_task
    ran: list[str] = []

    def dies_after_one(job: Any) -> Any:
        if ran:
            raise KeyboardInterrupt
        ran.append(job.key)
        return real(job)

    monkeypatch.setattr(bench_module, "episode_task", dies_after_one)
    assert main(argv) == 130
    params.write_text("desired_linear_vel: 0.9\n")
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"the files read changed since ({params.resolve()})" in err and not out.exists()

    def dies_at_once(job: Any) -> Any:
        raise KeyboardInterrupt

    monkeypatch.setattr(bench_module, "episode_task", dies_at_once)
    assert main([*argv, "--force"]) == 130
    assert "bench: stopped; no episode had finished" in capsys.readouterr().err
    assert not (tmp_path / ".bench.partial").exists()


def test_a_killed_bench_process_resumes(tmp_path: Path) -> None:
    out = tmp_path / "bench"
    argv = ["bench", "--suite", "smoke", "--policies", "rpp", "--seeds", "3", "--out", str(out)]
    journal = tmp_path / ".bench.partial"
    proc = subprocess.Popen(
        [sys.executable, "-m", "baselines.cli", *argv],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 300
        while not list(journal.glob("c*.json")) and time.monotonic() < deadline:
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        proc.kill()
    kept = {f.stem: json.loads(f.read_text()) for f in journal.glob("c*.json")}
    assert 1 <= len(kept) < 3 and not out.exists()
    assert main(argv) == 0
    records = _records(out, seconds=True)
    assert len(records) == 3 and all(r in records for r in kept.values())
    assert not journal.exists() and not list(tmp_path.glob(".bench.tmp-*"))


def test_another_runs_journal_is_refused_unless_forced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "bench"
    journal = tmp_path / ".bench.partial"
    journal.mkdir()
    (journal / "run.json").write_text(json.dumps({"command": "bench", "suite": "paper"}))
    (journal / "c000-p00-s00000.json").write_text("{}")
    argv = ["bench", "--suite", "smoke", "--policies", "rpp", "--seeds", "1", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "another run" in err and "--force" in err and not out.exists()
    # what differs, in words (the other run's suite; its policies were not set)
    assert "suite 'paper' there, 'smoke' now" in err and "policies not set there" in err
    assert "bench smoke" not in err  # refused before the progress bar
    assert main([*argv, "--force"]) == 0
    assert len(_records(out)) == 1 and not journal.exists()


def test_workers_and_ray_are_checked_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "bench"
    assert main([*SMOKE, "--workers", "2", "--ray", "local", "--out", str(out)]) == 2
    assert "--workers" in capsys.readouterr().err
    assert main([*SMOKE, "--ray", "not an address", "--out", str(out)]) == 2
    assert "--ray" in capsys.readouterr().err and not out.exists()
    # a head nobody listens on: refused in one line, not minutes of Ray's retries
    import socket

    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    assert main([*SMOKE, "--ray", f"127.0.0.1:{port}", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "cannot be reached" in err and not out.exists()
    assert not list(tmp_path.iterdir())  # no journal either


def test_tune_with_two_workers_and_after_an_interruption_makes_the_same_search(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("optuna")
    import baselines.tune as tune_module

    argv = ["tune", "--policy", "stanley", "--trials", "2", "--episodes", "2"]
    serial, spread, resumed = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    assert main([*argv, "--out", str(serial)]) == 0
    assert main([*argv, "--workers", "2", "--out", str(spread)]) == 0
    real = tune_module.trial_episode
    ran: list[str] = []

    def dies_after_three(job: Any) -> Any:
        if len(ran) == 3:
            raise KeyboardInterrupt
        ran.append(job.key)
        return real(job)

    monkeypatch.setattr(tune_module, "trial_episode", dies_after_three)
    capsys.readouterr()
    assert main([*argv, "--out", str(resumed)]) == 130  # interrupted
    err = capsys.readouterr().err
    assert "tune: stopped; 3 trial episodes are kept in" in err, err[-2000:]
    assert "rerun the same command to resume" in err

    def counts(job: Any) -> Any:
        ran.append(job.key)
        return real(job)

    ran.clear()
    monkeypatch.setattr(tune_module, "trial_episode", counts)
    assert main([*argv, "--out", str(resumed)]) == 0
    assert ran == ["t00001-e0001"]  # only the episode the interrupted run had not finished
    for out in (spread, resumed):
        for name in ("trials.csv", "best.yaml"):
            assert (out / name).read_text() == (serial / name).read_text(), (out, name)


def test_workers_far_beyond_the_cores_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import os

    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    assert main([*SMOKE, "--workers", "9", "--out", str(tmp_path / "b")]) == 2
    assert "allowed: at most 8 (4 per core of this machine's 2)" in capsys.readouterr().err
    assert not (tmp_path / "b").exists()


def test_a_journal_of_other_code_is_not_resumed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The package version was the identity's only word on the code: an edit in an editable
    install between a killed run and its resume averaged episodes of two codes in one table."""
    from baselines import journal as journal_mod

    out = tmp_path / "bench"
    argv = ["bench", "--suite", "smoke", "--policies", "rpp", "--seeds", "2", "--out", str(out)]
    monkeypatch.setattr(journal_mod, "code_digest", lambda: "before-the-edit")
    save = journal_mod.Journal.save
    saved: list[str] = []

    def stop_at_the_second(self: Any, key: str, *args: Any, **kwargs: Any) -> None:
        if saved:
            raise KeyboardInterrupt  # a Ctrl-C once one episode is kept
        saved.append(key)
        save(self, key, *args, **kwargs)

    monkeypatch.setattr(journal_mod.Journal, "save", stop_at_the_second)
    assert main(argv) == 130
    partial = tmp_path / ".bench.partial"
    assert (partial / f"{saved[0]}.json").is_file()
    monkeypatch.setattr(journal_mod.Journal, "save", save)
    capsys.readouterr()
    monkeypatch.setattr(journal_mod, "code_digest", lambda: "after-the-edit")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "the project's code changed since" in err and "--force" in err and not out.exists()
    assert main([*argv, "--force"]) == 0
    assert len(_records(out)) == 2 and not partial.exists()
