"""Every command's settings, resolved here and only here, in rising precedence: a base, then a settings
YAML (``--config``), then single ``name=value`` overrides (``--set``), then a command's own flags.

EM's (``resolve_settings``): the base is the start model's own settings, a preset, the settings file
`convert` wrote beside the log, the settings its kind starts from (a Turtlebot CSV's preset), or the
thesis's defaults; a settings file may name its preset on its first line (``preset: NAME``), and its
other fields override that preset, put on the log's columns. Any other config dataclass (a simulator's,
chapter 3's, the monitor's): ``layered_config``; an experiment's fields split between its learner and
its simulator: ``split_fields`` and ``merged``."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sensact.app.logs import OpenedLandmarkLog
from sensact.config import (
    build_config,
    config_from_dict,
    config_to_dict,
    load_yaml_mapping,
    merge_fields,
    parse_overrides,
    refuse_non_finite,
)
from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.presets import PRESET_KEY, for_log, preset_of
from sensact.records import JsonObject


@dataclass(frozen=True)
class Settings:
    config: EMConfig
    preset: str | None  # the preset the settings rest on, if any
    base: str  # where the base came from, for the user: "preset NAME", the settings file's path, ...


def _layer(log: OpenedLandmarkLog, base: EMConfig, preset: str | None, path: Path) -> tuple[JsonObject, str | None]:
    """``base`` with the settings file at ``path`` on it (rebased on the preset the file names)."""
    mapping = load_yaml_mapping(path)
    named = preset_of(mapping, str(path))
    if named is not None:
        base, preset = for_log(named, log.data), named
    rest = {k: v for k, v in mapping.items() if k != PRESET_KEY}
    return merge_fields(EMConfig, config_to_dict(base), rest), preset


def read_settings_file(path: Path, log: OpenedLandmarkLog | None = None) -> EMConfig:
    """The settings in the file at ``path`` (on the preset it names, put on ``log``'s columns; by default
    the log folder the file is in), as `learn em` reads a folder's em_config.yaml."""
    from sensact.app.logs import open_landmark_log

    log = log or open_landmark_log(Path(path).parent)
    fields, _ = _layer(log, EMConfig(), None, Path(path))
    return config_from_dict(EMConfig, fields, source=str(path))


def resolve_settings(
    log: OpenedLandmarkLog,
    *,
    preset: str | None = None,
    config: Path | None = None,
    sets: Sequence[str] = (),
    base: EMConfig | None = None,
) -> Settings:
    """What EM runs with on ``log``: ``base`` (a start model's settings), else ``preset`` put on the log's
    columns, else the settings file beside the log (unless ``config`` replaces it), else the settings its
    kind starts from (a Turtlebot CSV's preset), else the thesis's defaults; then ``config`` (a YAML file),
    then ``sets``."""
    name: str | None = None
    if base is not None:
        origin = "the start model's settings"
    elif preset is not None:
        base, name, origin = for_log(preset, log.data), preset, f"preset {preset}"
    elif config is None and log.settings_file is not None:
        origin = str(log.settings_file)
        fields, name = _layer(log, EMConfig(), None, log.settings_file)
        base = config_from_dict(EMConfig, fields, source=origin)
    elif log.defaults is not None:
        base, name, origin = log.defaults.config, log.defaults.preset, log.defaults.origin
    else:
        base, origin = EMConfig(), "the thesis's defaults"
    fields, sources = config_to_dict(base), []
    if config is not None:
        fields, name = _layer(log, base, name, config)
        sources.append(str(config))
    over = parse_overrides(sets)
    if over:
        sources.append("--set")
    fields = merge_fields(EMConfig, fields, over)
    cfg = config_from_dict(EMConfig, fields, source=" / ".join(sources) or origin)
    return Settings(cfg, name, origin)


def layered_config(cls: type, config: Path | None, sets: list[str] | None, base: Any = None, **flags: Any) -> Any:
    """``base`` or defaults < ``--config`` YAML < ``--set`` < explicit flags."""
    cfg = build_config(cls, config, sets or [], base=base)
    flags = {k: v for k, v in flags.items() if v is not None}
    for k, v in flags.items():
        refuse_non_finite(v, None, f"--{k.replace('_', '-')}", "the command line")
    try:
        return dataclasses.replace(cfg, **flags) if flags else cfg
    except ValueError as exc:  # the config's own checks, on what the flags gave it
        names = [f"--{k.replace('_', '-')}" for k in flags]
        given = ", ".join(
            f"{n} {v:g}" if isinstance(v, float) else f"{n} {v}" for n, v in zip(names, flags.values(), strict=True)
        )
        raise ConfigError(
            f"{exc} (given {given}).", field=", ".join(names), fix="see the command's --help for each option."
        ) from None


def settings_beside(log: Path, name: str, config: Path | None) -> Path | None:
    """``config``, or else the settings file ``name`` that `convert` or `simulate` wrote beside the log
    folder, if there is one."""
    beside = log / name
    if config is not None or not (log.is_dir() and beside.is_file()):
        return config
    return beside


def split_fields(set_: list[str] | None, config: Path | None, learner_cls: type) -> tuple[dict, dict]:
    """--set / --config fields go to the learner or the simulator, whichever has the field."""
    fields = {**(load_yaml_mapping(config) if config else {}), **parse_overrides(set_ or [])}
    accepts = getattr(learner_cls, "accepts", lambda k: k in learner_cls.__dataclass_fields__)
    learner = {k: v for k, v in fields.items() if accepts(k)}
    return learner, {k: v for k, v in fields.items() if k not in learner}


def merged(cls: type, base: Any, fields: JsonObject) -> Any:
    """``base`` with the given fields replaced, validated like any config."""
    return (
        config_from_dict(cls, merge_fields(cls, config_to_dict(base), fields), source="--set/--config")
        if fields
        else base
    )
