"""Generate a small perception dataset and check that a lane-offset regressor trained on some
fields beats predicting the mean on fields it never saw; then score the depth follower's lane
estimate against the labels, and the depth follower and the learned depth policy (shipped PPO)
driving fields of the same randomization, by the labels of the frames they saw.

    python examples/lane_offset.py runs/lane-ds --frames 3000 --workers 2
"""

from __future__ import annotations

import argparse

from baselines.dataset import generate, load_spec
from baselines.dataset.validate import depth_follower_check, driving_check, validate
from policies import shipped_model


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--frames", type=int, default=3000)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--driving-frames", type=int, default=1280, help="per policy driving")
    a = ap.parse_args()
    # the RL-size image keeps a few thousand frames to minutes; 64 frames per field
    spec = load_spec(None, {"width": 64, "height": 48, "frames_per_shard": 64, "frame_every": 4})
    generate(spec, a.out, seed=0, frames=a.frames, workers=a.workers)
    print(validate(a.out))
    print(depth_follower_check(a.out))
    learned = "ppo:" + str(shipped_model("AgriNav/FurrowFollowDepth-v2"))
    for name, policy in (("depth", "depth"), ("learned", learned), ("rpp", "rpp")):
        out = f"{a.out}-driving-{name}"
        print(driving_check(policy, out, a.driving_frames, seed=1, workers=a.workers))


if __name__ == "__main__":
    main()
