"""A sweep of bad inputs through the centrifuge CLI (issue 13): configs, records and output paths.

Every case must exit with status 2, name the field or column in stderr, and write nothing: the
folder the case runs in holds exactly the same files (names and bytes) before and after. The
record is built directly (no simulation), so a case that is not refused before the filter starts
shows up as a slow run and a failed assertion, not as a pass.
"""

import os
import shutil

import numpy as np
import pandas as pd
import pytest

from platcal.cli import main
from centrifuge_short import SHORT_POSITIONS, short_config, with_sections
from file_snapshot import snapshot

SCHEME = SHORT_POSITIONS
BASE = short_config(passes=1)
SAMPLE_S = 0.005


def record(n: int = 800) -> pd.DataFrame:
    """A record of the 'short' scheme with the right layout (values need not be physical)."""
    K = len(SCHEME)
    cmd = np.array(SCHEME, float)
    rng = np.random.default_rng(0)
    return pd.DataFrame({
        "position": np.repeat(np.arange(1, K + 1), n),
        "t": np.tile(np.arange(n) * SAMPLE_S, K),
        "alpha_cmd": np.repeat(cmd[:, 0], n), "beta_cmd": np.repeat(cmd[:, 1], n),
        "gamma_cmd": np.repeat(cmd[:, 2], n),
        # about the 10 g centripetal + 1 g gravity a position measures (the magnitude is checked)
        "Ax": 10 + rng.normal(0, 0.1, K * n), "Ay": rng.normal(0, 0.1, K * n), "Az": 1 + rng.normal(0, 0.1, K * n),
    })


def with_section(text: str) -> str:
    """BASE with the top-level sections of ``text`` replacing (or added to) BASE's."""
    return with_sections(BASE, text)


# ---- configs: (config text, command, expected field) --------------------------------------------
CONFIGS = {
    "inf noise": (with_section("noise: {sigma_a_ug: .inf}"), "simulate", "noise.sigma_a_ug"),
    "nan p0": (with_section("filter: {p0: {DF: .nan}}"), "identify", "filter.p0.DF"),
    "nan period": (with_section("filter: {period_ms: .nan}"), "identify", "filter.period_ms"),
    "nan latitude": (with_section("site: {latitude_deg: .nan}"), "simulate", "site.latitude_deg"),
    "inf truth": (with_section("truth: {DF_x: .inf}"), "simulate", "truth.DF_x"),
    "-inf rate": (with_section("centrifuge: {rate_deg_s: -.inf}"), "simulate", "centrifuge.rate_deg_s"),
    "nan dwell": (with_section("schemes:\n  short: {dwell_s: .nan, positions: [[45, 0, 167]]}"), "simulate",
                  "schemes.short.dwell_s"),
    "nan angle": (with_section("schemes:\n  short: {dwell_s: 4, positions: [[45, .nan, 167]]}"), "simulate",
                  "schemes.short.positions[1]"),
    "nan study noise": (with_section("study: {sigma_a_ug: [.nan]}"), "simulate", "study.sigma_a_ug[0]"),
    "nan filter R": (with_section("filter: {sigma_a_ug: .nan}"), "identify", "filter.sigma_a_ug"),
    "zero max gap": (with_section("record: {max_gap_s: 0}"), "identify", "record.max_gap_s"),
    "nan max gap": (with_section("record: {max_gap_s: .nan}"), "identify", "record.max_gap_s"),
    "unknown record key": (with_section("record: {max_gap: 1}"), "identify", "record"),
    "unknown coefficient": (with_section("truth: {DF_q: 1.0}"), "simulate", "truth.DF_q"),
    "passes not a number": (with_section("filter: {passes: two}"), "identify", "filter.passes"),
    "period not a multiple": (with_section("filter: {period_ms: 7}"), "identify", "filter.period_ms"),
    "negative seed": (with_section("seed: -1"), "simulate", "seed"),
    "not a mapping": ("- 1\n- 2\n", "simulate", "(top level)"),
    "yaml syntax": ("schemes: {short: [\n", "simulate", "--config"),
    "key given twice": (BASE + "seed: 1\nseed: 2\n", "simulate", "--config"),
    "binary config": (b"\xff\xfe\x00\x01rig: centrifuge\n\x89PNG", "simulate", "--config"),
    "parquet as config": (None, "simulate", "--config"),
    "missing config": ("", "simulate", "--config"),
}


@pytest.mark.parametrize("case", sorted(CONFIGS))
def test_bad_config(case, tmp_path, capsys):
    text, command, field = CONFIGS[case]
    cfg = tmp_path / "config.yaml"
    if case == "parquet as config":
        record().to_parquet(cfg)
    elif isinstance(text, bytes):
        cfg.write_bytes(text)
    elif case != "missing config":
        cfg.write_text(text)
    data = tmp_path / "run.csv"
    record().to_csv(data, index=False)
    before = snapshot(tmp_path)
    if command == "simulate":
        argv = ["simulate", "--config", str(cfg), "--scheme", "short", "--out", str(tmp_path / "new.csv")]
    else:
        argv = ["identify", "--config", str(cfg), "--scheme", "short", "--data", str(data),
                "--out", str(tmp_path / "id")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"error: {field}" in err, err
    assert "np." not in err and "Traceback" not in err
    assert snapshot(tmp_path) == before


# ---- records: how to spoil the clean record, expected column/field ------------------------------
def _rows(df, k):
    return df.index[df["position"] == k]


def _t_ms(df):
    df["t"] *= 1000.0


def _t_back(df):
    df.loc[5, "t"] = df.loc[3, "t"]


def _gap(df):
    r = _rows(df, 2)
    df.loc[r[400:], "t"] += 10.0  # 10 s gap, dwell otherwise right


def _small_gap_too_big(df):
    r = _rows(df, 3)
    return df.drop(r[300:330])  # 0.155 s without samples > 0.1 s


def _late_start(df):
    return df.drop(_rows(df, 1)[:100])  # the first 0.5 s of position 1 missing


def _short_dwell(df):
    return df.drop(df.index[df["t"] >= 2.0])


def _long_dwell(df):
    extra = df[df["t"] < 2.0].copy()
    extra["t"] += 4.0
    return pd.concat([df, extra]).sort_values(["position", "t"]).reset_index(drop=True)


def _one_sample(df):
    return df.drop(df.index[df["t"] > 0])


def _missing_position(df):
    return df.drop(_rows(df, 3))


def _position_7(df):
    df.loc[df.index[-1], "position"] = 7


def _position_fraction(df):
    df["position"] = df["position"].astype(float)
    df.loc[10, "position"] = 1.5


def _wrong_angles(df):
    df.loc[_rows(df, 2), "alpha_cmd"] = 10.0


def _nan_ax(df):
    df.loc[10, "Ax"] = np.nan


def _inf_t(df):
    df.loc[11, "t"] = np.inf


def _text_az(df):
    df["Az"] = df["Az"].astype(object)
    df.loc[20, "Az"] = "oops"


def _no_ay(df):
    return df.drop(columns=["Ay"])


def _extra_col(df):
    df["temperature"] = 20.0


def _half_truth(df):
    df["alpha"] = 0.0


def _nan_cmd(df):
    df.loc[30, "beta_cmd"] = np.nan


def _m_s2(df):
    df[["Ax", "Ay", "Az"]] *= 9.80665


def _mg(df):
    df.loc[_rows(df, 2), ["Ax", "Ay", "Az"]] *= 1000.0


def _huge(df):
    df["Ax"] = 1e300


RECORDS = {
    "accelerations 1e300": (_huge, "columns Ax, Ay, Az, position 1", "csv"),
    "accelerations in m/s^2": (_m_s2, "columns Ax, Ay, Az, position 1", "csv"),
    "accelerations in mg": (_mg, "columns Ax, Ay, Az, position 2", "csv"),
    "t in ms": (_t_ms, "column t, position 1", "csv"),
    "t not increasing": (_t_back, "column t, position 1", "csv"),
    "10 s gap": (_gap, "column t, position 2", "csv"),
    "gap over the limit": (_small_gap_too_big, "column t, position 3", "csv"),
    "first 0.5 s missing": (_late_start, "column t, position 1", "csv"),
    "dwell 2 s of 4": (_short_dwell, "column t, position 1", "csv"),
    "dwell 6 s of 4": (_long_dwell, "column t, position 1", "csv"),
    "one sample per position": (_one_sample, "column t, position 1", "csv"),
    "position missing": (_missing_position, "column position", "csv"),
    "position 7": (_position_7, "column position", "csv"),
    "position 1.5": (_position_fraction, "column position", "csv"),
    "commanded angles of another scheme": (_wrong_angles, "--data position 2", "csv"),
    "nan Ax": (_nan_ax, "column Ax, row 12", "csv"),
    "inf t": (_inf_t, "column t, row 13", "csv"),
    "text in Az": (_text_az, "column Az, row 22", "csv"),
    "missing column": (_no_ay, "column Ay", "csv"),
    "extra column": (_extra_col, "column temperature", "csv"),
    "half the truth columns": (_half_truth, "column beta", "csv"),
    "nan commanded angle": (_nan_cmd, "column beta_cmd", "csv"),
    "parquet: t in ms": (_t_ms, "column t, position 1", "parquet"),
    "parquet: position missing": (_missing_position, "column position", "parquet"),
    "parquet: nan Ax": (_nan_ax, "column Ax", "parquet"),
}


@pytest.mark.parametrize("case", sorted(RECORDS))
def test_bad_record(case, tmp_path, capsys):
    spoil, field, fmt = RECORDS[case]
    cfg = tmp_path / "config.yaml"
    cfg.write_text(BASE)
    df = record()
    new = spoil(df)
    df = df if new is None else new  # a spoiler edits in place or returns a new table
    data = tmp_path / f"run.{fmt}"
    df.to_parquet(data) if fmt == "parquet" else df.to_csv(data, index=False)
    before = snapshot(tmp_path)
    argv = ["identify", "--config", str(cfg), "--scheme", "short", "--data", str(data), "--out", str(tmp_path / "id")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert field in err, err
    assert "np." not in err and "Traceback" not in err
    assert snapshot(tmp_path) == before


# ---- files that are not what they are named, and truncated files --------------------------------
def _parquet_named_csv(path):
    record().to_parquet(path)


def _csv_named_parquet(path):
    record().to_csv(path, index=False)


def _binary(path):
    path.write_bytes(bytes(range(256)) * 10)


def _utf16(path):
    path.write_bytes(record().head(20).to_csv(index=False).encode("utf-16"))


def _truncated(path):
    text = record().to_csv(index=False)
    path.write_text(text[: text.rindex(",", 0, len(text) - 30)])


def _empty(path):
    path.write_text("")


def _header_only(path):
    path.write_text(",".join(record().columns) + "\n")


def _folder(path):
    path.mkdir()


def _truncated_parquet(path):
    record().to_parquet(path)
    path.write_bytes(path.read_bytes()[:-100])


def _semicolons(path):
    path.write_text(record().to_csv(index=False, sep=";"))


FILES = {
    "semicolon-separated": (_semicolons, "run.csv", "not comma-separated"),
    "parquet named .csv": (_parquet_named_csv, "run.csv", "Parquet"),
    "csv named .parquet": (_csv_named_parquet, "run.parquet", "not a Parquet"),
    "binary named .csv": (_binary, "run.csv", "UTF-8"),
    "UTF-16 csv": (_utf16, "run.csv", "UTF-8"),
    "truncated last line": (_truncated, "run.csv", "truncated"),
    "empty file": (_empty, "run.csv", "--data"),
    "header only": (_header_only, "run.csv", "no rows"),
    "data is a folder": (_folder, "run.csv", "folder"),
    "truncated parquet": (_truncated_parquet, "run.parquet", "--data"),
    "no such file": (lambda p: None, "run.csv", "no such file"),
}


@pytest.mark.parametrize("case", sorted(FILES))
def test_bad_record_file(case, tmp_path, capsys):
    make, name, words = FILES[case]
    cfg = tmp_path / "config.yaml"
    cfg.write_text(BASE)
    data = tmp_path / name
    make(data)
    before = snapshot(tmp_path)
    argv = ["identify", "--config", str(cfg), "--scheme", "short", "--data", str(data), "--out", str(tmp_path / "id")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "error: --data" in err and words in err, err
    assert snapshot(tmp_path) == before


# ---- output paths and options ------------------------------------------------------------------
def _out_under_file(tmp):
    (tmp / "afile").write_text("x")
    return str(tmp / "afile" / "sub" / "out")


def _out_is_file(tmp):
    (tmp / "afile").write_text("x")
    return str(tmp / "afile")


def _out_is_folder(tmp):
    (tmp / "adir").mkdir()
    return str(tmp / "adir")


def _out_read_only(tmp):
    (tmp / "ro").mkdir()
    os.chmod(tmp / "ro", 0o555)
    return str(tmp / "ro" / "out")


OUTPUTS = {
    "identify: parent is a file": ("identify", _out_under_file, "--out"),
    "identify: out is a file": ("identify", _out_is_file, "--out"),
    "identify: read-only folder": ("identify", _out_read_only, "--out"),
    "simulate: parent is a file": ("simulate", _out_under_file, "--out"),
    "simulate: out is a folder": ("simulate", _out_is_folder, "--out"),
    "simulate: read-only folder": ("simulate", _out_read_only, "--out"),
    "observability: parent is a file": ("observability", _out_under_file, "--out"),
    "montecarlo: parent is a file": ("montecarlo", _out_under_file, "--out"),
    "identify: unknown --estimator": ("identify", lambda tmp: str(tmp / "id"), "--estimator"),
    "simulate: --platform not used": ("simulate", lambda tmp: str(tmp / "x.csv"), "--platform"),
    "simulate: negative seed": ("simulate", lambda tmp: str(tmp / "x.csv"), "--seed"),
    "identify: unknown scheme": ("identify", lambda tmp: str(tmp / "id"), "--scheme"),
}


@pytest.mark.parametrize("case", sorted(OUTPUTS))
def test_bad_output_or_option(case, tmp_path, capsys):
    command, make, field = OUTPUTS[case]
    if "read-only" in case and os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    cfg = tmp_path / "config.yaml"
    cfg.write_text(BASE)
    data = tmp_path / "run.csv"
    record().to_csv(data, index=False)
    out = make(tmp_path)
    before = snapshot(tmp_path)
    argv = [command, "--config", str(cfg), "--scheme", "nope" if "unknown scheme" in case else "short",
            "--out", out]
    if command == "identify":
        argv += ["--data", str(data)]
    if command == "montecarlo":
        argv += ["--noise", "10", "--estimator", "ekf1"]
    if "--estimator" in case:  # neither a kind nor a name of study.estimators
        argv += ["--estimator", "nosuch"]
    if "--platform" in case:
        argv += ["--platform", "x"]
    if "negative seed" in case:
        argv += ["--seed", "-1"]
    try:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"error: {field}" in err, err
        assert snapshot(tmp_path) == before
    finally:
        if (tmp_path / "ro").exists():
            os.chmod(tmp_path / "ro", 0o755)
            shutil.rmtree(tmp_path / "ro")


def test_read_only_folder_refused_whoever_runs(tmp_path, monkeypatch, capsys):
    """The writability probe's failure (as a read-only folder or file system gives it) becomes exit 2."""
    import tempfile

    def refuse(*args, **kw):
        raise PermissionError(13, "Permission denied")

    cfg = tmp_path / "config.yaml"
    cfg.write_text(BASE)
    before = snapshot(tmp_path)
    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    code = main(["simulate", "--config", str(cfg), "--scheme", "short", "--out", str(tmp_path / "x.csv")])
    assert code == 2
    assert "error: --out: cannot write in" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


def test_sweep_has_at_least_40_cases():
    assert len(CONFIGS) + len(RECORDS) + len(FILES) + len(OUTPUTS) + len(PIPELINE) >= 40


# ---- failures are failures ---------------------------------------------------------------------
def test_failed_filter_run_exits_1_and_writes_nothing(tmp_path, capsys):
    """P0 of 1e200 deg/h overflows the covariance: every update fails; no result folder appears."""
    cfg = tmp_path / "config.yaml"
    cfg.write_text(with_section("filter: {period_ms: 20, passes: 1, p0: {DF: 1.0e200}}"))
    data = tmp_path / "run.csv"
    record().to_csv(data, index=False)
    before = snapshot(tmp_path)
    with pytest.warns(RuntimeWarning):
        code = main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(data),
                     "--out", str(tmp_path / "id")])
    assert code == 1
    err = capsys.readouterr().err
    assert "failed" in err and "measurement update(s) failed" in err and "np." not in err
    assert snapshot(tmp_path) == before


def test_run_problems_names_each_kind_of_failure():
    from platcal.rigs.centrifuge.ekf import Estimate
    from platcal.rigs.centrifuge.identify import run_problems

    n = 4
    names = ("DF_x", "DF_y", "alpha", "beta", "gamma")[:n]

    def est(x, P, bad):
        z = np.zeros((1, 0, n))
        return Estimate(names=names, x=x[None], P=P[None], history_t=np.zeros(0), history_x=z, history_sigma=z,
                        pass_x=x[None, None], pass_P=P[None, None], mean_nis=np.array([3.0]),
                        failed_updates=np.array([bad], dtype=np.int64))

    good = est(np.ones(n), np.eye(n), 0)
    assert run_problems(good) == []
    assert "2 measurement update(s) failed" in run_problems(est(np.ones(n), np.eye(n), 2))[0]
    x = np.ones(n)
    x[1] = np.nan
    assert "non-finite estimate(s) (DF_y)" in run_problems(est(x, np.eye(n), 0))[0]
    P = np.eye(n)
    P[0, 0] = -1.0
    assert run_problems(est(np.ones(n), P, 0)) == ["the final covariance is not positive definite"]
    P[0, 0] = np.inf
    assert run_problems(est(np.ones(n), P, 0)) == ["the covariance has non-finite entries"]


# ---- the pipeline's checks: every cross-reference before any job ---------------------------------
STUDY = ("study:\n  schemes: [short, classical]\n  sigma_a_ug: [10, 50]\n  paper: {scheme: short, estimator: ekf1}\n"
         "  single: {scheme: short}\n")
PIPELINE = {
    "paper estimator unknown": (STUDY.replace("estimator: ekf1", "estimator: ekf9"), "study.paper.estimator"),
    "paper scheme not swept": (STUDY.replace("paper: {scheme: short", "paper: {scheme: nope"), "study.paper.scheme"),
    "paper noise not swept": (STUDY.replace("}\n", ", sigma_a_ug: 7}\n"), "study.paper.sigma_a_ug"),
    "paper default noise not swept": (STUDY.replace("[10, 50]", "[20, 50]"), "study.paper.sigma_a_ug"),
    "unknown generated scheme": (STUDY.replace("classical]", "classical, ga_nonexistent]"), "study.schemes[2]"),
    "nan noise level": (STUDY.replace("[10, 50]", "[10, .nan]"), "study.sigma_a_ug[1]"),
    "single estimator unknown": (STUDY.replace("{scheme: short}", "{scheme: short, estimator: ekf7}"),
                                 "study.single.estimator"),
}


@pytest.mark.parametrize("case", sorted(PIPELINE))
def test_bad_study_section_refused_by_the_pipeline_check(case):
    from platcal.errors import InputError
    from platcal.io import read_yaml
    from platcal.rigs.centrifuge.study import check_study

    text, field = PIPELINE[case]
    with pytest.raises(InputError) as e:
        check_study(read_yaml(with_section(text)))
    assert e.value.field == field, e.value


def test_good_study_section_passes_the_pipeline_check():
    from platcal.io import read_yaml
    from platcal.rigs.centrifuge.study import check_study

    cfg = check_study(read_yaml(with_section(STUDY.replace("classical]", "classical, ga_J_n8, ga_doo]"))))
    assert cfg["study"]["paper"]["scheme"] == "short"


def test_inconsistent_filter_is_reported():
    from platcal.rigs.centrifuge.identify import consistency_warning

    warning = consistency_warning({"nees": 5.0e5, "nees_dof": 45})
    assert "NEES 5e+05 for 45 dof" in warning and "filter.passes: 2" in warning
    assert consistency_warning({"nees": 40.0, "nees_dof": 45}) is None  # chi2(45) 99.9 %: 80.1
    assert consistency_warning({"n_states": 48}) is None  # no truth: no NEES


def test_monte_carlo_flags_failed_runs_and_the_summary_counts_them():
    from platcal.rig import ReplicateBatch
    from platcal.study.montecarlo import tidy_frames
    from platcal.study.stats import summary

    q = pd.DataFrame({"name": ["a", "b"], "group": ["g1", "g1"], "unit": ["m", "s"], "truth": [1.0, 2.0]})
    est = np.array([[1.1, 2.0], [np.nan, 2.0], [1.0, 2.1], [1.0, 2.0]])
    batch = ReplicateBatch(quantities=q, estimate=est, sigma=np.ones((4, 2)),
                           nees=np.array([1.0, np.nan, 2.0, 1.5]), nees_dof=2, mean_nis=np.ones(4),
                           failed_updates=np.array([0, 0, 3, 0]), passes=1)
    coef, runs = tidy_frames(batch, "case", 2.5, "kf", [0, 1, 2, 3])
    assert runs["failed"].tolist() == [False, True, True, False]
    summ = summary(coef, runs)
    assert summ["failed_runs"].tolist() == [2] and summ["failed_updates"].tolist() == [3]
