"""``agrinav demo``: the main job on the embedded terrain, in a few minutes.

Benchmarks Nav2-like DWB, the shipped PPO checkpoint (where the checkout has it) and the blind
reference on the ``paper`` suite — the source paper's run: four Nav2 GPS waypoints, 33 m along a
lane, across the headland and 31 m back, RTK through robot_localization, in early and
intermediate corn on its P1 field — and prints the metrics table. The fields it drives are
saved first (one folder per case, with its preview) and printed, so what is printed is what
is driven.
Everything lands in ``runs/demo/``: ``scenarios/CASE/`` and ``paper/`` (the benchmark, a
trajectory figure per episode).
"""

from __future__ import annotations

from pathlib import Path

from scenario_gen import save
from scenario_gen.atomic import check_output_dir, mark_output
from scenario_gen.errors import InputError

SUITE = "paper"


def demo(out: str | Path, seeds: int = 2) -> Path:
    from policies import shipped_model

    from .bench import bench
    from .suites import suite

    out = Path(out)
    if seeds < 1:
        raise InputError("--seeds", seeds, "allowed: an integer >= 1")
    # re-running the demo replaces its own results
    check_output_dir(out, overwrite=True, what="--out", kind="demo")
    out.mkdir(parents=True, exist_ok=True)
    mark_output(out, "demo")
    print(
        f"the {SUITE} suite: the source paper's run (four Nav2 GPS waypoints: 33 m along a "
        "lane, across the headland, 31 m back) in each field below"
    )
    for case in suite(SUITE):
        scn = case.field()
        where = out / "scenarios" / case.group
        save(scn, where, overwrite=True)
        info = scn.summary()
        print(
            f"scenario {case.group}: {where} (preset {case.scenario}, {info['plants']} plants, "
            f"{info['route_m']} m route; preview.png)"
        )
    policies = ["blind", "dwb"]  # blind: what the field steers by itself, the reference row
    try:
        shipped_model("AgriNav/FieldRoute-v3")
        policies.append("ppo:shipped")
    except InputError as exc:  # a checkout without the trained model still runs the demo
        print(f"note: {exc}; benchmarking DWB and the blind reference only")
    cmd = (
        f"agrinav bench --suite {SUITE} --policies {','.join(policies)} --seeds {seeds} "
        f"--out {out / SUITE} --force"
    )
    bench(SUITE, policies, seeds, out / SUITE, cmd, force=True)
    print((out / SUITE / "benchmark.md").read_text())
    return out
