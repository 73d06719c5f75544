"""Loading the configuration: ``configs/default.yaml``, then ``--config`` files, then ``--set`` overrides.

Unknown keys are rejected with a "did you mean" suggestion, values of the wrong type (or outside an enum's
vocabulary) and numbers outside their field's :class:`~ptam.config.sections.Range` with a :class:`ConfigError`,
whether they come from a file or from ``--set``.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import os
import typing
from dataclasses import fields
from enum import StrEnum

import yaml

from ..errors import ConfigError
from ..resources import resource_path
from .sections import Config, Range


@functools.cache
def _section_types() -> dict[str, type]:
    hints = typing.get_type_hints(Config)
    return {f.name: hints[f.name] for f in fields(Config)}


@functools.cache
def _field_types(section_cls) -> dict[str, type]:
    return typing.get_type_hints(section_cls)


@functools.cache
def _field_ranges(section_cls) -> dict[str, Range]:
    """The :class:`Range` of each numeric field of a section (from its ``Annotated`` type)."""
    hints = typing.get_type_hints(section_cls, include_extras=True)
    return {
        name: r
        for name, hint in hints.items()
        if typing.get_origin(hint) is typing.Annotated
        for r in hint.__metadata__
        if isinstance(r, Range)
    }


def _check_range(where: str, value, rng: Range | None, source: str) -> None:
    """``value`` (a number, or a list of them, already of the field's type) lies in ``rng``."""
    if rng is None:
        return
    origin = "" if source == "--set" else f" ({source})"
    if isinstance(value, (list, tuple)):
        if rng.length is not None and len(value) != rng.length:
            raise ConfigError(f"config: {where} must have {rng.length} elements, got {len(value)}{origin}")
        items = [(f"{where}[{i}]", v) for i, v in enumerate(value)]
    else:
        items = [(where, value)]
    for at, v in items:
        if v not in rng:
            raise ConfigError(f"config: {at} must be in {rng}, got {v!r}{origin}")


def _suggest(name: str, options) -> str:
    close = difflib.get_close_matches(name, list(options), n=1, cutoff=0.5)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _coerce(where: str, value, typ):
    """Check ``value`` against a field type; ints are accepted where floats are expected."""
    origin = typing.get_origin(typ)
    if origin is list:
        (inner,) = typing.get_args(typ)
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"config: {where} must be a list of {inner.__name__}, got {value!r}")
        return [_coerce(f"{where}[{i}]", v, inner) for i, v in enumerate(value)]
    if isinstance(typ, type) and issubclass(typ, StrEnum):
        if isinstance(value, str) and value in typ._value2member_map_:
            return typ(value)
        raise ConfigError(f"config: {where} must be one of {', '.join(m.value for m in typ)}, got {value!r}")
    accepts = _SCALARS.get(typ)
    if accepts is not None and accepts(value):
        return float(value) if typ is float else value
    raise ConfigError(f"config: {where} must be {typ.__name__}, got {value!r}")


# A bool is an int to Python, never to a config file.
_SCALARS = {
    bool: lambda v: isinstance(v, bool),
    int: lambda v: isinstance(v, int) and not isinstance(v, bool),
    float: lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
    str: lambda v: isinstance(v, str),
}


def _merge(base: dict, overlay, source: str) -> None:
    if not isinstance(overlay, dict):
        raise ConfigError(f"{source}: expected a mapping of sections")
    sections = _section_types()
    for sec, values in overlay.items():
        if sec not in sections:
            raise ConfigError(f"{source}: unknown config section '{sec}'{_suggest(str(sec), sections)}")
        if not isinstance(values, dict):
            raise ConfigError(f"{source}: section '{sec}' must be a mapping")
        for key, v in values.items():
            _set(base, sec, key, v, source)


def _set(base: dict, sec: str, key: str, value, source: str) -> None:
    sections = _section_types()
    if sec not in sections:
        raise ConfigError(f"{source}: unknown config section '{sec}'{_suggest(sec, sections)}")
    hints = _field_types(sections[sec])
    if key not in hints:
        options = [f"{sec}.{k}" for k in hints] + [f"{s}.{k}" for s in sections for k in _field_types(sections[s])]
        raise ConfigError(f"{source}: unknown config key '{sec}.{key}'{_suggest(f'{sec}.{key}', options)}")
    coerced = _coerce(f"{sec}.{key}", value, hints[key])
    _check_range(f"{sec}.{key}", value, _field_ranges(sections[sec]).get(key), source)
    base.setdefault(sec, {})[key] = coerced


def _build(raw: dict) -> Config:
    sections = _section_types()
    built = {}
    for sec, cls in sections.items():
        values = raw.get(sec, {})
        missing = [f.name for f in fields(cls) if f.name not in values]
        if missing:
            raise ConfigError(f"config: section '{sec}' is missing {', '.join(missing)}")
        built[sec] = cls(**values)
    return Config(**built)


def _read_yaml(path: str):
    if not os.path.isfile(path):
        raise ConfigError(f"config file not found: {path}")
    try:
        with open(path) as f:
            return yaml.safe_load(f) or {}
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as e:
        raise ConfigError(f"cannot read config {path}: {str(e).splitlines()[0]}") from None


def parse_override(text: str) -> tuple[str, str, object]:
    """``section.key=value`` -> (section, key, value), the value parsed as YAML (so 3, 0.5, [1, 2], true)."""
    if "=" not in text or "." not in text.split("=", 1)[0]:
        raise ConfigError(f"--set expects section.key=value, got '{text}'")
    lhs, rhs = text.split("=", 1)
    sec, key = lhs.strip().split(".", 1)
    try:
        value = yaml.safe_load(rhs) if rhs.strip() else ""
    except yaml.YAMLError:
        value = rhs
    return sec, key, value


def _to_raw(cfg: Config) -> dict:
    return {f.name: dataclasses.asdict(getattr(cfg, f.name)) for f in fields(Config)}


def apply_overrides(cfg: Config, overrides: list[str]) -> Config:
    raw = _to_raw(cfg)
    for text in overrides:
        sec, key, value = parse_override(text)
        _set(raw, sec, key, value, "--set")
    return _build(raw)


def load_config(config_files: list[str] | None = None, overrides: list[str] | None = None) -> Config:
    """Defaults from configs/default.yaml, then each ``--config`` file, then each ``--set`` override."""
    raw: dict = {}
    default = str(resource_path("configs/default.yaml"))
    _merge(raw, _read_yaml(default), default)
    for path in config_files or []:
        _merge(raw, _read_yaml(path), path)
    cfg = _build(raw)
    return apply_overrides(cfg, overrides or [])


def default_config() -> Config:
    return load_config()
