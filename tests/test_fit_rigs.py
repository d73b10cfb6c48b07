"""Data that do not fit the model are caught on every rig (issue 25): the centrifuge, the
multiposition rig, the sled and the low-precision centrifuge. A clean simulated record is identified with exit 0 and a
passed ``fit`` block; each row of the issue's table exits 2 (refused before the filter) or 3
(identified, outputs marked ``fit: failed``) with the column named and no traceback.
"""

import json

import numpy as np
import pytest

from platcal.cli import main
from clean_records import simulated_records

G = 9.80665

CONFIGS = {
    "centrifuge": ("site: {latitude_deg: 28.2}\ncentrifuge: {rate_deg_s: 180, g_level: 10}\n"
                   "noise: {sigma_a_ug: 10, arw_deg_rth: 0.001, sigma_set_arcsec: 10}\n"
                   "schemes:\n  short: {dwell_s: 6, positions: [[45, 0, 167], [350, 0, 325], [209, 0, 182]]}\n"),
    "multiposition": ("rig: multiposition\nschemes: {small: {dwell_s: 6, positions: [[0, 0, 0], [90, 30, 0], "
                      "[180, -30, 90], [270, 20, 180], [45, 0, 270]]}}\n"),
}
CONFIGS["sled"] = "rig: sled\ntrajectory: {static_after_s: 10}\n"
CONFIGS["lowprec_centrifuge"] = "rig: lowprec_centrifuge\n"
SCHEME = {"centrifuge": "short", "multiposition": "small"}
SIMULATE = {**{rig: ["--scheme", s] for rig, s in SCHEME.items()}, "sled": [],
            "lowprec_centrifuge": ["--platform", "P1", "--run", "run1"]}
IDENTIFY = {**{rig: ["--scheme", s] for rig, s in SCHEME.items()}, "sled": [], "lowprec_centrifuge": []}
SUMMARY = {"centrifuge": "summary.json", "multiposition": "summary.json", "sled": "metrics.json",
           "lowprec_centrifuge": "summary.json"}
"""The file of each rig's identification that holds the fit block."""
CONSISTENT = ("centrifuge", "multiposition")
"""Rigs whose filter's measurement noise is the sensors' own, so a clean record's NIS per dof is
near 1; the sled's and the low-precision centrifuge's R are tuning margins far above the
navigation's noise (docs/rocket-sled.md §6.1, docs/lowprec-centrifuge.md §7): NIS per dof << 1."""


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """(config path, clean record frame) per rig: seed 3 of its small test."""
    return simulated_records(tmp_path_factory.mktemp("fit"), CONFIGS, SIMULATE, 3)


def identify(tmp_path, rig, clean, df, capsys):
    cfg, _ = clean[rig]
    data = tmp_path / "rec.csv"
    df.to_csv(data, index=False)
    out = tmp_path / "id"
    code = main(["identify", "--config", str(cfg), *IDENTIFY[rig], "--data", str(data), "--out", str(out)])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err, out


def fit_block(out, rig) -> dict:
    return json.loads((out / SUMMARY[rig]).read_text())["fit"]


@pytest.mark.parametrize("rig", sorted(CONFIGS))
def test_clean_record_fits(tmp_path, rig, clean, capsys):
    code, err, out = identify(tmp_path, rig, clean, clean[rig][1], capsys)
    assert code == 0, err
    fit = fit_block(out, rig)
    assert fit["verdict"] == "passed"
    assert all(c["score"] <= 1 for c in fit["channels"])
    if rig in CONSISTENT:
        assert abs(fit["nis_per_dof"] - 1) < 0.2  # per degree of freedom on every rig
    else:
        assert 0 < fit["nis_per_dof"] < 1


def _flip(col):
    def f(df):
        df[col] = -df[col]
        return df
    return f


def _scale(cols, k):
    def f(df):
        df[list(cols)] = df[list(cols)] * k
        return df
    return f


def _swap(a, b):
    def f(df):
        df[[a, b]] = df[[b, a]].to_numpy()
        return df
    return f


REFUSED = [  # (rig, spoil, column named): refused before the filter, exit 2
    ("multiposition", _scale(("Ax", "Ay", "Az"), G), "Ax"),  # m/s^2 instead of g
    ("multiposition", _flip("Ay"), "Ay"),
    ("multiposition", _swap("Ax", "Ay"), "Ax"),
    ("centrifuge", _flip("Ay"), "Ay"),
    ("centrifuge", _swap("Ax", "Az"), "Ax"),
    ("sled", _scale(("wx", "wy", "wz"), 180 / np.pi), "wx"),  # gyros in deg/s instead of rad/s
    ("sled", _flip("wz"), "wz"),
    ("sled", _scale(("fx", "fy", "fz"), 1 / G), "fz"),  # specific force in g (the median check)
    ("lowprec_centrifuge", _scale(("pE", "pN"), 1e-3), "pE"),  # positions in km
    ("lowprec_centrifuge", _flip("VE"), "VE"),
    ("lowprec_centrifuge", _swap("pE", "pN"), "pE"),
    # the specific force: a scale the fit cannot see (the coefficients absorb it), checked against
    # the derivative of VE, VN: 2e-3 moves an estimate by one sigma, mg for m/s^2 by hundreds
    ("lowprec_centrifuge", _scale(("fE",), 1.002), "fE"),
    ("lowprec_centrifuge", _scale(("fN",), 1 / (G * 1e-3)), "fN"),
    ("lowprec_centrifuge", _scale(("VN",), 3.6), "fN (or VN)"),  # km/h: fN no longer d(VN)/dt
]


@pytest.mark.parametrize("rig, spoil, column", REFUSED)
def test_unit_sign_swap_refused_before_the_filter(tmp_path, rig, spoil, column, clean, capsys):
    code, err, out = identify(tmp_path, rig, clean, spoil(clean[rig][1].copy()), capsys)
    assert code == 2, err
    assert f"column {column}" in err
    assert not out.exists()


@pytest.mark.parametrize("amplitude_s", [1e-5, 5e-4])  # +-10 us, and the row: +-0.5 ms
def test_centrifuge_timestamp_jitter_does_not_fit_and_names_the_clock(tmp_path, clean, capsys, amplitude_s):
    df = clean["centrifuge"][1].copy()
    df["t"] += np.random.default_rng(0).uniform(-amplitude_s, amplitude_s, len(df))  # on the stamps only
    code, err, out = identify(tmp_path, "centrifuge", clean, df, capsys)
    assert code == 3, err
    assert "column t jitters" in err and "worst channels" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fit"]["verdict"] == "failed"
    assert any(d.startswith("clock: column t") for d in summary["fit"]["diagnosis"])


def test_multiposition_misfit_exits_3_with_outputs(tmp_path, clean, capsys):
    df = clean["multiposition"][1].copy()
    df["Ax"] += 2e-4  # a 200 ug offset the model's bias prior does not expect within 6 s dwells
    df["Ax"] += np.random.default_rng(1).normal(0, 5e-5, len(df))  # and 10x the sensor noise
    code, err, out = identify(tmp_path, "multiposition", clean, df, capsys)
    assert code == 3, err
    assert "Ax" in err.split("worst channels:")[1]
    assert json.loads((out / "summary.json").read_text())["fit"]["verdict"] == "failed"


def test_sled_misfit_exits_3_with_outputs(tmp_path, clean, capsys):
    df = clean["sled"][1].copy()
    # a 20 deg/h x rate error (400 sigma of the config's 0.05 deg/h bias) during the run only, as
    # a vibration would rectify: at rest the gyros read the earth rate, so only the fit can see it
    run = (df["t"] > 5.1) & (df["t"] < 25.8)
    df.loc[run, "wx"] += 1e-4
    code, err, out = identify(tmp_path, "sled", clean, df, capsys)
    assert code == 3, err
    assert "run v_y" in err.split("worst channels:")[1]
    assert fit_block(out, "sled")["verdict"] == "failed"
    assert (out / "estimates.csv").exists()


@pytest.mark.parametrize("column, e", [("wx", 0.1), ("wy", 0.2), ("wz", 0.1), ("fy", 0.05)])
def test_sled_scale_in_the_former_blind_zone_refused(tmp_path, clean, capsys, column, e):
    """A gyro or lateral-force scale of 5-20 %: it used to pass (exit 0) with phi_x, phi_y (stop)
    or phi_z (run) moved by 5-12 sigma (wy: this short test rests 15 s, so it needs 0.2). The
    gyros' mean at rest is the earth rate's component (a scale is a bias e omega_i there); fy
    carries the Coriolis force 2 omega_z v at gain 1."""
    df = clean["sled"][1].copy()
    df[column] *= 1 + e
    code, err, out = identify(tmp_path, "sled", clean, df, capsys)
    assert code == 2, err
    assert f"column {column}" in err
    assert ("earth rate's component" if column[0] == "w" else "Coriolis force") in err
    assert not out.exists()


def test_sled_reports_what_the_gyros_errors_do_to_the_sigmas(tmp_path, clean, capsys):
    """Below the check at rest a gyro rate error cannot be seen, and the filters have no gyro
    state: metrics.json's gyro_rate_error gives the sigma with the gyros' own errors and the
    shift of the largest rate error that passes; a rate error inside it still exits 0."""
    code, err, out = identify(tmp_path, "sled", clean, clean["sled"][1], capsys)
    assert code == 0, err
    g = json.loads((out / "metrics.json").read_text())["gyro_rate_error"]
    stop_x = g["estimates"]["phi_x stop"]
    assert stop_x["sigma_with_gyro_arcsec"] > stop_x["sigma_arcsec"]
    # the zone left (this short test: phi_y run by about 2 sigma), said, not hidden
    assert max(max(e["shift_at_tolerance_sigmas"]) for e in g["estimates"].values()) > 1
    assert "gyro_rate_error" in err
    df = clean["sled"][1].copy()
    df["wx"] *= 1 + 0.5 * g["scale_tolerance"][0]  # half the largest scale the check at rest passes
    (tmp_path / "half").mkdir()
    code, err, out = identify(tmp_path / "half", "sled", clean, df, capsys)
    assert code == 0, err


def test_lowprec_misfit_exits_3_with_outputs(tmp_path, clean, capsys):
    # km/h: not a scale the plausibility check recognises; without fE, fN (differentiated from VE,
    # VN, so nothing to compare them with) the fit must catch it
    df = clean["lowprec_centrifuge"][1].drop(columns=["fE", "fN"])
    df["VN"] *= 3.6
    code, err, out = identify(tmp_path, "lowprec_centrifuge", clean, df, capsys)
    assert code == 3, err
    assert "zVN" in err.split("worst channels:")[1]
    assert fit_block(out, "lowprec_centrifuge")["verdict"] == "failed"
    assert (out / "estimates.csv").exists()


# ---------------------------------------------------------------- the clock rate (the former blind zones)

def _rate(e):
    def f(df):
        df["t"] = df["t"] * (1.0 + e)
        return df
    return f


@pytest.mark.parametrize("rig, e, chunk", [
    ("centrifuge", 1e-7, []),                          # in the former zone (4.6e-8 .. 1e-6: DIS_z up to 17 sigma)
    ("centrifuge", 1e-7, ["--chunk-rows", "500"]),     # the same, streamed: the scan measures the rate
    ("centrifuge", -1e-6, []),
    ("multiposition", 1e-3, []),                        # in the former zone (4.6e-4 .. 2.2e-3: DF_x up to 3 sigma)
    ("multiposition", 1e-3, ["--chunk-rows", "2000"]),  # the same, streamed: the scan measures the rate
])
def test_clock_rate_error_refused_naming_t_and_the_tolerance(tmp_path, rig, e, chunk, clean, capsys):
    cfg, df = clean[rig]
    data = tmp_path / "rec.csv"
    _rate(e)(df.copy()).to_csv(data, index=False)
    out = tmp_path / "id"
    code = main(["identify", "--config", str(cfg), *IDENTIFY[rig], "--data", str(data), "--out", str(out), *chunk])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and "error: --data column t:" in err, err
    assert f"{e:+.3g}" in err                          # the measured rate error
    assert "a clock-rate error above" in err and "of its sigma" in err
    assert ("sampling.sample_ms" if rig == "centrifuge" else "sampling.ts_ms") in err   # the fix
    assert not out.exists()                             # nothing written


@pytest.mark.parametrize("rig", ["centrifuge", "multiposition"])
def test_clock_rate_far_below_the_tolerance_passes_with_the_same_numbers(tmp_path, rig, clean, capsys):
    """A rate error a thousand times below what moves a coefficient by 0.3 sigma is not refused:
    the check measures, it does not flag every stamp that is not on the exact grid."""
    code, err, out = identify(tmp_path, rig, clean, _rate(1e-12)(clean[rig][1].copy()), capsys)
    assert code == 0, err


def test_jittered_stamps_are_not_a_rate_error(tmp_path, clean, capsys):
    """Stamps jittered +-1 us about the exact grid (a rate error of 0): the rate's standard error
    grows with the jitter, so the rate check does not refuse them (the jitter is the fit's)."""
    df = clean["multiposition"][1].copy()
    df["t"] += np.random.default_rng(2).uniform(-1e-6, 1e-6, len(df))
    code, err, out = identify(tmp_path, "multiposition", clean, df, capsys)
    assert code == 0, err


def test_clock_rate_measurement_is_unbiased_with_an_honest_error():
    """platcal.plausibility.segment_rate on stamps 5 ms apart, 1e-4 fast: exact stamps give the
    rate to rounding; jittered ones (+-0.5 ms, a tenth of the step) within 3 standard errors on
    at least 98 % of draws; a gap keeps the samples' slots; stamps scattered by more than a
    tenth of a step give no rate (their index may slip)."""
    from platcal.plausibility import ClockRate, segment_rate

    t = np.arange(600) * 0.005 * (1 + 1e-4)
    exact = segment_rate(t, 0.005)
    assert abs(exact.error - 1e-4) < 1e-12 and exact.samples == 600
    assert abs(segment_rate(np.delete(t, [100, 101, 300]), 0.005).error - 1e-4) < 1e-12
    rng = np.random.default_rng(7)
    z = [(r.error - 1e-4) / r.se for r in (segment_rate(t + rng.uniform(-5e-4, 5e-4, t.size), 0.005)
                                          for _ in range(200))]
    assert np.mean(np.abs(z) < 3) >= 0.98 and abs(np.mean(z)) < 0.3
    assert segment_rate(t + rng.uniform(-1.5e-3, 1.5e-3, t.size), 0.005) == ClockRate.none()
    # two positions on one clock: the better-measured one weighs more, the samples add
    both = ClockRate.combine([segment_rate(t, 0.005), segment_rate(t + rng.uniform(-1e-5, 1e-5, t.size), 0.005)])
    assert abs(both.error - 1e-4) < 1e-12 and both.samples == 1200


@pytest.mark.parametrize("rig", ["centrifuge", "multiposition"])
def test_summary_states_the_clock_rate_and_its_tolerance(tmp_path, rig, clean, capsys):
    code, err, out = identify(tmp_path, rig, clean, _rate(1e-12)(clean[rig][1].copy()), capsys)
    assert code == 0, err
    clock = json.loads((out / "summary.json").read_text())["clock"]
    assert abs(clock["rate_error"] - 1e-12) < 1e-13 and clock["rate_error_se"] < 1e-13
    assert 0 < clock["tolerance"] < 1e-3 and clock["most_sensitive"] and clock["share_of_sigma"] == 0.3
    assert clock["samples"] == len(clean[rig][1])


def test_clock_rate_against_a_whole_divisor_or_none():
    """The multiposition rig declares only its filter's period: a log sampled 2x faster is
    measured against half of it; one at a rate of its own (15.625 ms for 20 ms) is not measured."""
    from platcal.plausibility import ClockRate, segment_rate

    t = np.arange(3000) * 0.010 * (1 + 3e-4)
    r = segment_rate(t, 0.020, divisor=True)
    assert abs(r.error - 3e-4) < 1e-12 and r.step_s == 0.010
    assert segment_rate(np.arange(3000) * 0.015625, 0.020, divisor=True) == ClockRate.none()
