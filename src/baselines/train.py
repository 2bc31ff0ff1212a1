"""``agrinav train``: PPO on an AgriNav env, hyperparameters from ``hyperparams/ppo.yml``.

A run folder holds the final checkpoint (``checkpoint.json`` + ``policy.npz`` +
``optimizer.npz``, the safe format of ``policies.checkpoint``), ``checkpoints/step_N/`` every
``checkpoint_every`` steps (resume from any of them), ``config.yml`` (the exact hyperparameters
in zoo's format, env kwargs, seeds, versions), ``command.txt``, ``evaluations.json`` and
``learning_curve.png`` (held-out scenario seeds), and ``logs/`` (SB3's logger: CSV, and
TensorBoard event files when ``tensorboard`` is installed; every evaluation, the final one
included, under SB3's ``EvalCallback`` tags: ``EVAL_TAGS``). ``--device`` is checked to exist
(``resolve_device``) and the device trained on is recorded in ``checkpoint.json`` and
``config.yml``.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import shlex
import shutil
import sys
import threading
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from policies import checkpoint
from scenario_gen.atomic import check_creatable, lock_output, make_parents, remove_empty
from scenario_gen.errors import InputError, Notice
from scenario_gen.schema import to_mapping

from . import hyperparams as hpmod
from .evaluate import evaluate
from .figures import learning_curve


@dataclass(frozen=True)
class TrainRun:
    """Everything a run needs, checked before anything is created."""

    env_id: str
    out: Path
    seed: int = 0
    timesteps: int | None = None
    eval_every: int = 20_000
    eval_episodes: int = 4
    n_envs: int | None = None
    device: str = "cpu"
    overrides: dict[str, Any] = field(default_factory=dict)
    scenario: str | None = None
    checkpoint_every: int | None = None
    resume: Path | None = None
    # a new run that starts from this checkpoint's weights and observation normalisation
    # (fine-tuning: its own step count, a fresh optimizer, no warm start)
    init_from: Path | None = None
    warm_start: bool = True  # the env's envs.yml warm_start, if it has one
    env_kwargs: Path | None = None  # a YAML mapping merged over envs.yml's env_kwargs


def merge_env_kwargs(base: dict[str, Any], path: Path) -> dict[str, Any]:
    """``base`` with the YAML mapping in ``path`` merged over it
    (``hyperparams.merge_env_kwargs``)."""
    from scenario_gen.schema import load_yaml

    extra = load_yaml(path, "--env-kwargs")
    hpmod.refuse_split_keys(extra)
    check_make_keywords(extra)
    return hpmod.merge_env_kwargs(base, extra)


def check_make_keywords(kwargs: dict[str, Any]) -> None:
    """``gym.make``'s own keywords, which reach Gymnasium unchecked by the env (a negative step
    limit was a traceback from inside it, a number as a switch taken silently)."""
    steps = kwargs.get("max_episode_steps")
    if "max_episode_steps" in kwargs and steps is not None:
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise InputError(
                "--env-kwargs: max_episode_steps", steps, "allowed: an integer >= 1, or null"
            )
    checker = kwargs.get("disable_env_checker")
    if "disable_env_checker" in kwargs and not isinstance(checker, bool):
        raise InputError("--env-kwargs: disable_env_checker", checker, "allowed: true or false")


def _scenario_kwargs(env_kwargs: dict[str, Any], scenario: str | None) -> dict[str, Any]:
    """Train on a preset, a saved scenario folder or a bank instead of the file's scenario."""
    if scenario is None:
        return env_kwargs
    import scenario_gen as sg

    kw = {
        k: v for k, v in env_kwargs.items() if k not in ("scenario", "scenario_overrides", "bank")
    }
    path = Path(scenario)
    if (path / "scenario.json").is_file():
        kw["scenario"] = str(path.resolve())
    elif (path / "bank.yaml").is_file() or (path.is_dir() and any(path.glob("*/scenario.json"))):
        kw["bank"] = str(path.resolve())
    elif scenario in sg.preset_names():
        kw["scenario"] = scenario
        return kw
    else:
        raise InputError(
            "--scenario", scenario, "allowed: a preset, a scenario folder or a bank folder"
        )
    # a saved scenario cannot be regenerated: only env-side keys stay randomized
    from agrinav_gym.scenarios import ENV_KEYS

    rand = {k: v for k, v in (kw.get("randomize") or {}).items() if k in ENV_KEYS}
    kw["randomize"] = rand or None
    return kw


#: what a resumed run cannot change: the network and what its inputs were scaled by
RESUME_FIXED = ("policy", "policy_kwargs", "normalize")


def _same(key: str, a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Whether two hyperparameter sets agree on ``key`` (``normalize``: on observations, in
    either spelling — ``true`` or ``{norm_obs: true, ...}``)."""
    if key != "normalize":
        return bool(a[key] == b[key])

    def on(v: Any) -> bool:
        return bool(v.get("norm_obs", True)) if isinstance(v, dict) else bool(v)

    return on(a[key]) == on(b[key])


#: flags that say what a --hyperparams key says (a run given both took the flag's silently)
FLAG_KEYS = (("--n-envs", "n_envs", "n_envs"), ("--timesteps", "timesteps", "n_timesteps"))
#: env kwargs that --scenario replaces
SCENARIO_KEYS = ("scenario", "scenario_overrides", "bank")


def _refuse_both(run: TrainRun) -> None:
    """A setting given twice, two ways, differently: refused, as a flag given twice is."""
    for flag, attribute, key in FLAG_KEYS:
        value = getattr(run, attribute)
        if value is not None and key in run.overrides and run.overrides[key] != value:
            raise InputError(
                flag,
                value,
                f"--hyperparams {key}={run.overrides[key]!r} says otherwise; allowed: one of "
                "the two",
            )
    if run.scenario is not None and run.env_kwargs is not None:
        from scenario_gen.schema import load_yaml

        given = load_yaml(run.env_kwargs, "--env-kwargs")
        keys = [k for k in SCENARIO_KEYS if isinstance(given, dict) and k in given]
        if keys:
            raise InputError(
                "--scenario",
                run.scenario,
                f"--env-kwargs {run.env_kwargs} sets {', '.join(keys)} too, which --scenario "
                "replaces; allowed: one of the two",
            )


def prepare(run: TrainRun) -> tuple[hpmod.PPOHyperparams, hpmod.EnvSetup, dict[str, Any]]:
    _refuse_both(run)
    overrides = dict(run.overrides)
    if run.n_envs is not None:
        overrides["n_envs"] = run.n_envs
    if run.timesteps is not None:
        overrides["n_timesteps"] = run.timesteps
    saved: dict[str, Any] = {}
    meta: dict[str, Any] = checkpoint.read_meta(run.resume) if run.resume is not None else {}
    if run.resume is not None:
        # a resumed run goes on with the hyperparameters it was trained with (the command's
        # --hyperparams over them), not ppo.yml's: they may have been changed since
        saved = meta.get("hyperparams") or {}
        if not isinstance(saved, dict):
            raise InputError("--resume", str(run.resume), "its hyperparams are not a mapping")
        for key in RESUME_FIXED:
            if key in run.overrides and key in saved and not _same(key, run.overrides, saved):
                raise InputError(
                    f"hyperparams.{key}",
                    run.overrides[key],
                    f"the checkpoint was trained with {saved[key]!r}; allowed: that, to "
                    "--resume (or --init-from for a new run from its weights)",
                )
    hp, setup = hpmod.load(run.env_id, {**saved, **overrides})
    if run.out.exists() and (not run.out.is_dir() or any(run.out.iterdir())):
        raise InputError("--out", str(run.out), "allowed: a new or empty directory")
    check_creatable(run.out, "--out")
    resolve_device(run.device)  # an unavailable device is refused before anything is made
    if run.init_from is not None and run.resume is not None:
        raise InputError(
            "--init-from", str(run.init_from), "allowed: --resume or --init-from, not both"
        )
    resumed = None
    if run.resume is not None:
        if meta.get("env_id") != run.env_id or meta.get("optimizer") is None:
            raise InputError(
                "--resume",
                str(run.resume),
                f"allowed: a training checkpoint of {run.env_id} (with optimizer.npz)",
            )
        # every file of the checkpoint read now, before --out exists: a truncated optimizer
        # state used to fail after the run folder was made
        resumed = checkpoint.load(run.resume)
        checkpoint.read_npz(run.resume / checkpoint.OPTIMIZER, "--resume")
        done = int(meta.get("num_timesteps", 0))
        if hp.n_timesteps <= done:
            raise InputError(
                "--timesteps", hp.n_timesteps, f"allowed: more than the {done} steps already done"
            )
    init = None
    if run.init_from is not None:
        init = checkpoint.load(run.init_from)
        # the weights fit only the network they were trained in
        ours = checkpoint.policy_kwargs_to_json(hp.policy_kwargs)
        theirs_kw = init.meta.get("policy_kwargs") or {}
        for key in ("net_arch", "activation_fn"):
            if ours.get(key) != theirs_kw.get(key):
                raise InputError(
                    "--init-from",
                    str(run.init_from),
                    f"its network has {key} {theirs_kw.get(key)!r} where this run's "
                    f"hyperparameters have {ours.get(key)!r}; allowed: the same network "
                    f"(--hyperparams policy_kwargs=...)",
                )
        theirs = init.meta.get("normalization") is not None
        if theirs != hp.normalize_obs:  # the weights expect inputs scaled as in training
            on = {True: "on", False: "off"}
            raise InputError(
                "--init-from",
                str(run.init_from),
                f"has observation normalisation {on[theirs]} where {run.env_id}'s "
                f"hyperparameters have it {on[hp.normalize_obs]}; allowed: a checkpoint "
                f"trained with it {on[hp.normalize_obs]}",
            )
    base = dict(setup.env_kwargs)
    if run.env_kwargs is not None:
        base = merge_env_kwargs(base, run.env_kwargs)
    kwargs = _scenario_kwargs(base, run.scenario)
    import gymnasium as gym

    import agrinav_gym

    probe = gym.make(
        agrinav_gym.check_env_id(run.env_id, "env_id"),
        **kwargs,
        scenario_seeds=list(setup.train_seeds),
    )
    try:  # every env kwarg is valid before the run starts
        if init is not None:
            _check_spaces(init, probe, run.init_from)
        if resumed is not None:
            _check_spaces(resumed, probe, run.resume, "--resume")
    finally:
        probe.close()
    if run.resume is not None:
        trained = meta.get("env_kwargs")
        if isinstance(trained, dict) and trained != kwargs:
            changed = sorted(k for k in {*trained, *kwargs} if trained.get(k) != kwargs.get(k))
            warnings.warn(
                Notice(
                    f"--resume {run.resume} was trained with other env_kwargs "
                    f"({', '.join(changed)} differ): the run goes on in this command's env "
                    "(--env-kwargs, --scenario)"
                ),
                stacklevel=2,
            )
    # SB3 collects whole rollouts: asked for less than one, a run would train a whole one
    done = int(meta.get("num_timesteps", 0))
    rollout = hp.n_steps * hp.n_envs
    if hp.n_timesteps - done < rollout:
        raise InputError(
            "--timesteps",
            hp.n_timesteps,
            f"is less than one rollout{f' past the {done} steps done' if done else ''} "
            f"(n_steps {hp.n_steps} × n_envs {hp.n_envs} = {rollout} steps, which PPO "
            f"collects whole); allowed: at least {done + rollout}, or a smaller "
            "--hyperparams n_steps or --n-envs",
        )
    if (hp.n_timesteps - done) % rollout:
        whole = done + -(-(hp.n_timesteps - done) // rollout) * rollout
        warnings.warn(
            Notice(
                f"--timesteps {hp.n_timesteps} trains {whole} steps: PPO collects whole "
                f"rollouts of n_steps {hp.n_steps} × n_envs {hp.n_envs}"
            ),
            stacklevel=2,
        )
    return hp, setup, kwargs


def held_out(env_kwargs: dict[str, Any]) -> bool:
    """Whether validation seeds draw fields training never sees: not on a bank or a saved
    scenario folder, whose fields are the same whatever the seeds."""
    scenario = env_kwargs.get("scenario")
    folder = isinstance(scenario, str) and Path(scenario).is_dir()
    return env_kwargs.get("bank") is None and not folder


def _check_spaces(init: Any, env: Any, folder: Path | None, what: str = "--init-from") -> None:
    """A checkpoint to start from must see and act as the env does."""
    for space, theirs, ours in (
        ("observation space", init.policy.observation_space, env.observation_space),
        ("action space", init.policy.action_space, env.action_space),
    ):
        if checkpoint.space_to_json(theirs) != checkpoint.space_to_json(ours):
            raise InputError(
                what,
                str(folder),
                f"its {space} is not the env's; allowed: a checkpoint of an env with the same "
                "observations and actions",
            )


#: What ``--device`` takes.
DEVICES = ("cpu", "cuda", "cuda:N", "mps", "auto")


def resolve_device(text: str) -> str:
    """The torch device ``text`` names, checked to exist here: ``cpu``, ``cuda`` (the current
    CUDA device), ``cuda:N``, ``mps`` (Apple GPUs), or ``auto`` — CUDA where there is one,
    else the CPU (Stable-Baselines3's ``auto``; MPS only when named). An unavailable device is
    one clear error: Stable-Baselines3 itself would fall back to the CPU without a word."""
    import re

    import torch

    mps = getattr(torch.backends, "mps", None)
    has_mps = mps is not None and mps.is_available()
    here = f"allowed here: cpu, {'mps, ' if has_mps else ''}auto"
    if text == "auto":
        return resolve_device("cuda") if torch.cuda.is_available() else "cpu"
    if text == "cpu":
        return text
    cuda = re.fullmatch(r"cuda(?::(\d+))?", text) if isinstance(text, str) else None
    if cuda is not None:
        if not torch.cuda.is_available():
            build = f"torch {torch.__version__}" + (
                "" if torch.version.cuda else ", built without CUDA"
            )
            raise InputError("--device", text, f"CUDA is not available here ({build}); {here}")
        count = torch.cuda.device_count()
        index = int(cuda.group(1)) if cuda.group(1) else torch.cuda.current_device()
        if index >= count:
            raise InputError(
                "--device", text, f"allowed: cuda:0 to cuda:{count - 1} ({count} CUDA devices here)"
            )
        return f"cuda:{index}"
    if text == "mps":
        if not has_mps:
            raise InputError("--device", text, f"MPS is not available here; {here}")
        return text
    raise InputError("--device", text, f"allowed: {', '.join(DEVICES)}")


def device_record(device: str) -> dict[str, str]:
    """The device a run trained on, as its checkpoint and config.yml record it."""
    import platform

    import torch

    if device.startswith("cuda"):
        name = torch.cuda.get_device_name(torch.device(device))
    elif device == "mps":
        name = "Apple MPS"
    else:
        name = platform.processor() or platform.machine()
    return {"device": device, "device_name": name}


#: Evaluation results as logged (TensorBoard, CSV): Stable-Baselines3's ``EvalCallback`` tags
#: where it has one, the paper's metrics beside them.
EVAL_TAGS = {
    "return": "eval/mean_reward",
    "length": "eval/mean_ep_length",
    "success": "eval/success_rate",
    "rmse": "eval/rmse",
    "in_furrow_rmse": "eval/in_furrow_rmse",
    "completion": "eval/completion",
    "crops_hit": "eval/crops_hit",
}


def evaluations_json(history: list[dict[str, float]]) -> str:
    """The evaluations as strict JSON: null where no episode measured a value (NaN: routes
    that never reached a furrow step), which ``json.dumps`` would write as bare ``NaN``."""
    known = [{k: None if v != v else v for k, v in h.items()} for h in history]
    return json.dumps(known, indent=1, allow_nan=False)


def log_evaluation(logger: Any, res: dict[str, float], step: int) -> None:
    """One evaluation into SB3's logger, written at ``step``."""
    for key, tag in EVAL_TAGS.items():
        logger.record(tag, res[key])
    logger.dump(step)


def train(run: TrainRun, argv: list[str] | None = None) -> Path:
    hp, setup, kwargs = prepare(run)
    out = run.out
    made = make_parents(out.absolute())
    try:
        # A second run on the same --out is refused while this one holds the lock (both used
        # to exit 0, the second overwriting every checkpoint of the first).
        with lock_output(out.absolute(), "--out"):
            if out.exists() and (not out.is_dir() or any(out.iterdir())):
                raise InputError("--out", str(out), "allowed: a new or empty directory")
            created = not out.exists()
            out.mkdir(parents=True, exist_ok=True)
            try:
                cmd = argv if argv is not None else sys.argv  # first: a stopped run says so too
                (out / "command.txt").write_text(" ".join(shlex.quote(a) for a in cmd) + "\n")
                return _train(run, argv, hp, setup, kwargs)
            except BaseException:
                _stopped(out, created)
                raise
    except BaseException:
        remove_empty(made)  # the parent folders this run made, when nothing was kept in them
        raise


def _stopped(out: Path, created: bool) -> None:
    """A run that ended early: the checkpoints it finished stay (resumable, and the folder's
    command.txt says how it began); a run that finished none leaves nothing behind."""
    kept = sorted((out / "checkpoints").glob("step_*")) if (out / "checkpoints").is_dir() else []
    if kept:
        print(
            f"agrinav train: stopped; {len(kept)} checkpoint(s) kept in {out / 'checkpoints'} "
            f"(go on: --resume {kept[-1]} --out NEW_FOLDER)",
            file=sys.stderr,
        )
    elif created:
        shutil.rmtree(out, ignore_errors=True)
    else:  # the user's empty folder: emptied again
        for child in out.iterdir():
            if child.is_dir():
                shutil.rmtree(child, ignore_errors=True)
            else:
                child.unlink()


def _train(
    run: TrainRun,
    argv: list[str] | None,
    hp: hpmod.PPOHyperparams,
    setup: hpmod.EnvSetup,
    kwargs: dict[str, Any],
) -> Path:
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    out = run.out
    device = resolve_device(run.device)
    env_id = f"agrinav_gym:{run.env_id}"
    venv: Any = make_vec_env(
        functools.partial(_worker_env, env_id) if hp.n_envs > 1 else env_id,
        n_envs=hp.n_envs,
        seed=run.seed,
        vec_env_cls=SubprocVecEnv if hp.n_envs > 1 else DummyVecEnv,
        env_kwargs={**kwargs, "scenario_seeds": list(setup.train_seeds)},
    )
    norm = None
    if hp.normalize_obs:
        venv = norm = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0)
    try:
        model = PPO(env=venv, seed=run.seed, verbose=0, device=device, **hp.ppo_kwargs())
    except TypeError as exc:  # a keyword the policy's classes do not take (extractor kwargs)
        venv.close()
        raise InputError(
            "hyperparams.policy_kwargs", hp.policy_kwargs, f"cannot build the policy ({exc})"
        ) from None
    formats = ["csv", *(["tensorboard"] if _has_tensorboard() else [])]
    model.set_logger(configure(str(out / "logs"), formats))
    if run.resume is not None:
        restore(model, norm, run.resume)
    elif run.init_from is not None:
        restore(model, norm, run.init_from, "--init-from", optimizer=False)
        model.num_timesteps = model._num_timesteps_at_start = 0
    # Training-time evaluation (the curve, the best checkpoint, any stop/continue decision)
    # sees validation fields only: the test seeds are agrinav bench's.
    eval_kwargs = {**kwargs, "scenario_seeds": list(setup.val_seeds)}
    if not held_out(kwargs):
        warnings.warn(
            Notice(
                f"--scenario {run.scenario}: a saved scenario or bank has no held-out split, so "
                "the training-time evaluation drives the training fields (config.yml "
                "validation_fields says so): its curve is not a held-out score"
            ),
            stacklevel=2,
        )
    saver = _Saver(out, run, hp, setup, kwargs, device_record(device))
    history: list[dict[str, float]] = []
    t_start = time.perf_counter()

    def evaluation(m: Any) -> dict[str, float]:
        res = evaluate(
            _predictor(m, norm), run.env_id, eval_kwargs, run.eval_episodes, setup.val_seeds[0]
        )
        res.update(timesteps=int(m.num_timesteps), minutes=(time.perf_counter() - t_start) / 60)
        history.append(res)
        (out / "evaluations.json").write_text(evaluations_json(history))
        log_evaluation(m.logger, res, int(m.num_timesteps))
        return res

    ws = setup.warm(run.env_id) if run.warm_start and run.init_from is None else None
    if ws is not None and run.resume is None:
        from .imitation import clone, demonstrate

        train_kwargs = {**kwargs, "scenario_seeds": list(setup.train_seeds)}
        demo = demonstrate(run.env_id, train_kwargs, ws, hp.gamma, run.seed)
        fit = clone(model, norm, demo, ws, run.seed)
        report = {
            **to_mapping(ws),
            "steps": len(demo),
            "episodes": demo.episodes,
            "successes": demo.successes,
            **fit,
            "minutes": (time.perf_counter() - t_start) / 60,
        }
        (out / "warm_start.json").write_text(json.dumps(report, indent=1))
        evaluation(model)  # the clone itself, at 0 PPO steps
    elif run.init_from is not None:
        evaluation(model)  # the starting checkpoint on this run's validation fields

    callback = _callback(hp.n_timesteps, run, evaluation, lambda m: saver.periodic(m, norm))
    try:
        # resuming, SB3 counts total_timesteps on top of the steps already done
        model.learn(
            total_timesteps=hp.n_timesteps - int(model.num_timesteps),
            callback=callback,
            reset_num_timesteps=run.resume is None,
        )
        if not history or history[-1]["timesteps"] != int(model.num_timesteps):
            evaluation(model)  # the final policy's, logged like the others
    except BaseException as exc:
        # an interrupt or error mid-run: closing the workers must not hide it behind an error
        # of theirs (a pipe a dying worker closed)
        bar = getattr(callback, "bar", None)
        if bar is not None:  # before the error's line, not after it
            bar.close()
        _bounded(venv.close)
        _bounded(model.logger.close)
        if _diverged(exc):
            raise InputError(
                "hyperparams.learning_rate",
                hp.learning_rate,
                f"training diverged by step {int(model.num_timesteps)} (the policy's outputs "
                "are no longer finite); allowed: a smaller step size (ppo.yml's for this env: "
                f"{hpmod.load(run.env_id)[0].learning_rate}) or a tighter max_grad_norm "
                f"(now {hp.max_grad_norm:g})",
            ) from exc
        raise
    venv.close()
    model.logger.close()
    saver.final(model, norm, history)
    learning_curve(history, out / "learning_curve.png", run.env_id)
    return out


def _bounded(close: Callable[[], None], seconds: float = 15.0) -> None:
    """A clean-up after an interrupt, given ``seconds``: the interrupt can land while a lock
    is held (a worker's pipe, a log writer's queue), and a stop must not hang on it (an
    error of the clean-up's own must not hide the one being raised either)."""

    def run() -> None:
        with contextlib.suppress(Exception):
            close()

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(seconds)


def _diverged(exc: BaseException) -> bool:
    """torch's distributions refuse NaN or infinite parameters: the network's weights blew up."""
    text = str(exc)
    return isinstance(exc, ValueError) and "Expected parameter" in text and "invalid" in text


def _worker_env(env_id: str, **kwargs: Any) -> Any:
    """An env in a SubprocVecEnv worker, deaf to Ctrl-C: the terminal signals the whole process
    group, and the main process, which handles it, closes the workers (each would otherwise
    print a traceback of its own)."""
    import signal

    import gymnasium as gym

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return gym.make(env_id, **kwargs)


def _has_tensorboard() -> bool:
    try:
        import tensorboard  # noqa: F401
    except ImportError:
        print(
            "note: tensorboard is not installed (pip install 'agrinav-gym[train]'): CSV logs only"
        )
        return False
    return True


def _predictor(model: Any, norm: Any) -> Callable[[dict[str, Any]], Any]:
    def act(obs: dict[str, Any]) -> Any:
        o = obs
        if norm is not None:
            o = norm.normalize_obs({k: v[None] for k, v in obs.items()})
            o = {k: v[0] for k, v in o.items()}
        return model.predict(o, deterministic=True)[0]

    return act


def _callback(
    total: int,
    run: TrainRun,
    evaluation: Callable[[Any], dict[str, float]],
    save: Callable[[Any], None],
) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm import tqdm

    class Progress(BaseCallback):
        """Progress bar; periodic held-out evaluation (logged by ``evaluation``); checkpoints."""

        def _on_training_start(self) -> None:
            start = int(self.model.num_timesteps)
            self.bar = tqdm(total=total, initial=start, desc=f"train {run.env_id}", unit="step")
            self.next_eval = start + run.eval_every
            self.next_save = start + (run.checkpoint_every or total + 1)

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _evaluate(self) -> None:
            # between rollouts only, as the checkpoints: an evaluation inside a rollout scored
            # weights updated on fewer steps than the label it carried
            if self.num_timesteps >= self.next_eval:
                while self.next_eval <= self.num_timesteps:
                    self.next_eval += run.eval_every
                res = evaluation(self.model)
                self.bar.set_postfix(rmse=f"{res['rmse']:.3f}", done=f"{res['completion']:.0f}%")

        def _checkpoint(self) -> None:
            # between rollouts only: the weights and optimizer then hold every step counted
            # (a save inside a rollout would label N steps weights trained on fewer)
            if run.checkpoint_every and self.num_timesteps >= self.next_save:
                while self.next_save <= self.num_timesteps:
                    self.next_save += run.checkpoint_every
                save(self.model)

        def _on_rollout_start(self) -> None:  # the previous rollout's update is done
            self._checkpoint()
            self._evaluate()

        def _on_training_end(self) -> None:
            self._checkpoint()
            self.bar.close()

    return Progress()


class _Saver:
    def __init__(
        self,
        out: Path,
        run: TrainRun,
        hp: hpmod.PPOHyperparams,
        setup: hpmod.EnvSetup,
        kwargs: dict[str, Any],
        device: dict[str, str],
    ) -> None:
        self.out, self.run, self.hp, self.setup, self.kwargs = out, run, hp, setup, kwargs
        self.device = device  # the device trained on (device_record)

    def _meta(self, model: Any) -> dict[str, Any]:
        return {
            "env_id": self.run.env_id,
            "algo": "ppo",
            "seed": self.run.seed,
            "num_timesteps": int(model.num_timesteps),
            "hyperparams": hpmod.to_zoo(self.hp),
            "env_kwargs": self.kwargs,
            **self.device,
        }

    def write(self, folder: Path, model: Any, norm: Any) -> None:
        tmp = folder.with_name(f".{folder.name}.tmp-{os.getpid()}")
        shutil.rmtree(tmp, ignore_errors=True)
        name = "DepthMultiInputPolicy" if self.hp.policy != "MultiInputPolicy" else self.hp.policy
        try:
            checkpoint.save(
                tmp, model.policy, name, self.hp.policy_kwargs, norm, self._meta(model), True
            )
        except BaseException:  # a full disk, a kill: no half-written checkpoint stays behind
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        shutil.rmtree(folder, ignore_errors=True)
        tmp.rename(folder)

    def periodic(self, model: Any, norm: Any) -> None:
        (self.out / "checkpoints").mkdir(exist_ok=True)
        self.write(self.out / "checkpoints" / f"step_{int(model.num_timesteps):010d}", model, norm)

    def final(self, model: Any, norm: Any, history: list[dict[str, float]]) -> None:
        self.write(self.out / "final", model, norm)
        for f in (self.out / "final").iterdir():
            f.rename(self.out / f.name)
        (self.out / "final").rmdir()
        config = {
            "env_id": self.run.env_id,
            "algo": "ppo",
            "seed": self.run.seed,
            "hyperparams": hpmod.to_zoo(self.hp),
            "env_kwargs": self.kwargs,
            "train_seeds": list(self.setup.train_seeds),
            "val_seeds": list(self.setup.val_seeds),
            "validation_fields": (
                "held out: fields of val_seeds"
                if held_out(self.kwargs)
                else "the training fields (a saved scenario or bank has no held-out split)"
            ),
            "eval_seeds": list(self.setup.eval_seeds),
            "resumed_from": str(self.run.resume) if self.run.resume else None,
            "initialised_from": str(self.run.init_from) if self.run.init_from else None,
            # behaviour cloning before PPO (warm_start.json: its fit); a resumed run inherits it
            "warm_start": (
                self.setup.warm_start
                if self.run.warm_start and not self.run.resume and not self.run.init_from
                else None
            ),
            "minutes": history[-1]["minutes"] if history else None,
            **self.device,
            "versions": {
                n: metadata.version(n) for n in ("stable-baselines3", "torch", "agrinav-gym")
            },
        }
        (self.out / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))


def restore(
    model: Any, norm: Any, folder: Path, what: str = "--resume", optimizer: bool = True
) -> None:
    """Weights, Adam's state (with ``optimizer``, where the checkpoint holds it), normalisation
    statistics and step count from a checkpoint into an SB3 ``model`` (and its VecNormalize
    ``norm``)."""
    import torch

    loaded = checkpoint.load(folder)
    model.policy.load_state_dict(loaded.policy.state_dict())
    meta = loaded.meta
    opt = meta.get("optimizer")
    if optimizer and opt is not None:
        arrays = checkpoint.read_npz(folder / checkpoint.OPTIMIZER, what)
        state = model.policy.optimizer.state_dict()
        names = [n for n, _ in model.policy.named_parameters()]
        if names != opt["params"]:
            raise InputError(what, str(folder), "its optimizer does not fit this network")
        for i, n in enumerate(names):
            entries = {k.split("/", 1)[1]: v for k, v in arrays.items() if k.split("/", 1)[0] == n}
            if entries:
                state["state"][i] = {k: torch.from_numpy(v) for k, v in entries.items()}
        model.policy.optimizer.load_state_dict(state)
    if norm is not None:
        n = meta["normalization"]
        for k, rms in norm.obs_rms.items():
            rms.mean = np.asarray(n["mean"][k], np.float64)
            rms.var = np.asarray(n["var"][k], np.float64)
            rms.count = float((n.get("count") or {}).get(k, rms.count))  # checked on load
    model.num_timesteps = int(meta.get("num_timesteps", 0))
    model._num_timesteps_at_start = model.num_timesteps
