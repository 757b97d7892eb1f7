"""
How a configuration key is declared and checked: its range, its type, its description.

A section of the configuration is a frozen dataclass whose fields are
declared with :func:`spec` (or :func:`positive`, :func:`fraction`), which
stores the allowed range or choices and a one-line description in the
field's metadata. :func:`from_dict` builds a section from a mapping and
checks every key against that metadata, then calls the section's own
``check`` (consistency between keys, e.g. with :func:`check_below`); the
first problem raises one :class:`ConfigError` naming the key, the value and
what is allowed. ``config_doc`` documents every key from the same metadata.
"""

import dataclasses
from dataclasses import field
import math
import typing
from typing import Any, Callable, Optional, Tuple, Union


OIL_GRADE_NAMES = ('MIL-PRF-5606', 'MIL-PRF-83282')


def choices_of(meta: dict) -> Optional[Tuple[str, ...]]:
    """Return the choices of a field's metadata (None: any text), calling a function of them."""
    choices = meta.get('choices')
    return choices() if callable(choices) else choices


class ConfigError(ValueError):
    """A configuration value that is missing, unknown, mistyped or out of range."""


def spec(low: Optional[float] = None, high: Optional[float] = None, *,
         low_open: bool = False, high_open: bool = False, default: Any = dataclasses.MISSING,
         choices: Union[Tuple[str, ...], Callable[[], Tuple[str, ...]], None] = None,
         doc: str = '', default_factory: Any = dataclasses.MISSING, min_items: int = 1):
    """
    Declare a config field with its allowed range (or choices) and a short description.

    ``choices``: the names allowed, or a function returning them (a registry
    of laws the model has, read when a value is checked, see
    :func:`choices_of`). ``min_items``: the fewest entries a list field may hold.
    """
    meta = {'low': low, 'high': high, 'low_open': low_open, 'high_open': high_open,
            'choices': choices, 'doc': doc, 'min_items': min_items}
    return field(default=default, default_factory=default_factory, metadata=meta)


def positive(doc: str = '', **kw):
    """Declare a field that must be strictly positive."""
    return spec(0.0, None, low_open=True, doc=doc, **kw)


def fraction(doc: str = '', **kw):
    """Declare a field in the open-closed interval (0, 1]."""
    return spec(0.0, 1.0, low_open=True, doc=doc, **kw)


def range_text(meta: dict) -> str:
    """Return a field's allowed range as an interval, e.g. ``(0, 1]`` or ``(-inf, 300]``."""
    lo, hi = meta['low'], meta['high']
    left = '(' if meta['low_open'] or lo is None else '['
    right = ')' if meta['high_open'] or hi is None else ']'
    return (f'{left}{"-inf" if lo is None else f"{lo:g}"}, '
            f'{"inf" if hi is None else f"{hi:g}"}{right}')


def check_value(key: str, value: Any, tp: Any, meta: dict) -> Any:
    """Return ``value`` checked against its type ``tp`` and its ``spec`` metadata ``meta``."""
    origin = typing.get_origin(tp)
    if origin is typing.Union:  # Optional[X]
        if value is None:
            return None
        tp = [t for t in typing.get_args(tp) if t is not type(None)][0]
        origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, key)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f'{key} = {value!r}: expected true or false')
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f'{key} = {value!r}: expected a whole number in '
                              f'{range_text(meta)}')
    elif tp is float:
        if isinstance(value, str):
            # YAML 1.1 (PyYAML) reads 2.0e4, without an exponent sign, as text
            try:
                value = float(value)
            except ValueError:
                pass
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f'{key} = {value!r}: expected a number in {range_text(meta)}')
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f'{key} = {value!r}: expected a finite number in '
                              f'{range_text(meta)}')
    elif tp is str:
        if not isinstance(value, str):
            raise ConfigError(f'{key} = {value!r}: expected text')
        choices = choices_of(meta)
        if choices and value not in choices:
            raise ConfigError(f'{key} = {value!r}: unknown; allowed: {", ".join(choices)}')
        return value
    elif origin is tuple:
        item = typing.get_args(tp)[0]
        if not isinstance(value, (list, tuple)) or len(value) < meta.get('min_items', 1):
            what = 'numbers' if item is float else 'entries'
            raise ConfigError(f'{key} = {value!r}: expected a non-empty list of {what}')
        return tuple(check_value(f'{key}[{i}]', v, item, meta) for i, v in enumerate(value))
    elif origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f'{key} = {value!r}: expected a mapping')
        item = typing.get_args(tp)[1]
        for k in value:
            if not isinstance(k, str):
                raise ConfigError(f'{key}: key {k!r} is not text')
        return {k: check_value(f'{key}.{k}', v, item, meta) for k, v in value.items()}
    lo, hi = meta.get('low'), meta.get('high')
    bad_lo = lo is not None and (value <= lo if meta['low_open'] else value < lo)
    bad_hi = hi is not None and (value >= hi if meta['high_open'] else value > hi)
    if bad_lo or bad_hi:
        raise ConfigError(f'{key} = {value!r}: out of range; allowed {range_text(meta)}')
    return value


def from_dict(cls, data: Any, key: str = ''):
    """Build dataclass ``cls`` from a mapping, checking every key (``key`` is the path so far)."""
    where = key or 'the top level'
    if not isinstance(data, dict):
        raise ConfigError(f'{where}: expected a mapping of keys, got {data!r}')
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    retired = getattr(cls, 'RETIRED', {})
    for k in unknown:
        if k in retired:
            raise ConfigError(f'{key + "." if key else ""}{k}: no longer a key; {retired[k]}')
    if unknown:
        raise ConfigError(f'{key + "." if key else ""}{unknown[0]}: unknown key in {where}; '
                          f'allowed: {", ".join(sorted(names))}')
    values = {}
    for f in dataclasses.fields(cls):
        sub = f'{key}.{f.name}' if key else f.name
        if f.name not in data:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise ConfigError(f'{sub}: missing key')
            continue
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            values[f.name] = from_dict(tp, data[f.name], sub)
        else:
            values[f.name] = check_value(sub, data[f.name], tp, dict(f.metadata))
    obj = cls(**values)
    check = getattr(obj, 'check', None)
    if check is not None:
        check(key)
    return obj


def check_below(key: str, a_name: str, a: float, b_name: str, b: float) -> None:
    """Raise :class:`ConfigError` unless ``key.a_name`` (``a``) is below ``key.b_name``."""
    if not a < b:
        raise ConfigError(f'{key}.{a_name} = {a!r}: must be below {key}.{b_name} = {b!r}')
