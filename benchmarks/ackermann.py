"""Issue 108's bars on simulated F1TENTH cars: a 1/10-scale car lapping a corridor track with a 270-degree lidar
at 40 Hz for 300 s (12,000 scans), each run with its own truth (the yaml's gains 3-8 % off, the steering's zero
1-3 degrees off, a steering delay, the lidar's mount, the wheelbase), written as a ROS 1 bag or an MCAP and
taken through the user's route alone (``sensact convert bag BAG --out DIR`` then ``sensact learn em DIR``),
and one run on a track three times larger (gentle curves only).

    python benchmarks/ackermann.py [--runs 4] [--seconds 300] [--out results/ackermann.json]

Prints, per run, each bar's error (and in its sd) and the wall time of `learn em`; writes the JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from sensact.io.rosbag_write import write_car_bag
from sensact.sim.car import CarConfig, simulate_car


def truth_of(seed: int, seconds: float, scale: float = 1.0) -> CarConfig:
    """A car of its own: the yaml 3-8 % off in both gains (either way), its zero 1-3 degrees off."""
    rng = np.random.default_rng(1000 + seed)
    base = CarConfig(seconds=seconds, seed=seed, scale=scale)
    k = base.speed_to_erpm_gain * rng.uniform(0.95, 1.05)
    g = base.steering_angle_to_servo_gain * rng.uniform(0.95, 1.05)
    o = base.steering_angle_to_servo_offset + rng.uniform(-0.02, 0.02)
    off = [rng.uniform(0.03, 0.08) * rng.choice([-1, 1]) for _ in range(2)]
    zero = math.radians(rng.uniform(1, 3)) * rng.choice([-1, 1])
    mount = (rng.uniform(200, 300), rng.uniform(-15, 15), rng.uniform(-0.03, 0.03))
    return replace(
        base,
        speed_to_erpm_gain=k,
        steering_angle_to_servo_gain=g,
        steering_angle_to_servo_offset=o,
        wheelbase_m=rng.uniform(0.30, 0.36),
        steering_delay_s=rng.uniform(0.03, 0.12),
        mount=mount,
        urdf_mount=(round(mount[0] / 10) * 10, 0.0, 0.0),
        yaml_speed_gain=k * (1 + off[0]),
        yaml_servo_gain=g * (1 + off[1]),
        yaml_servo_offset=o + g * zero,  # commanding 0 rad, the wheels point `zero` to the left
    )


def _sensact(*args: str) -> tuple[int, float]:
    t0 = time.monotonic()
    rc = subprocess.run([sys.executable, "-m", "sensact", *args], capture_output=True, text=True).returncode
    return rc, time.monotonic() - t0


def score(cfg: CarConfig, doc: dict) -> dict:
    v, c, m = doc["vesc"], doc["car"], doc["lidar"]["mount"]
    out: dict = {}

    def one(name: str, value: float | None, sd: float | None, want: float, share: bool) -> None:
        if value is None:
            out[name] = {"value": None}
            return
        err = value - want
        out[name] = {
            "error": err / want if share else err,
            "error_sd": err / sd if sd else None,
        }

    one("speed_gain_share", v["speed_to_erpm_gain"], v["speed_to_erpm_gain_sd"], cfg.speed_to_erpm_gain, True)
    one(
        "steering_gain_share",
        v["steering_angle_to_servo_gain"],
        v["steering_angle_to_servo_gain_sd"],
        cfg.steering_angle_to_servo_gain,
        True,
    )
    one(
        "product_share",
        c["steering_gain_times_wheelbase_m"],
        c["steering_gain_times_wheelbase_m_sd"],
        cfg.steering_angle_to_servo_gain * cfg.wheelbase_m,
        True,
    )
    one("wheelbase_share", c["wheelbase_mm"], c["wheelbase_mm_sd"], cfg.wheelbase_m * 1000, True)
    for k, want in zip(("forward_mm", "left_mm", "yaw_rad"), cfg.mount, strict=True):
        one(k, m[k], m[k + "_sd"], want, False)
    ahead = c.get("straight_ahead")
    true_deg = math.degrees(
        (cfg.yaml_servo_offset - cfg.steering_angle_to_servo_offset) / cfg.steering_angle_to_servo_gain
    )
    if ahead is not None:
        one("straight_ahead_deg", ahead["wheel_angle_deg"], ahead["wheel_angle_deg_sd"], true_deg, False)
    out["flags"] = [f["code"] for f in doc["health"]["flags"]]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--out", type=Path, default=Path("results/ackermann.json"))
    args = ap.parse_args()
    runs = [(k, "ros1" if k % 2 else "mcap", 1.0) for k in range(1, args.runs + 1)] + [(99, "mcap", 3.0)]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed, fmt, scale in runs:
            cfg = truth_of(seed, args.seconds, scale)
            run = simulate_car(cfg)
            bag = write_car_bag(Path(tmp) / f"car{seed}", fmt, run)
            log, model = Path(tmp) / f"log{seed}", Path(tmp) / f"model{seed}.json"
            rc, _ = _sensact("convert", "bag", str(bag), "--out", str(log))
            assert rc == 0, f"convert failed on run {seed}"
            rc, seconds = _sensact("learn", "em", str(log), "--out", str(model), "--no-report")
            doc = json.loads(model.read_text())
            row = {"seed": seed, "format": fmt, "scale": scale, "scans": int(run.scan_t.size), "exit": rc,
                   "learn_em_s": seconds, **score(cfg, doc)}  # fmt: skip
            rows.append(row)
            cells = [
                f"{k} {row[k]['error']:+.4g} ({row[k]['error_sd']:+.1f} sd)"
                for k in row
                if isinstance(row[k], dict) and row[k].get("error") is not None
            ]
            print(f"run {seed} ({fmt}, scale {scale:g}, {row['scans']} scans): learn em {seconds:.1f} s, exit {rc}, "
                  f"flags {row['flags']}; " + "; ".join(cells), flush=True)  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(rows, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
