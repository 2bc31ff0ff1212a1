"""``agrinav demo``: the main job on the embedded default, in a few minutes.

Generates the default scenario (with its preview), then benchmarks Nav2-like DWB and the
shipped PPO checkpoint on the ``paper`` suite (the source paper's zigzag experiment) and prints
the metrics table. Everything lands in ``runs/demo/``.
"""

from __future__ import annotations

from pathlib import Path

from scenario_gen import generate, preset, save
from scenario_gen.atomic import check_output_dir, mark_output
from scenario_gen.errors import InputError


def demo(out: str | Path, seeds: int = 2) -> Path:
    from policies import shipped_model

    from .bench import bench

    out = Path(out)
    if seeds < 1:
        raise InputError("--seeds", seeds, "allowed: an integer >= 1")
    check_output_dir(out, overwrite=True)  # re-running the demo replaces its own results
    out.mkdir(parents=True, exist_ok=True)
    mark_output(out)
    scn = generate(preset("default"), seed=0)
    save(scn, out / "scenario", overwrite=True)
    print(f"scenario: {out / 'scenario'} ({scn.summary()['plants']} plants; preview.png)")
    policies = ["blind", "dwb"]  # blind: what the field steers by itself, the reference row
    try:
        shipped_model("AgriNav/FieldRoute-v2")
        policies.append("ppo:shipped")
    except InputError as exc:  # a checkout without the trained model still runs the demo
        print(f"note: {exc}; benchmarking DWB and the blind reference only")
    cmd = (
        f"agrinav bench --suite paper --policies {','.join(policies)} --seeds {seeds} "
        f"--out {out / 'paper'} --force"
    )
    bench("paper", policies, seeds, out / "paper", cmd, force=True)
    print((out / "paper" / "benchmark.md").read_text())
    return out
