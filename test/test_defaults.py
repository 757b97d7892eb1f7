"""A default is defined once: no definition in the package contradicts the configuration's."""

import dataclasses
import importlib
import inspect
import pkgutil
import typing

import wet_eha_thermal
from wet_eha_thermal.config import Config

UNSET = dataclasses.MISSING


def config_sections():
    """Return every dataclass of the configuration, the top level and its nested sections."""
    found, todo = [], [Config]
    while todo:
        cls = todo.pop()
        if cls in found:
            continue
        found.append(cls)
        for tp in typing.get_type_hints(cls).values():
            for inner in (tp, *typing.get_args(tp)):
                todo += [t for t in (inner, *typing.get_args(inner))
                         if dataclasses.is_dataclass(t)]
    return found


def dataclass_defaults(cls):
    """Return each field of a dataclass with its default (UNSET when it has none)."""
    out = {}
    for f in dataclasses.fields(cls):
        if f.default is not UNSET:
            out[f.name] = f.default
        elif f.default_factory is not UNSET:
            out[f.name] = f.default_factory()
        else:
            out[f.name] = UNSET
    return out


def signature_defaults(func):
    """Return each parameter of a function with its default (UNSET when it has none)."""
    return {name: UNSET if p.default is inspect.Parameter.empty else p.default
            for name, p in inspect.signature(func).parameters.items()}


def definitions():
    """Yield (where, defaults) for every dataclass, function and method of the package."""
    for info in pkgutil.walk_packages(wet_eha_thermal.__path__, 'wet_eha_thermal.'):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if getattr(obj, '__module__', None) != module.__name__:
                continue
            where = f'{module.__name__}.{name}'
            if inspect.isfunction(obj):
                yield where, obj, signature_defaults(obj)
            elif inspect.isclass(obj):
                if dataclasses.is_dataclass(obj):
                    yield where, obj, dataclass_defaults(obj)
                for attr, member in vars(obj).items():
                    # a dataclass's generated __init__ repeats its fields, compared above
                    if inspect.isfunction(member) and not (
                            attr == '__init__' and dataclasses.is_dataclass(obj)):
                        yield f'{where}.{attr}', member, signature_defaults(member)


def is_value(default):
    """Tell whether a default is a setting's value (not "unset" or a nested section)."""
    return default is not UNSET and default is not None and not dataclasses.is_dataclass(default)


def test_no_parameter_named_as_a_config_key_has_another_default():
    # e.g. the alert rule's latch once defaulted to false while the configuration's is true
    sections = {cls: dataclass_defaults(cls) for cls in config_sections()}
    found = list(definitions())
    clashes = []
    for cls, keys in sections.items():
        for where, obj, defaults in found:
            if obj is cls:
                continue
            for name in sorted(set(keys) & set(defaults)):
                ours, theirs = keys[name], defaults[name]
                if is_value(ours) and is_value(theirs) and not ours == theirs:
                    clashes.append(f'{where}: {name} = {theirs!r}, in the configuration '
                                   f'{cls.__name__}.{name} = {ours!r}')
    assert not clashes, '\n'.join(clashes)


def test_the_check_sees_the_configurations_sections_and_the_alert_rule():
    names = {cls.__name__ for cls in config_sections()}
    assert {'Config', 'AlertLevels', 'Channel', 'Thermocouple'} <= names
    assert any(where.endswith('alerts.AlertRule') for where, _, _ in definitions())
