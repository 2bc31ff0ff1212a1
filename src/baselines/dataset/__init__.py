"""Domain-randomized datasets: labelled perception frames (``agrinav dataset perception``)."""

from .card import write_card
from .loader import PerceptionDataset
from .run import generate
from .spec import SCHEMA_VERSION, PerceptionSpec, load_spec

__all__ = [
    "SCHEMA_VERSION",
    "PerceptionDataset",
    "PerceptionSpec",
    "generate",
    "load_spec",
    "write_card",
]
