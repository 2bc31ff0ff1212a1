"""Argument types shared by subcommands: checked at parse time, reported as one line."""

from __future__ import annotations

import argparse
import weakref
from collections.abc import Callable, Sequence
from typing import Any

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


def separated(sep: str, what: str) -> Callable[[str], list[str]]:
    """A ``sep``-separated list of distinct non-empty entries: ``"a,,b"``, a trailing ``sep``
    or ``"a,a"`` is refused (a lost or doubled entry is more often a slip than an intent),
    spaces around entries dropped."""

    def parse(text: str) -> list[str]:
        items = [part.strip() for part in text.split(sep)]
        if not text.strip() or any(not item for item in items):
            raise argparse.ArgumentTypeError(
                f"got {text!r}; allowed: a {sep!r}-separated list of {what} with no empty entry"
            )
        twice = sorted({item for item in items if items.count(item) > 1})
        if twice:
            raise argparse.ArgumentTypeError(
                f"got {text!r}: {', '.join(map(repr, twice))} given twice; allowed: each of "
                f"the {what} once"
            )
        return items

    return parse


class _Once:
    """A flag refused when given twice (``--suite smoke --suite paper`` would run the last
    silently: more often a slip than an intent); mixed in before argparse's action."""

    option_strings: Sequence[str]

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[Any] | None,
        option_string: str | None = None,
    ) -> None:
        # the namespaces this flag was given in (argparse's Namespace is unhashable)
        seen: list[weakref.ref[argparse.Namespace]] = [
            r for r in getattr(self, "_seen", []) if r() is not None
        ]
        if self.option_strings and any(r() is namespace for r in seen):
            parser.error(f"argument {'/'.join(self.option_strings)}: given twice; allowed: once")
        seen.append(weakref.ref(namespace))
        self._seen = seen
        super().__call__(parser, namespace, values, option_string)  # type: ignore[misc]


class StoreOnce(_Once, argparse._StoreAction):
    """argparse's ``store``, once."""


class StoreTrueOnce(_Once, argparse._StoreTrueAction):
    """argparse's ``store_true``, once."""
