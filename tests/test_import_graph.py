"""The packages' import graph: no circles, and the layers point one way.

Read from the sources (every ``import``, including those inside functions and under
``TYPE_CHECKING``: a circle through a deferred import is still a circle in the design). A
``from pkg import sub`` where ``sub`` is a module depends on that module, not on ``pkg``'s
``__init__``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent.parent / "src"
PACKAGES = ("scenario_gen", "agrinav_gym", "policies", "baselines")
#: the order imports may point in: a package imports only those before it
LAYERS = {name: set(PACKAGES[:k]) for k, name in enumerate(PACKAGES)}


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for p in (SRC / pkg).rglob("*.py"):
            parts = list(p.relative_to(SRC).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = p
    return out


MODULES = _modules()


def _imports(name: str, path: Path) -> Iterator[str]:
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            subs = [f"{mod}.{a.name}" for a in node.names if f"{mod}.{a.name}" in MODULES]
            if len(subs) < len(node.names):  # some names are attributes of ``mod`` itself
                yield mod
            yield from subs
        elif isinstance(node, ast.Import):
            yield from (a.name for a in node.names)


GRAPH = {
    name: {m for m in _imports(name, path) if m in MODULES and m != name}
    for name, path in MODULES.items()
}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_the_cycle_finder_finds_a_circle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_circles(package: str) -> None:
    inside = {k: {m for m in v if m.split(".")[0] == package} for k, v in GRAPH.items()}
    inside = {k: v for k, v in inside.items() if k.split(".")[0] == package}
    assert _cycles(inside) == []


@pytest.mark.parametrize("package", PACKAGES)
def test_packages_import_down_the_layers_only(package: str) -> None:
    allowed = LAYERS[package] | {package}
    wrong = sorted(
        f"{k} -> {m}"
        for k, v in GRAPH.items()
        if k.split(".")[0] == package
        for m in v
        if m.split(".")[0] not in allowed
    )
    assert wrong == []


def _importers_of(prefix: str) -> set[str]:
    return {
        k for k, v in GRAPH.items() if any(m == prefix or m.startswith(prefix + ".") for m in v)
    }


def test_the_render_engine_knows_no_sensor_physics_or_env() -> None:
    """``agrinav_gym.render`` builds on config, interface and robot only."""
    allowed = ("agrinav_gym.render", "agrinav_gym.config", "agrinav_gym.interface")
    allowed += ("agrinav_gym.robot", "agrinav_gym.rewards")  # rewards: config's own import
    wrong = sorted(
        f"{k} -> {m}"
        for k, v in GRAPH.items()
        if k.startswith("agrinav_gym.render")
        for m in v
        if m.startswith("agrinav_gym") and not m.startswith(allowed)
    )
    assert wrong == []


def test_offline_tools_are_not_imported_at_run_time() -> None:
    users = {k for k in _importers_of("agrinav_gym.tools") if not k.startswith("agrinav_gym.tools")}
    assert users == set()


def test_the_studio_and_the_cli_do_not_import_each_other_both_ways() -> None:
    studio_to_cli = {
        f"{k} -> {m}"
        for k, v in GRAPH.items()
        if k.startswith("baselines.studio")
        for m in v
        if m.startswith("baselines.cli")
    }
    assert studio_to_cli == set()
