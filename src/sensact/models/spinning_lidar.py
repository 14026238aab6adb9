"""The spinning multi-beam lidars chapter 5 learns from, as their packets lay out a firing (sec. 2.5.2).

Sec. 5.1 reads a lidar as firings ``1/f`` apart, each a rotation and one distance per laser. Every unit
here fits that once its packets are unpacked; what differs is how a packet holds its firings, and when
within a firing each laser fires:

* **HDL-64E**: 64 lasers, an upper and a lower block of 32 per firing, 6 firings a packet; all fire at once
  (as the thesis takes it).
* **HDL-32E**: 32 lasers fired one after another, 1.152 µs apart, in a 46.08 µs firing; 12 firings a packet.
* **VLP-32C**: 32 lasers fired in pairs, 2.304 µs apart, in a 55.296 µs firing; 12 firings a packet; 4 mm
  distance steps.
* **VLP-16** and its **Puck Hi-Res** twin (±10°, product id 0x24): 16 lasers, 2.304 µs apart, in a 55.296 µs
  firing; two firings a block (the second's rotation halfway to the next block's), 24 firings a packet.
* **Ouster OS-1** (legacy lidar packets on port 7502): a column of 16, 32, 64 or 128 beams a firing, all at
  once, 16 columns a packet; the rotation from the encoder (90,112 counts a turn, clockwise), ranges in mm.

A laser that fires ``tau_l`` after its firing's start points ``omega * tau_l`` further round than the
firing's rotation: sec. 5.1 learns that effective angle, and ``delay_s`` turns it back into the laser's
own (``rot_correction``, which for the HDL-32E and VLP-16 is zero: ROS's driver adds the same turn).
Rotations are read as the packets give them, clockwise in 0.01° (``CarLog`` turns them counterclockwise).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

VELODYNE_PORT = 2368
VELODYNE_PAYLOAD_BYTES = 1206
OUSTER_PORT = 7502
OUSTER_COLUMNS_PER_PACKET = 16
OUSTER_ENCODER_COUNTS = 90_112  # a turn, as the OS-1 counts it
OUSTER_BEAMS = (16, 32, 64, 128)  # the OS-1's models
OUSTER_VALID = 0xFFFFFFFF  # a column's status word when it holds a measurement


def ouster_payload_bytes(beams: int) -> int:
    """A legacy OS-1 lidar packet: 16 columns of a 16-byte header, 12 bytes a beam and a 4-byte status."""
    return OUSTER_COLUMNS_PER_PACKET * (16 + 12 * beams + 4)


def _vlp16_vertical() -> tuple[float, ...]:
    return tuple(float(i - 15 if i % 2 == 0 else i) for i in range(16))  # -15, 1, -13, 3, ... 15


def _hi_res_vertical() -> tuple[float, ...]:
    # the Puck Hi-Res: -10° to -0.67° on the even ids and +0.67° to +10° on the odd, 4/3° apart
    return tuple(float((-10.0 if i % 2 == 0 else 2.0 / 3.0) + (i // 2) * 4.0 / 3.0) for i in range(16))


def _hdl32e_vertical() -> tuple[float, ...]:
    # -30.67 to -9.33 on the even ids and -9.33 to +10.67 on the odd, 4/3° apart (the ROS driver's 32db.yaml)
    return tuple(float((-30.67 if i % 2 == 0 else -9.33) + (i // 2) * 4.0 / 3.0) for i in range(32))


# the VLP-32C's datasheet geometry (laser ids 0-31): vertical angles and rot_correction, degrees, as ROS's
# driver and velodyne_decoder carry them
_VLP32C_VERTICAL = (-25.0, -1.0, -1.667, -15.639, -11.31, 0.0, -0.667, -8.843, -7.254, 0.333, -0.333, -6.148)
_VLP32C_VERTICAL += (-5.333, 1.333, 0.667, -4.0, -4.667, 1.667, 1.0, -3.667, -3.333, 3.333, 2.333, -2.667, -3.0)
_VLP32C_VERTICAL += (7.0, 4.667, -2.333, -2.0, 15.0, 10.333, -1.333)
_VLP32C_ROT = (-1.4, 4.2, -1.4, 1.4, -1.4, 1.4, -4.2, 1.4, -1.4, 4.2, -1.4, 1.4, -4.2, 1.4, -4.2, 1.4, -1.4, 4.2)
_VLP32C_ROT += (-1.4, 4.2, -4.2, 1.4, -1.4, 1.4, -1.4, 1.4, -1.4, 4.2, -4.2, 1.4, -1.4, 1.4)


@dataclass(frozen=True)
class LidarUnit:
    """How one model of spinning lidar lays out its firings."""

    name: str
    lasers: int
    firings_per_packet: int
    firing_s: float  # one firing of every laser; the unit's nominal firing rate is its inverse
    delay_s: tuple[float, ...]  # when each laser fires after its firing's start, by laser id
    distance_unit_m: float
    port: int
    payload_bytes: int
    product_id: int | None = None  # the Velodyne's last status byte
    vertical_deg: tuple[float, ...] | None = None  # fixed by the model; None: each unit's own (a calibration)
    rot_correction_deg: tuple[float, ...] | None = None  # the datasheet's horizontal angles, where it gives them
    columns: int | None = None  # an OS-1's firings a turn (its lidar_mode)
    dual: bool = False  # a Velodyne in dual-return mode: each firing fills two blocks (last, then strongest)

    def in_dual_return(self) -> LidarUnit:
        """The unit in dual-return mode: a packet holds half the firings."""
        return replace(self, firings_per_packet=self.firings_per_packet // 2, dual=True)

    @property
    def firing_hz(self) -> float:
        return 1.0 / self.firing_s

    @property
    def velodyne(self) -> bool:
        return self.port == VELODYNE_PORT


def ouster_unit(beams: int = 64, columns: int = 1024, hz: float = 10.0) -> LidarUnit:
    return LidarUnit(
        "OS-1",
        beams,
        OUSTER_COLUMNS_PER_PACKET,
        1.0 / (columns * hz),
        (0.0,) * beams,
        0.001,
        OUSTER_PORT,
        ouster_payload_bytes(beams),
        columns=columns,
    )


_VLP16 = LidarUnit(
    "VLP-16",
    16,
    24,
    55.296e-6,
    tuple(2.304e-6 * i for i in range(16)),
    0.002,
    VELODYNE_PORT,
    VELODYNE_PAYLOAD_BYTES,
    0x22,
    _vlp16_vertical(),
    (0.0,) * 16,
)

UNITS: dict[str, LidarUnit] = {
    "HDL-64E": LidarUnit("HDL-64E", 64, 6, 1.0 / 7800.0, (0.0,) * 64, 0.002, VELODYNE_PORT, VELODYNE_PAYLOAD_BYTES),
    "HDL-32E": LidarUnit(
        "HDL-32E",
        32,
        12,
        46.08e-6,
        tuple(1.152e-6 * i for i in range(32)),
        0.002,
        VELODYNE_PORT,
        VELODYNE_PAYLOAD_BYTES,
        0x21,
        _hdl32e_vertical(),
        (0.0,) * 32,
    ),
    "VLP-32C": LidarUnit(
        "VLP-32C",
        32,
        12,
        55.296e-6,
        tuple(2.304e-6 * (i // 2) for i in range(32)),
        0.004,
        VELODYNE_PORT,
        VELODYNE_PAYLOAD_BYTES,
        0x28,
        _VLP32C_VERTICAL,
        _VLP32C_ROT,
    ),
    "VLP-16": _VLP16,
    # the VLP-16's Hi-Res twin: the same firings, its lasers within ±10°, told apart by its product id
    "Puck Hi-Res": replace(_VLP16, name="Puck Hi-Res", product_id=0x24, vertical_deg=_hi_res_vertical()),
    "OS-1": ouster_unit(),
}
# Velodynes whose packets lay their lasers out otherwise (more block ids a firing): named, not read
UNREAD_PRODUCTS = {0xA1: "VLS-128", 0x31: "Velarray"}
MODEL_NAMES = tuple(UNITS)
