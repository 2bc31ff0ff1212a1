"""The ranges a controller's parameters may take, checked before a controller is built.

A parameter file (``rpp:params.yaml``, as ``agrinav tune`` writes) or keywords given in Python
pass through ``check_params``: a name the controller does not have, a value of the wrong kind
or outside its range is one ``InputError`` naming the parameter, the value and what is allowed
— a negative lookahead or a zero speed is refused, not driven as a robot that never moves. The
ranges bound what is physically meaningful for a field robot, not what works well (that is the
tuning budget's question).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from scenario_gen.errors import InputError


@dataclass(frozen=True)
class Param:
    """A number in [lo, hi] (``lo_open``: lo excluded), or null where ``none_ok``; ``flag``: a
    true/false switch instead."""

    lo: float = 0.0
    hi: float = math.inf
    lo_open: bool = False
    none_ok: bool = False
    flag: bool = False

    def allowed(self) -> str:
        if self.flag:
            return "allowed: true or false"
        left = "(" if self.lo_open else "["
        text = f"allowed: a number in {left}{self.lo:g}, {self.hi:g}]"
        return text + (" or null" if self.none_ok else "")

    def ok(self, v: Any) -> bool:
        if self.flag:
            return isinstance(v, bool)
        if v is None:
            return self.none_ok
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            return False
        try:
            x = float(v)
        except OverflowError:  # YAML reads integers of any length
            return False
        above = x > self.lo if self.lo_open else x >= self.lo
        return math.isfinite(x) and above and x <= self.hi


def check_params(
    policy: str,
    table: Mapping[str, Param],
    values: Mapping[Any, Any],
    ordered: tuple[tuple[str, str], ...] = (),
    defaults: Mapping[str, Any] | None = None,
) -> None:
    """Refuse any of ``values`` that ``table`` does not allow (names first, then values), and
    a pair of ``ordered`` (a, b) with a above b (a value not given: its default)."""
    unknown = sorted(str(k) for k in values if not isinstance(k, str) or k not in table)
    if unknown:
        raise InputError(
            f"policy {policy}", unknown, f"unknown parameters; allowed: {', '.join(table)}"
        )
    for name, value in values.items():
        if not table[name].ok(value):
            raise InputError(f"policy {policy}: {name}", value, table[name].allowed())
    given = {**(defaults or {}), **values}
    for a, b in ordered:
        if given.get(a) is not None and given.get(b) is not None and given[a] > given[b]:
            raise InputError(
                f"policy {policy}: {a}", given[a], f"allowed: at most {b} ({given[b]:g})"
            )
