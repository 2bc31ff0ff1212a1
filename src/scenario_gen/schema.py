"""The one configuration dialect: frozen typed dataclasses whose fields carry unit, range and doc.

Scenario specs, env config, DWB parameters and PPO hyperparameters are all built with
``from_mapping``: unknown keys and bad values raise ``InputError`` naming the dotted field, the
value and what is allowed. ``field_rows`` turns the metadata into the config reference
(docs/config.md), so documentation and validation cannot disagree. YAML is read through
``load_yaml``: bounded in size and depth, with aliases refused (an alias bomb expands
exponentially before a single key can be checked).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import types
from dataclasses import field as dc_field
from pathlib import Path
from typing import Any, Union, get_args, get_origin, get_type_hints

import numpy as np
import yaml

from .errors import InputError

MAX_YAML_BYTES = 1 << 20
MAX_DEPTH = 32


def param(
    default: Any,
    doc: str,
    lo: float | None = None,
    hi: float | None = None,
    choices: tuple[Any, ...] | None = None,
    above: bool = False,
) -> Any:
    """A config field: its default, what it means (with its unit) and what is allowed
    (``above``: ``lo`` itself is not)."""
    meta = {"doc": doc, "lo": lo, "hi": hi, "choices": choices, "above": above}
    if isinstance(default, (dict, list)):
        frozen = default
        return dc_field(default_factory=lambda: _plain(frozen), metadata=meta)
    return dc_field(default=default, metadata=meta)


def plain(obj: Any) -> Any:
    """Nested dicts/lists/scalars only (tuples become lists): what YAML and JSON hold."""
    return _plain(obj)


def _plain(obj: Any, depth: int = 0) -> Any:
    if depth > MAX_DEPTH:
        raise InputError("config", "<nested>", f"allowed: at most {MAX_DEPTH} levels of nesting")
    if isinstance(obj, dict):
        return {k: _plain(v, depth + 1) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v, depth + 1) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def merge(
    base: dict[str, Any], overrides: dict[str, Any], what: str = "overrides"
) -> dict[str, Any]:
    """Deep-merge ``overrides`` (nested dicts and/or dotted keys; named ``what`` in errors)
    into a copy of ``base``."""
    if not isinstance(overrides, dict):
        raise InputError(what, overrides, "allowed: a mapping of keys to values")
    _given_once(overrides)
    out = _plain(base)
    for key, value in overrides.items():
        if not isinstance(key, str) or not key:
            raise InputError(what, key, "allowed: non-empty string keys")
        parts = key.split(".")
        node = out
        for i, part in enumerate(parts[:-1]):
            nxt = node.get(part)
            if not isinstance(nxt, dict):
                if part in node:
                    raise InputError(".".join(parts[: i + 1]), nxt, "is not a section")
                nxt = node[part] = {}
            node = nxt
        last = parts[-1]
        if isinstance(value, dict) and isinstance(node.get(last), dict):
            node[last] = merge(node[last], value, what)
        else:
            node[last] = _plain(value)
    return out


def _given_once(overrides: dict[str, Any]) -> None:
    """Refuse a field that one mapping sets twice, dotted and nested (``{"robot.v_max": 1.2,
    "robot": {"v_max": 0.5}}``): which wins would depend on the keys' order."""
    seen: set[str] = set()

    def walk(prefix: str, node: dict[Any, Any]) -> None:
        for key, value in node.items():
            if not isinstance(key, str) or not key:
                continue  # merge names it
            path = f"{prefix}{key}"
            if isinstance(value, dict) and value:
                walk(f"{path}.", value)
            elif path in seen:
                raise InputError(path, value, "is given twice (dotted and nested); give it once")
            else:
                seen.add(path)

    walk("", overrides)


def from_mapping(cls: type, data: Any, prefix: str = "") -> Any:
    """Build a frozen config dataclass from a mapping, checking every key and value."""
    where = prefix.rstrip(".") or "spec"
    if not isinstance(data, dict):
        raise InputError(where, data, "allowed: a mapping of keys to values")
    hints = get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(str(k) for k in set(data) - set(fields))
    if unknown:
        raise InputError(
            f"{prefix}{unknown[0]}",
            data.get(unknown[0]),
            f"unknown key; allowed keys here: {', '.join(fields)}",
        )
    kwargs: dict[str, Any] = {}
    for name, value in data.items():
        f, tp, path = fields[name], hints[name], f"{prefix}{name}"
        if dataclasses.is_dataclass(tp):
            kwargs[name] = from_mapping(tp, value, path + ".")  # type: ignore[arg-type]
        else:
            kwargs[name] = coerce(value, tp, f.metadata, path)
    return cls(**kwargs)


def to_mapping(obj: Any) -> dict[str, Any]:
    out: dict[str, Any] = _plain(dataclasses.asdict(obj))
    return out


def coerce(value: Any, tp: Any, meta: Any, path: str) -> Any:
    """``value`` checked against a field's type hint and metadata (range, choices)."""
    args = get_args(tp)
    if get_origin(tp) in (Union, types.UnionType) and type(None) in args:
        if value is None:
            return None
        rest = [a for a in args if a is not type(None)]
        tp = rest[0] if len(rest) == 1 else Union[tuple(rest)]  # noqa: UP007
        args = get_args(tp)
    elif value is None:
        raise InputError(path, value, f"allowed: {describe(tp, meta)} (not null)")
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        for alt in args:
            try:
                return coerce(value, alt, meta, path)
            except InputError:
                continue
        raise InputError(path, value, f"allowed: {describe(tp, meta)}")
    if origin is tuple:
        inner = get_args(tp)
        if inner and inner[-1] is Ellipsis:
            inner = (inner[0],) * (len(value) if isinstance(value, (list, tuple)) else 0)
        if not isinstance(value, (list, tuple)) or len(value) != len(inner):
            raise InputError(path, value, f"allowed: {describe(tp, meta)}")
        return tuple(
            scalar(v, t, meta, f"{path}[{i}]")
            for i, (v, t) in enumerate(zip(value, inner, strict=True))
        )
    if origin is dict:
        if not isinstance(value, dict):
            raise InputError(path, value, "allowed: a mapping")
        kt, vt = get_args(tp)
        choices = meta.get("choices")
        out = {}
        for k, v in value.items():
            if choices is not None and k not in choices:
                raise InputError(f"{path}.{k}", v, f"unknown key; allowed: {', '.join(choices)}")
            out[scalar(k, kt, {}, path)] = coerce(
                v,
                vt,
                {"lo": meta.get("lo"), "hi": meta.get("hi"), "above": meta.get("above")},
                f"{path}.{k}",
            )
        return out
    if origin is list:
        (it,) = get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise InputError(path, value, f"allowed: a list of {describe(it, {})}")
        return [coerce(v, it, meta, f"{path}[{i}]") for i, v in enumerate(value)]
    if tp is Any:
        return _plain(value)
    return scalar(value, tp, meta, path)


def scalar(value: Any, tp: Any, meta: Any, path: str) -> Any:
    if isinstance(value, np.generic):  # numpy scalars are as good as Python's
        value = value.item()
    if tp is bool:
        if not isinstance(value, bool):
            raise InputError(path, value, "allowed: true or false")
        return value
    if tp is int:
        if isinstance(value, bool) or not (
            isinstance(value, int) or (isinstance(value, float) and value.is_integer())
        ):
            raise InputError(path, value, f"allowed: {describe(tp, meta)}")
        value = int(value)
    elif tp is float:
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise InputError(path, value, f"allowed: {describe(tp, meta)}")
        value = float(value)
    elif tp is str:
        if not isinstance(value, str):
            raise InputError(path, value, f"allowed: {describe(tp, meta)}")
    lo, hi, choices = meta.get("lo"), meta.get("hi"), meta.get("choices")
    if choices is not None and value not in choices:
        raise InputError(path, value, f"allowed: {describe(tp, meta)}")
    low = lo is not None and (value <= lo if meta.get("above") else value < lo)
    if low or (hi is not None and value > hi):
        raise InputError(path, value, f"allowed: {describe(tp, meta)}")
    return value


def describe(tp: Any, meta: Any) -> str:
    """What a field accepts, in words ("a number in [0.05, 50]")."""
    choices = meta.get("choices")
    args = get_args(tp)
    if get_origin(tp) in (Union, types.UnionType):
        rest = [a for a in args if a is not type(None)]
        text = " or ".join(describe(a, meta) for a in rest)
        return text + (" or null" if type(None) in args else "")
    if get_origin(tp) is tuple:
        inner = [a for a in args if a is not Ellipsis]
        return f"a list of {len(inner) if Ellipsis not in args else 'any number of'} " + (
            describe(inner[0], meta).replace("a number", "numbers") if inner else "values"
        )
    if get_origin(tp) in (dict, list):
        return "a mapping" if get_origin(tp) is dict else "a list"
    if choices:
        return "one of " + ", ".join(map(str, choices))
    name = {float: "a number", int: "an integer", str: "a string", bool: "true/false"}.get(
        tp, getattr(tp, "__name__", str(tp))
    )
    lo, hi = meta.get("lo"), meta.get("hi")
    opening = "(" if meta.get("above") else "["
    if lo is not None and hi is not None:
        return f"{name} in {opening}{_num(lo)}, {_num(hi)}]"
    if lo is not None:
        return f"{name} {'>' if meta.get('above') else '>='} {_num(lo)}"
    return name


def _num(v: float) -> str:
    if float(v).is_integer() and abs(v) < 1e15:
        n = int(v)
        return f"2**{n.bit_length() - 1}" if n > 1 << 20 and n & (n - 1) == 0 else str(n)
    return f"{v:g}"


def field_rows(cls: type, prefix: str = "") -> list[tuple[str, str, str, str]]:
    """(dotted name, default, allowed, doc) for every field, nested sections flattened."""
    hints = get_type_hints(cls)
    rows: list[tuple[str, str, str, str]] = []
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            rows += field_rows(tp, f"{prefix}{f.name}.")  # type: ignore[arg-type]
            continue
        default = (
            f.default
            if f.default is not dataclasses.MISSING
            else f.default_factory()
            if f.default_factory is not dataclasses.MISSING
            else None
        )
        rows.append(
            (
                f"{prefix}{f.name}",
                json.dumps(_plain(default), ensure_ascii=False),
                describe(tp, f.metadata),
                str(f.metadata.get("doc", "")),
            )
        )
    return rows


# ----------------------------------------------------------------------------- YAML in


class _NoAliasLoader(yaml.SafeLoader):
    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.constructor.ConstructorError(
                None, None, "aliases (*name) are not allowed", event.start_mark
            )
        return super().compose_node(parent, index)

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        # PyYAML keeps the last of two equal keys silently: a typo'd duplicate would override
        # the value the user reads above it
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key: PyYAML reports it itself
                break
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


# YAML 1.1 (PyYAML) reads an exponent only with a dot and a signed power: ``1e6``, ``2e-3`` and
# ``1.5e3`` would be strings, and a config value typed as a number would be refused as one.
# YAML 1.2 reads them as floats.
_NoAliasLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+.0123456789"),
)


# YAML 1.1 (PyYAML) also reads ``36:32:57`` as the base-60 integer 131577 and ``1:30.5`` as
# 90.5; a latitude written as degrees:minutes:seconds would be taken as a wrong number (or, at
# ``0:32``, as a plausible one). YAML 1.2 dropped base 60: such a value is a string here, and a
# field that wants a number refuses it by name.
_BASE10 = {
    "tag:yaml.org,2002:int": re.compile(
        r"""^(?:[-+]?0b[0-1_]+
        |[-+]?0[0-7_]+
        |[-+]?(?:0|[1-9][0-9_]*)
        |[-+]?0x[0-9a-fA-F_]+)$""",
        re.X,
    ),
    "tag:yaml.org,2002:float": re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+][0-9]+)?
        |\.[0-9][0-9_]*(?:[eE][-+][0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
}
_NoAliasLoader.yaml_implicit_resolvers = {
    first: [
        (tag, _BASE10[tag] if rx.match("1:30.5") or rx.match("1:30") else rx) for tag, rx in entries
    ]
    for first, entries in _NoAliasLoader.yaml_implicit_resolvers.items()
}


def parse_yaml(text: str, what: str, source: str | None = None) -> Any:
    """YAML text to plain data: size-bounded, aliases refused, depth-bounded; errors name
    ``source`` (the file) where given, else the text's start."""
    if len(text) > MAX_YAML_BYTES:
        raise InputError(what, f"{len(text)} bytes", f"allowed: at most {MAX_YAML_BYTES} bytes")
    try:
        data = yaml.load(text, Loader=_NoAliasLoader)
    except yaml.YAMLError as exc:
        reason = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
        if "aliases" in str(exc):
            reason = "aliases (*name) are not allowed: they can expand exponentially"
        mark = getattr(exc, "problem_mark", None)
        if mark is not None:
            reason += f", line {mark.line + 1} column {mark.column + 1}"
        where = source if source is not None else _head(text)
        raise InputError(what, where, f"is not valid YAML ({reason})") from None
    except RecursionError:
        raise InputError(
            what, "<nested>", f"allowed: at most {MAX_DEPTH} levels of nesting"
        ) from None
    except ValueError as exc:  # an integer of more digits than Python converts (4,300)
        if "integer string conversion" not in str(exc):
            raise
        raise InputError(
            what, "<an integer of thousands of digits>", "allowed: numbers of at most 4300 digits"
        ) from None
    return _plain(data)


def load_yaml(path: str | Path, what: str = "--config") -> dict[str, Any]:
    """A YAML file holding a mapping (or nothing), read with ``parse_yaml``'s bounds."""
    p = Path(path)
    if not p.is_file():
        raise InputError(what, str(path), "allowed: an existing YAML file")
    size = p.stat().st_size
    if size > MAX_YAML_BYTES:
        raise InputError(what, str(path), f"is {size} bytes; allowed: at most {MAX_YAML_BYTES}")
    raw = p.read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(what, str(path), "is not a UTF-8 text file (binary?)") from None
    if "\x00" in text:
        raise InputError(what, str(path), "is not a text file (it holds NUL bytes)")
    data = parse_yaml(text, what, str(path))
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise InputError(what, str(path), "allowed: a YAML mapping at the top level")
    return data


def _head(text: str) -> str:
    return text[:40]


#: Python converts integers of at most this many digits (sys.get_int_max_str_digits()).
MAX_INT_DIGITS = 4300


class _Refused(Exception):
    def __init__(self, why: str) -> None:
        self.why = why


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise _Refused(f"has the key {k!r} twice; allowed: each key once")
        out[k] = v
    return out


def _bounded_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise _Refused(f"holds an integer of {len(text):,} digits; allowed: {MAX_INT_DIGITS}")
    return int(text)


def parse_json(data: str | bytes, what: str, name: str = "") -> Any:
    """JSON to plain data, every reader's one way in: invalid text, duplicate keys (which
    ``json`` resolves silently, last wins), integers of thousands of digits and deep nesting
    are ``InputError``s naming ``what`` (and ``name``, the file)."""
    try:
        text = data.decode("utf-8") if isinstance(data, bytes) else data
        return json.loads(text, object_pairs_hook=_unique_keys, parse_int=_bounded_int)
    except _Refused as exc:
        raise InputError(what, name, exc.why) from None
    except (ValueError, UnicodeDecodeError) as exc:  # JSONDecodeError is a ValueError
        raise InputError(what, name, f"is not valid JSON ({exc})") from None
    except RecursionError:
        raise InputError(what, name, "is nested too deeply") from None


def field_info(cls: type, dotted: str) -> tuple[Any, Any] | None:
    """(type hint, metadata) of a dotted field of a config dataclass; None if there is none."""
    parts = dotted.split(".")
    for i, part in enumerate(parts):
        if not dataclasses.is_dataclass(cls):
            return None
        fields = {f.name: f for f in dataclasses.fields(cls)}
        if part not in fields:
            return None
        tp = get_type_hints(cls)[part]
        if i == len(parts) - 1:
            return (None, None) if dataclasses.is_dataclass(tp) else (tp, fields[part].metadata)
        cls = tp
    return None


def is_integer_field(tp: Any) -> bool:
    """An ``int`` or ``int | None`` field (bool excluded)."""
    args = [a for a in get_args(tp) if a is not type(None)] if get_args(tp) else [tp]
    return args == [int]
