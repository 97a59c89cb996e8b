"""Typed, range-checked dataclass fields: the one parameter mechanism of the package.

SlamConfig, the simulator's SimConfig and the node's NodeConfig declare their fields
with `num` and `choice`, check them with `check_fields` and read plain mappings
(YAML, the ROS parameter server) through `coerce`, so every bad value fails the same
way: one line naming the parameter and what is allowed.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping


class ConfigError(ValueError):
    """A parameter is unknown, of the wrong type or out of its allowed range."""


def num(default: float, lo: float, hi: float, doc: str) -> Any:
    """A number field allowed in [lo, hi]."""
    return dataclasses.field(default=default, metadata={"range": (lo, hi), "doc": doc})


def choice(default: str, choices: tuple[str, ...], doc: str) -> Any:
    """A string field that must be one of choices."""
    return dataclasses.field(default=default, metadata={"choices": choices, "doc": doc})


def check_fields(obj: Any) -> None:
    """Raises ConfigError for the first field out of its range or choices."""
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if v is None:
            continue
        lo_hi = f.metadata.get("range")
        if lo_hi and not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                          and lo_hi[0] <= v <= lo_hi[1]):
            raise ConfigError(f"{f.name}={v!r} must be in [{lo_hi[0]}, {lo_hi[1]}]")
        choices = f.metadata.get("choices")
        if choices and v not in choices:
            raise ConfigError(f"{f.name}={v!r} must be one of {', '.join(choices)}")


def coerce(cls: type, values: Mapping[str, Any]) -> dict[str, Any]:
    """Field values of cls from a plain mapping: unknown keys and wrong types raise."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    out: dict[str, Any] = {}
    for key, v in values.items():
        if key not in fields:
            raise ConfigError(f"unknown parameter '{key}' (known: {', '.join(sorted(fields))})")
        # a switch in [0, 1] (toggle_noise) also takes true/false; a count never does
        switch = fields[key].metadata.get("range") == (0, 1)
        out[key] = _coerce_one(key, str(fields[key].type), v, bool_as_int=switch)
    return out


def _coerce_one(key: str, kind: str, v: Any, *, bool_as_int: bool = False) -> Any:
    if v is None and "None" in kind:
        return None
    base = kind.split("|")[0].split("[")[0].strip().replace("builtins.", "")
    if base == "bool":
        if isinstance(v, bool) or v in (0, 1):
            return bool(v)
        raise ConfigError(f"{key}={v!r} must be true or false")
    if base == "int":
        if isinstance(v, bool) and not bool_as_int:
            raise ConfigError(f"{key}={v!r} must be an integer, not true/false")
        if isinstance(v, (int, float)) and float(v).is_integer():
            return int(v)
        raise ConfigError(f"{key}={v!r} must be an integer")
    if base == "float":
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return float(v)
        raise ConfigError(f"{key}={v!r} must be a number")
    if base == "str":
        if isinstance(v, str):
            return v
        raise ConfigError(f"{key}={v!r} must be a string")
    if base == "list" and not isinstance(v, list):
        raise ConfigError(f"{key}={v!r} must be a list")
    return v
