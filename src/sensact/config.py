"""Configuration dataclasses: JSON round trip, YAML files and ``--set name=value`` overrides.

Every algorithm and simulator has a frozen config dataclass whose defaults are the thesis's constants.
This module turns user text into such a dataclass with errors that name the field and the fix.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import types
import typing
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

from sensact.errors import ConfigError
from sensact.records import JsonObject

C = TypeVar("C")


def config_to_dict(config: Any) -> JsonObject:
    """A JSON-ready dict of a config dataclass (tuples become lists)."""
    return json.loads(json.dumps(dataclasses.asdict(config)))


def config_to_yaml(
    config: Any, header: str = "", always: tuple[str, ...] = (), against: Any = None, lead: JsonObject | None = None
) -> str:
    """The fields of ``config`` (and of the configs nested in it) that differ from their defaults (or at the
    top level from ``against``'s, a config of the same kind: a preset), and the top-level fields named in
    ``always`` (ones the user should see and set), as a YAML file that ``build_config`` reads back to
    ``config`` (on ``against``); ``header`` becomes its leading comment, ``lead``'s fields its first ones."""
    import yaml

    def changed(obj: Any, ref: Any = None, keep: tuple[str, ...] = ()) -> Any:
        """``obj``'s fields that differ from ``ref``'s (a config of its kind), or else from their defaults, and
        those ``keep`` names (``group.field`` for a group's)."""
        if not dataclasses.is_dataclass(obj):
            return [changed(x) for x in obj] if isinstance(obj, tuple | list) else obj
        out = {}
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            if f.name in keep:
                out[f.name] = changed(value)
                continue
            inner = tuple(k.partition(".")[2] for k in keep if k.startswith(f.name + "."))
            if inner and dataclasses.is_dataclass(value):
                out[f.name] = changed(value, None if ref is None else getattr(ref, f.name), inner)
                continue
            if ref is not None:
                sub = getattr(ref, f.name)
                if value != sub:
                    nested = dataclasses.is_dataclass(value) and dataclasses.is_dataclass(sub)
                    out[f.name] = changed(value, sub) if nested else changed(value)
                continue
            if f.default is not dataclasses.MISSING and value == f.default:
                continue
            if f.default_factory is not dataclasses.MISSING and value == f.default_factory():
                continue
            out[f.name] = changed(value)
        return out

    fields = json.loads(json.dumps((lead or {}) | changed(config, against, always)))

    def block(mapping: JsonObject, indent: str = "") -> str:
        """One line per field, a group's fields indented under it, lists in flow (a mapping of scalars alone
        would come out as one flow line)."""
        out = ""
        for k, v in mapping.items():
            if isinstance(v, dict) and v:
                out += f"{indent}{k}:\n" + block(v, indent + "  ")
                continue
            style = None if isinstance(v, list | dict) else False
            out += "".join(
                indent + line + "\n"
                for line in yaml.safe_dump({k: v}, sort_keys=False, default_flow_style=style).splitlines()
            )
        return out

    text = block(fields)
    comment = "".join(f"# {line}\n".replace("# \n", "#\n") for line in header.splitlines())
    return comment + text


def _coerce(value: Any, annotation: Any, name: str, source: str) -> Any:
    """Convert a YAML/JSON/CLI value to the field's declared type, or raise ConfigError."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if annotation is Any:
        return value
    if dataclasses.is_dataclass(annotation) and isinstance(annotation, type):
        if isinstance(value, annotation):
            return value
        if not isinstance(value, Mapping):
            raise ConfigError(
                f"expected a mapping of {annotation.__name__} fields, got {_short(value)}.",
                file=source,
                field=name,
                fix="give a mapping such as {name: x, degree: 3}.",
            )
        return config_from_dict(annotation, value, source=f"{source}: {name}")
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _coerce(value, arg, name, source)
            except ConfigError as exc:
                errors.append(exc.problem)
        raise ConfigError(
            f"cannot read {value!r} ({'; '.join(errors)}).",
            file=source,
            field=name,
            fix=f"give a value of type {annotation}.",
        )
    if origin is typing.Literal:
        if value not in args:
            raise ConfigError(
                f"{value!r} is not one of {list(args)}.",
                file=source,
                field=name,
                fix=f"use one of {', '.join(map(str, args))}.",
            )
        return value
    if origin is tuple:
        if isinstance(value, str):
            value = [v for v in value.replace("[", "").replace("]", "").split(",") if v.strip()]
        if not isinstance(value, list | tuple):
            raise ConfigError(
                f"expected a list, got {_short(value)}.",
                file=source,
                field=name,
                fix="give a list such as [1, 2, 3] or 1,2,3.",
            )
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(v, args[0], name, source) for v in value)
        if len(args) != len(value):
            raise ConfigError(
                f"expected {len(args)} values, got {len(value)}.",
                file=source,
                field=name,
                fix=f"give exactly {len(args)} values.",
            )
        return tuple(_coerce(v, a, name, source) for v, a in zip(value, args, strict=True))
    if annotation is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.lower() in ("true", "yes", "1", "on", "false", "no", "0", "off"):
            return value.lower() in ("true", "yes", "1", "on")
        raise ConfigError(
            f"expected true or false, got {_short(value)}.", file=source, field=name, fix="use true or false."
        )
    if annotation in (int, float, str):
        try:
            if annotation is int and isinstance(value, float) and not value.is_integer():
                raise ValueError
            return annotation(value)
        except (TypeError, ValueError):
            raise ConfigError(
                f"expected {annotation.__name__}, got {_short(value)}.",
                file=source,
                field=name,
                fix=f"give a {annotation.__name__}.",
            ) from None
    return value


def config_from_dict(cls: type[C], data: JsonObject, *, source: str = "config") -> C:
    """Build ``cls`` from a mapping; unknown keys are an error naming the closest valid fields. A null for a
    float field whose default is infinite is that default: JSON has no infinity, and the JSON writer
    (``io/atomic.write_json``) puts a null there, so a config read back from a model.json is the one written."""
    regroup = getattr(cls, "regroup", None)  # a config in groups reads its fields' flat and dotted names
    if regroup is not None:
        data = regroup(data)
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    kwargs = {}
    for key, value in data.items():
        if key not in fields:
            near = difflib.get_close_matches(key, fields, n=1)
            raise ConfigError(
                f"unknown field {key!r} for {cls.__name__}.",
                file=source,
                field=key,
                fix=(f"did you mean {near[0]!r}? " if near else "") + f"valid fields are: {', '.join(sorted(fields))}.",
            )
        default = fields[key].default
        if value is None and hints[key] is float and isinstance(default, float) and math.isinf(default):
            kwargs[key] = default
            continue
        kwargs[key] = _coerce(value, hints[key], key, source)
        refuse_non_finite(kwargs[key], default, key, source)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        text = str(exc).rstrip()
        raise ConfigError(
            text if text.endswith((".", "?", ")")) else text + ".",
            file=source,
            fix="check the values against the documentation.",
        ) from None


def refuse_non_finite(value: Any, default: Any, name: str, source: str) -> None:
    """A number in a config is finite (an infinite default, "no limit", may be given as inf), and a seed is
    one numpy accepts (0 to 2**63 - 1): NaN slips past every ``x > 0`` check, and a seed of -1 is a crash."""
    values = value if isinstance(value, tuple) else (value,)
    for v in values:
        if isinstance(v, float) and not math.isfinite(v) and not (isinstance(default, float) and v == default):
            raise ConfigError(f"{v!r} is not a finite number.", file=source, field=name, fix="give a finite number.")
    if name.lstrip("-") == "seed" and isinstance(value, int) and not 0 <= value < 2**63:
        raise ConfigError(
            f"{value} is not a seed.", file=source, field=name, fix="give a whole number from 0 to 2**63 - 1."
        )


def parse_overrides(pairs: Iterable[str]) -> JsonObject:
    """``["a=1", "b=[1,2]"]`` -> ``{"a": 1, "b": [1, 2]}``; values are parsed as YAML scalars/lists."""
    import yaml

    out: JsonObject = {}
    for pair in pairs:
        if "=" not in pair:
            raise ConfigError(f"override {pair!r} has no '='.", field="--set", fix="write --set name=value.")
        key, text = pair.split("=", 1)
        try:
            out[key.strip()] = yaml.safe_load(text)
        except yaml.YAMLError:
            out[key.strip()] = text
    return out


def _short(value: Any) -> str:
    """A value as an error line shows it: at most 80 characters (a YAML alias bomb's repr is gigabytes)."""
    import reprlib

    r = reprlib.Repr()
    r.maxlevel, r.maxlist, r.maxdict, r.maxstring, r.maxother = 3, 4, 4, 60, 60
    return r.repr(value)[:80]


MAX_YAML_NODES = 100_000  # a settings file is a few dozen values: more, expanded, is an alias bomb


def _expanded_size(node: Any, seen: dict[int, int]) -> int:
    """How many nodes ``node`` holds with every alias expanded, each shared node counted once per use."""
    key = id(node)
    if key in seen:
        return seen[key]
    seen[key] = 1  # a node that holds itself: counted once
    value = getattr(node, "value", None)
    size = 1
    if isinstance(value, list):
        for item in value:
            size += (
                sum(_expanded_size(n, seen) for n in item) if isinstance(item, tuple) else _expanded_size(item, seen)
            )
            if size > MAX_YAML_NODES:
                break
    seen[key] = size
    return size


def safe_yaml(text: str, path: Path, error: type[Exception] = ConfigError) -> Any:
    """``text`` read as YAML (safe_load), refused in one line (``error``) where its aliases expand beyond any
    settings or calibration file (a "billion laughs"). YAML's own errors are the caller's to word."""
    import yaml

    root = yaml.compose(text, Loader=yaml.SafeLoader)
    if root is not None and _expanded_size(root, {}) > MAX_YAML_NODES:
        raise error(
            f"over {MAX_YAML_NODES:,} values once its aliases are expanded: not a file sensact reads.",
            file=path,
            fix="write it without anchors and aliases.",
        )
    return yaml.safe_load(text)


def load_yaml_mapping(path: str | Path) -> JsonObject:
    """Read a YAML file that must hold a mapping of field names to values."""
    import yaml

    path = Path(path)
    if not path.is_file():
        raise ConfigError("file not found.", file=path, fix="give the path of an existing YAML file.")
    try:
        data = safe_yaml(path.read_text(encoding="utf-8"), path)
    except yaml.YAMLError as exc:
        raise ConfigError(
            f"not valid YAML ({exc.__class__.__name__}).", file=path, fix="check the indentation and quoting."
        ) from None
    except UnicodeDecodeError:
        raise ConfigError("not a UTF-8 text file.", file=path, fix="save it as UTF-8 text.") from None
    except RecursionError:
        raise ConfigError(
            "nested too deeply to be a settings file.", file=path, fix="write one 'field: value' per line."
        ) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(
            "the top level must be a mapping of field: value.", file=path, fix="write one 'field: value' per line."
        )
    return data


def build_config(
    cls: type[C], yaml_path: str | Path | None = None, overrides: Iterable[str] = (), base: Any = None
) -> C:
    """``base`` (or the defaults), then the YAML file, then ``--set`` overrides, in rising precedence."""
    data: JsonObject = config_to_dict(base) if base is not None else {}
    sources = []
    if yaml_path is not None:
        data = merge_fields(cls, data, load_yaml_mapping(yaml_path))
        sources.append(str(yaml_path))
    over = parse_overrides(overrides)
    if over:
        sources.append("--set")
    data = merge_fields(cls, data, over)
    return config_from_dict(cls, data, source=" / ".join(sources) or "defaults")


def merge_fields(cls: type, base: JsonObject, over: JsonObject) -> JsonObject:
    """``over``'s fields on ``base``'s (both mappings of ``cls``'s fields): a group of fields given as a mapping
    changes only the fields it names (a config in groups: ``regroup`` first puts flat and dotted names in
    their group)."""
    regroup = getattr(cls, "regroup", None)
    if regroup is not None:
        base, over = regroup(base), regroup(over)
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = {**out[key], **value}
        else:
            out[key] = value
    return out
