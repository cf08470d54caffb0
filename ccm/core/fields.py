"""Typed field declarations for config dataclasses: each field says how its value is checked.

A spec declares its fields with :func:`checked`, naming a check from :mod:`ccm.core.errors`
(``check_positive``, ``vec2``, ...: any ``check(key, value) -> value``), and parses a mapping
with :func:`field_values`. The field list is the list of allowed keys; a missing required key,
an unknown key and a bad value each raise one :class:`ConfigError` naming the full dotted key
(``task.scene.springs[1].stiffness: must be > 0, got -1``). What a single field cannot say (a
detach time after the attach time, a segment of non-zero length) stays in the spec's
``from_mapping``, after the fields are checked.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

from ccm.core.errors import (
    ConfigError,
    check_choice,
    check_keys,
    check_positive,
    check_vector,
    to_plain,
)

Check = Callable[[str, Any], Any]


def checked(
    check: Check,
    default: Any = dataclasses.MISSING,
    *,
    factory: Callable[[], Any] | None = None,
    required: str = "is required",
) -> Any:
    """A dataclass field whose value :func:`field_values` checks with ``check(key, value)``.

    Without ``default`` or ``factory`` the key is required (``required`` is the error text
    when it is missing). A ``None`` default makes the field optional: ``None`` is then not
    checked.
    """
    meta = {"check": check, "required": required}
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def unchecked(key: str, value: Any) -> Any:
    """A check that accepts any value (the spec checks it against its other fields, or the
    component that reads it does)."""
    return value


def one_of(options: Sequence[str]) -> Check:
    """A check: one of ``options``."""
    return lambda key, value: check_choice(key, value, options)


def nested(parse: Callable[[Any, str], Any]) -> Check:
    """A check that parses a nested spec with its ``from_mapping(cfg, key)``."""
    return lambda key, value: parse(value, key)


def field_values(
    cls: type, cfg: Any, key: str, *, extra: tuple[str, ...] = ()
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The checked values of ``cls``'s :func:`checked` fields found in ``cfg`` (missing
    optional ones left to their defaults), and ``cfg`` as a plain mapping.

    Keys other than ``extra`` (keys the caller reads itself, listed first in the error) and
    the fields of ``cls`` are refused; a missing required field is refused with its
    ``required`` text.
    """
    d = to_plain(cfg, key)
    fields = [f for f in dataclasses.fields(cls) if "check" in f.metadata]
    check_keys(key, d, [*extra, *(f.name for f in dataclasses.fields(cls))])
    out: dict[str, Any] = {}
    for f in fields:
        k = f"{key}.{f.name}"
        if f.name not in d:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise ConfigError(k, f.metadata["required"])
            continue
        value = d[f.name]
        if value is None and f.default is None:
            out[f.name] = None
            continue
        out[f.name] = f.metadata["check"](k, value)
    return out, d


def vector(n: int, *, positive: bool = False) -> Check:
    """A check: a finite ``n``-vector as a tuple of floats; with ``positive`` each entry must
    be > 0 (errors name ``key[i]``)."""

    def check(key: str, value: Any) -> tuple[float, ...]:
        out = tuple(float(v) for v in check_vector(key, value, n))
        if positive:
            for i, v in enumerate(out):
                check_positive(f"{key}[{i}]", v)
        return out

    return check
