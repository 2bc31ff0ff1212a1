"""How much of the depth image each camera model leaves invalid where the episodes start.

A D455 reports nothing nearer than its minimum range, so under maize taller than the camera a
leaf at the lens blanks part of the frame. The proxy camera (a core and one leaf band per plant)
and the mesh camera (the plants' triangles) draw that leaf differently; this resets an env with
each camera model on the same seeds and compares the share of invalid (0) pixels in the first
frame: the mean with a 95 % bootstrap interval, and how many frames are invalid everywhere.

Run ``python benchmarks/depth_invalid_share.py`` (≈ 10 s on 2 cores; ``--resets 48``,
``--env-kwargs '{"scenario_overrides": {"crop": {"stage": 2}}}'`` for another field).
"""

from __future__ import annotations

import argparse
import json
import platform
import warnings

import numpy as np

MODELS = ("proxy", "mesh")


def invalid_shares(env_id: str, kwargs: dict, model: str, resets: int) -> np.ndarray:
    import gymnasium as gym

    import agrinav_gym  # noqa: F401  (registers the envs)

    config = {**kwargs.get("config", {}), "camera": {"model": model}}
    env = gym.make(env_id, **{**kwargs, "config": config})
    try:
        out = []
        for seed in range(resets):
            obs, _ = env.reset(seed=seed)
            out.append(float((obs["depth"] == 0).mean()))
        return np.asarray(out)
    finally:
        env.close()


def interval(x: np.ndarray, rng: np.random.Generator, n: int = 2000) -> tuple[float, float]:
    means = rng.choice(x, (n, len(x))).mean(axis=1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="AgriNav/FurrowFollowDepth-v3")
    ap.add_argument("--env-kwargs", default="{}", help="JSON of gym.make keywords")
    ap.add_argument("--resets", type=int, default=24)
    args = ap.parse_args()
    kwargs = json.loads(args.env_kwargs)
    warnings.simplefilter("ignore")  # the fixed-field note, once per env
    rng = np.random.default_rng(0)
    print(
        f"{args.env} {kwargs or ''}; {args.resets} resets (seeds 0..{args.resets - 1}); "
        f"{platform.machine()}, {platform.python_version()}"
    )
    shares = {m: invalid_shares(args.env, kwargs, m, args.resets) for m in MODELS}
    print("camera  invalid share of the first frame (mean [95 % CI])  frames all invalid")
    for m, x in shares.items():
        lo, hi = interval(x, rng)
        print(
            f"{m:6}  {x.mean():.2f} [{lo:.2f}, {hi:.2f}]  (min {x.min():.2f}, max {x.max():.2f})"
            f"  {int((x == 1.0).sum())} of {len(x)}"
        )
    d = shares["proxy"] - shares["mesh"]
    lo, hi = interval(d, rng)
    print(f"paired proxy − mesh: {d.mean():+.2f} [{lo:+.2f}, {hi:+.2f}]")


if __name__ == "__main__":
    main()
