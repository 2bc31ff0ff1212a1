"""Benchmark suites: the same held-out scenarios and seeds for every policy.

Evaluation seeds start at 10⁹ and scenario seeds are drawn from the hyperparameters' eval range,
disjoint from every training range (MetaDrive-style splits).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from agrinav_gym.interface import GNSS_RTK_FIXED, GNSS_RTK_FLOAT, OBSERVATION_KEYS
from agrinav_gym.sim.terramechanics import measured_strength
from scenario_gen import ScenarioError

EVAL_SEED = 1_000_000_000
ALL_OBS = list(OBSERVATION_KEYS)  # every policy finds its inputs


@dataclass(frozen=True)
class Case:
    group: str  # the scenario group a results row belongs to
    env_id: str
    scenario: str
    overrides: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    max_steps: int | None = None
    # Scenario keys drawn afresh each episode (from the episode's reset seed), generated with
    # seeds from the eval range: geometries no training run drew.
    randomize: dict[str, Any] = field(default_factory=dict)
    # One long run per episode in which every stall, corridor exit or stalk contact is an
    # intervention after which the run resumes from the route (episodes.run_with_interventions)
    interventions: bool = False
    # The index of the case (in its suite) whose evaluation seeds this one reuses: the same
    # fields and sensor noise, so the two differ only in what the case changes (paired
    # comparisons). None: the case's own seeds.
    seeds_of: int | None = None

    @property
    def planted(self) -> bool:
        """The case sets the planting drift (at 0 too: the reference row), so its records
        carry the path's error from the lanes as planted beside the logged route's."""
        layout = self.overrides.get("layout", {})
        return "drift_amplitude" in layout or "layout.drift_amplitude" in self.randomize

    def env_kwargs(self) -> dict[str, Any]:
        kw: dict[str, Any] = {
            "scenario": self.scenario,
            "observations": ALL_OBS,
            "scenario_seed": EVAL_SEED,
        }
        if self.overrides:
            kw["scenario_overrides"] = self.overrides
        if self.config:
            kw["config"] = self.config
        if self.randomize:
            kw["randomize"] = self.randomize
            kw["scenario_seeds"] = list(EVAL_SCENARIO_SEEDS)
        return kw

    def field(self) -> Any:
        """The one field every episode of this case drives, generated as its env generates it
        (a case that randomizes scenario keys draws a field per episode: refused)."""
        from agrinav_gym.scenarios import ScenarioSource

        if self.randomize:
            raise ScenarioError("case", self.group, "draws a new field each episode")
        return ScenarioSource(self.scenario, self.overrides or None, EVAL_SEED).first


#: Held-out scenario seeds, the range every envs.yml entry evaluates on.
EVAL_SCENARIO_SEEDS = (1_000_000_000, 1_001_000_000)
PAPER_FIELD = {"field": {"width": 12.5, "length": 30.0}, "route": {"lanes": 2}}
#: The field the seed robot's four waypoints lie on (31 m lanes; benchmarks/paper_waypoints.py).
PAPER_WAYPOINT_FIELD: dict[str, Any] = {"field": {"width": 12.5, "length": 39.0}}


#: The `paper` case on ridged planting, as the source paper's simulated field was.
PAPER_RIDGED = "corn-early, ridged 12 cm"

#: The paper run's step limit: the navigator, not the clock, ends a stuck run. Per goal Nav2's
#: tree gives up after 14 progress-check failures (10 s each) and six recoveries (≤ 10 s
#: each): 200 s; three goals, plus the 70 m route at DWB's tuned 0.42 m/s (167 s), is 767 s,
#: 15,340 control steps at 20 Hz.
PAPER_MAX_STEPS = 15_400


def heldout_dem() -> str:
    """The DEM no training field comes from (``baselines/heldout_terrain``: 25 m, BC interior)."""
    from importlib import resources

    return str(resources.files("baselines").joinpath("heldout_terrain", "bc_interior_25m.tif"))


def paper_waypoints() -> str:
    """The shipped waypoint file of the `paper` suite (Nav2's GPS waypoint format)."""
    from importlib import resources

    return str(resources.files("baselines.hyperparams").joinpath("paper_waypoints.yml"))


#: Nav2 Humble's progress checker (SimpleProgressChecker: 0.5 m within 10 s, else the goal
#: fails), so a stall is a failure after 10 s, not a run to the step limit.
NAV2_PROGRESS: dict[str, Any] = {"progress_time": 10.0, "progress_radius": 0.5}

#: robot_localization as its documentation asks a user to set it up beyond the node's defaults:
#: the base_link -> gps transform navsat_transform reads from TF, smooth_lagged_data with 1 s
#: of history (the fix arrives 0.1 s after its epoch), and a Mahalanobis gate on the GPS at 5σ.
RL_USER_SETUP: dict[str, Any] = {
    "gps_lever_arm": True,
    "smooth_lagged_data": True,
    "history_length_s": 1.0,
    "gps_rejection_threshold": 5.0,
}

#: The benchmark's localisation: RTK through robot_localization (ekf_node + navsat_transform)
#: as a Nav2 user runs it, with no knowledge of the simulator's error models.
RTK_NAV2: dict[str, Any] = {
    "localisation": {"kind": "robot_localization", "robot_localization": RL_USER_SETUP},
    "gnss": {"mode": GNSS_RTK_FIXED},
    "task": NAV2_PROGRESS,
}

#: The same with the oracle EKF (``ekf``: it knows the simulator's error models, an upper
#: bound): the `localisation` suite's reference rows, the v1 `zigzag` run, and the conditions
#: the shipped tuning searches and PPO checkpoints ran under.
RTK_EKF: dict[str, Any] = {**RTK_NAV2, "localisation": {"kind": "ekf"}}

#: The FieldRoute test suites' clock: the progress checker's own rate (20 s per metre of route;
#: TaskConfig.seconds_per_metre), so the step limit never ends an episode a robot that keeps
#: the checker quiet would finish (tuned DWB at 0.42 m/s took ≈ 200 s, the registered 4,000
#: steps, on the longest routes). A route of ≥ 10 m gets ≥ 4,000 steps: every episode that
#: ended before the registered limit is unchanged.
ROUTE_CLOCK: dict[str, Any] = {
    "seconds_per_metre": NAV2_PROGRESS["progress_time"] / NAV2_PROGRESS["progress_radius"]
}
#: the TimeLimit wrapper's backstop behind the route's clock (a 250 m route at 20 s/m)
ROUTE_CLOCK_BACKSTOP = 100_000

#: Each ``ood`` case holds one axis out of the FieldRoute training ranges (envs.yml): the
#: randomized keys it fixes, its scenario overrides and its env config.
OOD_AXES: tuple[tuple[str, tuple[str, ...], dict[str, Any], dict[str, Any]], ...] = (
    (
        "ridged 12 cm",
        ("furrows.enabled", "furrows.depth"),
        {"furrows": {"enabled": True, "depth": 0.12}},
        {},
    ),
    ("rows 0.8 m", ("layout.row_spacing",), {"layout": {"row_spacing": 0.8}}, {}),
    ("rows 1.2 m", ("layout.row_spacing",), {"layout": {"row_spacing": 1.2}}, {}),
    ("maize 0.18 m in-row", (), {"layout": {"plant_spacing": 0.18}}, {}),
    (
        "slope 9-12 deg",
        ("terrain.max_slope_deg",),
        {},
        {"randomize": {"terrain.max_slope_deg": [9.0, 12.0]}},
    ),
    ("RTK float", (), {}, {"gnss": {"mode": GNSS_RTK_FLOAT, "fix": {"model": "constant"}}}),
    # Appended, never inserted: a case's evaluation seeds follow from its index.
    (
        "curved rows R 15-30 m",
        (),
        {"layout": {"row_geometry": "curved", "curve_radius": [15.0, 30.0]}},
        {},
    ),
    (
        "contour rows, slope 4-8 deg",
        ("terrain.max_slope_deg",),
        {"layout": {"row_geometry": "contour"}},
        {"randomize": {"terrain.max_slope_deg": [4.0, 8.0]}},
    ),
    (
        "stones 0.3/m², 5 % lodged",
        (),
        {"obstacles": {"stone_density": 0.3, "stalk_lodging": 0.05}},
        {},
    ),
    # The farmer's answer to staggered row ends: a turn sized to the footprint, in a headland
    # wide enough for it (the keyhole needs ≈ 4 m past the crop at R 0.9 m).
    (
        "curved rows R 15-30 m, keyhole turns",
        (),
        {
            "layout": {"row_geometry": "curved", "curve_radius": [15.0, 30.0], "headland": 5.0},
            "route": {"turn": "keyhole"},
        },
        {},
    ),
    (
        "contour rows, slope 4-8 deg, keyhole turns",
        ("terrain.max_slope_deg",),
        {"layout": {"row_geometry": "contour", "headland": 5.0}, "route": {"turn": "keyhole"}},
        {"randomize": {"terrain.max_slope_deg": [4.0, 8.0]}},
    ),
    # The terrain source held out: the same slope draw on a DEM of another region, grid,
    # projection and sample type (baselines/heldout_terrain/README.md).
    (
        "second real DEM (BC interior, 25 m)",
        (),
        {"terrain": {"source": "dem", "path": heldout_dem()}},
        {},
    ),
)


def _unseen() -> list[Case]:
    """FieldRoute on geometries drawn like the PPO training split's, from the eval seeds."""
    from .hyperparams import load

    _, setup = load("AgriNav/FieldRoute-v3")
    kw = setup.env_kwargs
    over = dict(kw.get("scenario_overrides", {}))
    rand = {k: v for k, v in kw.get("randomize", {}).items() if "." in k}
    config = {**RTK_NAV2, "task": {**NAV2_PROGRESS, **ROUTE_CLOCK}}
    return [
        Case(
            "unseen fields",
            "AgriNav/FieldRoute-v3",
            str(kw.get("scenario", "paper-p1")),
            over,
            config,
            ROUTE_CLOCK_BACKSTOP,
            randomize=rand,
        )
    ]


def _ood() -> list[Case]:
    """FieldRoute on held-out geometries (eval seeds), one planting/sensing axis outside the
    training ranges per case."""
    (base,) = _unseen()
    cases = []
    for group, fixed, overrides, extra in OOD_AXES:
        rand = {k: v for k, v in base.randomize.items() if k not in fixed}
        rand.update(extra.get("randomize", {}))
        config = {**base.config, **{k: v for k, v in extra.items() if k != "randomize"}}
        over = {**base.overrides}
        for section, values in overrides.items():
            over[section] = {**over.get(section, {}), **values}
        cases.append(
            Case(
                group,
                base.env_id,
                base.scenario,
                over,
                config,
                base.max_steps,
                randomize=rand,
            )
        )
    return cases


#: The simulator values nobody measured for this robot, each at both ends of its plausible
#: range (sources in docs/physics.md and docs/localisation.md): a case's config section and
#: values. Appended, never inserted: a case's evaluation seeds follow from its index.
SENSITIVITY: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("default soil", "soil", {}),
    ("soil friction 0.4", "soil", {"friction": 0.4}),
    ("soil friction 0.8", "soil", {"friction": 0.8}),
    ("soil shear modulus 0.01 m", "soil", {"shear_modulus": 0.01}),
    ("soil shear modulus 0.05 m", "soil", {"shear_modulus": 0.05}),
    # the tyre's contact across its tread: a point in the registered envs, 0.15 m the
    # Summit-XL's (its URDF's wheel), 0.25 m a wider field tyre
    ("tread 0.15 m", "soil", {"contact_width": 0.15}),
    ("tread 0.25 m", "soil", {"contact_width": 0.25}),
    ("canopy 2.5 m, foliage 0.4 dB/m", "foliage", {"foliage_db_per_m": 0.4}),
    ("canopy 2.5 m, foliage 2 dB/m", "foliage", {"foliage_db_per_m": 2.0}),
    # Open-sky multipath slips of RTK fixed (gnss.fix.multipath_mtbf_s, 600 s assumed): with a
    # 10 s re-fix, 120 s is ≈ 92 % of the time fixed, none 100 %; on the `unseen` fields,
    # paired with "default soil" (every value at its default)
    ("multipath slips every 120 s", "multipath", {"multipath_mtbf_s": 120.0}),
    ("no multipath slips", "multipath", {"multipath_mtbf_s": 1e6}),
    # Appended, as a row's place sets its seeds: ridges that yield (sim.terramechanics), the
    # Summit-XL's tread on two of Wong's measured soils (a firmer and a looser one)
    *(
        (f"ground yields: {name}", "soil", {"contact_width": 0.15, **measured_strength(name)})
        for name in ("sandy loam 15 % (LLL)", "dry sand (LLL)")
    ),
    # The proxy camera's plant parameters (DWB's costmap reads its depth): the table fitted on
    # flat lanes instead of the ridged lanes' default; paired with "default soil"
    ("proxy camera fitted on flat lanes", "camera", {"proxy_fit": "flat"}),
    # Slips every 40 s (≈ 80 % of the time fixed): the one fixed ratio found for a receiver of
    # this class, a ZED-F9P's 80 % in a static session (docs/localisation.md), read as slips
    ("multipath slips every 40 s", "multipath", {"multipath_mtbf_s": 40.0}),
)


def _sensitivity() -> list[Case]:
    """The ranking with each assumed simulator value at the ends of its range: soil values on
    the `unseen` fields (flat and ridged: where the soil decides how much a ridge steers),
    foliage loss under 2.5 m maize over the antenna (where the GNSS fix depends on it), open-sky
    multipath slips of RTK fixed and the proxy camera's fitted table on the `unseen` fields."""
    (base,) = _unseen()
    cases = []
    first: dict[str, int] = {}  # every case of a kind drives the first one's fields and seeds
    for i, (group, kind, values) in enumerate(SENSITIVITY):
        # the multipath and camera rows pair with the default soil row: every value at its
        # default
        paired = 0 if kind in ("multipath", "camera") else first.setdefault(kind, i)
        if kind == "foliage":
            config = {**base.config, "gnss": {**RTK_NAV2["gnss"], "fix": values}}
            over = {**PAPER_FIELD, "crop": {"stage": 5}}
            cases.append(
                Case(
                    group,
                    "AgriNav/FieldRoute-v3",
                    "paper-p1",
                    over,
                    config,
                    base.max_steps,
                    seeds_of=paired,
                )
            )
            continue
        if kind in ("soil", "camera"):
            config = {**base.config, kind: values}
        else:
            config = {**base.config, "gnss": {**RTK_NAV2["gnss"], "fix": values}}
        cases.append(
            Case(
                group,
                base.env_id,
                base.scenario,
                base.overrides,
                config,
                base.max_steps,
                randomize=base.randomize,
                seeds_of=paired,
            )
        )
    return cases


#: Rows off the map (docs/localisation.md "Rows off the map"): each planter pass drifts from the
#: logged line by up to this amplitude (m): none, an RTK-guided planter's few centimetres, and
#: pass-to-pass free or subscription corrections' decimetres (the cited ranges' 0.05 and 0.2 m).
DRIFT_AMPLITUDES = ((0.0, "logged rows"), (0.05, "RTK planter"), (0.2, "SBAS planter"))
#: the drift's longest wavelength is assumed (docs/localisation.md): drawn per field from the
#: part of its swept range a 22 m lane feels as a curve rather than an offset
DRIFT_WAVELENGTH = [30.0, 100.0]
#: rows a planter sows in one pass, which drift together (common maize planters: 4 to 12 rows);
#: the lane driven may lie inside a pass (its width kept) or between two (its width varies)
DRIFT_PASS_ROWS = [4, 6, 8, 12]


def _drift() -> list[Case]:
    """GNSS-only following against perception on rows planted off their logged lines: one
    lane of 0.3 m maize (where depth-only following works on the crop meshes) on the paper's
    1 m rows, the route the logged line, the planter's drift at each amplitude, the navigation
    suites' estimator, progress checker and route clock; every case drives the first one's
    fields and seeds (a new field and drift shape each episode), so the rows differ only in
    how far the plants stray."""
    cases = []
    for i, (amplitude, label) in enumerate(DRIFT_AMPLITUDES):
        over = {
            "crop": {"stage": 1},
            "layout": {"row_spacing": 1.0, "drift_amplitude": amplitude},
        }
        cases.append(
            Case(
                f"{label} ({amplitude:g} m)",
                "AgriNav/FurrowFollow-v3",
                "default",
                over,
                {
                    **RTK_NAV2,
                    "camera": {"model": "mesh"},
                    "task": {**NAV2_PROGRESS, **ROUTE_CLOCK},
                },
                # the route's clock, not a step limit, ends a slow run the progress checker
                # lets go on (DWB reads the leaves into its costmap and slows in the lane)
                max_steps=ROUTE_CLOCK_BACKSTOP,
                randomize={
                    "layout.drift_wavelength": DRIFT_WAVELENGTH,
                    "layout.drift_pass_rows": {"choices": DRIFT_PASS_ROWS},
                },
                seeds_of=None if i == 0 else 0,
            )
        )
    return cases


def _long() -> list[Case]:
    """Eight lanes of 30 m (≈ 260 m of route) with interventions, as field trials report
    row following: mean distance between interventions, sparse (P1) and real maize spacing."""
    over = {**PAPER_FIELD, "field": {"width": 10.5, "length": 30.0}, "route": {"lanes": 8}}
    config = {**RTK_NAV2, "task": {**NAV2_PROGRESS, "max_crops_hit": 0}}
    return [
        Case(
            g,
            "AgriNav/FieldRoute-v3",
            "paper-p1",
            {**over, **o},
            config,
            12_000,
            interventions=True,
        )
        for g, o in (
            ("8 lanes, flat", {}),
            ("8 lanes, maize 0.18 m in-row", {"layout": {"plant_spacing": 0.18}}),
        )
    ]


def _localisation() -> list[Case]:
    """The paper run under each localisation: ideal (debug), RTK fixed / float without
    canopy effects, and the canopy-driven fix modes under 2.5 m maize over the antenna."""
    const = {"fix": {"model": "constant"}}
    rows = (
        ("ideal", 3, {"localisation": {"kind": "ideal"}}),
        (
            "RTK fixed",
            3,
            {"localisation": {"kind": "ekf"}, "gnss": {"mode": GNSS_RTK_FIXED, **const}},
        ),
        (
            "RTK float",
            3,
            {"localisation": {"kind": "ekf"}, "gnss": {"mode": GNSS_RTK_FLOAT, **const}},
        ),
        ("canopy 2.5 m", 5, RTK_EKF),
    )
    cases = [
        Case(g, "AgriNav/FieldRoute-v3", "paper-p1", {**PAPER_FIELD, "crop": {"stage": s}}, c)
        for g, s, c in rows
    ]
    # Appended: the same runs with the estimator a Nav2 user runs, paired with the oracle's
    # rows (same fields and noise): its defaults, and as a careful user sets it up
    # (base_link -> gps transform, smooth_lagged_data with 1 s of history, GPS gate at 5σ).
    for label, rl in (
        ("robot_localization", {}),
        ("robot_localization tuned", RL_USER_SETUP),
    ):
        for ref in (1, 3):  # RTK fixed; canopy 2.5 m
            base = cases[ref]
            loc = {"kind": "robot_localization", "robot_localization": rl}
            cases.append(
                Case(
                    f"{base.group}, {label}",
                    base.env_id,
                    base.scenario,
                    base.overrides,
                    {**base.config, "localisation": loc},
                    seeds_of=ref,
                )
            )
    return cases


def suite(name: str) -> list[Case]:
    """The cases of a suite, in a fixed order."""
    if name == "smoke":
        # A 14 m lane: long enough that the 0.3 m start offset and the 0.3 m success tolerance
        # leave a finished lane above 95 % completion; the slowest shipped controller (DWB,
        # ≈ 0.45 m/s) drives it in ≈ 650 steps.
        tiny = {
            "field": {"width": 6.0, "length": 18.0},
            "layout": {"headland": 1.5},
            "terrain": {"margin": 4.0},
        }
        return [Case("tiny", "AgriNav/FurrowFollow-v3", "default", tiny, max_steps=800)]
    if name == "paper":
        # The source paper's experiment as it ran: four Nav2 GPS waypoints (33 m along a lane,
        # across the headland, 31 m back) read through the datum, the straight-leg plan between
        # them handed over a waypoint at a time as Nav2's waypoint follower does (each a goal
        # reached within 0.25 m), RTK GNSS through robot_localization, Nav2's progress checker
        # and its default tree's recoveries, the follower going on past a waypoint the tree gives up
        # (stop_on_failure: false, Humble's nav2_params.yaml), early and intermediate corn on
        # the P1 density (1 m rows).
        route = {"waypoints": paper_waypoints()}
        nav2 = {
            **NAV2_PROGRESS,
            "waypoint_goals": True,
            "recoveries": True,
            "stop_on_failure": False,
        }
        goals = {**RTK_NAV2, "task": nav2}
        cases = [
            Case(
                f"corn-{label}",
                "AgriNav/FieldRoute-v3",
                "paper-p1",
                {**PAPER_WAYPOINT_FIELD, "route": route, "crop": {"stage": stage}},
                goals,
                max_steps=PAPER_MAX_STEPS,
            )
            for label, stage in (("early", 1), ("intermediate", 3))
        ]
        # Appended: early corn on the ridges the paper's own field had (its heightmap furrows,
        # 0.10-0.15 m: the ridged preset's 0.12 m), on the first case's fields and seeds.
        ridged = {**cases[0].overrides, "furrows": {"enabled": True, "depth": 0.12}}
        return [
            *cases,
            dataclasses.replace(cases[0], group=PAPER_RIDGED, overrides=ridged, seeds_of=0),
        ]
    if name == "zigzag":
        # The v1 `paper` run: a zigzag over two lanes with a headland U-turn of the row
        # spacing's diameter (not what the paper drove), RTK through the oracle EKF, early and
        # intermediate corn on P1.
        return [
            Case(
                f"corn-{label}",
                "AgriNav/FieldRoute-v3",
                "paper-p1",
                {**PAPER_FIELD, "crop": {"stage": stage}},
                RTK_EKF,
            )
            for label, stage in (("early", 1), ("intermediate", 3))
        ]
    if name == "unseen":
        return _unseen()
    if name == "localisation":
        return _localisation()
    if name == "ood":
        return _ood()
    if name == "long":
        return _long()
    if name == "sensitivity":
        return _sensitivity()
    if name in ("growth", "growth-proxy"):
        # Dense maize (0.18 m in the row) on the paper's 1 m rows: in 0.75 m rows a 0.62 m
        # Summit-XL touches stalks at 2 cm of error, and crop contact, not perception, would end
        # every episode. 1,500 steps leave the slowest controller time to finish a lane. The
        # depth images come from the crop meshes (`growth`) or their fitted proxies
        # (`growth-proxy`): where depth-only following fails is what the meshes say.
        model = "mesh" if name == "growth" else "proxy"
        return [
            Case(
                f"{h} m",
                "AgriNav/FurrowFollow-v3",
                "default",
                {"crop": {"stage": s}, "layout": {"row_spacing": 1.0}},
                {"camera": {"model": model}},
                max_steps=1500,
            )
            for s, h in ((1, 0.3), (2, 0.6), (3, 1.2), (4, 1.8), (5, 2.5))
        ]
    if name == "drift":
        return _drift()
    if name == "density":
        return [
            Case(
                p.upper(),
                "AgriNav/FurrowFollow-v3",
                f"paper-{p}",
                {"field": {"width": 20.0, "length": 30.0}},
            )
            for p in ("p1", "p2", "p3", "p4")
        ]
    if name == "terrain":
        return [
            Case("flat", "AgriNav/FurrowFollow-v3", "default"),
            Case("hillside", "AgriNav/FurrowFollow-v3", "hillside"),
        ]
    raise ScenarioError("--suite", name, f"allowed: one of {', '.join(SUITES)}")


SUITES = (
    "smoke",
    "paper",
    "zigzag",
    "unseen",
    "ood",
    "long",
    "localisation",
    "growth",
    "growth-proxy",
    "density",
    "terrain",
    "sensitivity",
    "drift",
)
