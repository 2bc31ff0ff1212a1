"""Argument types shared by subcommands: checked at parse time, reported as one line."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import yaml

from scenario_gen.errors import InputError

MAX_SEED = 2**63 - 1


def int_at_least(lo: int, hi: int | None = None) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"got {text!r}; allowed: an integer") from None
        if value < lo or (hi is not None and value > hi):
            rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
            raise argparse.ArgumentTypeError(f"got {value}; allowed: an integer {rng}")
        return value

    return parse


seed_type = int_at_least(0, MAX_SEED)
#: Episodes (or seeds per case) one command may ask for: 10⁴ FieldRoute episodes are days of
#: simulation already; a typo such as 10¹² must be an error, not a run that never ends.
MAX_EPISODES = 10_000
episodes_type = int_at_least(1, MAX_EPISODES)


def parse_set(items: list[str], flag: str = "--set") -> dict[str, Any]:
    """``key=value`` pairs (``--set``, ``--hyperparams``), values parsed as YAML."""
    from scenario_gen.schema import parse_yaml

    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise InputError(flag, item, "allowed: key=value, e.g. layout.row_spacing=0.76")
        try:
            out[key.strip()] = parse_yaml(raw, f"{flag} {key}") if raw.strip() else None
        except yaml.YAMLError:  # pragma: no cover  (parse_yaml reports YAML errors itself)
            raise InputError(f"{flag} {key}", raw, "is not a valid YAML value") from None
    return out
