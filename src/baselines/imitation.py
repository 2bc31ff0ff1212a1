"""A warm start for PPO: behaviour cloning of a classical controller, actor and critic.

PPO from scratch on the randomized FieldRoute fields learned to follow a furrow but not the
headland U-turn (45 % completion after 750k steps). Here a controller that drives the turn
(``rpp`` by default) drives the *training* fields first, with a correlated yaw-rate
perturbation on what is executed so that the data holds the recoveries from off-line states
(DART: the label is always the controller's own, unperturbed action). PPO's actor mean is
then regressed onto those actions and its critic onto the discounted returns of the same
rollouts — a critic that already knows the value of driving keeps the first PPO updates from
undoing the clone. PPO then trains as usual, on its own reward.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from scenario_gen.arrays import FloatArray
from scenario_gen.schema import param


@dataclass(frozen=True)
class WarmStart:
    """``envs.yml``'s ``warm_start`` section: who demonstrates, how much, how it is fitted."""

    policy: str = param("rpp", "controller that demonstrates (dwb, rpp, depth)")
    episodes: int = param(40, "demonstration episodes on training fields", 1, 10_000)
    steer_noise: float = param(
        0.3, "std of the yaw-rate perturbation executed (not labelled), rad/s", 0, 3
    )
    steer_noise_tau: float = param(1.0, "correlation time of the perturbation, s", 0.05, 60)
    epochs: int = param(30, "passes over the demonstrations", 1, 1000)
    learning_rate: float = param(1e-3, "Adam step size of the fit", 1e-6, 1)


@dataclass
class Demonstrations:
    obs: dict[str, NDArray[np.float32]]  # (n, ...) per observation key
    actions: NDArray[np.float32]  # (n, 2) the controller's own actions
    returns: NDArray[np.float32]  # (n,) discounted return from each step (0 after the end)
    episodes: int
    successes: int

    def __len__(self) -> int:
        return len(self.actions)


def demonstrate(
    env_id: str,
    env_kwargs: dict[str, Any],
    ws: WarmStart,
    gamma: float,
    seed: int,
) -> Demonstrations:
    """``ws.episodes`` episodes of ``ws.policy`` on the env built from ``env_kwargs`` (which
    carry the training scenario seeds), one ``SeedSequence`` for resets and perturbation."""
    import gymnasium as gym

    import agrinav_gym
    from policies import make_policy

    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5EED]))
    env: Any = gym.make(agrinav_gym.check_env_id(env_id), **env_kwargs)
    obs_buf: dict[str, list[NDArray[np.float32]]] = {}
    acts: list[NDArray[np.float32]] = []
    rets: list[FloatArray] = []
    successes = 0
    try:
        pi = make_policy(ws.policy, env)
        u = env.unwrapped
        a = math.exp(-u.dt / ws.steer_noise_tau)
        w_max = u.interface.w_max
        for _ in tqdm(range(ws.episodes), desc=f"demonstrations ({ws.policy})", unit="episode"):
            obs, _ = env.reset(seed=int(rng.integers(2**31)))
            pi.reset()
            noise, rewards = 0.0, []
            while True:
                act = np.asarray(pi.act(obs), np.float32)
                for k, v in obs.items():
                    obs_buf.setdefault(k, []).append(np.asarray(v, np.float32))
                acts.append(act.copy())
                noise = a * noise + ws.steer_noise * math.sqrt(1 - a * a) * rng.normal()
                run = act.copy()
                run[1] = np.clip(run[1] + noise / w_max, -1.0, 1.0)
                obs, r, term, trunc, info = env.step(run)
                rewards.append(float(r))
                if term or trunc:
                    successes += bool(info.get("is_success", False))
                    break
            rets.append(_discounted(np.asarray(rewards), gamma))
    finally:
        env.close()
    return Demonstrations(
        {k: np.stack(v) for k, v in obs_buf.items()},
        np.stack(acts),
        np.concatenate(rets).astype(np.float32),
        ws.episodes,
        successes,
    )


def _discounted(rewards: FloatArray, gamma: float) -> FloatArray:
    out = np.empty_like(rewards)
    acc = 0.0
    for i in range(len(rewards) - 1, -1, -1):
        acc = rewards[i] + gamma * acc
        out[i] = acc
    return out


def clone(
    model: Any, norm: Any, demo: Demonstrations, ws: WarmStart, seed: int
) -> dict[str, float]:
    """Fit ``model``'s actor mean to the demonstrated actions and its critic to their returns
    (observations normalised as ``norm`` will, its statistics started from the data); returns
    the final mean squared errors."""
    import torch

    obs = demo.obs
    if norm is not None:
        for k, rms in norm.obs_rms.items():
            x = obs[k].astype(np.float64)
            rms.mean, rms.var, rms.count = x.mean(axis=0), x.var(axis=0), float(len(x))
        obs = norm.normalize_obs(obs)
    policy = model.policy
    device = policy.device
    t_obs = {k: torch.as_tensor(np.asarray(v, np.float32), device=device) for k, v in obs.items()}
    t_act = torch.as_tensor(demo.actions, device=device)
    t_ret = torch.as_tensor(demo.returns, device=device)
    with torch.no_grad():  # returns are O(100): start the critic at their mean, fit the rest
        policy.value_net.bias.fill_(float(t_ret.mean()))
    opt = torch.optim.Adam(policy.parameters(), lr=ws.learning_rate)
    gen = torch.Generator().manual_seed(int(seed))
    n, batch = len(demo), 256
    a_err = v_err = float("nan")
    policy.set_training_mode(True)
    for _ in tqdm(range(ws.epochs), desc="behaviour cloning", unit="epoch"):
        perm = torch.randperm(n, generator=gen)
        sa = sv = 0.0
        for i in range(0, n, batch):
            idx = perm[i : i + batch].to(device)
            o = {k: v[idx] for k, v in t_obs.items()}
            features = policy.extract_features(o)
            if policy.share_features_extractor:
                latent_pi, latent_vf = policy.mlp_extractor(features)
            else:
                latent_pi = policy.mlp_extractor.forward_actor(features[0])
                latent_vf = policy.mlp_extractor.forward_critic(features[1])
            mean = policy.action_net(latent_pi)
            value = policy.value_net(latent_vf).squeeze(-1)
            la = torch.mean((mean - t_act[idx]) ** 2)
            lv = torch.mean((value - t_ret[idx]) ** 2)
            opt.zero_grad()
            (la + lv / max(1.0, float(t_ret.abs().mean()))).backward()
            opt.step()
            sa += float(la.detach()) * len(idx)
            sv += float(lv.detach()) * len(idx)
        a_err, v_err = sa / n, sv / n
    policy.set_training_mode(False)
    return {"action_mse": a_err, "value_mse": v_err}
