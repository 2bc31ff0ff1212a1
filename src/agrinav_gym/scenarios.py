"""Where an env's scenarios come from, and what is re-drawn at each reset.

``ScenarioSource``: a fixed scenario (a ``Scenario`` or a saved folder), a preset (name,
overrides, seed; regenerated each reset when scenario keys are randomized, with seeds from a
``[low, high)`` range — disjoint ranges make disjoint train/test splits) or a bank (the folders
its ``bank.yaml`` lists, one drawn per reset). ``Randomization``: the ranges re-drawn each
reset, typed and checked completely when the env is built — every bound against its field's
type and range, every choice, and every combination of extremes against the generator's
cross-field checks — so a bad range fails at construction, naming the range given.
"""

from __future__ import annotations

import itertools
import json
import warnings
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import scenario_gen as sg
from scenario_gen import Scenario
from scenario_gen.errors import InputError, Notice
from scenario_gen.generate import COUPLED_FIELDS, PATH_KEYS, check_fields_used, check_spec
from scenario_gen.schema import coerce, field_info, is_integer_field, load_yaml, plain, to_mapping
from scenario_gen.spec import ScenarioSpec

from .config import EnvConfig

#: Keys of ``randomize`` handled by the env rather than the scenario spec: the ``EnvConfig``
#: fields a reset can change without rebuilding the env, named as those fields (their bounds
#: and choices are the config's).
ENV_KEYS = (
    "gnss.mode",
    # the receiver under canopy (docs/localisation.md): foliage loss and the opt-in faults
    "gnss.fix.false_fix_prob",
    "gnss.fix.foliage_db_per_m",
    "gnss.fix.jump_rate_hz",
    # open sky: how often multipath slips RTK fixed to float (assumed: docs/localisation.md)
    "gnss.fix.multipath_mtbf_s",
    "gnss.fix.refix_sky_exponent",
    "lighting.soil_rgb",
    "lighting.sun_azimuth_deg",
    "lighting.sun_elevation_deg",
)
#: Former names of env keys, still accepted with a warning.
RENAMED_KEYS = {
    "gnss_mode": "gnss.mode",
    "soil_colour": "lighting.soil_rgb",
    "light_azimuth_deg": "lighting.sun_azimuth_deg",
    "light_elevation_deg": "lighting.sun_elevation_deg",
}


@dataclass(frozen=True)
class Draw:
    """One key's distribution: uniform over [lo, hi] (integers for integer fields) or a choice."""

    key: str
    lo: Any = None
    hi: Any = None
    choices: tuple[Any, ...] | None = None
    integer: bool = False

    def given(self) -> str:
        """The distribution as the user wrote it: [lo, hi] or {choices: [...]}."""
        if self.choices is not None:
            return f"{{choices: {list(self.choices)}}}"
        return f"[{self.lo}, {self.hi}]"

    def sample(self, rng: np.random.Generator) -> Any:
        if self.choices is not None:
            return self.choices[int(rng.integers(len(self.choices)))]
        if isinstance(self.lo, list):  # e.g. soil colour: two RGB triplets
            return list(rng.uniform(np.asarray(self.lo, float), np.asarray(self.hi, float)))
        if self.integer:
            return int(rng.integers(self.lo, self.hi + 1))
        return float(rng.uniform(self.lo, self.hi))

    @property
    def extremes(self) -> tuple[Any, ...]:
        return self.choices if self.choices is not None else (self.lo, self.hi)


def _parse(key: str, spec: Any) -> tuple[Any, Any, tuple[Any, ...] | None]:
    where = f"randomize.{key}"
    if isinstance(spec, dict):
        if set(spec) != {"choices"} or not isinstance(spec["choices"], (list, tuple)):
            raise InputError(where, spec, "allowed: [low, high] or {choices: [...]}")
        if len(spec["choices"]) == 0:
            raise InputError(where, spec, "allowed: a non-empty list of choices")
        return None, None, tuple(spec["choices"])
    if isinstance(spec, (list, tuple)) and len(spec) == 2:
        return spec[0], spec[1], None
    raise InputError(where, spec, "allowed: [low, high] or {choices: [...]}")


_VALIDATED: OrderedDict[str, tuple[tuple[Draw, ...], tuple[str, ...]]] = OrderedDict()


def _memo_key(ranges: dict[str, Any], base: ScenarioSpec | None) -> str | None:
    try:
        return json.dumps([ranges, to_mapping(base) if base is not None else None], sort_keys=True)
    except (TypeError, ValueError):  # something JSON cannot hold: validate it every time
        return None


class Randomization:
    """The ``randomize`` argument, validated; ``sample`` draws keys in sorted order."""

    def __init__(self, ranges: Any, base: ScenarioSpec | None) -> None:
        if ranges is None:
            ranges = {}
        if not isinstance(ranges, dict):
            raise InputError("randomize", ranges, "allowed: a mapping {key: [low, high]}")
        # The same ranges on the same base pass the same checks: a dataset builds an env per
        # shard, a vector env one per worker (the checks cost ~0.1 s); failures are not kept.
        memo = _memo_key(ranges, base)
        known = _VALIDATED.get(memo) if memo is not None else None
        self.draws: list[Draw] = list(known[0]) if known is not None else []
        if known is not None:
            self.scenario_keys: tuple[str, ...] = known[1]
            return
        scenario_draws: list[Draw] = []
        ranges = _renamed(ranges)
        for key in sorted(ranges):
            lo, hi, choices = _parse(key, ranges[key])
            if key in ENV_KEYS:
                draw = _env_draw(key, lo, hi, choices)
            else:
                draw = _scenario_draw(key, lo, hi, choices, base)
                scenario_draws.append(draw)
            self.draws.append(draw)
        self.scenario_keys = tuple(d.key for d in scenario_draws)
        if scenario_draws and base is not None:
            _check_inputs(scenario_draws, base)
            _check_combinations(scenario_draws, base, ranges)
        if memo is not None:
            _VALIDATED[memo] = (tuple(self.draws), self.scenario_keys)
            while len(_VALIDATED) > 32:
                _VALIDATED.popitem(last=False)

    def __bool__(self) -> bool:
        return bool(self.draws)

    def sample(self, rng: np.random.Generator) -> tuple[dict[str, Any], dict[str, Any]]:
        """(scenario overrides, env values) for one reset."""
        scn: dict[str, Any] = {}
        env: dict[str, Any] = {}
        for d in self.draws:
            (env if d.key in ENV_KEYS else scn)[d.key] = d.sample(rng)
        return scn, env


def _renamed(ranges: dict[Any, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in ranges.items():
        if not isinstance(key, str):
            raise InputError("randomize", key, "allowed: string keys")
        if key in RENAMED_KEYS:
            new = RENAMED_KEYS[key]
            warnings.warn(
                f"randomize.{key} is now randomize.{new} (the config field it sets)",
                DeprecationWarning,
                stacklevel=4,
            )
            if new in ranges:
                raise InputError(f"randomize.{key}", key, f"given twice, as {key} and {new}")
            key = new
        out[key] = value
    return out


def _env_draw(key: str, lo: Any, hi: Any, choices: tuple[Any, ...] | None) -> Draw:
    where = f"randomize.{key}"
    info = field_info(EnvConfig, key)
    assert info is not None and info[0] is not None
    tp, meta = info
    values = list(choices) if choices is not None else [lo, hi]
    checked = [coerce(v, tp, meta, where) for v in values]
    if choices is not None:
        return Draw(key, choices=tuple(plain(v) for v in checked))
    if meta.get("choices") is not None:
        raise InputError(
            where, [lo, hi], f"allowed: {{choices: [...]}} of {', '.join(meta['choices'])}"
        )
    if any(v is None for v in checked):
        raise InputError(where, [lo, hi], "allowed: [low, high] bounds, not null")
    if isinstance(checked[0], tuple):  # e.g. soil colour: uniform per channel
        lo_v, hi_v = list(checked[0]), list(checked[1])
        if any(a > b for a, b in zip(lo_v, hi_v, strict=True)):
            raise InputError(where, [lo, hi], "allowed: low <= high in every channel")
        return Draw(key, lo_v, hi_v)
    if checked[0] > checked[1]:
        raise InputError(where, [lo, hi], "allowed: [low, high] with low <= high")
    return Draw(key, float(checked[0]), float(checked[1]))


def _number(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _scenario_draw(
    key: str, lo: Any, hi: Any, choices: tuple[Any, ...] | None, base: ScenarioSpec | None
) -> Draw:
    where = f"randomize.{key}"
    spec = base or ScenarioSpec()
    info = field_info(ScenarioSpec, key)
    if info is None:
        allowed = [*sorted(ENV_KEYS), "<section>.<field> of the scenario spec (docs/config.md)"]
        raise InputError(where, key, f"unknown key; allowed: {', '.join(allowed)}")
    if info[0] is None:
        raise InputError(where, key, "is a section; randomize one of its fields")
    for v in choices if choices is not None else (lo, hi):
        try:
            spec.replace({key: v})
        except InputError as exc:
            raise InputError(where, choices or [lo, hi], exc.allowed) from None
    if choices is not None:
        return Draw(key, choices=choices)
    integer = is_integer_field(info[0])
    if not (_number(lo) and _number(hi)):
        raise InputError(where, [lo, hi], "allowed: numbers [low, high] (or {choices: [...]})")
    if lo > hi:
        raise InputError(where, [lo, hi], "allowed: [low, high] with low <= high")
    if integer and not (float(lo).is_integer() and float(hi).is_integer()):
        raise InputError(where, [lo, hi], "allowed: integer bounds for an integer field")
    return Draw(
        key, int(lo) if integer else float(lo), int(hi) if integer else float(hi), None, integer
    )


#: terrain sources that read ``terrain.path``, and what it must be
_PATH_SOURCES = {"dem": "a GeoTIFF", "mesh": "a mesh file"}


def _check_inputs(draws: list[Draw], base: ScenarioSpec) -> None:
    """Choices the generator refuses whatever else is drawn — a file that is not there, a
    terrain source without its file — refused now, not redrawn (with a warning) at resets."""
    drawn = {d.key: d for d in draws}
    for d in draws:
        if d.choices is None:
            continue
        if d.key in PATH_KEYS:
            for c in d.choices:
                path = Path(str(c)).expanduser() if c is not None else None
                if path is not None and not path.is_file():
                    here = "" if path.is_absolute() else f" (from {Path.cwd()})"
                    raise InputError(
                        f"randomize.{d.key}",
                        c,
                        f"is not a file{here}; allowed: choices of existing files, or null",
                    )
        if d.key == "terrain.source":
            t = drawn.get("terrain.path")
            paths = t.choices if t is not None and t.choices else (base.terrain.path,)
            for c in d.choices:
                if c in _PATH_SOURCES and None in paths:
                    raise InputError(
                        f"randomize.{d.key}",
                        c,
                        f"reads terrain.path ({_PATH_SOURCES[c]}), which is not set"
                        f"{' in every choice' if t is not None else ''}; allowed: set it, or "
                        "choose among sources without a file",
                    )


def _check_combinations(draws: list[Draw], base: ScenarioSpec, ranges: dict[str, Any]) -> None:
    """The generator's cross-field checks must pass at every combination of the extremes of
    the fields they relate (``COUPLED_FIELDS``; the others at each of their extremes alone):
    the same verdict as enumerating all combinations, without its 2^n specs."""
    groups = [[d for d in draws if d.key in g] for g in COUPLED_FIELDS]
    coupled = {d.key for g in groups for d in g}
    groups = [g for g in groups if g] + [[d] for d in draws if d.key not in coupled]
    for group in groups:
        for values in itertools.product(*(d.extremes for d in group)):
            over = dict(zip((d.key for d in group), values, strict=True))
            try:
                check_spec(base.replace(over))
            except InputError as exc:
                key = next(
                    (k for k in over if exc.field.endswith(k) or k.endswith(exc.field)),
                    group[0].key,
                )
                raise InputError(
                    f"randomize.{key}",
                    ranges[key],
                    f"reaches {exc.field} = {exc.value!r} with {over}; {exc.allowed}",
                ) from None


# ----------------------------------------------------------------------------- sources


class Bank:
    """Scenarios saved under one folder by ``agrinav scenario --count N``: the ones its
    ``bank.yaml`` lists (a folder without one: every subfolder holding scenario.json)."""

    def __init__(self, directory: str | Path, cache: int = 8) -> None:
        if not isinstance(directory, (str, Path)) or not str(directory):
            raise InputError("bank", directory, "allowed: the path of a bank folder")
        root = Path(directory)
        if not root.is_dir():
            raise InputError(
                "bank",
                str(directory),
                "is not a folder; allowed: a folder of scenarios (agrinav scenario --count N)",
            )
        listing = root / "bank.yaml"
        if listing.is_file():
            data = load_yaml(listing, "bank.yaml")  # its size is checked before it is read
            names = data.get("scenarios")
            if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
                raise InputError("bank", str(listing), "allowed: a bank.yaml listing 'scenarios'")
            outside = [n for n in names if Path(n).is_absolute() or ".." in Path(n).parts]
            if outside:
                raise InputError("bank.yaml", outside[0], "allowed: folders inside the bank")
            self.dirs = [root / n for n in names]
            missing = [str(d) for d in self.dirs if not (d / "scenario.json").is_file()]
            if missing:
                raise InputError("bank", missing[0], "is listed in bank.yaml but missing")
        else:
            self.dirs = sorted(d for d in root.iterdir() if (d / "scenario.json").is_file())
        if not self.dirs:
            raise InputError(
                "bank", str(directory), "holds no scenario directories (with scenario.json)"
            )
        self._cache: OrderedDict[Path, Scenario] = OrderedDict()
        self._size = cache

    def __len__(self) -> int:
        return len(self.dirs)

    def sample(self, rng: np.random.Generator) -> Scenario:
        d = self.dirs[int(rng.integers(len(self.dirs)))]
        if d in self._cache:
            self._cache.move_to_end(d)
            return self._cache[d]
        scn = sg.load(d)
        self._cache[d] = scn
        while len(self._cache) > self._size:
            self._cache.popitem(last=False)
        return scn


#: Draws of randomized scenario keys the generator may refuse in a row before a reset fails.
MAX_REDRAWS = 20


class RefusedDrawWarning(UserWarning):
    """Some randomized draws make a field the generator refuses (they are drawn again)."""


class FixedFieldWarning(Notice):
    """Every reset of an env drives the same field: nothing about the field is drawn per reset
    (``ScenarioSource.fixed_field``). A notice, once per env; silence it with
    ``warnings.filterwarnings("ignore", category=FixedFieldWarning)`` where that is meant."""


class ScenarioSource:
    """One way in for every kind of scenario; ``sample`` is called at each reset."""

    def __init__(
        self,
        scenario: Any = None,
        overrides: dict[str, Any] | None = None,
        seed: int = 0,
        seed_range: tuple[int, int] | list[int] | None = None,
        bank: str | Path | None = None,
        randomize: Any = None,
    ) -> None:
        if (
            isinstance(seed, bool)
            or not isinstance(seed, (int, np.integer))
            or not 0 <= seed < 2**63
        ):
            raise InputError("scenario_seed", seed, "allowed: an integer in [0, 2**63)")
        lo, hi = _seed_range(seed_range)
        self.seed_range = (lo, hi)
        self.seed, self.seeds_given = int(seed), seed_range is not None
        self.bank = Bank(bank) if bank is not None else None
        if self.bank is not None and scenario is not None:
            raise InputError("scenario", scenario, "give a scenario or a bank, not both")
        self.kind = "bank" if self.bank else "fixed" if _is_fixed(scenario) else "preset"
        if overrides is not None and not isinstance(overrides, dict):
            raise InputError(
                "scenario_overrides", overrides, "allowed: a mapping of spec overrides"
            )
        if self.kind != "preset" and overrides:
            raise InputError(
                "scenario_overrides", overrides, "apply only to presets, not to a saved scenario"
            )
        self.preset = str(scenario or "default") if self.kind == "preset" else None
        self.overrides = dict(overrides or {})
        base = sg.preset(self.preset, **self.overrides) if self.preset else None
        if base is not None and self.overrides:  # the user's fixed values (not the draws)
            check_fields_used(base)
        self.randomization = Randomization(randomize, base)
        if self.randomization.scenario_keys and self.kind != "preset":
            raise InputError(
                "randomize",
                list(self.randomization.scenario_keys),
                "scenario keys need a preset scenario to regenerate",
            )
        self.base = base
        self.redraws = 0  # randomized draws the generator refused (and were drawn again)
        if self.bank is not None:
            self.first = self.bank.sample(np.random.default_rng(seed))
        elif isinstance(scenario, Scenario):
            self.first = check_scenario(scenario, "scenario")
        elif self.kind == "fixed":
            self.first = sg.load(Path(scenario))
        else:
            assert base is not None
            self.first = sg.generate(base, int(seed))

    def sample(
        self, rng: np.random.Generator, current: Scenario, option: Any = None
    ) -> tuple[Scenario, dict[str, Any]]:
        """The next episode's scenario and the env randomization values.

        Draw order (fixed, for determinism): the bank member, the randomized values in sorted
        key order, then the generation seed.
        """
        scn = current
        if option is not None:
            scn = (
                check_scenario(option, "options.scenario")
                if isinstance(option, Scenario)
                else _load_option(option)
            )
        elif self.bank is not None:
            scn = self.bank.sample(rng)
        over, env = self.randomization.sample(rng)
        if over and option is None:
            assert self.base is not None
            for attempt in range(MAX_REDRAWS + 1):
                try:
                    scn = sg.generate(self.base.replace(over), int(rng.integers(*self.seed_range)))
                    break
                except InputError as exc:
                    # a combination the generator refuses for this terrain (contour rows on a
                    # window too flat for them): draw again from the same stream
                    if attempt == MAX_REDRAWS:
                        # name what the user gave: the refused field's range where it is one
                        # of theirs, else every randomized scenario key's
                        mine = [d for d in self.randomization.draws if d.key == exc.field]
                        if not mine:
                            keys = set(self.randomization.scenario_keys)
                            mine = [d for d in self.randomization.draws if d.key in keys]
                        if len(mine) == 1:
                            field, given = f"randomize.{mine[0].key}", mine[0].given()
                        else:
                            field = "randomize"
                            given = "; ".join(f"{d.key} {d.given()}" for d in mine)
                        raise InputError(
                            field,
                            given,
                            f"{MAX_REDRAWS + 1} draws in a row were refused, the last: "
                            f"{exc.field}: got {exc.value!r}; {exc.allowed} (narrow the range)",
                        ) from None
                    self.redraws += 1
                    if self.redraws == 1:
                        warnings.warn(
                            f"a drawn field was refused ({exc.field}: {exc.allowed}); drawn "
                            "again: the randomize ranges hold combinations the generator "
                            "refuses on some terrain, so those are never driven",
                            RefusedDrawWarning,
                            stacklevel=2,
                        )
                    over, env = self.randomization.sample(rng)
        return scn, env

    def describe(self) -> dict[str, Any]:
        return {"kind": self.kind, "preset": self.preset, "overrides": self.overrides}

    def fixed_field(self) -> str | None:
        """Why every reset drives the same field, in one line (None: a field is drawn per
        reset, from a bank or by randomized scenario keys). Only the start pose, the lane and
        the sensors' noise then change between episodes."""
        if self.bank is not None or self.randomization.scenario_keys:
            return None
        if self.preset is not None:
            what = f"preset {self.preset!r} at scenario_seed {self.seed}"
        else:
            what = f"the scenario given ({self.first.spec.name!r})"
        unused = "; scenario_seeds alone changes nothing" if self.seeds_given else ""
        return (
            f"every reset drives one field, {what}{unused}: randomize a scenario key (e.g. "
            "randomize={'layout.plant_spacing': [0.15, 0.25]}) or pass bank=FOLDER to draw "
            "a field per reset"
        )


def check_scenario(scn: Scenario, where: str) -> Scenario:
    """A ``Scenario`` built in Python rather than loaded: the checks ``load`` makes of a folder
    that an object skips (finite plants and route, known species, heights > 0)."""
    from scenario_gen import CATALOG

    p = scn.plants
    arrays = {"x": p.x, "y": p.y, "z": p.z, "height": p.height}
    for name, a in arrays.items():
        if not np.isfinite(np.asarray(a, np.float64)).all():
            raise InputError(f"{where}.plants.{name}", "NaN or inf", "allowed: finite values")
    if (np.asarray(p.height) <= 0).any():
        raise InputError(f"{where}.plants.height", "<= 0", "allowed: heights > 0 m")
    unknown = sorted(set(map(str, p.species)) - set(CATALOG))
    if unknown:
        raise InputError(f"{where}.plants.species", unknown[0], f"allowed: {', '.join(CATALOG)}")
    if not np.isfinite(scn.route.xyz).all():
        raise InputError(f"{where}.route", "NaN or inf", "allowed: finite waypoints")
    return scn


def _is_fixed(scenario: Any) -> bool:
    if isinstance(scenario, Scenario):
        return True
    if scenario is None:
        return False
    if not isinstance(scenario, (str, Path)) or not str(scenario):
        raise InputError(
            "scenario", scenario, "allowed: a Scenario, a scenario directory or a preset name"
        )
    if (Path(scenario) / "scenario.json").is_file():
        return True
    if str(scenario) in sg.preset_names():
        return False
    path = Path(scenario)
    if (path / "bank.yaml").is_file():
        members = sorted(p.name for p in path.iterdir() if (p / "scenario.json").is_file())
        example = f" (e.g. {path / members[0]})" if members else ""
        raise InputError(
            "scenario",
            str(scenario),
            f"is a bank of scenarios (bank.yaml); allowed: one of its members{example}, or "
            "the whole bank as the env's bank=FOLDER",
        )
    if path.is_dir():
        raise InputError(
            "scenario",
            str(scenario),
            "is a folder without scenario.json; allowed: a scenario folder (one that "
            "`agrinav scenario` wrote)",
        )
    if path.exists():
        raise InputError(
            "scenario", str(scenario), "is a file; allowed: a scenario folder or a preset name"
        )
    if isinstance(scenario, Path) or "/" in str(scenario) or "\\" in str(scenario):
        raise InputError(
            "scenario", str(scenario), "no such folder; allowed: a scenario directory or a preset"
        )
    raise InputError(
        "scenario",
        str(scenario),
        f"allowed: a Scenario, a scenario directory or a preset ({', '.join(sg.preset_names())})",
    )


def _load_option(option: Any) -> Scenario:
    """``reset(options={"scenario": ...})``'s scenario; bad ones named as that option."""
    try:
        if not _is_fixed(option):
            return sg.generate(sg.preset(str(option)), 0)
    except InputError as exc:
        if exc.field not in ("scenario", "preset"):
            raise
        raise InputError(
            "options.scenario",
            option,
            "allowed: a Scenario, a scenario folder or a preset name "
            f"({', '.join(sg.preset_names())})",
        ) from None
    return sg.load(Path(option))


def _seed_range(seed_range: Any) -> tuple[int, int]:
    if seed_range is None:
        return 0, 2**31 - 1
    ok = (
        isinstance(seed_range, (list, tuple))
        and len(seed_range) == 2
        and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in seed_range)
        and 0 <= seed_range[0] < seed_range[1] <= 2**63
    )
    if not ok:
        raise InputError(
            "scenario_seeds", seed_range, "allowed: [low, high) integers, 0 <= low < high <= 2**63"
        )
    return int(seed_range[0]), int(seed_range[1])
