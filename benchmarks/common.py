"""What several benchmark scripts share (scripts run from this folder, so they import it)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

import scenario_gen as sg

T = TypeVar("T")


def s_curve(i: int) -> np.ndarray:
    """Step ``i`` of the benchmarks' gentle S-curve: normalised (speed, yaw rate) in [-1, 1]."""
    return np.array([0.6, 0.15 * np.sin(i / 15.0)], np.float32)


def drive(env: Any, n: int, start: int = 0) -> float:
    """Seconds spent in ``env.step`` over ``n`` steps of ``s_curve`` (phase from ``start``);
    an episode's end resets, untimed."""
    total = 0.0
    for i in range(start, start + n):
        a = s_curve(i)
        t0 = time.perf_counter()
        _, _, term, trunc, _ = env.step(a)
        total += time.perf_counter() - t0
        if term or trunc:
            env.reset()
    return total


def lane_centre_pose(scn: sg.Scenario) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, base_link position) facing along the rows at the middle lane's centre."""
    rows = scn.rows
    mid = len(rows.offsets) // 2
    lane = 0.5 * (rows.offsets[mid - 1] + rows.offsets[mid])
    t = 0.5 * (rows.starts.min() + rows.ends.max())
    x, y = rows.to_enu(np.array([t]), np.array([lane]))
    c, s = math.cos(rows.angle), math.sin(rows.angle)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    return rot, np.array([x[0], y[0], float(scn.terrain.height_at(x[0], y[0])) + 0.11])


def pybullet_camera(
    cid: int, model: Any, rot: np.ndarray, pos: np.ndarray, vfov_deg: float, max_range: float
) -> tuple[Any, Any]:
    """pybullet view and projection matrices of camera ``model`` on a base at ``pos``/``rot``
    (the same pose and vertical FOV as the mesh camera; far plane at twice its range)."""
    import pybullet as p

    o = pos + rot @ np.asarray(model.position)
    axis = rot @ model.rotation
    view = p.computeViewMatrix(
        o.tolist(), (o + axis[:, 0]).tolist(), axis[:, 2].tolist(), physicsClientId=cid
    )
    aspect = model.width / model.height
    proj = p.computeProjectionMatrixFOV(vfov_deg, aspect, 0.1, 2 * max_range, physicsClientId=cid)
    return view, proj


def suite_case_names(ap: Any, suite: str, cases: str) -> list[str]:
    """The ``;``-separated case names ``cases`` of ``suite`` (cases without interventions),
    or an argparse error naming the suites or the cases there are."""
    from baselines.bench import suite_cases
    from scenario_gen.errors import InputError

    rows = [c.strip() for c in cases.split(";") if c.strip()]
    try:
        names = [c.group for c in suite_cases(suite) if not c.interventions]
    except InputError as e:  # its message names the suites there are
        ap.error(str(e))
    missing = [r for r in rows if r not in names]
    if missing or not rows:
        ap.error(f"--cases: {missing or cases!r}; allowed: any of {'; '.join(names)}")
    return rows


def drive_cases(
    suite: str,
    rows: list[str],
    configs: dict[str, str],
    policy: str,
    seeds: int,
    episode: Callable[[Any, Any, int, str], T],
) -> dict[tuple[str, str], list[T]]:
    """``episode(env, policy, reset seed, estimator name)`` on the first ``seeds`` evaluation
    seeds of each case in ``rows``, under each of ``configs`` (name: JSON of dotted env config
    keys merged over the suite's), with a progress bar; keyed by (name, case)."""
    from tqdm import tqdm

    from baselines.bench import _make_env, episode_seed, suite_cases
    from policies import make_policy

    results: dict[tuple[str, str], list[T]] = {}
    with tqdm(total=len(configs) * len(rows) * seeds, unit="ep") as bar:
        for name, config in configs.items():
            cases = suite_cases(suite, config)
            index = {c.group: i for i, c in enumerate(cases)}
            for row in rows:
                case = cases[index[row]]
                env = _make_env(case)
                try:
                    pi = make_policy(policy, env)
                    eps = results.setdefault((name, row), [])
                    for k in range(seeds):
                        bar.set_postfix(estimator=name, case=row)
                        eps.append(episode(env, pi, episode_seed(index[row], case, k), name))
                        bar.update()
                finally:
                    env.close()
    return results


def add_drive_args(
    ap: Any, suite: str, cases: str, estimators: str, known: Any, cases_help: str = ""
) -> None:
    """The arguments ``drive_cases`` needs: --suite, --cases, --policy, --seeds, --estimators
    (comma-separated, of ``known``); ``checked_drive_args`` reads them back."""
    ap.add_argument("--suite", default=suite, help="the benchmark suite to drive")
    ap.add_argument(
        "--cases", default=cases, help="';'-separated case names of the suite" + cases_help
    )
    ap.add_argument("--policy", default="rpp:tuned", help="the controller (bench's spec)")
    ap.add_argument("--seeds", type=int, default=8, help="episodes per case and estimator")
    ap.add_argument(
        "--estimators", default=estimators, help=f"comma-separated, of {', '.join(known)}"
    )


def checked_drive_args(ap: Any, args: Any, known: Any) -> tuple[list[str], list[str]]:
    """(estimator names, case names) from ``add_drive_args``'s arguments, or an argparse error
    naming the value and what is allowed."""
    if args.seeds < 2:
        ap.error(f"--seeds: {args.seeds}; allowed: at least 2 (an interval needs two episodes)")
    chosen = [e.strip() for e in args.estimators.split(",") if e.strip()]
    if not chosen or any(e not in known for e in chosen):
        ap.error(f"--estimators: {args.estimators!r}; allowed: any of {', '.join(known)}")
    return chosen, suite_case_names(ap, args.suite, args.cases)


def drive_chosen(
    ap: Any, args: Any, known: dict[str, str], episode: Callable[[Any, Any, int, str], T]
) -> dict[tuple[str, str], list[T]]:
    """``drive_cases`` over the estimators and cases ``add_drive_args``'s arguments chose
    (``checked_drive_args``), each estimator's config from ``known``."""
    chosen, rows = checked_drive_args(ap, args, known)
    configs = {name: known[name] for name in chosen}
    return drive_cases(args.suite, rows, configs, args.policy, args.seeds, episode)


def ci_cell(values: list[float], scale: float = 1000.0, fmt: str = "+.0f") -> str:
    """Mean [95 % bootstrap interval] of ``values`` × ``scale`` (default: m as mm)."""
    from baselines.report import mean_ci

    ci = mean_ci([v * scale for v in values])
    return "—" if ci is None else f"{ci[0]:{fmt}} [{ci[1]:{fmt}}, {ci[2]:{fmt}}]"
