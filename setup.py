"""The compiled sensor kernels (src/agrinav_gym/csrc); everything else is in pyproject.toml.

The extension is optional: where it cannot be built the sensors fall back to numpy and Embree
(the same images, slower). Flags: -O3 and no errno from math calls (sqrt inlines); no
-ffast-math, whose reordering would change results between builds.
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "agrinav_gym._native",
            sources=[
                "src/agrinav_gym/csrc/module.c",
                "src/agrinav_gym/csrc/proxycast.c",
                "src/agrinav_gym/csrc/raster.c",
                "src/agrinav_gym/csrc/frame.c",
                "src/agrinav_gym/csrc/packets.c",
            ],
            depends=["src/agrinav_gym/csrc/native.h", "src/agrinav_gym/csrc/batch.h"],
            extra_compile_args=["-O3", "-fno-math-errno", "-fno-trapping-math", "-std=c99"],
            optional=True,
        )
    ]
)
