"""Timestamps as recorded (issue 13): a log with jittered sample times and a constant clock offset
per position is identified as well as the clean record of the same run, from CSV and Parquet.

The "real" log is simulated noise-free on a 0.05 ms grid and sampled at 5 ms +- up to 0.1 ms (the
jitter is real: each sample is the truth at its recorded time); the clean record takes the same
run's samples exactly on the 5 ms grid. The same accelerometer noise (10 ug per sample) is then
added to both, so they differ only in their times.
"""

import json

import numpy as np
import pandas as pd
import pytest

from centrifuge_short import short_config
from platcal.cli import main
from platcal.io import read_yaml
from platcal.model.frames import DEG
from platcal.rigs.centrifuge.config import study_from_config
from platcal.rigs.centrifuge.record import nearest_samples, position_origin
from platcal.rigs.centrifuge.simulate import simulate

CONFIG = short_config(passes=2, extra="sampling: {sample_ms: 5}\n")
FINE_MS = 0.05
SUB = 100  # fine samples per 5 ms sample
JITTER = 2  # +- 2 fine samples = +- 0.1 ms


def test_nearest_samples_and_origin():
    t = np.arange(0, 1.0, 0.005)
    np.testing.assert_array_equal(nearest_samples(t, 0.02, 0.0025), np.arange(0, 200, 4))
    jit = t + np.random.default_rng(1).uniform(-1e-4, 1e-4, t.size)
    keep = nearest_samples(jit, 0.02, 0.0025)
    np.testing.assert_array_equal(keep, np.arange(0, 200, 4))
    gap = np.delete(t, np.arange(40, 60))  # 0.1 s without samples: those instants are dropped
    assert nearest_samples(gap, 0.02, 0.0025).size == 50 - 5
    # the filter's default instants start one period after the reset (ekf.filter_times)
    np.testing.assert_array_equal(nearest_samples(t, 0.02, 0.0025, first=1), np.arange(4, 200, 4))
    assert position_origin(t, 0.005, 0.1) == 0.0
    assert position_origin(jit + 0.0001, 0.005, 0.1) == 0.0  # clock restarted: origin stays 0
    assert abs(position_origin(jit + 1234.5, 0.005, 0.1) - 1234.5) < 2e-5  # grid fit, not the first sample


def _records(tmp_path):
    """(clean, jittered-and-offset) records of one noise-free run with the same added noise."""
    raw = read_yaml(CONFIG)
    raw["sampling"] = {"sample_ms": FINE_MS}
    study = study_from_config(raw)
    scheme = study.schemes["short"]
    sim = simulate(study.truth, scheme, study.centrifuge.scheme_params(scheme), study.noise,
                   None, sample_s=FINE_MS / 1000)
    K, n_fine = scheme.n_positions, sim.t.size
    n = n_fine // SUB
    rng = np.random.default_rng(7)
    noise = rng.normal(0.0, study.noise.sigma_a_ug * 1e-6, (K, n, 3))
    jitter = rng.integers(-JITTER, JITTER + 1, (K, n))
    frames = {}
    for name in ("clean", "jittered"):
        rows = []
        for k in range(K):
            idx = np.arange(n) * SUB
            t_off = 0.0
            if name == "jittered":
                idx = np.clip(idx + jitter[k], 0, n_fine - 1)
                t_off = 3600.0 + 61.25 * k  # the logger's clock: no restart at the position's start
            rows.append(pd.DataFrame({
                "position": k + 1, "t": sim.t[idx] + t_off,
                "alpha_cmd": scheme.angles_deg[k, 0], "beta_cmd": scheme.angles_deg[k, 1],
                "gamma_cmd": scheme.angles_deg[k, 2],
                "Ax": sim.A[0, k, idx, 0] + noise[k, :, 0], "Ay": sim.A[0, k, idx, 1] + noise[k, :, 1],
                "Az": sim.A[0, k, idx, 2] + noise[k, :, 2],
                "alpha": sim.angles[0, k, idx, 0] / DEG, "beta": sim.angles[0, k, idx, 1] / DEG,
                "gamma": sim.angles[0, k, idx, 2] / DEG,
            }))
        frames[name] = pd.concat(rows, ignore_index=True)
    return frames


def _identify(tmp_path, data, name, allow_failure=False):
    """summary.json of ``platcal identify`` (None if the run failed, exit 1, and that is allowed)."""
    cfg = tmp_path / "config.yaml"
    cfg.write_text(CONFIG)
    out = tmp_path / name
    code = main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(data), "--out", str(out)])
    if allow_failure and code == 1:
        assert not out.exists()
        return None
    # exit 3: identified, but the record does not fit the model (issue 25), outputs marked so
    assert code == 0 or (allow_failure and code == 3)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fit"]["verdict"] == ("passed" if code == 0 else "failed")
    return summary


@pytest.mark.slow
def test_jittered_offset_log_identifies_as_well_as_the_clean_record(tmp_path):
    frames = _records(tmp_path)
    jit = frames["jittered"]
    steps = jit.groupby("position")["t"].diff().dropna()
    assert steps.min() < 0.00491 and steps.max() > 0.00509  # the jitter is there
    clean_csv = tmp_path / "clean.csv"
    frames["clean"].to_csv(clean_csv, index=False)
    clean = _identify(tmp_path, clean_csv, "id_clean")
    results = {}
    for fmt in ("csv", "parquet"):
        data = tmp_path / f"jittered.{fmt}"
        jit.to_csv(data, index=False) if fmt == "csv" else jit.to_parquet(data, index=False)
        results[fmt] = _identify(tmp_path, data, f"id_{fmt}")
    for fmt, res in results.items():
        # every 20 ms filter instant of the 4 s dwell has its sample: 0.02 .. 3.98 s, 199 of them
        # (the sample at the reset instant t = 0 is not used, docs/centrifuge-model.md §9)
        assert res["samples_used_per_position"] == {"1": 199, "2": 199, "3": 199}, fmt
        assert res["failed_updates"] == 0
        ratio = res["max_abs_rel_err_pct_gyro"] / clean["max_abs_rel_err_pct_gyro"]
        print(f"{fmt}: largest gyro error {res['max_abs_rel_err_pct_gyro']:.3f} % vs clean "
              f"{clean['max_abs_rel_err_pct_gyro']:.3f} % (ratio {ratio:.4f}); NEES {res['nees']:.1f} vs "
              f"{clean['nees']:.1f}")
        assert 0.9 <= ratio <= 1.1, fmt
    # control: the same samples stamped with the nominal grid times are identified far worse, so
    # the recorded times are what makes the jittered log as good as the clean one
    nominal = jit.copy()
    nominal["t"] = frames["clean"]["t"].to_numpy()
    nominal.to_csv(tmp_path / "nominal.csv", index=False)
    wrong = _identify(tmp_path, tmp_path / "nominal.csv", "id_nominal", allow_failure=True)
    if wrong is not None:
        assert wrong["max_abs_rel_err_pct_gyro"] > 5 * clean["max_abs_rel_err_pct_gyro"]
    # a small gap (50 ms, under record.max_gap_s) is accepted: only the instants it covers are lost
    gap = jit.drop(jit.index[(jit["position"] == 2) & (jit.groupby("position").cumcount().between(400, 409))])
    gap.to_parquet(tmp_path / "gap.parquet", index=False)
    res = _identify(tmp_path, tmp_path / "gap.parquet", "id_gap")
    assert res["samples_used_per_position"]["1"] == 199 and 196 <= res["samples_used_per_position"]["2"] < 199
    assert res["max_abs_rel_err_pct_gyro"] == pytest.approx(results["parquet"]["max_abs_rel_err_pct_gyro"], rel=0.1)
    assert results["csv"]["max_abs_rel_err_pct_gyro"] == pytest.approx(results["parquet"]["max_abs_rel_err_pct_gyro"],
                                                                       rel=1e-9)
