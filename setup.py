"""The compiled kernels (src/agrinav_gym/render/csrc: the sensors', the tyres', the EKF's, the
route's, the GNSS sky's); everything else is in pyproject.toml.

The extension is optional: where it cannot be built the sensors fall back to numpy and Embree
(the same images, slower), the tyre model, the EKF and the route to their Python twins. Flags:
-O3 and no errno from math calls (sqrt inlines); no -ffast-math, whose reordering would change
results between builds.
"""

import hashlib
from pathlib import Path

from setuptools import Extension, setup

CSRC = Path(__file__).parent / "src" / "agrinav_gym" / "render" / "csrc"


def source_hash() -> str:
    """The kernels' sources, hashed as sensors/native.py hashes them: an extension built from
    other sources than those beside it (a pull or an edit without a rebuild) is refused there."""
    h = hashlib.sha256()
    for f in sorted(CSRC.glob("*.[ch]")):
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:16]


setup(
    ext_modules=[
        Extension(
            "agrinav_gym.render._native",
            sources=[
                "src/agrinav_gym/render/csrc/module.c",
                "src/agrinav_gym/render/csrc/proxycast.c",
                "src/agrinav_gym/render/csrc/raster.c",
                "src/agrinav_gym/render/csrc/frame.c",
                "src/agrinav_gym/render/csrc/packets.c",
                "src/agrinav_gym/render/csrc/tyres.c",
                "src/agrinav_gym/render/csrc/ekf.c",
                "src/agrinav_gym/render/csrc/rl.c",
                "src/agrinav_gym/render/csrc/routes.c",
                "src/agrinav_gym/render/csrc/sky.c",
            ],
            depends=["src/agrinav_gym/render/csrc/native.h", "src/agrinav_gym/render/csrc/batch.h"],
            define_macros=[("AGRINAV_SOURCE_HASH", f'"{source_hash()}"')],
            extra_compile_args=["-O3", "-fno-math-errno", "-fno-trapping-math", "-std=c99"],
            optional=True,
        )
    ]
)
