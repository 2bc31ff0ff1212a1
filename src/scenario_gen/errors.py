"""The one exception type for bad input, shared by every AgriNav package."""

from __future__ import annotations

from typing import Any


class InputError(ValueError):
    """Bad input: a spec field, an env argument, a policy name, a file, a CLI flag.

    The message always names the offending field, the value given and what is allowed, so the
    CLI prints it as one line (exit status 2) and a user can fix the input without reading a
    traceback. It is a ``ValueError``, so generic handlers keep working.
    """

    def __init__(self, field: str, value: Any, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field}: got {_short(value)}; {allowed}")

    def __reduce__(self) -> tuple[Any, ...]:
        # subprocess vector envs send exceptions back through pickle
        return (type(self), (self.field, self.value, self.allowed))


class Notice(UserWarning):
    """Something the user should know that is not an error (the run goes on): the commands
    print it as one line, ``agrinav COMMAND: note: ...``, once a command."""


#: The scenario generator's historical name for the same type (one type, two names).
ScenarioError = InputError


def _short(value: Any, limit: int = 80) -> str:
    try:
        text = repr(value)
    except Exception:  # a hostile __repr__ must not turn an input error into a crash
        text = f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[: limit - 3] + "..."
