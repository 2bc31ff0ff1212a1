"""The parameter form, generated from the spec's own metadata (``field_rows``/``field_info``).

Each spec field gets the widget its type and metadata call for: a select for ``choices``, a
switch for booleans, a number for ints and floats (clearable when null is allowed), a text box
for strings. Its label is the key, its hint the field's doc and what is allowed, exactly as
``docs/config.md`` and the CLI's error messages say, so the page and the CLI cannot disagree.
Values are checked by the session (the CLI's own code), not by the widgets: an out-of-range
value stays visible with its error under it instead of being silently clamped.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any, get_args, get_origin

from nicegui import ui
from nicegui.elements.mixins.validation_element import ValidationElement

from scenario_gen.errors import InputError
from scenario_gen.schema import field_info, field_rows, is_integer_field, parse_yaml
from scenario_gen.spec import ScenarioSpec

#: Keys set elsewhere: the terrain source by the command line, the field by the map, the
#: crop model by the model picker.
NOT_IN_FORM = frozenset(
    {
        "terrain.source",
        "terrain.path",
        "terrain.datum",
        "terrain.up_axis",
        "field.geojson",
        "crop.model",
    }
)
SECTIONS = (
    ("field", "Field rectangle (used until a polygon is drawn)"),
    ("layout", "Layout"),
    ("crop", "Crop"),
    ("furrows", "Furrows"),
    ("route", "Route"),
    ("obstacles", "Obstacles (stones, litter, fallen stalks)"),
    ("terrain", "Terrain"),
)


def rows(section: str) -> list[tuple[str, str, str, str]]:
    """(key, default, allowed, doc) of a section's fields shown in the form."""
    return [
        r
        for r in field_rows(ScenarioSpec)
        if r[0].split(".")[0] == section and r[0] not in NOT_IN_FORM
    ]


def is_sequence(tp: Any) -> bool:
    """A field holding a list or tuple (a range like [30, 80]): edited as text."""
    if get_origin(tp) in (list, tuple):
        return True
    types = [a for a in get_args(tp) if a is not type(None)]
    return any(get_origin(t) in (list, tuple) for t in types)


def as_text(value: Any) -> str:
    """What a text widget shows: nothing for null, JSON for a list, the value otherwise."""
    if value is None:
        return ""
    return json.dumps(list(value)) if isinstance(value, (list, tuple)) else str(value)


def parse(key: str, value: Any) -> Any:
    """A widget's value as the spec field's type: numbers that are whole become ints for int
    fields, an empty number is null, a list typed as text is read as YAML ("[30, 80]"). Range
    and type are checked later, by the session."""
    info = field_info(ScenarioSpec, key)
    tp = info[0] if info else None
    if value == "" or value is None:
        return None
    if tp is not None and is_sequence(tp) and isinstance(value, str):
        return parse_yaml(value, key)
    if is_integer_field(tp) and isinstance(value, float) and value.is_integer():
        return int(value)
    return value


class Form:
    """Widgets by dotted key, with the error shown under the one it concerns."""

    def __init__(self, on_change: Callable[[str, Any], None]) -> None:
        self.on_change = on_change
        self.widgets: dict[str, Any] = {}
        self.hints: dict[str, str] = {}
        self.labels: dict[str, Any] = {}  # section-level error labels ("field", "route", ...)
        self.input_errors: dict[str, str] = {}
        self.shown_error: str | None = None
        self._muted = False

    # ------------------------------------------------------------------ building
    def section(self, section: str, values: dict[str, Any]) -> None:
        for key, _default, allowed, doc in rows(section):
            self.add(key, values[key], doc, allowed)

    def add(self, key: str, value: Any, doc: str, allowed: str) -> Any:
        info = field_info(ScenarioSpec, key)
        assert info is not None and info[0] is not None
        tp, meta = info
        name = key.split(".", 1)[-1]
        hint = f"{doc} · {allowed}"
        choices = meta.get("choices")
        types = [a for a in get_args(tp) if a is not type(None)] or [tp]
        handler = self._handler(key)
        w: Any
        if choices:
            w = ui.select(list(choices), value=value, label=name, on_change=handler)
        elif types == [bool]:
            w = ui.switch(name, value=bool(value), on_change=handler)
        elif is_sequence(tp):
            w = ui.input(label=name, value=as_text(value), on_change=handler)
        elif types[0] in (int, float):
            w = ui.number(label=name, value=value, on_change=handler)
            if type(None) in get_args(tp):
                w.props("clearable")
        else:
            w = ui.input(label=name, value="" if value is None else str(value), on_change=handler)
        if isinstance(w, ValidationElement):
            w.without_auto_validation()  # the session validates; NiceGUI would clear its error
        w.classes("w-full")
        # hide-bottom-space: the hint's area grows with its text (Quasar reserves one line for
        # it otherwise, and a hint that wraps runs over the next field's label)
        w.props.update({"hint": hint, "dense": True, "hide-bottom-space": True, "data-key": key})
        w.tooltip(hint)
        self.widgets[key] = w
        self.hints[key] = hint
        return w

    def _handler(self, key: str) -> Callable[[Any], None]:
        def handle(e: Any) -> None:
            if not self._muted:
                self.on_change(key, parse(key, e.value))

        return handle

    def set_values(self, values: dict[str, Any]) -> None:
        """Show ``values`` (dotted key -> value) without firing change handlers."""
        self._muted = True
        try:
            for key, w in self.widgets.items():
                if key in values:
                    v = values[key]
                    w.value = as_text(v) if isinstance(w, ui.input) else v
        finally:
            self._muted = False

    # ------------------------------------------------------------------ errors
    def target(self, field: str) -> str | None:
        """The widget or section label an ``InputError.field`` belongs to."""
        if field in self.widgets or field in self.labels:
            return field
        for part in field.replace(" ", "").split("/"):  # "layout.headland/edge_margin"
            if part in self.widgets:
                return part
        head = field.split(".")[0].split("[")[0]
        for key in (head, f"{head}."):
            if key in self.labels:
                return key
        return "general" if "general" in self.labels else None

    def show(self, err: InputError, sticky: bool = False) -> str | None:
        """Put ``err`` next to what it concerns; ``sticky`` for a value the session refused."""
        where = self.target(err.field)
        if where is None:
            return None
        if sticky:
            self.input_errors[where] = str(err)
        else:
            self.clear_shown()
            self.shown_error = where
        self._set(where, str(err))
        return where

    def clear_input(self, key: str) -> None:
        if self.input_errors.pop(key, None) is not None:
            self._set(key, None)

    def clear_shown(self) -> None:
        if self.shown_error is not None and self.shown_error not in self.input_errors:
            self._set(self.shown_error, None)
        self.shown_error = None

    def _set(self, where: str, message: str | None) -> None:
        w = self.widgets.get(where)
        if isinstance(w, ValidationElement):
            w.error = message  # Quasar's error slot, under the field
        elif where in self.labels or w is not None:
            label = self.labels.get(where) or self.labels.get(f"{where.split('.')[0]}.")
            if label is not None:
                label.set_text(message or "")
                label.set_visibility(message is not None)
