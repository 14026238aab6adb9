"""EM's presets, shipped as YAML beside this file: where a real robot starts from, instead of code.

Each preset is a whole ``EMConfig`` (its YAML lists the fields that differ from the thesis's defaults,
each with its reason). A preset names a log's columns (``range_mm``, ``v_mm_s``); ``for_log`` puts it
on the columns a log really has: a differential drive's wheel speeds instead of (v, omega), a 1-D
robot's own readings as its channels. A settings file may name its preset (``preset: NAME``) and
override fields below it; `convert` writes one so (``settings_yaml``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import replace
from functools import cache
from importlib import resources
from typing import TYPE_CHECKING

import numpy as np

from sensact.config import config_from_dict, config_to_yaml
from sensact.errors import ConfigError
from sensact.io.turtlebot import EM_READINGS, LEARNER_SETTINGS, SPEC_RANGE_M
from sensact.learn.bootstrap import BootstrapConfig
from sensact.learn.em.config import ChannelConfig, EMConfig
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.wheel_drive import wheel_pair
from sensact.records import JsonObject

if TYPE_CHECKING:
    from sensact.sim.diffdrive import DiffDriveConfig

# name -> what it is for (`sensact learn em --help` lists them)
PRESETS = {
    "aibo_field": "the thesis's Aibo on its field: discrete actions, beacon heights and bearings (ch. 4)",
    "differential_drive_camera": "a differential drive with a range-and-bearing camera (MRCLAM's robots)",
    "range_only_anchors": "a differential drive with a range-only sensor (UWB anchors); set where it starts",
    "track_1d": "a 1-D robot driving to and from a wall, reading distance sensors (the Turtlebot)",
}
PRESET_KEY = "preset"  # a settings file's field naming its preset


def preset_yaml(name: str) -> str:
    """The preset's YAML text, as shipped; an unknown name is one line listing the presets."""
    if name not in PRESETS:
        raise ConfigError(
            f"no preset {name!r}.",
            field="--preset",
            fix=f"use one of {', '.join(PRESETS)}.",
        )
    return resources.files(__package__).joinpath(f"{name}.yaml").read_text(encoding="utf-8")


@cache  # a frozen config: every caller may share it, and the YAML is read once
def load_preset(name: str) -> EMConfig:
    """The preset ``name`` as an ``EMConfig``, on the columns it names (``for_log`` moves it to a log's)."""
    import yaml

    return config_from_dict(EMConfig, yaml.safe_load(preset_yaml(name)) or {}, source=f"preset {name}")


def mrclam_config() -> EMConfig:
    """MRCLAM's settings: the differential_drive_camera preset on (v_mm_s, omega_rad_s)."""
    return load_preset("differential_drive_camera")


def diffdrive_config(command_names: tuple[str, ...]) -> EMConfig | None:
    """The differential_drive_camera preset for a differential drive logged either as (v, omega), as MRCLAM
    is, or as its wheel speeds (``models.wheel_drive.wheel_pair``: ``left_mm_s, right_mm_s``, or the
    wheels' turning rates in any one unit); None for other commands. On wheel speeds the forward speed
    is the wheels' mean, so it depends on their sum alone (``(left_mm_s+right_mm_s)``): the same family
    as on (v, omega), a linear change of commands, so the units a robot logs its commands in do not
    change what it learns."""
    names = tuple(command_names)
    if names == ("v_mm_s", "omega_rad_s"):
        return mrclam_config()
    pair = wheel_pair(names)
    if pair is not None:
        return mrclam_config().replace(action_inputs=(f"v_y_mm_s:({pair[0]}+{pair[1]})",))
    return None


def planar_config(command_names: tuple[str, ...]) -> EMConfig:
    """A starting point for any robot with a range-and-bearing camera: ``diffdrive_config`` on a
    differential drive's commands; on any others the same with every velocity, sideways too, affine in
    every command, since nothing says the robot cannot side-step (a legged robot's ``(v, v_left, omega)``)."""
    return diffdrive_config(command_names) or mrclam_config().replace(action_zero_mean=(), action_inputs=())


def range_only_config(command_names: tuple[str, ...], start_pose: tuple[float, float, float]) -> EMConfig:
    """The range_only_anchors preset on these commands, starting from ``start_pose`` (x mm, y mm, heading
    rad): ``planar_config`` without bearings, the turn rate on the turn command alone (``omega_rad_s``,
    or on wheel speeds their difference; no such command: free)."""
    base = load_preset("range_only_anchors")
    inputs = planar_config(command_names).action.inputs
    if "omega_rad_s" in command_names:
        inputs += ("v_theta_rad_s:omega_rad_s",)
    elif (pair := wheel_pair(command_names)) is not None:
        inputs += (f"v_theta_rad_s:({pair[1]}-{pair[0]})",)
    zero_mean = base.action.zero_mean if diffdrive_config(command_names) else ()
    return base.replace(
        action_inputs=inputs,
        action_zero_mean=zero_mean,
        start_prior_mean=tuple(float(v) for v in start_pose),
    )


def distance_channel(name: str, robust: bool) -> ChannelConfig:
    """The track_1d preset's distance channel (its poor line) under the log's own name."""
    t = load_preset("track_1d")
    kind = ("student_t", ROBUST_NU) if robust else ("none", 0.0)
    return ChannelConfig(
        name,
        t.thesis.sensor_degree,
        t.thesis.start_height_intercept_px,
        t.thesis.start_height_slope_px_per_mm,
        t.thesis.start_sigma_height_px,
        robust=kind[0],
        robust_param=kind[1],
    )


ROBUST_NU = 4.0  # the Student-t degrees of freedom of a robust distance reading (the Turtlebot's sonar1)


def turtlebot_em_config(readings: tuple[str, ...] = EM_READINGS) -> EMConfig:
    """The track_1d preset on a Turtlebot CSV's columns: sonar1 robust from the poor line; each IR channel
    a cubic from a poor line, valid within its datasheet range. ``readings``: the columns a file has."""
    chans = [distance_channel("sonar1", robust=True)]
    for name in (r for r in EM_READINGS[1:] if r in readings):
        lo, hi = SPEC_RANGE_M[name]
        chans.append(ChannelConfig(name, 3, 1.5, -0.0002, 1.0, lo * 1000.0, hi * 1000.0))
    return replace(load_preset("track_1d"), channels=tuple(chans))


def track_em_config(
    data: LandmarkLog,
    distance_reading: str,
    windows: dict[str, tuple[float, float]] | None = None,
    robust: tuple[str, ...] = (),
) -> EMConfig:
    """The track_1d preset on a 1-D robot's own readings (`sensact convert track`): the reading in a
    distance unit first, from the preset's poor line; every other reading from a flat line at its median
    with its spread as sigma, which says nothing of the distance, so that its f is learned from where the
    others place the robot (on training1.csv the IR channels learn as well as from their datasheet lines:
    raw_ir3 3.1 % against 5.7 %). ``windows``: each reading's valid distances (mm); ``robust``: the
    readings read with a Student-t."""
    windows = windows or {}
    chans = []
    for name in [distance_reading, *(r for r in data.reading_names if r != distance_reading)]:
        lo, hi = windows.get(name, (-math.inf, math.inf))
        if name == distance_reading:
            chans.append(replace(distance_channel(name, name in robust), valid_min=lo, valid_max=hi))
            continue
        v = data.obs_readings[:, data.reading_names.index(name)]
        v = v[np.isfinite(v)]
        spread = float(np.std(v)) if v.size > 1 else 0.0
        # four digits: a start, written into em_config.yaml for a person to read
        start = (float(f"{np.median(v):.4g}") if v.size else 0.0, 0.0, float(f"{spread:.4g}") if spread > 0 else 1.0)
        kind = ("student_t", ROBUST_NU) if name in robust else ("none", 0.0)
        chans.append(ChannelConfig(name, 3, *start, lo, hi, *kind))
    return replace(load_preset("track_1d"), channels=tuple(chans))


def for_log(name: str, data: LandmarkLog) -> EMConfig:
    """The preset ``name`` on ``data``'s columns: a planar preset on the log's commands (wheel speeds, a
    side-stepper's), track_1d with the log's first reading as its distance channel and the others from
    flat lines. A preset that cannot fit the log is one line."""
    cfg = load_preset(name)
    planar = name != "track_1d"
    if planar != (data.geometry.has_heading):
        raise ConfigError(
            f"preset {name} is for a {'planar' if planar else '1-D'} robot and {data.source} is a {data.geometry} log.",
            field="--preset",
            fix=f"use one of {', '.join(n for n in PRESETS if (n != 'track_1d') == data.geometry.has_heading)}.",
        )
    if name == "differential_drive_camera":
        return planar_config(data.command_names)
    if name == "range_only_anchors":
        return range_only_config(data.command_names, cfg.thesis.start_prior_mean)
    if name == "track_1d" and data.is_continuous:
        return track_em_config(data, data.reading_names[0])
    return cfg


def preset_of(settings: JsonObject, source: str) -> str | None:
    """The preset a settings mapping names (its ``preset`` field), checked; None when it names none."""
    name = settings.get(PRESET_KEY)
    if name is None:
        return None
    if not isinstance(name, str) or name not in PRESETS:
        raise ConfigError(
            f"no preset {name!r}.", file=source, field=PRESET_KEY, fix=f"use one of {', '.join(PRESETS)}."
        )
    return name


def settings_yaml(
    name: str, config: EMConfig, data: LandmarkLog, header: str = "", always: tuple[str, ...] = ()
) -> str:
    """A settings file for ``data`` naming preset ``name`` and the fields of ``config`` that differ from the
    preset on the log's columns (and those in ``always``), which ``app.settings`` reads back to ``config``."""
    return config_to_yaml(config, header, always, against=for_log(name, data), lead={PRESET_KEY: name})


def simulator_settings(sim: DiffDriveConfig) -> EMConfig:
    """The EM settings for a simulated robot's log, as ``sensact simulate diffdrive`` writes them:
    ``planar_config`` for its logged commands (MRCLAM's on a differential drive's, every
    velocity free on a side-stepper's), or for a radio sensor ``range_only_config`` from where the robot
    was put."""
    if sim.reads_bearing:
        return planar_config(sim.logged_command_names)
    return range_only_config(sim.logged_command_names, sim.start_pose)


# chapter 3 on the Turtlebot (experiments/turtlebot.py): an affine action model, since a wheel-speed controller
# tracks its command nearly linearly and four speeds cannot identify a quartic (eq. 3.2); t_start 60 s, so
# that A_t replaces A0 only after the log's first, single-command leg
TURTLEBOT_LEARNER = BootstrapConfig(t_start_s=60.0, action_degree=1)


def learner_for(sensor: str, base: BootstrapConfig = TURTLEBOT_LEARNER) -> BootstrapConfig:
    return dataclasses.replace(base, **LEARNER_SETTINGS.get(sensor, {}))


def track_learner(robust: bool) -> BootstrapConfig:
    """Chapter 3's settings for another 1-D robot's distance reading (``sensact convert track``): the
    Turtlebot's, with sonar1's outlier gate for a reading asked to be robust. Its windows in value are
    sonar1's datasheet in metres, not this reading's, and are left out."""
    gate = LEARNER_SETTINGS["sonar1"]["outlier_gate"] if robust else None
    return dataclasses.replace(TURTLEBOT_LEARNER, outlier_gate=gate)
