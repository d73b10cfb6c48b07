"""Monte Carlo machinery: seeding, study schemes, validation, cells, statistics, figures."""

import ast
import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from platcal.errors import InputError
from platcal.rig import get_rig
from platcal.estimation.consistency import nees_band
from platcal.rigs.centrifuge import RIG
from platcal.rigs.centrifuge import report
from platcal.rigs.centrifuge import study as mc
from platcal.seeding import stable_key
from platcal.study import montecarlo as smc
from platcal.study import nees_figure, plots, stats, sweep
from platcal.study.tables import frame_markdown
from platcal.model.frames import DEG, c_rp
from platcal.io import normalise_numbers, read_yaml

BASE = {
    "seed": 7,
    "schemes": {"table1": {"dwell_s": 2, "positions": [[45, 0, 167], [350, 0, 325], [209, 0, 182],
                                                         [134, 0, 141], [106, 0, 338], [142, 0, 269]]}},
    "study": {"schemes": ["table1", "classical", "random"], "dwell_s": 2, "random_schemes": {"count": 2},
              "sigma_a_ug": [10, 50], "replicates": 5, "batch": 2},
}


def cfg(**study):
    raw = json.loads(json.dumps(BASE))
    raw["study"].update(study)
    return mc.check_study(raw)


def test_stable_key_is_sha256_not_python_hash():
    assert stable_key("table1") == int.from_bytes(hashlib.sha256(b"table1").digest()[:4], "big")
    assert sweep.noise_key(10) == 10000 and sweep.noise_key(2.5) == 2500


def test_replicate_seeds_distinct_and_keyed_by_level_not_index():
    s = {tuple(smc.replicate_seed(1, sc, sa, r).generate_state(2))
         for sc in ("table1", "classical") for sa in (5, 10) for r in range(3)}
    assert len(s) == 12
    a = smc.replicate_seed(1, "table1", 10, 2)
    assert a.spawn_key == (stable_key("table1"), 10000, 2) and a.entropy == 1


def test_classical_scheme_puts_each_axis_up_and_down():
    sch = mc.classical_scheme(60)
    ups = [c_rp(a * DEG, b * DEG, g * DEG)[:, 2] for a, b, g in sch.positions]
    expected = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]]
    np.testing.assert_allclose(ups, expected, atol=1e-12)


def test_random_schemes_do_not_depend_on_count():
    a = mc.random_schemes(3, 2, 6, 60)
    b = mc.random_schemes(3, 4, 6, 60)
    assert a[1].positions == b[1].positions and a[0].positions != a[1].positions
    for s in b:
        ang = s.angles_deg
        assert np.all(ang[:, 1] == 0) and ang.min() >= 0 and ang.max() <= 359


def test_scheme_names_expand_random_and_accept_generated():
    c = cfg(schemes=["table1", "random", "ga_J", "classical"])
    assert mc.scheme_names(c) == ["table1", "random_1", "random_2", "ga_J", "classical"]
    assert mc.is_generated("ga_J", c["study"]) and not mc.is_generated("table1", c["study"])


@pytest.mark.parametrize("study, field", [
    ({"replicates": "ten"}, "study.replicates"),
    ({"sigma_a_ug": [10, -5]}, "study.sigma_a_ug[1]"),
    ({"schemes": ["table1", "nosuch"]}, "study.schemes[1]"),
    ({"schemes": ["random_3"]}, "study.schemes[0]"),
    ({"estimators": {"ekf1": {"passes": 0}}}, "study.estimators.ekf1.passes"),
    ({"single": {"estimator": "ukf"}}, "study.single.estimator"),
    ({"sigma_a_ug": [10, 10.0]}, "study.sigma_a_ug"),
    ({"backend": "dask"}, "study.backend"),
    ({"bogus": 1}, "study"),
])
def test_bad_study_names_the_field(study, field):
    with pytest.raises(InputError) as e:
        cfg(**study)
    assert e.value.field == field


def test_normalise_numbers_reads_yaml11_floats():
    d = {"a": "1.0e4", "b": ["2e3", "x1e3"], "c": {"d": "table1"}}
    assert normalise_numbers(d) == {"a": 1e4, "b": [2e3, "x1e3"], "c": {"d": "table1"}}


def test_code_hash_covers_the_compute_closure_only():
    mods = {m.rsplit(".", 1)[-1] for m in smc.module_closure([type(RIG.montecarlo).__module__, smc.__name__])}
    assert {"montecarlo", "study", "simulate", "ekf", "kalman", "attitude", "frames", "config", "scheme"} <= mods
    assert not {"plots", "report", "design", "cli"} & mods
    assert smc.code_hash() != smc.compute_code_hash(RIG) and len(smc.compute_code_hash(RIG)) == 16
    assert smc.code_hash(["platcal.study.plots"]) != smc.code_hash()


@pytest.mark.parametrize("rig", ["multiposition", "sled"])
def test_code_hash_follows_a_kernel_named_by_path(rig):
    # the lanes kernels are imported only as a batch runs (f"{__package__}.filter_lanes:..."): an
    # edit of them must rerun the rig's cells like an edit of an imported module
    mods = smc.module_closure([type(get_rig(rig).montecarlo).__module__, smc.__name__])
    assert f"platcal.rigs.{rig}.filter_lanes" in mods


def test_a_path_of_the_files_own_package_is_read_as_an_import(tmp_path):
    f = tmp_path / "mod.py"
    f.write_text('KERNEL = f"{__package__}.kernels:run"\nOTHER = f"{__package__}.x"\nFIG = "platcal.logs.f:g"\n')
    st = f.stat()
    assert smc._platcal_imports(f, "platcal.rigs.r", (st.st_mtime_ns, st.st_size)) == ("platcal.rigs.r.kernels",)


def test_import_reading_is_cached_but_an_edited_file_is_read_again(tmp_path):
    # the master reads each module's imports once for all closures; an edit (new mtime or size)
    # within the same process must not be hidden by that cache
    f = tmp_path / "mod.py"
    f.write_text("from .io import read_yaml\n")
    st = f.stat()
    first = smc._platcal_imports(f, "platcal.study", (st.st_mtime_ns, st.st_size))
    assert first == ("platcal.study.io", "platcal.study.io.read_yaml")
    assert smc._platcal_imports(f, "platcal.study", (st.st_mtime_ns, st.st_size)) is first
    f.write_text("import platcal.rig\nfrom ..plausibility import clock_rate\n")
    st = f.stat()
    assert smc._platcal_imports(f, "platcal.study", (st.st_mtime_ns, st.st_size)) == (
        "platcal.rig", "platcal.plausibility", "platcal.plausibility.clock_rate")


def test_imports_nested_anywhere_in_the_statements_are_read(tmp_path):
    f = tmp_path / "mod.py"
    f.write_text("def f():\n    if x:\n        from .a import b\n    else:\n        import platcal.c\n"
                 "class K:\n    def g(self):\n        try:\n            pass\n        except E:\n"
                 "            from . import d\n        finally:\n            from .e import h\n"
                 "for i in y:\n    pass\nelse:\n    with z:\n        from .m import n\n"
                 "match v:\n    case 1:\n        from .p import q\n")
    st = f.stat()
    got = smc._platcal_imports(f, "platcal.study", (st.st_mtime_ns, st.st_size))
    assert set(got) == {"platcal.study.a", "platcal.study.a.b", "platcal.c", "platcal.study", "platcal.study.d",
                        "platcal.study.e", "platcal.study.e.h", "platcal.study.m", "platcal.study.m.n",
                        "platcal.study.p", "platcal.study.p.q"}


def test_the_statement_walk_finds_every_import_a_full_walk_finds_in_the_package():
    # the master reads imports from the statements alone (issue 22 item 4): on every module of
    # the package it must find what a walk of every node finds, or an edit would leave a stale cell
    root = Path(smc.__file__).resolve().parents[1]
    for f in root.rglob("*.py"):
        tree = ast.parse(f.read_text())
        every = {type(n).__name__ + ast.dump(n) for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))}
        stmts = {type(n).__name__ + ast.dump(n) for n in smc._statements(tree.body)
                 if isinstance(n, (ast.Import, ast.ImportFrom))}
        assert stmts == every, f


@pytest.fixture(scope="module")
def small_cell():
    c = cfg(replicates=4, batch=4)
    sch = mc.builtin_scheme(c, "table1")
    return c, sch, smc.run_cell(RIG, c, sch, 20, "ekf1", threads=1)


def test_cell_tidy_frames(small_cell):
    c, sch, (coef, runs, timing) = small_cell
    assert list(coef.columns) == smc.COEF_COLUMNS and list(runs.columns) == smc.RUN_COLUMNS
    assert len(coef) == 4 * 45 and len(runs) == 4
    assert coef["replicate"].tolist() == sorted(coef["replicate"])
    np.testing.assert_allclose(coef["error"], coef["estimate"] - coef["truth"])
    assert np.all(np.isfinite(runs["nees"])) and (runs["nees_dof"] == 45).all()
    assert timing["replicates"] == 4 and timing["wall_s"] > 0


def test_cell_does_not_depend_on_batch_threads_or_backend(small_cell):
    c, sch, (coef, runs, _) = small_cell
    for kw in ({"batch": 1, "threads": 2}, {"batch": 3, "threads": 2, "backend": "joblib"}):
        coef2, runs2, _ = smc.run_cell(RIG, c, sch, 20, "ekf1", **kw)
        pd.testing.assert_frame_equal(coef, coef2, check_exact=True)
        pd.testing.assert_frame_equal(runs, runs2, check_exact=True)


def test_single_run_is_the_sweeps_replicate(small_cell):
    c, sch, (coef, _, _) = small_cell
    study, est, _ = mc.run_single(c, sch, 20, "ekf1", 2)
    np.testing.assert_array_equal(est.coef[0], coef.loc[coef["replicate"] == 2, "estimate"].to_numpy())
    h = mc.history_frame(est, sch)
    assert set(h["state"]) == set(est.names) and h["position"].between(1, 6).all()


def test_estimators_share_the_data_and_pass_one_is_the_paper_filter(small_cell):
    c, sch, (coef, _, _) = small_cell
    _, est, _ = mc.run_single(c, sch, 20, "ekf2", 0)
    # the first pass of the 2-pass filter is the 1-pass filter on the same data
    np.testing.assert_allclose(est.pass_x[0, 0], coef.loc[coef["replicate"] == 0, "estimate"], rtol=0, atol=0)


def synthetic(n_rep=20, seed=0):
    from platcal.model.instruments import NAMES, group_of
    from platcal.rigs.centrifuge.catalogue import load_catalogue

    rng = np.random.default_rng(seed)
    truth = load_catalogue().truth
    rows, runs = [], []
    for est in ("ekf1", "ekf2"):
        for r in range(n_rep):
            rel = rng.normal(0, 1, 45)
            for i, n in enumerate(NAMES):
                e = truth[i] * (1 + rel[i] / 100)
                rows.append(dict(scheme="table1", noise=10.0, estimator=est, replicate=r, name=n,
                                 group=group_of(n), unit="u", truth=truth[i], estimate=e, sigma=abs(truth[i]) / 100,
                                 error=e - truth[i], rel_err_pct=rel[i]))
            runs.append(dict(scheme="table1", noise=10.0, estimator=est, replicate=r, passes=1,
                             nees=float(rng.chisquare(45)), nees_dof=45, mean_nis=3.0, failed_updates=0))
    return pd.DataFrame(rows), pd.DataFrame(runs)


def test_stats_tables():
    coef, runs = synthetic()
    t = report.table2_montecarlo(coef, "table1", 10, "ekf1")
    assert len(t) == 45 and t["coefficient"].iloc[0] == "DF_x" and t["coefficient"].iloc[-1] == "theta_oz"
    assert (t["n"] == 20).all()
    np.testing.assert_allclose(t["mean_rel_sigma_pct"], 1.0)
    assert 0.5 < t["std_rel_err_pct"].mean() < 1.5
    np.testing.assert_allclose(t["paper_z"], (t["paper_rel_err_pct"] - t["mean_rel_err_pct"]) / t["std_rel_err_pct"])
    s = stats.summary(coef, runs)
    assert len(s) == 2 and {"max_rms_rel_err_pct_gyro", "share_in_band", "mean_nees"} <= set(s.columns)
    lo, hi = nees_band(45)
    assert lo == pytest.approx(28.366, abs=1e-3) and hi == pytest.approx(65.410, abs=1e-3)
    assert frame_markdown(s.head(1)).count("\n") == 3


def test_markdown_rows_are_what_iterrows_gives():
    """frame_markdown reads the rows of ``df.values`` (not a Series per row): the text is the
    former ``iterrows`` body's, e.g. an int beside a float column is read as a float, a mixed
    frame keeps each value's type, missing and infinite values print '-', booleans 1 and 0 (format 'g')."""
    mixed = pd.DataFrame({"i": [1, 2, 3], "f": [1.5, np.nan, np.inf], "s": ["a", None, "c"],
                          "b": [True, False, True]})
    assert frame_markdown(mixed).splitlines()[1:] == ["|---:|---:|---|---:|", "| 1 | 1.5 | a | 1 |",
                                                      "| 2 | - | - | 0 |", "| 3 | - | c | 1 |"]
    numeric = pd.DataFrame({"n": [7, 1234567], "x": [0.25, -2.0]})
    assert frame_markdown(numeric, {"n": ".1f"}).splitlines()[1:] == ["|---:|---:|", "| 7.0 | 0.25 |",
                                                                     "| 1234567.0 | -2 |"]
    assert frame_markdown(pd.DataFrame({"a": []})) == "| a |\n|---:|\n"


def test_figures_are_byte_stable(tmp_path):
    coef, runs = synthetic(5)
    for k in (1, 2):
        nees_figure.nees_histogram(runs, tmp_path / f"n{k}.png")
        plots.rms_vs_noise(coef, tmp_path / f"r{k}.png", report.GROUP_TITLES, RIG.montecarlo.noise.label)
    assert (tmp_path / "n1.png").read_bytes() == (tmp_path / "n2.png").read_bytes()
    assert (tmp_path / "r1.png").read_bytes() == (tmp_path / "r2.png").read_bytes()


def test_default_config_study_validates():
    from pathlib import Path

    raw = read_yaml((Path(__file__).parents[1] / "config" / "centrifuge.yaml").read_text())
    c = mc.check_study(raw)
    names = mc.scheme_names(c)
    assert names[:2] == ["table1", "classical"] and "random_1" in names


def test_package_code_hash_covers_a_rig_and_the_core_it_imports(monkeypatch):
    h = {r: smc.package_code_hash(f"platcal.rigs.{r}") for r in ("sled", "lowprec_centrifuge", "multiposition")}
    assert len(set(h.values())) == 3 and all(len(v) == 16 for v in h.values())
    # a shared module the rig imports is part of its hash: changing its bytes changes the hash
    seen = []
    real = smc.code_hash
    monkeypatch.setattr(smc, "code_hash", lambda mods, data=(): seen.append((list(mods), list(data))) or real(mods, data))
    smc.package_code_hash("platcal.rigs.sled")
    mods, data = seen[0]
    assert "platcal.io" in mods and "platcal.rigs.sled.filters" in mods
    # the claims ledger's file is the claims rule's, not the simulations'
    assert data == ["rigs/sled/data/config.schema.yaml"]
