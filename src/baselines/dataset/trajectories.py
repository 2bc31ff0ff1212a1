"""``agrinav dataset trajectories``: policy rollouts as a Minari dataset (offline RL, imitation).

Minari is an optional extra (``pip install agrinav-gym[dataset]``: minari + h5py). Infos are
reduced to a fixed schema (Minari needs the same keys at every step): the true cross-track
error, crops hit, whether the episode succeeded, the GNSS fix position and every named reward
part. The env spec travels with the dataset, so ``dataset.recover_environment()`` rebuilds it.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import warnings
from collections.abc import Iterator
from importlib.metadata import version
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from scenario_gen.atomic import check_output_dir, output_dir
from scenario_gen.errors import InputError

INFO_KEYS = ("cte", "crops_hit", "is_success", "lat", "lon")
DATASET_ID = re.compile(r"^[a-z0-9_]+/[a-z0-9_]+-v\d+$")


def _minari() -> Any:
    try:
        import jax  # noqa: F401  (Minari's DataCollector buffers episodes with it)
        import minari
    except ImportError:
        raise InputError(
            "dataset trajectories",
            "minari",
            "needs the dataset extra: pip install 'agrinav-gym[dataset]' (minari[create], h5py)",
        ) from None
    return minari


def fixed_info(info: dict[str, Any], parts: tuple[str, ...]) -> dict[str, Any]:
    """The info of a step with the same keys and types every step."""
    out: dict[str, Any] = {k: np.float64(info.get(k, 0.0)) for k in ("cte", "lat", "lon")}
    out["crops_hit"] = np.int64(info.get("crops_hit", 0))
    out["is_success"] = np.bool_(info.get("is_success", False))
    rewards = info.get("rewards", {})
    out["rewards"] = {k: np.float64(rewards.get(k, 0.0)) for k in parts}
    return out


@contextlib.contextmanager
def _datasets_root(root: Path) -> Iterator[None]:
    # Minari reads its root from the environment when it writes; restored afterwards.
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root)
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def record(
    env_id: str,
    policy: str,
    episodes: int,
    out: str | Path,
    seed: int = 0,
    dataset_id: str = "agrinav/furrow_follow-v0",
    force: bool = False,
) -> Path:
    """Roll ``policy`` out for ``episodes`` episodes (reset seeds ``seed``, ``seed + 1``, ...)
    and write the Minari dataset ``dataset_id`` under ``out``; returns its folder."""
    import gymnasium as gym

    import agrinav_gym
    from agrinav_gym.rewards import REWARD_TERMS
    from policies import check_policy_spec, make_policy
    from policies.spec import policy_files

    minari = _minari()
    from minari.data_collector.callbacks import StepDataCallback

    if episodes < 1:
        raise InputError("--episodes", episodes, "allowed: an integer >= 1")
    if not DATASET_ID.match(dataset_id):
        raise InputError("--dataset-id", dataset_id, "allowed: namespace/name-vN, lower case")
    check_policy_spec(policy)
    reads = policy_files([policy])  # a checkpoint inside --out: --force must not delete it
    check_output_dir(out, force, "--out", kind="dataset", inputs=reads)
    agrinav_gym.check_env_id(env_id, "--env")
    env = gym.make(env_id)
    parts = tuple(sorted(REWARD_TERMS))

    class FixedInfo(StepDataCallback):  # type: ignore[misc,unused-ignore]
        def __call__(self, env: Any, obs: Any, info: Any, **kw: Any) -> Any:
            data = super().__call__(env, obs, info, **kw)
            data["info"] = fixed_info(info, parts)
            return data

    with output_dir(out, force, "--out", kind="dataset", inputs=reads) as tmp, _datasets_root(tmp):
        # the collector's buffer folder goes inside the output's temporary folder, which the
        # next run on the same --out removes if this one is killed (it was ~/.minari/...)
        collector = minari.DataCollector(env, step_data_callback=FixedInfo, record_infos=True)
        returns: list[float] = []
        bar = tqdm(range(episodes), unit="episode", desc=f"recording {policy}")
        try:
            pi = make_policy(policy, collector)
            for k in bar:
                obs, _ = collector.reset(seed=seed + k)
                pi.reset()
                total = 0.0
                while True:
                    obs, r, term, trunc, _ = collector.step(pi.act(obs))
                    total += float(r)
                    if term or trunc:
                        break
                returns.append(total)
            reference = random_return(env_id, seed, episodes)
            with warnings.catch_warnings():
                # Minari asks for a code link and an e-mail: the dataset names the exact
                # package version it was made with (requirements), which is what reproduces it
                warnings.filterwarnings("ignore", "`code_permalink`", UserWarning)
                warnings.filterwarnings("ignore", "`author_email`", UserWarning)
                collector.create_dataset(
                    dataset_id,
                    eval_env=env.spec,
                    algorithm_name=f"agrinav {policy}",
                    description=f"{policy} on {env_id}, reset seeds {seed}..{seed + episodes - 1}",
                    author="AgriNav Gym developers",
                    requirements=[f"agrinav-gym=={version('agrinav-gym')}"],
                    # the D4RL convention: 0 = uniformly random actions, 1 = the recorded policy
                    ref_min_score=reference,
                    ref_max_score=float(np.mean(returns)),
                )
        except (KeyboardInterrupt, SystemExit):  # Ctrl-C, SIGTERM: say what stays
            bar.close()
            print(
                f"dataset: stopped after {len(returns)} of {episodes} episodes; nothing was "
                "kept (a Minari dataset is written whole: rerun to record it)",
                file=sys.stderr,
            )
            raise
        finally:
            collector.close()
    return Path(out) / dataset_id


def random_return(env_id: str, seed: int, episodes: int) -> float:
    """Mean return of uniformly random actions on the recorded reset seeds (the reference
    minimum score); the action space is seeded, so it is the same every time."""
    import gymnasium as gym

    env = gym.make(env_id)
    try:
        env.action_space.seed(seed)
        returns = []
        for k in tqdm(range(episodes), unit="episode", desc="random actions (reference score)"):
            env.reset(seed=seed + k)
            total, done = 0.0, False
            while not done:
                _, r, term, trunc, _ = env.step(env.action_space.sample())
                total += float(r)
                done = term or trunc
            returns.append(total)
        return float(np.mean(returns))
    finally:
        env.close()


def load(out: str | Path, dataset_id: str = "agrinav/furrow_follow-v0") -> Any:
    """The Minari dataset ``record`` wrote under ``out``, without setting
    ``MINARI_DATASETS_PATH`` by hand (it names the folder Minari reads datasets from)."""
    minari = _minari()
    if not (Path(out) / dataset_id).is_dir():
        raise InputError("dataset", str(Path(out) / dataset_id), "allowed: a folder record wrote")
    with _datasets_root(Path(out)):
        return minari.load_dataset(dataset_id)
