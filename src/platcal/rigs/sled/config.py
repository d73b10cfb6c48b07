"""The sled study configuration (docs/rocket-sled.md §10): schema validation and a typed view.

Every key has a default in ``data/config.schema.yaml``; :func:`load_config` also refuses what
the schema cannot express (a trajectory that never stops, phases off the IMU grid, a filter
period that is not a whole number of IMU samples), naming the field.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from ...mapping_keys import with_mapping_schema
from ...schema import load_schema, validate

G = 9.80665
"""Gravity and the unit g, m/s^2 (docs/rocket-sled.md §1)."""
OMEGA_E = 7.292115e-5
"""Earth rate, rad/s (docs/rocket-sled.md §1)."""
ARCSEC = np.pi / 180 / 3600
"""One arc second in rad."""
DEG_H = np.pi / 180 / 3600
"""One deg/h in rad/s."""


@dataclass(frozen=True)
class Phase:
    accel_g: float
    duration_s: float


@dataclass(frozen=True)
class SledConfig:
    """A validated sled config (units as in the YAML; see the schema's descriptions)."""

    raw: dict
    latitude_deg: float
    track_azimuth_deg: float
    static_before_s: float
    phases: tuple[Phase, ...]
    brake_g: float
    static_after_s: float
    rate_hz: float
    accel: dict
    gyro: dict
    alignment_arcsec: tuple[float, float, float]
    states: int
    period_ms: float
    compensation: str
    tuning: str
    r_velocity: float
    r_position: float
    seed: int
    study: dict

    @property
    def dt(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def kf_every(self) -> int:
        """IMU samples per filter step (period_ms · rate_hz / 1000, checked whole)."""
        return int(round(self.period_ms * self.rate_hz / 1000.0))

    @property
    def omega_ie(self) -> np.ndarray:
        """Earth rate in the track frame, rad/s (§1): Ω[cosL cosA, cosL sinA, sinL]."""
        L, A = np.radians(self.latitude_deg), np.radians(self.track_azimuth_deg)
        return OMEGA_E * np.array([np.cos(L) * np.cos(A), np.cos(L) * np.sin(A), np.sin(L)])


def _samples(seconds: float, rate: float, field: str, allow_zero: bool = False) -> int:
    """Whole IMU samples of a duration; refuse durations off the sample grid or too short."""
    n = seconds * rate
    k = int(round(n))
    if abs(n - k) > 1e-6 * max(1.0, n):
        raise InputError(field, f"{seconds} s is not a whole number of IMU samples at {rate} Hz")
    if k == 0 and not allow_zero:
        raise InputError(field, "must last at least one IMU sample (a phase of zero duration)")
    return k


def check_trajectory(cfg: SledConfig) -> None:
    """Refuse trajectories that never stop or run backwards (docs/rocket-sled.md §2)."""
    rate = cfg.rate_hz
    _samples(cfg.static_before_s, rate, "trajectory.static_before_s", allow_zero=True)
    _samples(cfg.static_after_s, rate, "trajectory.static_after_s")
    v = 0.0
    for i, ph in enumerate(cfg.phases):
        _samples(ph.duration_s, rate, f"trajectory.phases[{i}].duration_s")
        v += ph.accel_g * G * ph.duration_s
        if v < 0 or (i == 0 and v <= 0):
            raise InputError(f"trajectory.phases[{i}].accel_g",
                             f"the sled would move backwards (velocity {v:.3f} m/s at the end of the phase); "
                             "the first phase must accelerate along +X and the velocity stay >= 0")
    if v <= 0:
        raise InputError("trajectory.phases", "the sled is at rest before braking: the trajectory never runs")
    if cfg.brake_g <= 0:
        raise InputError("trajectory.brake_g", "must be > 0 g, otherwise the sled never stops")


def load_config(raw) -> SledConfig:
    """Validate a raw ``rig: sled`` mapping (defaults filled) and return the typed config."""
    cfg = validate(raw, with_mapping_schema(load_schema("platcal.rigs.sled", "data/config.schema.yaml")))
    tr, imu, fl = cfg["trajectory"], cfg["imu"], cfg["filter"]
    out = SledConfig(
        raw=cfg,
        latitude_deg=float(cfg["site"]["latitude_deg"]),
        track_azimuth_deg=float(cfg["site"]["track_azimuth_deg"]),
        static_before_s=float(tr["static_before_s"]),
        phases=tuple(Phase(float(p["accel_g"]), float(p["duration_s"])) for p in tr["phases"]),
        brake_g=float(tr["brake_g"]),
        static_after_s=float(tr["static_after_s"]),
        rate_hz=float(imu["rate_hz"]),
        accel={k: float(v) for k, v in imu["accel"].items()},
        gyro={k: float(v) for k, v in imu["gyro"].items()},
        alignment_arcsec=tuple(float(x) for x in cfg["alignment"]["sigma_arcsec"]),
        states=int(fl["states"]),
        period_ms=float(fl["period_ms"]),
        compensation=fl["compensation"],
        tuning=fl["tuning"],
        r_velocity=float(fl["r_sigma"]["velocity_m_s"]),
        r_position=float(fl["r_sigma"]["position_m"]),
        seed=int(cfg["seed"]),
        study=cfg["study"],
    )
    m = out.period_ms * out.rate_hz / 1000.0
    if abs(m - round(m)) > 1e-9 or round(m) < 1:
        raise InputError("filter.period_ms", f"must be a whole number (>= 1) of IMU samples of {1000 / out.rate_hz:g} ms")
    check_trajectory(out)
    return out
