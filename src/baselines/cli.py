"""``agrinav``: the command line. Bad input exits 2 with one line naming field, value and rule."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from scenario_gen.errors import ScenarioError


def _parse_set(items: Sequence[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError("--set", item, "allowed: key=value, e.g. layout.row_spacing=0.76")
        try:
            out[key.strip()] = yaml.safe_load(raw) if raw.strip() else None
        except yaml.YAMLError:
            raise ScenarioError(f"--set {key}", raw, "is not a valid YAML value") from None
    return out


def _parse_datum(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != 3:
        raise ScenarioError("--datum", text, "allowed: LAT,LON,ALT in degrees and metres")
    return vals


def scenario_spec_from_args(args: argparse.Namespace) -> Any:
    """preset < --config file < --dem/--mesh/--field/--lod flags < --set overrides."""
    from scenario_gen.config import load_yaml, merge, preset

    base = preset(args.preset).to_dict()
    if args.config:
        base = merge(base, load_yaml(args.config))
    flags: dict[str, Any] = {}
    if args.dem and args.mesh:
        raise ScenarioError("--dem/--mesh", (args.dem, args.mesh), "allowed: one terrain source")
    if args.dem:
        flags.update({"terrain.source": "dem", "terrain.path": args.dem})
    if args.mesh:
        if not args.datum:
            raise ScenarioError(
                "--datum", None, "--mesh needs --datum LAT,LON,ALT of the mesh origin"
            )
        flags.update({"terrain.source": "mesh", "terrain.path": args.mesh})
    if args.datum:
        flags["terrain.datum"] = _parse_datum(args.datum)
    if args.field:
        flags["field.geojson"] = args.field
    if args.lod is not None:
        flags["terrain.lod"] = args.lod
    from scenario_gen.config import ScenarioSpec

    return ScenarioSpec.from_dict(merge(merge(base, flags), _parse_set(args.set)))


def cmd_scenario(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from scenario_gen import generate
    from scenario_gen.io import check_output_dir

    if args.count < 1:
        raise ScenarioError("--count", args.count, "allowed: an integer >= 1")
    if args.seed < 0:
        raise ScenarioError("--seed", args.seed, "allowed: an integer >= 0")
    spec = scenario_spec_from_args(args)
    out = Path(args.out)
    if args.count == 1:
        check_output_dir(out, args.force)
        t0 = time.perf_counter()
        scn = generate(spec, args.seed)
        t_gen = time.perf_counter() - t0
        scn.save(out, overwrite=args.force, preview=not args.no_preview)
        t_all = time.perf_counter() - t0
        rows = {
            **scn.summary(),
            "generate_s": round(t_gen, 3),
            "total_s": round(t_all, 3),
            "out": str(out),
        }
        width = max(map(len, rows))
        for k, v in rows.items():
            print(f"{k:<{width}}  {v}")
        return 0
    # A bank: one scenario per seed, generated once and reused across many episodes.
    check_output_dir(out, args.force)
    seeds = range(args.seed, args.seed + args.count)
    tmp_names = []
    out.mkdir(parents=True, exist_ok=True)
    for seed in tqdm(seeds, desc="scenarios", unit="scn"):
        name = f"seed-{seed:06d}"
        generate(spec, seed).save(out / name, overwrite=True, preview=not args.no_preview)
        tmp_names.append(name)
    (out / "bank.yaml").write_text(
        yaml.safe_dump(
            {"spec": spec.to_dict(), "seeds": list(seeds), "scenarios": tmp_names}, sort_keys=False
        )
    )
    print(f"{args.count} scenarios ({spec.name}, seeds {seeds.start}..{seeds.stop - 1}) in {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from scenario_gen.config import preset_names

    parser = argparse.ArgumentParser(prog="agrinav", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sc = sub.add_parser(
        "scenario",
        help="generate a crop-field scenario on real terrain",
        description="Generate a scenario directory (scenario.json, terrain.npz, "
        "plants.csv, route.csv, field.geojson, preview.png).",
    )
    sc.add_argument("--preset", default="default", choices=preset_names())
    sc.add_argument("--seed", type=int, default=0)
    sc.add_argument("--out", required=True, help="output directory (must not exist, or --force)")
    sc.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a spec field, e.g. --set layout.row_spacing=0.76 (repeatable)",
    )
    sc.add_argument("--config", help="YAML file of spec overrides")
    sc.add_argument("--dem", help="GeoTIFF DEM (any CRS)")
    sc.add_argument("--mesh", help="terrain mesh (glTF/GLB, OBJ, PLY, DAE)")
    sc.add_argument("--datum", help="LAT,LON,ALT of the mesh origin")
    sc.add_argument("--field", help="GeoJSON polygon of the field (WGS84 lon/lat)")
    sc.add_argument("--lod", type=int, help="level of detail (Web-Mercator zoom 0-22)")
    sc.add_argument(
        "--count",
        type=int,
        default=1,
        help="generate a bank of COUNT scenarios, seeds SEED..SEED+COUNT-1",
    )
    sc.add_argument("--force", action="store_true", help="replace an existing output directory")
    sc.add_argument("--no-preview", action="store_true", help="skip preview.png")
    sc.set_defaults(func=cmd_scenario)

    tr = sub.add_parser("train", help="train a learned policy (PPO) on an AgriNav env")
    tr.add_argument("--env", required=True, help="env id, e.g. AgriNav/FurrowFollow-v0")
    tr.add_argument("--algo", default="ppo", choices=["ppo"])
    tr.add_argument("--timesteps", type=int, required=True)
    tr.add_argument("--seed", type=int, default=0)
    tr.add_argument("--out", required=True)
    tr.add_argument("--eval-every", type=int, default=20000, help="timesteps between evaluations")
    tr.add_argument("--eval-episodes", type=int, default=4)
    tr.set_defaults(func=cmd_train)

    ru = sub.add_parser(
        "run", help="run a policy for some episodes: metrics.json + trajectory plots"
    )
    ru.add_argument("--env", default="AgriNav/FieldRoute-v0")
    ru.add_argument("--policy", required=True, help="dwb, rpp, depth or ppo:PATH")
    ru.add_argument("--seed", type=int, default=1_000_000_000)
    ru.add_argument("--episodes", type=int, default=1)
    ru.add_argument("--scenario", help="a scenario directory or preset (default: the env's)")
    ru.add_argument("--out", required=True)
    ru.add_argument("--video", action="store_true", help="write an MP4 of the first episode")
    ru.set_defaults(func=cmd_run)

    be = sub.add_parser("bench", help="benchmark policies on a suite: results.json, benchmark.md")
    be.add_argument("--suite", required=True, help="smoke, paper, growth, density or terrain")
    be.add_argument("--policies", required=True, help="comma list: dwb,rpp,depth,ppo:PATH")
    be.add_argument("--seeds", type=int, default=3)
    be.add_argument("--out", required=True)
    be.set_defaults(func=cmd_bench)

    de = sub.add_parser("demo", help="default scenario + DWB vs shipped PPO on the paper suite")
    de.add_argument("--out", default="runs/demo")
    de.add_argument("--seeds", type=int, default=2)
    de.set_defaults(func=cmd_demo)
    return parser


def cmd_demo(args: argparse.Namespace) -> int:
    from baselines.demo import demo

    demo(args.out, args.seeds)
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from baselines.bench import run

    records = run(
        args.env, args.policy, args.seed, args.episodes, args.out, args.scenario, args.video
    )
    for r in records:
        print({k: (round(v, 3) if isinstance(v, float) else v) for k, v in r.items()})
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from baselines.bench import bench, command_line

    pols = [p.strip() for p in args.policies.split(",") if p.strip()]
    bench(args.suite, pols, args.seeds, args.out, command_line(args.argv))
    print((Path(args.out) / "benchmark.md").read_text())
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from baselines.train import train

    out = train(
        args.env,
        args.timesteps,
        args.seed,
        args.out,
        args.eval_every,
        args.eval_episodes,
        argv=args.argv,
    )
    print(f"model, config, command and learning curve in {out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = ["agrinav", *(argv if argv is not None else sys.argv[1:])]  # for "reproduce"
    try:
        return int(args.func(args))
    except ScenarioError as exc:
        print(f"agrinav {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("agrinav: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
