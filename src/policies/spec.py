"""A policy as the command line and the benchmarks name it: ``NAME`` or ``NAME:ARG``.

``rpp``, ``dwb:nav2``, ``ppo:runs/fr/best``, ``rpp:tuned.yaml``: the name picks the controller
(``policies.POLICIES``), the argument its configuration or checkpoint. Parsed here only; what
each argument may be is checked by ``policies.check_policy_spec``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

SEPARATOR = ":"
#: the shipped checkpoint for the env's id (``ppo:shipped``)
SHIPPED_ARG = "shipped"
#: every form a policy spec takes, as the command line's help lists them
FORMS = (
    "dwb (= dwb:furrow), dwb:nav2, dwb:tuned, dwb:PATH.yaml; rpp and stanley, each also "
    ":tuned or :PATH.yaml (a parameter file, as agrinav tune writes); depth; blind (a constant "
    "command, no sensors); ppo:PATH (a checkpoint folder) or ppo:shipped"
)


class PolicySpec(NamedTuple):
    name: str
    arg: str  # "" when there is none

    @classmethod
    def parse(cls, text: str) -> PolicySpec:
        name, _, arg = text.partition(SEPARATOR)
        return cls(name, arg)

    def __str__(self) -> str:
        return f"{self.name}{SEPARATOR}{self.arg}" if self.arg else self.name


def policy_files(specs: Sequence[str]) -> list[Path]:
    """The parameter files and checkpoint folders the policies read (an ``--out`` replaced
    with ``--force`` must not hold them)."""
    paths = (PolicySpec.parse(spec).arg for spec in specs)
    return [Path(p) for p in paths if p and Path(p).exists()]
