"""The one exception type for bad scenario input."""

from __future__ import annotations

from typing import Any


class ScenarioError(ValueError):
    """Bad input to the scenario generator.

    The message always names the offending field, the value given and what is allowed, so a
    CLI can print it as one line and a user can fix the input without reading a traceback.
    """

    def __init__(self, field: str, value: Any, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field}: got {_short(value)}; {allowed}")


def _short(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
