"""sensact's frame and units (the thesis's: robot x right, y forward, heading 0 facing the map's +y,
millimetres) turned into what a ROS user reads (REP 103: x forward, y left; SI units), once, for every
figure, page and export a user sees (one internal frame, docs/design.md). The map's own x and y are the same axes in
both; only the robot's axes, the heading's zero and the units differ."""

from __future__ import annotations

MM = 1e-3
# sensact's velocity name: its REP 103 name and the factor to it (a track's is toward the wall or beacon)
VELOCITY_REP = {
    "v_x_mm_s": ("vy_m_s", -MM),
    "v_y_mm_s": ("vx_m_s", MM),
    "v_theta_rad_s": ("vyaw_rad_s", 1.0),
    "v_mm_s": ("v_toward_m_s", MM),
}
REP_ORDER = ("vx_m_s", "vy_m_s", "vyaw_rad_s", "v_toward_m_s")
LABEL = "REP 103: x forward, y left; SI"


def si(name: str) -> tuple[str, float]:
    """A command's or reading's SI name and the factor from sensact's unit to it (v_mm_s -> v_m_s, x 1e-3);
    a name in no length unit (height_px, omega_rad_s) is kept, factor 1."""
    for suffix, to in (("_mm_s", "_m_s"), ("_mm", "_m")):
        if name.endswith(suffix):
            return name[: -len(suffix)] + to, MM
    return name, 1.0


def velocity_rep(name: str) -> tuple[str, float]:
    """A learned velocity's REP 103 name and factor (``VELOCITY_REP``), or its SI name where it has none."""
    return VELOCITY_REP.get(name) or si(name)
