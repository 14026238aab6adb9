"""The EM settings a calibration runs with, in rising precedence: a base (the start model's own, a preset,
the settings file `convert` wrote beside the log, a Turtlebot CSV's preset, or the thesis's defaults),
then a settings YAML, then single ``name=value`` overrides. A settings file may name its preset on its
first line (``preset: NAME``): its other fields override that preset, put on the log's columns."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from sensact.app.logs import OpenedLandmarkLog
from sensact.config import config_from_dict, config_to_dict, load_yaml_mapping, merge_fields, parse_overrides
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
