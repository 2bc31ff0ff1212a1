"""The seed robot's four GPS waypoints, laid on the `paper` suite's field.

The source paper's Summit-XL drove four Nav2 GPS waypoints: a 33 m leg along a lane, a 6.5 m
headland leg, a 31 m leg back. This script lays that shape on the P1 field the `paper` suite
generates (1 m rows, 31 m lanes, the evaluation scenario seed): W1 1 m before the first lane's
crop, W2 1 m past its end (33 m), W3 across the headland to the lane six over (6 m: with 1 m
rows lane centres lie a whole number of metres apart, so the seed's 6.5 m cannot be a lane),
W4 31 m back along that lane. It writes them in Nav2's GPS waypoint format to
``src/baselines/hyperparams/paper_waypoints.yml``, which the suite reads through the datum
(``scenario_gen.waypoints``). Run ``python benchmarks/paper_waypoints.py`` after a change to
the P1 preset or the suite's field.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

import scenario_gen as sg
from baselines.suites import EVAL_SEED, PAPER_WAYPOINT_FIELD

OUT = Path(__file__).resolve().parents[1] / "src" / "baselines" / "hyperparams"
LEGS = (33.0, 6.0, 31.0)


def main() -> None:
    scn = sg.generate(sg.preset("paper-p1", **PAPER_WAYPOINT_FIELD), EVAL_SEED)
    lanes = scn.lanes
    along, across = scn.rows.u, scn.rows.n
    first = lanes[0]
    start, end = (first[0], first[1]) if (first[1] - first[0]) @ along > 0 else first[::-1]
    w1 = start - along * 1.0
    w2 = w1 + along * LEGS[0]
    w3 = w2 + across * LEGS[1]
    w4 = w3 - along * LEGS[2]
    pts = np.array([w1, w2, w3, w4])
    lat, lon, _ = scn.geo.enu_to_geodetic(pts[:, 0], pts[:, 1], 0.0)  # on the tangent plane
    heading = [np.arctan2(*along[::-1])] * 2 + [np.arctan2(*(-along)[::-1])] * 2
    data = {
        "waypoints": [
            {
                "latitude": round(float(a), 9),
                "longitude": round(float(o), 9),
                "yaw": round(float(h), 6),
            }
            for a, o, h in zip(lat, lon, heading, strict=True)
        ]
    }
    header = (
        "# The seed robot's four GPS waypoints (33 m along a lane, 6 m across the headland, 31 m\n"
        "# back) on the paper suite's P1 field; made by benchmarks/paper_waypoints.py.\n"
    )
    (OUT / "paper_waypoints.yml").write_text(header + yaml.safe_dump(data, sort_keys=False))
    print(f"lane {float(np.linalg.norm(end - start)):.1f} m; wrote {OUT / 'paper_waypoints.yml'}")


if __name__ == "__main__":
    main()
