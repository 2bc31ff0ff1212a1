"""The config reference (docs/config.md), generated from the fields' own metadata.

``python -m baselines.configdoc`` rewrites the file; a test checks it is current, so the
documentation, the validation and the defaults cannot drift apart.
"""

from __future__ import annotations

import sys
from pathlib import Path

from scenario_gen.schema import field_rows

HEADER = """# Configuration reference

Generated from the config classes by `python -m baselines.configdoc` — do not edit by hand.
Every table is what the code validates: unknown keys are errors, values outside *allowed* are
refused with the field named. Units are in the descriptions; `*_deg` fields are degrees.
"""


def _table(title: str, intro: str, cls: type, prefix: str = "") -> list[str]:
    lines = [
        f"## {title}",
        "",
        intro,
        "",
        "| key | default | allowed | meaning |",
        "|---|---|---|---|",
    ]
    for name, default, allowed, doc in field_rows(cls, prefix):
        doc = doc.replace("|", "\\|")  # |cte| inside a table cell
        lines.append(f"| `{name}` | `{default}` | {allowed} | {doc} |")
    return [*lines, ""]


def reference() -> str:
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.rewards import REWARD_TERMS, RewardTerm
    from baselines.hyperparams import EnvSetup, PPOHyperparams
    from baselines.imitation import WarmStart
    from policies.dwb import DWBParams
    from scenario_gen.spec import ScenarioSpec

    out = [HEADER]
    out += _table(
        "Scenario spec",
        "`scenario_gen.preset(name, **overrides)`, `agrinav scenario --set key=value`, "
        "`--config file.yaml`, and the scenario keys of an env's `randomize`.",
        ScenarioSpec,
    )
    out += _table(
        "Env config",
        "`gym.make(id, config={section: {key: value}})`.",
        EnvConfig,
        "config.",
    )
    out += [
        "## Reward terms",
        "",
        "`config={'reward': {term: {weight: w, ...}}}`: the reward is Σ weight × term; each "
        "weighted term is reported in `info['rewards']`.",
        "",
    ]
    for name, cls in REWARD_TERMS.items():
        doc = " ".join((cls.__doc__ or "").split()) if cls.__doc__ != RewardTerm.__doc__ else ""
        out += _table(f"`{name}`", doc, cls, f"config.reward.{name}.")
    out += _table(
        "DWB parameters",
        "`policies/config/dwb_nav2.yaml` (the reference) and `dwb_furrow.yaml` (its changes), "
        "Nav2's names; `make_policy('dwb:nav2' | 'dwb:furrow' | 'dwb:FILE.yaml', env)` (a file "
        "lists changes to `dwb_nav2.yaml`). null: the robot's own value.",
        DWBParams,
    )
    out += _table(
        "PPO hyperparameters",
        "`src/baselines/hyperparams/ppo.yml` (rl-baselines3-zoo format) and `agrinav train "
        "--hyperparams key=value`.",
        PPOHyperparams,
    )
    out += _table(
        "Training env setup",
        "`src/baselines/hyperparams/envs.yml`: what zoo takes on its command line.",
        EnvSetup,
    )
    out += _table(
        "PPO warm start",
        "`warm_start:` of an env in `envs.yml`: behaviour cloning of a controller before PPO "
        "(`agrinav train --no-warm-start` skips it, and so does a run that starts from a "
        "checkpoint with `--init-from`).",
        WarmStart,
    )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """``python -m baselines.configdoc [PATH]``: write the reference (default docs/config.md)."""
    if argv and (argv[0].startswith("-") or len(argv) > 1):
        print("usage: python -m baselines.configdoc [PATH]  (default: docs/config.md)")
        return 0 if argv[0] in ("-h", "--help") else 2
    path = Path(argv[0] if argv else "docs/config.md")
    path.write_text(reference())
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
