"""Why a sled gyro or lateral-force scale passed with a wrong answer (issue 25), measured.

For seeds 0..N-1 of the sled's default test (``platcal simulate`` replicate r of case default),
one column times (1 + e): what moves, each in its own standard error -- the column's mean at rest
against the earth rate (:func:`platcal.rigs.sled.record.static_rate_sigma`, the check of
``check_static_rates``), the run filter's fit check (largest NIS per dof, normalised mean), the
stop filter's innovations (NIS per dof over v_y, r_y, v_x, r_x), and the estimates (shift from
the clean run in the clean sigma, largest over phi run/stop). In process, no files written.

    python benchmarks/fit_sensitivity_sled_zone.py [--seeds 5] [--column wx] [--e 0.01 0.1 1]
"""

from __future__ import annotations

import argparse

import numpy as np

from platcal.rigs.sled.config import DEG_H, load_config
from platcal.rigs.sled.identify import estimates, identify, record_fit
from platcal.rigs.sled.montecarlo import replicate_seeds
from platcal.rigs.sled.record import rest_samples, static_rate_sigma
from platcal.rigs.sled.simulate import simulate
from platcal.rigs.sled.trajectory import build_trajectory

COLS = {"fx": ("f", 0), "fy": ("f", 1), "fz": ("f", 2), "wx": ("w", 0), "wy": ("w", 1), "wz": ("w", 2)}


def stats(cfg, traj, f, w):
    """Static gyro z-scores, fit figures, stop NIS and the estimates of one record."""
    t = np.arange(f.shape[0]) * cfg.dt
    rest = rest_samples(cfg, traj, t)   # the check's own rest samples
    sig = static_rate_sigma(cfg, rest.sum() * cfg.dt)
    arw = cfg.gyro["arw_deg_rth"] * np.pi / 180 / 60 / np.sqrt(rest.sum() * cfg.dt)
    mean = w[rest].mean(axis=0)
    idn = identify(cfg, traj, f[None], w[None], t=t)
    fit = record_fit(idn)
    st = idn.stop
    ok = np.isfinite(st.s_var[0]) & (st.s_var[0] > 0)
    nis_stop = float(np.nanmean(np.where(ok, st.innov[0] ** 2 / np.where(ok, st.s_var[0], 1), np.nan)))
    nis_run = max(c.nis_per_dof for c in fit.channels)
    mean_run = max(abs(c.mean) for c in fit.channels)
    return {"z_static": (mean - cfg.omega_ie) / sig, "z_noise": (mean - cfg.omega_ie) / arw,
            "nis_run": nis_run, "mean_run": mean_run, "nis_stop": nis_stop, "passed": fit.passed,
            "est": estimates(idn, None)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--column", choices=sorted(COLS), action="append")
    ap.add_argument("--e", type=float, nargs="+", default=[0.01, 0.1, 1.0])
    a = ap.parse_args()
    cfg = load_config({"rig": "sled"})
    traj = build_trajectory(cfg)
    cols = a.column or ["wx", "wy", "wz", "fy"]
    print(f"omega_ie (deg/h) = {np.round(cfg.omega_ie / DEG_H, 3)}, static sigma (deg/h) = "
          f"{np.round(static_rate_sigma(cfg, cfg.static_before_s + cfg.static_after_s) / DEG_H, 4)}")
    print("column e seed | static z (gyro x,y,z: vs config sigma) | z vs ARW only | run NIS/dof max, |mean| max, "
          "passed | stop NIS/dof | largest shift (sigma) estimate")
    for seed in range(a.seeds):
        sb = simulate(cfg, replicate_seeds(cfg.raw, "default", [seed]))
        f0, w0 = sb.f[0], sb.w[0]
        clean = stats(cfg, traj, f0, w0)
        c0 = clean["est"]
        for col in cols:
            for e in [0.0] + list(a.e):
                f, w = f0.copy(), w0.copy()
                arr = f if COLS[col][0] == "f" else w
                arr[:, COLS[col][1]] *= 1 + e
                s = clean if e == 0 else stats(cfg, traj, f, w)
                d = np.abs(s["est"]["estimate"] - c0["estimate"]) / c0["sigma"]
                i = int(np.nanargmax(d.to_numpy()))
                who = f"{c0['name'][i]} {c0['filter'][i]}"
                print(f"{col} {e:g} {seed} | {np.array2string(s['z_static'], precision=2)} | "
                      f"{np.array2string(s['z_noise'], precision=1)} | {s['nis_run']:.3g} {s['mean_run']:.3g} "
                      f"{s['passed']} | {s['nis_stop']:.3g} | {float(d.iloc[i]):.3g} {who}")


if __name__ == "__main__":
    main()
