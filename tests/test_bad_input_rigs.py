"""A sweep of bad inputs through the CLI of the three newer rigs (issue 13, item 5): multiposition,
sled and lowprec_centrifuge; configs, records, output paths and options.

Every case must exit with status 2, name the field or column in stderr (no traceback, no numpy
reprs) and write nothing: the folder the case runs in holds exactly the same files (names and
bytes) before and after. One small record per rig is simulated once (tiny configs) and then
spoiled per case; a case that is not refused before the work starts shows up as a failed
assertion on the exit status or on the folder, not as a pass.
"""


import numpy as np
import pandas as pd
import pytest

from platcal.cli import main
from clean_records import simulated_records
from file_snapshot import snapshot

G = 9.80665

CONFIGS = {
    "multiposition": "rig: multiposition\nschemes: {tiny: {dwell_s: 1, positions: [[0, 0, 0], [90, 0, 0]]}}\n",
    "sled": ("rig: sled\ntrajectory: {static_before_s: 1, phases: [{accel_g: 2, duration_s: 1}], brake_g: 4, "
             "static_after_s: 1}\n"),
    "lowprec_centrifuge": ("rig: lowprec_centrifuge\nprofile: {rest_first_s: 2, rest_between_s: 2, rate_hz: 20}\n"
                           "runs: {P1: {run1: [2, 3]}, P2: {run1: [2, 4]}}\n"
                           "traditional: {levels_g: [2, 3], hold_s: 3, rest_last_s: 2}\n"),
}
SIMULATE = {"multiposition": ["--scheme", "tiny"], "sled": [],
            "lowprec_centrifuge": ["--platform", "P1", "--run", "run1"]}
IDENTIFY = {"multiposition": ["--scheme", "tiny"], "sled": [], "lowprec_centrifuge": []}


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """One clean simulated record per rig (and the lowprec traditional run), as frames."""
    d = tmp_path_factory.mktemp("clean")
    out = {rig: frame for rig, (_, frame) in simulated_records(d, CONFIGS, SIMULATE, 1).items()}
    cfg = d / "lowprec_centrifuge.yaml"
    rec = d / "trad.csv"
    assert main(["simulate", "--config", str(cfg), "--platform", "P1", "--run", "traditional", "--seed", "1",
                 "--out", str(rec)]) == 0
    out["lowprec_traditional"] = pd.read_csv(rec)
    return out


def _pos(df, k):
    return df["position"] == k


def _gap(df, a, b, mask=None):
    """Rows with a < t < b (within ``mask``) dropped."""
    m = (df["t"] > a) & (df["t"] < b)
    if mask is not None:
        m &= mask
    return df[~m].reset_index(drop=True)


def _swap_t(df, i):
    df = df.copy()
    df.loc[[i, i + 1], "t"] = df.loc[[i + 1, i], "t"].to_numpy()
    return df


def _set(df, col, row, value):
    df = df.copy()
    if df[col].dtype != object and isinstance(value, str):
        df[col] = df[col].astype(object)
    elif isinstance(value, float):
        df[col] = df[col].astype(float)
    df.loc[row, col] = value
    return df


def _boost_halved(df):
    df = df.copy()
    m = (df["t"] > 1.1) & (df["t"] < 1.9)   # the tiny sled's +2 g phase is t = 1 .. 2 s
    df.loc[m, "fx"] *= 0.5
    return df


def _in_g(df):
    df = df.copy()
    df[["fx", "fy", "fz"]] /= G
    return df


# ---- records: (rig, how to spoil the clean record, extra identify options, expected field) ------
RECORDS = {
    # multiposition, scheme 'tiny': 2 positions x 1 s at 20 ms (record.max_gap_s 0.1 s)
    "mp gap": ("multiposition", lambda d: _gap(d, 0.3, 0.6, _pos(d, 1)), [], "--data column t, position 1"),
    "mp t in ms": ("multiposition", lambda d: d.assign(t=d.t * 1000), [], "--data column t, position 1"),
    "mp t not increasing": ("multiposition", lambda d: _swap_t(d, 10), [], "--data column t, position 1"),
    "mp dwell 0.5 s for 1 s": ("multiposition", lambda d: d[d.t <= 0.5], [], "--data column t, position 1"),
    "mp position missing": ("multiposition", lambda d: d[_pos(d, 1)], [], "--data column position"),
    "mp extra position": ("multiposition", lambda d: pd.concat([d, d[_pos(d, 2)].assign(position=3)]), [],
                          "--data column position"),
    "mp wrong angles": ("multiposition", lambda d: d.assign(gamma_cmd=np.where(_pos(d, 2), 45.0, d.gamma_cmd)), [],
                        "--data position 2"),
    "mp wrong scheme": ("multiposition", lambda d: d, ["--scheme", "S8"], "--data position 2"),
    "mp missing angle sensor": ("multiposition", lambda d: d.drop(columns=["beta_m"]), [], "--data column beta_m"),
    "mp nan Ax": ("multiposition", lambda d: _set(d, "Ax", 5, np.nan), [], "--data column Ax, row 7"),
    "mp text in t": ("multiposition", lambda d: _set(d, "t", 3, "0.06s"), [], "--data column t, row 5"),
    "mp unknown column": ("multiposition", lambda d: d.assign(temp=1.0), [], "--data column temp"),
    "mp two of three truth": ("multiposition", lambda d: d.drop(columns=["gamma"]), [], "--data column gamma"),
    "mp fractional position": ("multiposition", lambda d: _set(d, "position", 0, 1.5), [], "--data column position"),
    # sled, tiny trajectory: 1 s static, 1 s at +2 g, braking at 4 g, 1 s static (record.max_gap_s 0.02 s)
    "sled gap 0.05 s": ("sled", lambda d: _gap(d, 0.50, 0.55), [], "--data column t"),
    "sled t in ms": ("sled", lambda d: d.assign(t=d.t * 1000), [], "--data column t"),
    "sled t not increasing": ("sled", lambda d: _swap_t(d, 20), [], "--data column t"),
    "sled too short": ("sled", lambda d: d.iloc[:-20], [], "--data column t"),
    "sled other trajectory": ("sled", _boost_halved, [], "--data column fx"),
    "sled specific force in g": ("sled", _in_g, [], "--data column fz"),
    "sled missing wz": ("sled", lambda d: d.drop(columns=["wz"]), [], "--data column wz"),
    "sled nan fy": ("sled", lambda d: _set(d, "fy", 7, np.nan), [], "--data column fy, row 9"),
    "sled unknown column": ("sled", lambda d: d.assign(baro=0.0), [], "--data column baro"),
    "sled header only": ("sled", lambda d: d.iloc[:0], [], "--data"),
    # lowprec_centrifuge, 20 Hz, P1 run1 = spins to 2 and 3 g (record.max_gap_s 0.05 s)
    "lp gap": ("lowprec_centrifuge", lambda d: _gap(d, 1.0, 1.2), [], "--data column t"),
    "lp t in ms": ("lowprec_centrifuge", lambda d: d.assign(t=d.t * 1000), [], "--data column t"),
    "lp t not increasing": ("lowprec_centrifuge", lambda d: _swap_t(d, 5), [], "--data column t"),
    "lp levels of no configured run": ("lowprec_centrifuge", lambda d: d.assign(
        heading_deg=np.mod(np.unwrap(np.radians(d.heading_deg)) * 1.5 * 180 / np.pi, 360)), [],
        "--data column heading_deg"),
    "lp proposed run as traditional": ("lowprec_centrifuge", lambda d: d, ["--method", "traditional"],
                                       "--data column schedule"),
    "lp bad schedule": ("lowprec_centrifuge", lambda d: _set(d, "schedule", 4, "spin"), [],
                        "--data column schedule, row 6"),
    "lp fE without fN": ("lowprec_centrifuge", lambda d: d.drop(columns=["fN"]), [], "--data column fN"),
    "lp missing heading": ("lowprec_centrifuge", lambda d: d.drop(columns=["heading_deg"]), [],
                           "--data column heading_deg"),
    "lp nan VE": ("lowprec_centrifuge", lambda d: _set(d, "VE", 9, np.nan), [], "--data column VE, row 11"),
    "lp traditional at other levels": ("lowprec_traditional", lambda d: d.assign(
        heading_deg=np.mod(np.unwrap(np.radians(d.heading_deg)) * 1.3 * 180 / np.pi, 360)),
        ["--method", "traditional"], "--data column heading_deg"),
    "lp traditional plateau cut": ("lowprec_traditional", lambda d: d.drop(
        index=d.index[d.schedule == "hold"][:20]).reset_index(drop=True).pipe(
        lambda x: x.assign(t=np.arange(len(x)) * 0.05)), ["--method", "traditional"], "--data column schedule"),
}


def _identify_refused(tmp_path, capsys, cfg, record, rig, opts, field) -> None:
    """``platcal identify`` on ``record`` (written as CSV) with the rig's options (plus ``opts``;
    ``opts`` alone when they name the scheme) exits 2 naming ``field``, with no traceback and
    nothing written."""
    data = tmp_path / "rec.csv"
    record.to_csv(data, index=False)
    opts = opts if "--scheme" in opts else IDENTIFY[rig] + opts
    before = snapshot(tmp_path)
    assert main(["identify", "--config", str(cfg), "--data", str(data), *opts, "--out", str(tmp_path / "id")]) == 2
    err = capsys.readouterr().err
    assert f"error: {field}" in err, err
    assert "np." not in err and "Traceback" not in err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("case", sorted(RECORDS))
def test_bad_record(case, records, tmp_path, capsys):
    key, spoil, extra, field = RECORDS[case]
    rig = "lowprec_centrifuge" if key == "lowprec_traditional" else key
    cfg = tmp_path / "c.yaml"
    cfg.write_text(CONFIGS[rig])
    _identify_refused(tmp_path, capsys, cfg, spoil(records[key].copy()), rig, extra, field)


# ---- record files that are not UTF-8 CSV / Parquet (one rig each, by how it is spoilt) ------------
def _file_cases():
    def parquet_as_csv(df, path):
        df.to_parquet(path)

    def csv_as_parquet(df, path):
        path.with_suffix(".parquet").write_text(df.to_csv(index=False))
        return path.with_suffix(".parquet")

    def utf16(df, path):
        path.write_bytes(df.head(30).to_csv(index=False).encode("utf-16"))

    def truncated(df, path):
        text = df.head(50).to_csv(index=False)
        path.write_text(text[: text.rstrip("\n").rfind(",")])

    def semicolons(df, path):
        path.write_text(df.head(30).to_csv(index=False, sep=";"))

    def folder(df, path):
        path.mkdir()

    return {"parquet named .csv": ("multiposition", parquet_as_csv, "--data"),
            "csv named .parquet": ("sled", csv_as_parquet, "--data"),
            "utf-16 text": ("lowprec_centrifuge", utf16, "--data"),
            "truncated last line": ("sled", truncated, "--data line"),
            "semicolon separated": ("multiposition", semicolons, "--data column"),
            "a folder": ("lowprec_centrifuge", folder, "--data")}


FILES = _file_cases()


@pytest.mark.parametrize("case", sorted(FILES))
def test_bad_record_file(case, records, tmp_path, capsys):
    rig, make, field = FILES[case]
    cfg = tmp_path / "c.yaml"
    cfg.write_text(CONFIGS[rig])
    data = tmp_path / "rec.csv"
    data = make(records[rig].copy(), data) or data
    before = snapshot(tmp_path)
    assert main(["identify", "--config", str(cfg), "--data", str(data), *IDENTIFY[rig],
                 "--out", str(tmp_path / "id")]) == 2
    err = capsys.readouterr().err
    assert f"error: {field}" in err, err
    assert "Traceback" not in err
    assert snapshot(tmp_path) == before


# ---- configs and options: (rig, extra config text, command options, expected field) --------------
CASES = {
    "mp zero max gap": ("multiposition", "record: {max_gap_s: 0}", [], "record.max_gap_s"),
    "mp nan max gap": ("multiposition", "record: {max_gap_s: .nan}", [], "record.max_gap_s"),
    "mp unknown record key": ("multiposition", "record: {max_gap: 1}", [], "record"),
    "mp inf sample period": ("multiposition", "sampling: {ts_ms: .inf}", [], "sampling.ts_ms"),
    "mp unknown default scheme": ("multiposition", "default_scheme: nope", [], "default_scheme"),
    "mp unknown scheme": ("multiposition", "", ["--scheme", "nope"], "--scheme"),
    "mp unknown estimator": ("multiposition", "", ["--estimator", "ukf"], "--estimator"),
    "mp method given": ("multiposition", "", ["--method", "x"], "--method"),
    "sled negative max gap": ("sled", "record: {max_gap_s: -1}", [], "record.max_gap_s"),
    "sled period not whole samples": ("sled", "filter: {period_ms: 7}", [], "filter.period_ms"),
    "sled unknown study case": ("sled", "study: {cases: [nope]}", [], "study.cases[0]"),
    "sled scheme given": ("sled", "", ["--scheme", "x"], "--scheme"),
    "sled estimator given": ("sled", "", ["--estimator", "ekf"], "--estimator"),
    "lp zero max gap": ("lowprec_centrifuge", "record: {max_gap_s: 0}", [], "record.max_gap_s"),
    "lp run named traditional": ("lowprec_centrifuge", "runs: {P1: {traditional: [2, 3]}, P2: {run1: [2, 4]}}", [],
                                 "runs.P1"),
    "lp run of unknown platform": ("lowprec_centrifuge", "runs: {P1: {run1: [2, 3]}, P2: {run1: [2, 4]}, "
                                   "P9: {run1: [2, 3]}}", [], "runs.P9"),
    "lp unknown method": ("lowprec_centrifuge", "", ["--method", "nope"], "--method"),
    "lp scheme given": ("lowprec_centrifuge", "", ["--scheme", "x"], "--scheme"),
}


def _config(rig: str, extra: str) -> str:
    """The rig's tiny config with the top-level sections of ``extra`` replacing its own."""
    keys = {line.split(":")[0] for line in extra.splitlines() if line and not line.startswith(" ")}
    kept = [line for line in CONFIGS[rig].splitlines() if line.split(":")[0] not in keys]
    return "\n".join(kept) + "\n" + extra + "\n"


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_config_or_option(case, records, tmp_path, capsys):
    rig, extra, opts, field = CASES[case]
    cfg = tmp_path / "c.yaml"
    cfg.write_text(_config(rig, extra))
    _identify_refused(tmp_path, capsys, cfg, records[rig], rig, opts, field)


# ---- output paths: under a file, an existing file as the output folder ---------------------------
@pytest.mark.parametrize("rig", sorted(CONFIGS))
@pytest.mark.parametrize("where", ["under a file", "a file"])
def test_bad_output_path(rig, where, records, tmp_path, capsys):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(CONFIGS[rig])
    data = tmp_path / "rec.csv"
    records[rig].to_csv(data, index=False)
    blocker = tmp_path / "taken"
    blocker.write_text("x")
    out = blocker / "id" if where == "under a file" else blocker
    before = snapshot(tmp_path)
    assert main(["identify", "--config", str(cfg), "--data", str(data), *IDENTIFY[rig], "--out", str(out)]) == 2
    assert "error: --out" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


# ---- failures are failures: a filter run that breaks exits 1 and writes nothing ------------------
FAILING = {
    "multiposition": lambda d: _set(d, "Ax", 30, 1e200),     # an absurd sample: the EKF's state overflows
    "sled": lambda d: _set(d, "fy", 30, 1e300),              # the navigation overflows
    "lowprec_centrifuge": lambda d: _set(d, "fE", 300, 1e300),  # (f/g0)^2 overflows: the filter's F is not finite
}


@pytest.mark.parametrize("rig", sorted(FAILING))
def test_failed_run_exits_1_and_writes_nothing(rig, records, tmp_path, capsys):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(CONFIGS[rig])
    data = tmp_path / "rec.csv"
    FAILING[rig](records[rig].copy()).to_csv(data, index=False)
    before = snapshot(tmp_path)
    with np.errstate(all="ignore"):
        rc = main(["identify", "--config", str(cfg), "--data", str(data), *IDENTIFY[rig], "--out", str(tmp_path / "id")])
    err = capsys.readouterr().err
    assert rc == 1, err
    assert "failed" in err and "Nothing was written" in err and "Traceback" not in err
    assert snapshot(tmp_path) == before


def test_studies_flag_and_count_failed_runs():
    """Sled and lowprec studies: failed runs are flagged, counted and left out of the tables."""
    from platcal.rigs.lowprec_centrifuge.scenario import failed_fits
    from platcal.rigs.lowprec_centrifuge.study import drop_failed
    from platcal.rigs.sled.study import split_failed, table1

    x = np.array([[1.0, 2.0], [np.nan, 1.0], [1.0, 1.0]])
    P = np.array([np.eye(2), np.eye(2), [[1.0, 2.0], [2.0, 1.0]]])   # the third is not positive definite
    assert failed_fits(x, P).tolist() == [False, True, True]
    assert failed_fits(x).tolist() == [False, True, False]
    coeffs = pd.DataFrame({"seed": [0, 0, 1, 1], "platform": "P1", "method": "proposed", "run": "run1",
                           "coefficient": ["kA_x", "k2_x"] * 2, "estimate": [1.0, 2.0, np.nan, 3.0],
                           "failed": [False, False, True, True]})
    cross = pd.DataFrame({"seed": [0, 1], "effect_pct": [90.0, np.nan], "failed": [False, True]})
    c, k, n = drop_failed(cross, coeffs)
    assert n == 1 and len(k) == 2 and c["effect_pct"].tolist() == [90.0]
    from platcal.rigs.sled.study import TABLE1_COLUMNS

    m = pd.DataFrame({"seed": [0, 1, 2], "failed": [False, True, False],
                      **{k: [1.0, np.nan, 3.0] for k, _ in TABLE1_COLUMNS}})
    ok, failed = split_failed({"default": m})
    assert failed == {"default": 1} and ok["default"]["seed"].tolist() == [0, 2]
    assert table1(ok, failed).loc[0, "failed runs"] == 1
