"""``agrinav scenario``: generate a scenario folder, or a bank of them."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from scenario_gen.errors import InputError

from ..scenario_spec import add_spec_arguments, spec_from_args
from .args import MAX_SEED, int_at_least, seed_type


def add(sub: Any) -> None:
    sc = sub.add_parser(
        "scenario",
        help="generate a crop-field scenario on real terrain",
        description="Generate a scenario directory (scenario.json, terrain.npz, "
        "plants.csv, route.csv, field.geojson, preview.png), or a bank with --count.",
    )
    add_spec_arguments(sc)
    sc.add_argument("--seed", type=seed_type, default=0)
    sc.add_argument("--out", required=True, help="output directory (must not exist, or --force)")
    sc.add_argument(
        "--count",
        type=int_at_least(1, 100_000),
        default=1,
        help="generate a bank of COUNT scenarios, seeds SEED..SEED+COUNT-1",
    )
    sc.add_argument("--force", action="store_true", help="replace an existing output directory")
    sc.add_argument("--no-preview", action="store_true", help="skip preview.png")
    sc.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import yaml
    from tqdm import tqdm

    from scenario_gen import generate, save
    from scenario_gen.atomic import check_output_dir, output_dir
    from scenario_gen.generate import input_files

    spec = spec_from_args(args)
    if args.seed + args.count - 1 > MAX_SEED:
        raise InputError(
            "--seed/--count",
            (args.seed, args.count),
            f"allowed: seeds up to {MAX_SEED} (seed + count - 1)",
        )
    out = Path(args.out)
    # the files it reads (an --out replaced with --force must not hold them)
    inputs = [args.config, *input_files(spec).values()]
    check_output_dir(out, args.force, "--out", kind="scenario", inputs=inputs)
    if args.count == 1:
        t0 = time.perf_counter()
        scn = generate(spec, args.seed)
        t_gen = time.perf_counter() - t0
        save(scn, out, overwrite=args.force, preview=not args.no_preview, what="--out")
        rows = {
            **scn.summary(),
            "generate_s": round(t_gen, 3),
            "total_s": round(time.perf_counter() - t0, 3),
            "out": str(out),
        }
        width = max(map(len, rows))
        for k, v in rows.items():
            if isinstance(v, dict):  # slope_deg, obstacle counts: "median 3.1, p90 4.0, ..."
                v = ", ".join(f"{a} {b}" for a, b in v.items())
            print(f"{k:<{width}}  {v}")
        return 0
    # A bank: one scenario per seed, written as one folder that appears only when complete;
    # bank.yaml lists its members, and only those are ever sampled.
    seeds = range(args.seed, args.seed + args.count)
    names = [f"seed-{seed:06d}" for seed in seeds]
    first = generate(spec, seeds.start)  # bad input is reported before the bank folder exists
    with output_dir(out, args.force, "--out", kind="scenario", inputs=inputs) as tmp:
        for seed, name in tqdm(
            zip(seeds, names, strict=True), total=len(names), desc="scenarios", unit="scn"
        ):
            try:
                scn = first if seed == seeds.start else generate(spec, seed)
            except InputError as exc:  # one seed's draw: say which (the others generated)
                raise InputError(
                    exc.field, exc.value, f"{exc.allowed} (bank member seed {seed})"
                ) from None
            save(scn, tmp / name, preview=not args.no_preview)
        (tmp / "bank.yaml").write_text(
            yaml.safe_dump(
                {"spec": spec.to_dict(), "seeds": list(seeds), "scenarios": names},
                sort_keys=False,
            )
        )
    print(f"{args.count} scenarios ({spec.name}, seeds {seeds.start}..{seeds.stop - 1}) in {out}")
    return 0
