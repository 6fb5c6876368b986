"""Configuration sections as frozen dataclasses of numbers: the checks every one of them needs, written once.

A section (``ssm``, ``scaling``, ``collision``) comes from a YAML mapping or from code; either way a value
that is not a finite number, or a key the section does not have, is a ConfigError naming the section and
the key (``ssm.reaction_time: expected a finite number, got 'fast'``).
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import TypeVar

from shared.core.errors import ConfigError

T = TypeVar("T")


def check_numbers(section: object, name: str, skip: tuple[str, ...] = (), non_negative: bool = False) -> None:
    """Every field of the dataclass `section` (except `skip`) is a finite int or float (not a bool), and
    not negative when `non_negative`; ConfigError '<name>.<field>: ...' otherwise."""
    for f in fields(section):
        if f.name in skip:
            continue
        value = getattr(section, f.name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"{name}.{f.name}: expected a finite number, got {value!r}")
        if non_negative and value < 0:
            raise ConfigError(f"{name}.{f.name}: must not be negative, got {value!r}")


def from_mapping(cls: type[T], raw: object, name: str) -> T:
    """The section `cls` from a config mapping (None: its defaults); a non-mapping or an unknown key raises
    ConfigError naming the section, bad values raise from the section's own checks. A field whose metadata says
    ``setting: False`` (a value the cell sets as it runs) is not a key."""
    if raw is None:
        return cls()
    if not isinstance(raw, dict):
        raise ConfigError(f"{name}: expected a mapping, got {type(raw).__name__}")
    known = {f.name for f in fields(cls) if f.metadata.get("setting", True)}   # not a state set at run time
    unknown = sorted(set(map(str, raw)) - known)
    if unknown:
        raise ConfigError(f"{name}: unknown key(s) {unknown}; known: {sorted(known)}")
    return cls(**raw)
