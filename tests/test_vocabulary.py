"""Each shared vocabulary is spelled once: GNSS fix modes in ``agrinav_gym.interface``, species
in ``scenario_gen.crops``; every other module imports the names (string literals in the
sources, docstrings aside)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from agrinav_gym.interface import FIX_LEVELS, OBSERVATION_KEYS, RECEIVER_MODES
from scenario_gen.crops import CATALOG, CROP_SPECIES, WEED_SPECIES

SRC = Path(__file__).resolve().parent.parent / "src"

VOCABULARIES = {
    "GNSS modes": (set(FIX_LEVELS) - {"none"}, "agrinav_gym/interface.py"),
    "species": (set(CATALOG), "scenario_gen/crops.py"),
}
#: literals that are another vocabulary's words or a documented default, with the reason
ALLOWED = {
    ("scenario_gen/spec.py", "corn"),  # crop.species' default value
    ("agrinav_gym/tools/proxy_fit.py", "corn"),  # the fit plants weeds in maize rows
    ("baselines/dataset/labels.py", "weed"),  # a label file's field name (is the plant a weed)
    ("baselines/dataset/card.py", "weed"),  # reads that field
}


def _literals(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text())
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
        and node.body
        and isinstance(node.body[0], ast.Expr)
    }
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and id(node) not in docstrings
    ]


@pytest.mark.parametrize("vocabulary", sorted(VOCABULARIES))
def test_a_vocabulary_is_spelled_in_its_own_module_only(vocabulary: str) -> None:
    words, home = VOCABULARIES[vocabulary]
    elsewhere = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        if rel == home:
            continue
        elsewhere += [
            f"{rel}:{line}: {text!r}"
            for line, text in _literals(path)
            if text in words and (rel, text) not in ALLOWED
        ]
    assert elsewhere == []


def test_the_vocabularies_hang_together() -> None:
    assert set(RECEIVER_MODES) < set(FIX_LEVELS)
    assert WEED_SPECIES in CATALOG and WEED_SPECIES not in CROP_SPECIES
    assert len(set(OBSERVATION_KEYS)) == len(OBSERVATION_KEYS)
