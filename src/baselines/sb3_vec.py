"""Stable-Baselines3 training over ``agrinav_gym.make_vec``: several envs per worker process.

SB3's ``SubprocVecEnv`` gives every env a process and pickles each env's info dict every step;
on a machine with fewer cores than envs the processes queue for the cores and the main process
unpickles one reply per env. ``BatchedSB3VecEnv`` runs the same envs ``n_envs / workers`` to a
process (``make_vec``: a Gymnasium ``SyncVectorEnv`` in each, infos packed into arrays) and turns
the batch back into what SB3 expects — a list of per-env infos, ``terminal_observation`` and
``TimeLimit.truncated`` at an episode's end, the reset's info in ``reset_infos`` — so a model
sees the same observations, rewards and episode ends as through ``SubprocVecEnv`` with the same
seeds (tested step for step). Episode statistics come from Gymnasium's
``RecordEpisodeStatistics`` (the ``episode`` info SB3's ``Monitor`` writes: ``r``, ``l``, ``t``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers import RecordEpisodeStatistics
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from agrinav_gym.vector import make_vec
from scenario_gen.errors import InputError

#: The keys SAME_STEP autoreset adds to a vector info at an episode's end.
_FINAL = ("final_obs", "final_info")


def unbatch_info(info: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """A Gymnasium vector info (arrays with ``_key`` masks, nested dicts alike) as ``n``
    per-env dicts holding the keys each env had; numbers come back as Python numbers."""
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in info.items():
        if key.startswith("_") and key[1:] in info:
            continue  # a mask
        mask = info.get(f"_{key}")
        if isinstance(value, dict):
            per_env: Sequence[Any] = unbatch_info(value, n)
        elif isinstance(value, np.ndarray) and value.dtype != object and value.ndim == 1:
            per_env = value.tolist()
        else:
            per_env = value
        for i in range(n):
            if mask is None or mask[i]:
                out[i][key] = per_env[i]
    return out


class BatchedSB3VecEnv(VecEnv):
    """An SB3 ``VecEnv`` of ``n_envs`` copies of ``gym.make(env_id, **env_kwargs)`` in
    ``workers`` processes (``agrinav_gym.make_vec``)."""

    def __init__(
        self,
        env_id: str,
        n_envs: int,
        workers: int | None = None,
        env_kwargs: dict[str, Any] | None = None,
        context: str = "spawn",
    ) -> None:
        self.venv = make_vec(
            env_id,
            n_envs,
            workers,
            context=context,
            autoreset_mode=AutoresetMode.SAME_STEP,
            wrappers=(RecordEpisodeStatistics,),
            **(env_kwargs or {}),
        )
        super().__init__(n_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self.render_mode = self.venv.render_mode
        self._actions: Any = None

    @property
    def workers(self) -> int:
        return len(self.venv.sizes)

    def reset(self) -> VecEnvObs:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        if any(self._options):
            raise InputError("options", self._options, "allowed: none (make_vec resets alike)")
        obs, info = self.venv.reset(seed=seeds)
        self.reset_infos = unbatch_info(info, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, term, trunc, info = self.venv.step(self._actions)
        dones = term | trunc
        if not dones.any():
            infos = unbatch_info(info, self.num_envs)
            for d in infos:  # as SubprocVecEnv, on every step
                d["TimeLimit.truncated"] = False
            return obs, rewards, dones, infos
        final_obs, final_info = info.get("final_obs"), info.get("final_info", {})
        now = unbatch_info(
            {k: v for k, v in info.items() if k.lstrip("_") not in _FINAL}, self.num_envs
        )
        ended = unbatch_info(final_info, self.num_envs)
        infos = []
        for i in range(self.num_envs):
            if not dones[i]:
                now[i]["TimeLimit.truncated"] = False
                infos.append(now[i])
                continue
            # as SubprocVecEnv: the last step's info, its observation and whether time ran out
            assert final_obs is not None
            ended[i]["terminal_observation"] = final_obs[i]
            ended[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
            infos.append(ended[i])
            self.reset_infos[i] = now[i]  # the new episode's reset info
        return obs, rewards, dones, infos

    def close(self) -> None:
        self.venv.close()

    def _all(self, indices: VecEnvIndices, what: str) -> None:
        if indices is not None and sorted(self._get_indices(indices)) != list(range(self.num_envs)):
            raise InputError("indices", indices, f"allowed: None (every env) for {what}")

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        values = self.venv.get_attr(attr_name)
        return [values[i] for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self._all(indices, "set_attr")
        self.venv.set_attr(attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        self._all(indices, "env_method")
        return list(self.venv.call(method_name, *method_args, **method_kwargs))

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        wrapped = self.venv.wrapped(wrapper_class)
        return [wrapped[i] for i in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return list(self.venv.render() or [None] * self.num_envs)
