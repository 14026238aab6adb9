"""A spinning lidar's per-laser geometry (sec. 2.5.2): vertical angles phi_l and horizontal angles theta_l.

Laser ``l`` at rotation ``theta_r`` sees a return at distance ``d`` at
``(d cos(phi_l) cos(theta_l + theta_r + theta_b), d cos(phi_l) sin(...), d sin(phi_l))`` (eq. 2.35).
Angles are radians, indexed by the laser id of the packets and the calibration file. ``extra`` keeps
every other per-laser field of a calibration file so that it can be written back unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sensact.records import JsonObject


@dataclass(frozen=True, eq=False)
class LaserIntrinsics:
    vertical_rad: np.ndarray  # (n,) phi_l
    horizontal_rad: np.ndarray  # (n,) theta_l (ROS: rot_correction)
    distance_resolution_m: float = 0.002
    extra: tuple[JsonObject, ...] = field(default=())

    def __post_init__(self) -> None:
        v = np.asarray(self.vertical_rad, dtype=float).reshape(-1)
        h = np.asarray(self.horizontal_rad, dtype=float).reshape(-1)
        if v.shape != h.shape or v.size == 0:
            raise ValueError("one vertical and one horizontal angle per laser")
        object.__setattr__(self, "vertical_rad", v)
        object.__setattr__(self, "horizontal_rad", h)
        if self.extra and len(self.extra) != v.size:
            raise ValueError("extra needs one entry per laser")

    @property
    def n_lasers(self) -> int:
        return int(self.vertical_rad.size)

    def vertical_order(self) -> np.ndarray:
        """Laser ids sorted by increasing vertical angle: the thesis's index l (sec. 2.5.2)."""
        return np.argsort(self.vertical_rad, kind="stable")

    def with_horizontal(self, horizontal_rad: np.ndarray) -> LaserIntrinsics:
        return LaserIntrinsics(self.vertical_rad, horizontal_rad, self.distance_resolution_m, self.extra)

    def to_dict(self) -> JsonObject:
        return {
            "kind": "laser_intrinsics",
            "vertical_rad": self.vertical_rad.tolist(),
            "horizontal_rad": self.horizontal_rad.tolist(),
            "distance_resolution_m": self.distance_resolution_m,
        }
