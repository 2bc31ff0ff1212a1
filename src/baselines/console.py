"""The ``agrinav`` console script: imports the command line (≈ 1–2 s: the simulator's
packages) inside a Ctrl-C handler, so an interrupt while it loads is one line, not a traceback."""

from __future__ import annotations

import sys


def main() -> int:
    try:
        from baselines.cli import main as command_line
    except KeyboardInterrupt:
        print("agrinav: interrupted", file=sys.stderr)
        return 130
    return command_line()
