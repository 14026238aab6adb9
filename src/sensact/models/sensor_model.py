"""What every sensor model does for EM (sec. 4.1's ``S``, eq. 4.19's observation model): the protocol the
landmark sensor implements, and every new sensor (a gyro, a GNSS receiver) will. EM's E-step reads a
sensor only through ``kernel_inputs`` and the compiled passes' one channel function, which switches on the
sensor's ``kind`` as it switches on a geometry's ``mode``; its M-step only through ``update``. A new sensor
is one module implementing this, and its kind in the compiled channel.
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from sensact.core.geometry import Geometry
from sensact.records import JsonObject


class SightingLog(Protocol):
    """The part of a log a sensor reads: which step each sighting belongs to, what it saw and read."""

    geometry: Geometry
    source: str
    obs_ptr: np.ndarray  # (T+1,) rows of step t are obs_ptr[t]:obs_ptr[t+1]
    obs_landmark: np.ndarray  # (K,)
    obs_readings: np.ndarray  # (K, C)
    obs_bearing_rad: np.ndarray  # (K,)
    reading_names: tuple[str, ...]
    landmarks_xy: np.ndarray  # (L, 2)

    @property
    def n_observations(self) -> int: ...


@runtime_checkable
class SensorModel(Protocol):
    kind: ClassVar[int]  # the compiled channel's switch (``core.ekf_smoother.LANDMARK``, ...)
    mount: Any  # where the sensor sits on the robot (a ``SensorMount`` for a planar one)

    @property
    def noise_groups(self) -> tuple[str, ...]:
        """The readings that each have a noise sigma of their own, in the E-step's channel order."""

    @property
    def sigmas(self) -> tuple[float, ...]:
        """Each noise group's sigma (NaN where the sensor does not read that group)."""

    @property
    def parameters(self) -> np.ndarray:
        """Every learned number of the sensor, flat (``with_parameters`` reads it back)."""

    def with_parameters(self, values: np.ndarray) -> SensorModel: ...

    def named_parameters(self) -> dict[str, float]:
        """Every learned number by a readable name (for error bars and tables)."""

    def kernel_inputs(self, data: SightingLog) -> tuple[Any, Any]:
        """What the compiled E-step reads of this sensor on ``data``: ``(Sightings, SensorInputs)``."""

    def predict(self, poses: np.ndarray, data: SightingLog, rows: np.ndarray) -> np.ndarray:
        """``(R, G)``: the mean reading of each noise group at sightings ``rows`` seen from the robot at
        ``poses`` (one per row)."""

    def update(self, seen: Any, landmarks_xy: np.ndarray, geometry: Geometry, **how: Any) -> SensorModel:
        """The M-step (eqs. 4.25, 4.27, 4.28) from the sightings ``seen`` at the E-step's sampled poses."""

    def to_dict(self) -> JsonObject: ...
