"""The compiled kernels under AddressSanitizer and UndefinedBehaviorSanitizer (``make sanitize``).

Builds ``src/agrinav_gym/render/csrc`` with ``-fsanitize=address,undefined
-fno-sanitize-recover=all`` into a temporary folder (the normal build is left alone) and runs
the kernels' test files against that build: ``AGRINAV_NATIVE_LIB`` points render/native.py at
it, ``CI=true`` makes a build that fails to load a failure, and ASan's runtime is preloaded
(Python itself is not instrumented). Any report fails the run: the first error aborts the
process (``halt_on_error``, no recovery), and reports are also written to the temporary folder,
where the run looks for them afterwards. Leak detection is off (``detect_leaks=0``): the
interpreter's and the extension libraries' allocations alive at exit would drown any report;
the kernels free what they allocate on every path, which the tests exercise, but a leak there
would not be caught here. The new/delete pairing check is off too
(``alloc_dealloc_mismatch=0``): pybullet's C++ frees a heightfield's ``new[]`` buffer with
``delete`` (``processCreateCollisionShapeCommand``) in the tests that drive the tyre kernel on a
pybullet world, and the kernels are C, with no ``new`` or ``delete`` to pair.

Run from the repository root with the project's interpreter: ``python tools/sanitize_kernels.py``
(extra arguments go to pytest). Needs a C compiler whose ASan runtime ``cc
-print-file-name=libasan.so`` finds (GCC's; ``CC`` picks another compiler).
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CSRC = ROOT / "src" / "agrinav_gym" / "render" / "csrc"
#: the test files that drive the kernels (the reference-only cases are left out: they run no C)
TESTS = [
    "tests/agrinav_gym/test_native.py",
    "tests/agrinav_gym/test_mesh_camera.py",
    "tests/agrinav_gym/test_pixel_noise.py",
    "tests/agrinav_gym/test_sensors.py",
    "tests/agrinav_gym/test_step_kernels.py",
    "tests/agrinav_gym/test_robot_localization_kernel.py",
]
SELECT = "not reference"
FLAGS = [
    "-fsanitize=address,undefined",
    "-fno-sanitize-recover=all",
    "-fno-omit-frame-pointer",
    "-g",
    "-O1",
    # as setup.py: C99 (floating-point contraction off) and no errno from math calls
    "-std=c99",
    "-fno-math-errno",
    "-fno-trapping-math",
    "-fPIC",
    "-shared",
]


def source_hash() -> str:
    sys.path.insert(0, str(ROOT / "src"))
    from agrinav_gym.render.native import source_hash as hash_of

    return hash_of(CSRC)


def build(cc: str, out: Path) -> Path:
    lib = out / "_native_sanitized.so"
    include = sysconfig.get_paths()["include"]
    cmd = [
        cc,
        *FLAGS,
        f"-I{include}",
        f'-DAGRINAV_SOURCE_HASH="{source_hash()}"',
        *(str(p) for p in sorted(CSRC.glob("*.c"))),
        "-o",
        str(lib),
    ]
    print("+", shlex.join(cmd), flush=True)
    subprocess.run(cmd, check=True)
    return lib


def runtime(cc: str, name: str) -> str:
    path = subprocess.run(
        [cc, f"-print-file-name={name}"], check=True, capture_output=True, text=True
    ).stdout.strip()
    if not os.path.isabs(path) or not os.path.exists(path):
        sys.exit(f"{cc} does not find {name} (the sanitizer run needs GCC's libasan)")
    return os.path.realpath(path)


def preload(cc: str) -> list[str]:
    """ASan's runtime first, then the C++ runtime: ASan looks up ``__cxa_throw`` when it starts,
    and the C++ extension modules (matplotlib's, pybullet) throw through it later."""
    return [runtime(cc, "libasan.so"), runtime(cc, "libstdc++.so.6")]


def main(argv: list[str]) -> int:
    cc = os.environ.get("CC", "cc")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="agrinav-sanitize-") as tmp:
        out = Path(tmp)
        lib = build(cc, out)
        reports = out / "reports"
        reports.mkdir()
        env = dict(os.environ)
        env.update(
            AGRINAV_NATIVE_LIB=str(lib),
            CI="true",
            PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT / "src"), env.get("PYTHONPATH")])),
            LD_PRELOAD=" ".join(filter(None, [*preload(cc), env.get("LD_PRELOAD")])),
            ASAN_OPTIONS=(
                f"detect_leaks=0:alloc_dealloc_mismatch=0:halt_on_error=1:log_path={reports}/asan"
            ),
            UBSAN_OPTIONS=f"halt_on_error=1:print_stacktrace=1:log_path={reports}/ubsan",
        )
        env.pop("AGRINAV_NATIVE", None)  # the kernels must be in use
        check = (
            "from agrinav_gym.render import native; import sys; "
            "native.require('the sanitizer run'); "
            "sys.exit(0 if native.origin() == sys.argv[1] else 'the sanitized build is not in use')"
        )
        subprocess.run([sys.executable, "-c", check, str(lib)], env=env, cwd=ROOT, check=True)
        # --capture=sys: a report written to fd 2 as the process aborts reaches the terminal
        cmd = [sys.executable, "-m", "pytest", "-q", "--capture=sys", "-p", "no:cacheprovider"]
        run = subprocess.run([*cmd, "-k", SELECT, *TESTS, *argv], env=env, cwd=ROOT)
        found = sorted(reports.iterdir())
        for f in found:
            print(f"--- {f.name}\n{f.read_text(errors='replace')}", file=sys.stderr)
        took = time.perf_counter() - t0
        ok = run.returncode == 0 and not found
        verdict = "clean" if ok else f"FAILED (pytest {run.returncode}, {len(found)} reports)"
        print(f"sanitizer run: {verdict} in {took:.0f} s")
        return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
