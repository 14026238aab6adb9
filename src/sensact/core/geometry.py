"""Robot families by state space: what a pose is, how it moves, how far a landmark is from it.

A ``Geometry`` owns its state size and names, the robot-frame velocities its action models give, the
thesis's fixed motion noise for it, how a displacement moves a pose (eq. 2.28) and the distance from its
sensor to a landmark. ``has_heading`` answers every question a heading raises: bearings, a sensor's mount, turns,
sideways slip; ``state_is_range`` says the state is the distance itself. Adding a family is one subclass
here (or in a module of its own) and ``register``; the compiled E-step kernels switch on ``mode``.

JSON carries a geometry by ``name`` (``"planar"``, ``"track"``); ``geometry_named`` turns it back.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from sensact.core import pose_models as pm


class Geometry:
    name: ClassVar[str]
    mode: ClassVar[int]  # pose_models.PLANAR or TRACK: the compiled kernels' switch
    state_names: ClassVar[tuple[str, ...]]  # of the state w, in the units the log keeps
    velocity_names: ClassVar[tuple[str, ...]]  # the robot-frame velocities an action model gives
    thesis_motion_sd: ClassVar[tuple[float, ...]]  # Sigma_m per step (sec. 4.4.1)
    has_heading: ClassVar[bool]  # bearings, a mount, turns and sideways slip exist
    state_is_range: ClassVar[bool]  # the state is the distance the sensor reads (no map to place it on)

    @property
    def n(self) -> int:
        return len(self.state_names)

    def motion_variance(self, sd_mm: float, sd_rad: float) -> np.ndarray:
        """The diagonal of Sigma_m in the robot frame from one sd per length and per angle (sec. 4.4.1)."""
        return np.array([(sd_rad if name.endswith("_rad") else sd_mm) ** 2 for name in self.state_names])

    def apply_displacement(self, w: np.ndarray, disp: np.ndarray) -> np.ndarray:
        return pm.apply_displacement(w, disp, self.mode)

    def relative_displacement(self, w1: np.ndarray, w2: np.ndarray) -> np.ndarray:
        return pm.relative_displacement(w1, w2, self.mode)

    def sensor_distance(self, poses: np.ndarray, landmark_xy: np.ndarray, mount: np.ndarray) -> np.ndarray:
        return pm.sensor_distance(poses, landmark_xy, mount, self.mode)

    def __str__(self) -> str:
        return self.name

    def json_value(self) -> str:
        """How a JSON file names this geometry (``geometry_named`` reads it back)."""
        return self.name

    def __repr__(self) -> str:
        return f"<geometry {self.name}>"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Geometry) and other.name == self.name

    def __hash__(self) -> int:
        return hash(self.name)

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return geometry_named, (self.name,)  # one instance per family, across processes too


class Planar(Geometry):
    """Chapter 4: w = (x, y, theta); the robot frame has x to the right and y forward (sec. 2.5.1)."""

    name = "planar"
    mode = pm.PLANAR
    state_names = ("x_mm", "y_mm", "theta_rad")
    velocity_names = ("v_x_mm_s", "v_y_mm_s", "v_theta_rad_s")
    thesis_motion_sd = (10.0, 10.0, 0.1)
    has_heading = True
    state_is_range = False


class Track(Geometry):
    """Sec. 4.4.3: the state is the distance to the one beacon; a forward velocity shortens it."""

    name = "track"
    mode = pm.TRACK
    state_names = ("distance",)
    velocity_names = ("v_mm_s",)
    thesis_motion_sd = (10.0,)
    has_heading = False
    state_is_range = True


PLANAR = Planar()
TRACK = Track()
GEOMETRIES: dict[str, Geometry] = {}


def register(geometry: Geometry) -> Geometry:
    GEOMETRIES[geometry.name] = geometry
    return geometry


register(PLANAR)
register(TRACK)


def geometry_named(name: str | Geometry) -> Geometry:
    """The geometry a JSON file or a constructor names; a Geometry passes through."""
    if isinstance(name, Geometry):
        return name
    try:
        return GEOMETRIES[name]
    except (KeyError, TypeError):
        raise ValueError(f"geometry must be one of {', '.join(map(repr, GEOMETRIES))}, not {name!r}") from None
