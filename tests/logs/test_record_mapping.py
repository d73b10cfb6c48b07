"""A vendor's log read through the config's ``record:`` mapping (issue 21, item 1).

Per rig a simulated record is rewritten as another logger would write it (other column names,
other units, an extra column) and identified through a mapping: the estimates equal those of the
original record to 1e-6 of their sigma. Bad mappings exit 2 naming the field, nothing written.
"""

import json

import numpy as np
import pandas as pd
import pymap3d
import pytest
import yaml

from platcal.cli import main
from platcal.logs.increments import sample_intervals
from platcal.mapping import RecordMapping, conversion_factor
from platcal.errors import InputError
from platcal.records import iter_table, read_table
from platcal.rigs.sled.config import load_config
from platcal.rigs.sled.identify import estimates, identify as sled_identify
from platcal.rigs.sled.record import read_record, record_arrays

G = 9.80665
CENTRIFUGE = {"rig": "centrifuge", "noise": {"sigma_a_ug": 10, "arw_deg_rth": 0.001, "sigma_set_arcsec": 10},
              "schemes": {"short": {"dwell_s": 3, "positions": [[45, 0, 167], [350, 0, 325], [209, 0, 182],
                                                                  [134, 0, 141], [106, 0, 338], [142, 0, 269]]}}}
MULTIPOSITION = {"rig": "multiposition", "schemes": {"short": {"dwell_s": 4, "positions": [
    [0, 0, 0], [180, 0, 0], [90, 0, 0], [270, 0, 0], [90, 0, 90], [270, 0, 90], [45, 0, 45], [135, 0, 300]]}}}
SLED = {"rig": "sled", "trajectory": {"static_after_s": 4}}
LOWPREC = {"rig": "lowprec_centrifuge", "profile": {"rest_first_s": 10, "rest_between_s": 30},
           "runs": {"P1": {"run1": [5, 8]}, "P2": {"run1": [5, 8]}}, "traditional": {"levels_g": [5, 8], "hold_s": 60, "rest_last_s": 10}}


def write_cfg(path, raw, record=None):
    raw = json.loads(json.dumps(raw))
    if record is not None:
        raw["record"] = record
    path.write_text(yaml.safe_dump(raw))
    return str(path)


def simulated(tmp_path, raw, *opts):
    """``(config path, record path)`` of a record simulated with ``opts``."""
    cfg = write_cfg(tmp_path / "c.yaml", raw)
    rec = tmp_path / "rec.csv"
    assert main(["simulate", "--config", cfg, *opts, "--out", str(rec)]) == 0
    return cfg, rec


def identify(cfg, data, out, *opts):
    assert main(["identify", "--config", cfg, "--data", str(data), "--out", str(out), "--no-truth", *opts]) == 0
    return pd.read_csv(out / "estimates.csv")


def assert_same(a: pd.DataFrame, b: pd.DataFrame):
    assert list(a["name"]) == list(b["name"])
    ea, eb, sig = (x.to_numpy(float) for x in (a["estimate"], b["estimate"], a["sigma"]))
    assert np.array_equal(np.isnan(ea), np.isnan(eb))
    # quantities without a sigma (e.g. the sled's compensated X): within 1e-6 of their size
    scale = np.where(np.isfinite(sig), sig, np.abs(ea))
    ok = np.isfinite(ea)
    assert np.all(np.abs(ea - eb)[ok] <= 1e-6 * scale[ok])
    assert np.allclose(a["sigma"], b["sigma"], rtol=1e-6, atol=0, equal_nan=True)


def test_units_parse_with_the_rigs_g():
    assert conversion_factor("m/s^2", "g", G, "f") == pytest.approx(1 / G, rel=1e-15)
    assert conversion_factor("mg", "m/s^2", 9.8, "f") == pytest.approx(9.8e-3, rel=1e-15)
    assert conversion_factor("ug", "g", G, "f") == pytest.approx(1e-6, rel=1e-15)
    assert conversion_factor("deg/h", "rad/s", G, "f") == pytest.approx(np.pi / 180 / 3600, rel=1e-15)
    assert conversion_factor("arcsec", "deg", G, "f") == pytest.approx(1 / 3600, rel=1e-15)
    assert conversion_factor("us", "s", G, "f") == pytest.approx(1e-6, rel=1e-15)
    with pytest.raises(InputError) as e:
        conversion_factor("deg", "g", G, "record.units.Ax")
    assert e.value.field == "record.units.Ax"


def test_iso_times_and_ignore_extra():
    df = pd.DataFrame({"when": ["2026-01-01T10:00:00.000Z", "2026-01-01T10:00:00.020Z", "2026-01-01T10:00:00.040Z"],
                       "acc": [1.0, 2.0, 3.0], "temp": [20.0, 20.0, 20.0]})
    m = RecordMapping(columns={"t": "when", "Ax": "acc"}, units={"t": "iso", "Ax": "mg"}, ignore_extra=True)
    out = m.apply(df, {"t": "s", "Ax": "g"}, ("t", "Ax"))
    assert list(out.columns) == ["t", "Ax"]
    assert np.allclose(out["t"], [0.0, 0.02, 0.04], atol=1e-12)
    assert np.allclose(out["Ax"], [1e-3, 2e-3, 3e-3], rtol=1e-15)


def test_metadata_header_lines(tmp_path):
    """``record.header_lines``: the metadata above the column header is skipped, whole or in
    chunks; a bad value's line number counts it; Parquet and a file shorter than its header are
    refused naming the field."""
    body = "t,Ax\n0.0,1.0\n0.02,2.0\n0.04,3.0\n0.06,4.0\n"
    (tmp_path / "plain.csv").write_text(body)
    (tmp_path / "meta.csv").write_text("Logger X, serial 12\nstarted 10:00\n" + body)
    m = RecordMapping(header_lines=2)
    units = {"t": "s", "Ax": "g"}
    plain = read_table(tmp_path / "plain.csv", ("t", "Ax"))
    pd.testing.assert_frame_equal(read_table(tmp_path / "meta.csv", ("t", "Ax"), mapping=m, units=units), plain)
    chunks = list(iter_table(tmp_path / "meta.csv", ("t", "Ax"), mapping=m, units=units, chunk_rows=3))
    assert [len(c) for c in chunks] == [3, 1]
    pd.testing.assert_frame_equal(pd.concat([c.to_pandas() for c in chunks], ignore_index=True), plain)
    with pytest.raises(InputError):  # the metadata read as the header
        read_table(tmp_path / "meta.csv", ("t", "Ax"))
    (tmp_path / "bad.csv").write_text("Logger X\nstarted 10:00\n" + body.replace("0.04,3.0", "0.04,x"))
    with pytest.raises(InputError) as e:
        list(iter_table(tmp_path / "bad.csv", ("t", "Ax"), mapping=m, units=units, chunk_rows=2))
    assert e.value.field == "--data column Ax, row 6"  # line 6 of the file
    plain_df = pd.read_csv(tmp_path / "plain.csv")
    plain_df.to_parquet(tmp_path / "p.parquet", index=False)
    for path in (tmp_path / "p.parquet", tmp_path / "short.csv"):
        (tmp_path / "short.csv").write_text("one\ntwo\n")
        with pytest.raises(InputError) as e:
            read_table(path, ("t", "Ax"), mapping=m if path.suffix == ".parquet" else RecordMapping(header_lines=5),
                       units=units)
        assert e.value.field == "record.header_lines"


@pytest.mark.slow
def test_centrifuge_vendor_log(tmp_path):
    cfg, rec = simulated(tmp_path, CENTRIFUGE, "--scheme", "short", "--seed", "1")
    base = identify(cfg, rec, tmp_path / "a", "--scheme", "short")
    df = pd.read_csv(rec)
    log = pd.DataFrame({"Pos": df["position"], "Time_ms": df["t"] * 1e3, "temp_C": 21.5})
    for c in ("alpha_cmd", "beta_cmd", "gamma_cmd"):
        log[c.upper()] = np.deg2rad(df[c])
    for c in ("Ax", "Ay", "Az"):
        log[f"acc_{c[1]}"] = df[c] * G
    # a logger's metadata above the column header (record.header_lines)
    meta = "# Logger: ACQ-9000 v2.1\n# Date: 2026-11-25 10:00:00\n# Site: lab 3, 10 g centrifuge\n"
    (tmp_path / "vendor.csv").write_text(meta + log.to_csv(index=False))
    record = {"header_lines": 3, "columns": {"position": "Pos", "t": "Time_ms", "alpha_cmd": "ALPHA_CMD", "beta_cmd": "BETA_CMD",
                          "gamma_cmd": "GAMMA_CMD", "Ax": "acc_x", "Ay": "acc_y", "Az": "acc_z"},
              "units": {"t": "ms", "alpha_cmd": "rad", "beta_cmd": "rad", "gamma_cmd": "rad",
                        "Ax": "m/s^2", "Ay": "m/s^2", "Az": "m/s^2"}, "ignore_extra": True}
    mcfg = write_cfg(tmp_path / "m.yaml", CENTRIFUGE, record)
    assert_same(base, identify(mcfg, tmp_path / "vendor.csv", tmp_path / "b", "--scheme", "short"))


@pytest.mark.slow
def test_multiposition_vendor_log(tmp_path):
    cfg, rec = simulated(tmp_path, MULTIPOSITION, "--scheme", "short", "--seed", "3")
    base = identify(cfg, rec, tmp_path / "a", "--scheme", "short")
    df = pd.read_csv(rec).drop(columns=["alpha", "beta", "gamma"])
    log = df.rename(columns={"t": "time_us", "Ax": "ax_mg", "Ay": "ay_mg", "Az": "az_mg", "alpha_m": "enc_a",
                             "beta_m": "enc_b", "gamma_m": "enc_c"})
    log["time_us"] = df["t"] * 1e6
    for c in ("ax_mg", "ay_mg", "az_mg"):
        log[c] = log[c] * 1e3
    for c in ("enc_a", "enc_b", "enc_c"):
        log[c] = log[c] * 3600.0
    log.to_parquet(tmp_path / "vendor.parquet", index=False)
    record = {"columns": {"t": "time_us", "Ax": "ax_mg", "Ay": "ay_mg", "Az": "az_mg", "alpha_m": "enc_a",
                          "beta_m": "enc_b", "gamma_m": "enc_c"},
              "units": {"t": "us", "Ax": "mg", "Ay": "mg", "Az": "mg", "alpha_m": "arcsec", "beta_m": "arcsec",
                        "gamma_m": "arcsec"}}
    mcfg = write_cfg(tmp_path / "m.yaml", MULTIPOSITION, record)
    assert_same(base, identify(mcfg, tmp_path / "vendor.parquet", tmp_path / "b", "--scheme", "short"))


@pytest.mark.slow
def test_sled_vendor_log(tmp_path):
    cfg, rec = simulated(tmp_path, SLED, "--seed", "5")
    df = pd.read_csv(rec)
    log = pd.DataFrame({"time_ms": df["t"] * 1e3})
    for a in "xyz":
        log[f"acc_{a}_g"] = df[f"f{a}"] / G
    for a in "xyz":
        log[f"gyro_{a}"] = np.rad2deg(df[f"w{a}"]) * 3600.0
    log["status"] = 1
    log.to_csv(tmp_path / "vendor.csv", index=False)
    record = {"columns": {"t": "time_ms", **{f"f{a}": f"acc_{a}_g" for a in "xyz"},
                          **{f"w{a}": f"gyro_{a}" for a in "xyz"}},
              "units": {"t": "ms", **{f"f{a}": "g" for a in "xyz"}, **{f"w{a}": "deg/h" for a in "xyz"}},
              "ignore_extra": True}

    def run(raw, path):
        c = load_config(raw)
        traj, frame, t = read_record(path, c)
        f, w = record_arrays(frame)
        return estimates(sled_identify(c, traj, f, w, t=t), None)

    a = run(SLED, rec)
    b = run({**SLED, "record": record}, tmp_path / "vendor.csv")
    assert_same(a, b)
    mcfg = write_cfg(tmp_path / "m.yaml", SLED, record)
    assert main(["identify", "--config", mcfg, "--data", str(tmp_path / "vendor.csv"), "--out",
                 str(tmp_path / "b")]) == 0


@pytest.mark.slow
def test_lowprec_vendor_log(tmp_path):
    cfg, rec = simulated(tmp_path, LOWPREC, "--platform", "P1", "--run", "run1", "--seed", "7")
    base = identify(cfg, rec, tmp_path / "a")
    df = pd.read_csv(rec)
    start = pd.Timestamp("2026-03-02T08:00:00Z")
    stamps = start + pd.to_timedelta(np.round(df["t"] * 1e9).astype("int64"), unit="ns")
    log = pd.DataFrame({"utc": stamps.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
                        "vel_e": df["VE"], "vel_n": df["VN"], "pos_e_mm": df["pE"] * 1e3, "pos_n_mm": df["pN"] * 1e3,
                        "azimuth": np.deg2rad(df["heading_deg"]), "f_e": df["fE"] / G * 1e3,
                        "f_n": df["fN"] / G * 1e3, "mode": df["schedule"]})
    log.to_csv(tmp_path / "vendor.csv", index=False)
    record = {"columns": {"t": "utc", "VE": "vel_e", "VN": "vel_n", "pE": "pos_e_mm", "pN": "pos_n_mm",
                          "heading_deg": "azimuth", "fE": "f_e", "fN": "f_n", "schedule": "mode"},
              "units": {"t": "iso", "pE": "mm", "pN": "mm", "heading_deg": "rad", "fE": "mg", "fN": "mg"}}
    mcfg = write_cfg(tmp_path / "m.yaml", LOWPREC, record)
    assert_same(base, identify(mcfg, tmp_path / "vendor.csv", tmp_path / "b"))


BAD = [({"units": {"t": "fortnights_x"}}, "record.units.t"),
       ({"units": {"Ax": "deg"}}, "record.units.Ax"),
       ({"columns": {"Qx": "acc"}}, "record.columns.Qx"),
       ({"columns": {"Ax": "no_such_column"}}, "record.columns.Ax"),
       ({"columns": {"Ax": "position"}, "ignore_extra": True}, "record.columns.position")]


@pytest.mark.parametrize("record,field", BAD)
def test_bad_mapping_exits_2(tmp_path, capsys, record, field):
    rec = tmp_path / "rec.csv"
    n = 10
    pd.DataFrame({"position": np.ones(n), "t": np.arange(n) * 0.01, "alpha_cmd": 0.0, "beta_cmd": 0.0,
                  "gamma_cmd": 0.0, "Ax": 0.0, "Ay": 0.0, "Az": 1.0}).to_csv(rec, index=False)
    cfg = write_cfg(tmp_path / "m.yaml", CENTRIFUGE, record)
    out = tmp_path / "out"
    assert main(["identify", "--config", cfg, "--data", str(rec), "--scheme", "short", "--out", str(out)]) == 2
    assert f"error: {field}:" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
def test_sled_increments(tmp_path):
    """delta-v (m/s) and delta-theta (arcsec) per sample, converted over each sample's interval."""
    cfg, rec = simulated(tmp_path, SLED, "--seed", "5")
    df = pd.read_csv(rec)
    dts = sample_intervals(df["t"].to_numpy())
    log = pd.DataFrame({"t": df["t"]})
    for a in "xyz":
        log[f"dv_{a}"] = df[f"f{a}"] * dts
        log[f"dth_{a}"] = np.rad2deg(df[f"w{a}"] * dts) * 3600.0
    log.to_csv(tmp_path / "inc.csv", index=False)
    record = {"kind": "increments", "columns": {**{f"f{a}": f"dv_{a}" for a in "xyz"},
                                                **{f"w{a}": f"dth_{a}" for a in "xyz"}},
              "units": {f"w{a}": "arcsec" for a in "xyz"}}
    base = identify(cfg, rec, tmp_path / "a")
    mcfg = write_cfg(tmp_path / "m.yaml", SLED, record)
    got = identify(mcfg, tmp_path / "inc.csv", tmp_path / "b")
    assert_same(base[base["sigma"].notna()], got[base["sigma"].notna()])


def test_increments_refused_without_rate_columns(tmp_path, capsys):
    cfg = write_cfg(tmp_path / "m.yaml", LOWPREC, {"kind": "increments"})
    rec = tmp_path / "rec.csv"
    rec.write_text("t,VE,VN,pE,pN,heading_deg,schedule\n0,0,0,0,0,0,static\n")
    assert main(["identify", "--config", cfg, "--data", str(rec), "--out", str(tmp_path / "o")]) == 2
    assert "error: record.kind:" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def _geodetic_log(df, lat0=40.0, lon0=116.0, h0=50.0):
    """The record with pE, pN as WGS84 latitude, longitude (deg) and height (m) of an INS."""
    lat, lon, h = pymap3d.enu2geodetic(df["pE"].to_numpy(), df["pN"].to_numpy(), np.zeros(len(df)), lat0, lon0, h0)
    return df.drop(columns=["pE", "pN"]).assign(lat_deg=lat, lon_deg=lon, alt_m=h)


@pytest.mark.slow
def test_lowprec_geodetic_log(tmp_path):
    """Latitude, longitude and height in, local east/north positions out (issue 21, item 2)."""
    cfg, rec = simulated(tmp_path, LOWPREC, "--platform", "P1", "--run", "run1", "--seed", "7")
    df = pd.read_csv(rec)
    # the geodetic log's positions start at its first sample; the simulated first sample carries noise
    df[["pE", "pN"]] -= df[["pE", "pN"]].iloc[0]
    df.to_csv(tmp_path / "rec0.csv", index=False)
    base = identify(cfg, tmp_path / "rec0.csv", tmp_path / "a")
    _geodetic_log(df).to_csv(tmp_path / "geo.csv", index=False)
    record = {"geodetic": {"lat": "lat_deg", "lon": "lon_deg", "height": "alt_m"}}
    mcfg = write_cfg(tmp_path / "m.yaml", LOWPREC, record)
    assert_same(base, identify(mcfg, tmp_path / "geo.csv", tmp_path / "b"))


GEODETIC_BAD = [(CENTRIFUGE, {"lat": "lat_deg", "lon": "lon_deg"}, "record.geodetic"),  # a rig without positions
                (LOWPREC, {"lat": "latitude", "lon": "lon_deg"}, "record.geodetic.lat"),  # no such column
                (LOWPREC, {"lat": "lon_deg", "lon": "lat_deg"}, "record.geodetic.lat"),  # 116 deg: not a latitude
                (LOWPREC, {"lat": "lat_text", "lon": "lon_deg"}, "record.geodetic.lat, row 2")]  # not a number


@pytest.mark.parametrize("raw, geodetic, field", GEODETIC_BAD)
def test_bad_geodetic_mapping_exits_2(tmp_path, capsys, raw, geodetic, field):
    n = 10
    pd.DataFrame({"t": np.arange(n) * 0.01, "VE": 0.0, "VN": 0.0, "heading_deg": 0.0, "schedule": "static",
                  "lat_deg": 40.0, "lon_deg": 116.0, "lat_text": "north"}).to_csv(tmp_path / "geo.csv", index=False)
    cfg = write_cfg(tmp_path / "m.yaml", raw, {"geodetic": geodetic, "ignore_extra": True})
    out = tmp_path / "out"
    opts = ["--scheme", "short"] if raw is CENTRIFUGE else []
    assert main(["identify", "--config", cfg, "--data", str(tmp_path / "geo.csv"), *opts, "--out", str(out)]) == 2
    assert f"error: {field}" in capsys.readouterr().err
    assert not out.exists()
