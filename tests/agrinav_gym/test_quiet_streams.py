"""pybullet's own prints (build time on import, URDF merging) stay off the commands' streams."""

from __future__ import annotations

import subprocess
import sys

SCRIPT = """
import warnings
warnings.simplefilter("ignore")
import gymnasium as gym
import agrinav_gym
env = gym.make("AgriNav/FurrowFollow-v3")
env.reset(seed=0)
env.close()
print("done")
"""


def test_an_env_made_through_pipes_prints_only_what_the_caller_prints() -> None:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout == "done\n"
    assert "pybullet" not in out.stderr
    assert "build time" not in out.stderr


def test_quiet_restores_the_stream_after_an_error() -> None:
    code = (
        "import sys\n"
        "from agrinav_gym.sim.quiet import quiet\n"
        "try:\n"
        "    with quiet(sys.stderr):\n"
        "        print('hidden', file=sys.stderr)\n"
        "        raise RuntimeError\n"
        "except RuntimeError:\n"
        "    print('seen', file=sys.stderr)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stderr == "seen\n"
