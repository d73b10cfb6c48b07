"""What a command of one rig imports (issue 22 item 3: long logs in little memory): the commands
on a log (simulate, identify, inspect, compensate) load neither the figures (matplotlib), the
design search (pymoo), the exact rank test (sympy) nor scipy.stats; the study commands and the
claims are named by module path and imported only when chosen. Each check runs in a fresh
interpreter (this one has imported everything already)."""

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from platcal.estimation.consistency import chi2_quantile, normal_quantile
from platcal.rig import get_rig, resolve, rig_modules, rig_names

RIGS = sorted(rig_names())
ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("matplotlib", "pymoo", "sympy", "scipy.stats", "platcal.study.campaign")
"""(scipy.optimize is not here: the low-precision centrifuge's record needs scipy.interpolate, which loads it.)"""
LOG_COMMANDS = ("simulate", "identify", "inspect", "compensate")

PROBE = """
import json, sys
from platcal.cli import build_parser
from platcal.rig import get_rig
rig = get_rig(sys.argv[1])
build_parser(rig)
for name in sys.argv[2:]:
    rig.command(name)
print(json.dumps(sorted(m for m in {heavy} if m in sys.modules)))
"""


def loaded_after(rig: str, commands, heavy=HEAVY) -> list[str]:
    """The ``heavy`` modules loaded by a fresh interpreter that parses the rig's command line and
    resolves ``commands``."""
    out = subprocess.run([sys.executable, "-c", PROBE.format(heavy=heavy), rig, *commands], check=True,
                         capture_output=True, text=True)
    return json.loads(out.stdout)


@pytest.mark.parametrize("rig", RIGS)
def test_a_command_on_a_log_loads_no_figure_design_or_stats_library(rig):
    commands = [c for c in LOG_COMMANDS if c in get_rig(rig).commands]
    assert "identify" in commands
    assert loaded_after(rig, commands) == []


def test_a_study_command_loads_its_own_libraries_when_chosen():
    # the probe would see them: the centrifuge's design command searches with pymoo; its report
    # command rewrites report.md from the tables and draws nothing (issue 22 item 4)
    assert "pymoo" in loaded_after("centrifuge", ["design"])
    assert "matplotlib" not in loaded_after("centrifuge", ["report"])


@pytest.mark.parametrize("rig", RIGS)
def test_choosing_identify_loads_no_pandas(rig):
    """pandas is some 40 MB of a streamed identify's floor (issue 22 item 3): the modules an
    identify imports write its tables without it and name the ones that need it by module path."""
    assert "pandas" not in loaded_after(rig, ["identify"], heavy=("pandas",))


IDENTIFY_PROBE = """
import sys
from platcal.cli import main
code = main(sys.argv[1:])
print("pandas" in sys.modules)
sys.exit(code)
"""

SMALL = {
    "centrifuge": ("site: {latitude_deg: 28.2}\ncentrifuge: {rate_deg_s: 180, g_level: 10}\n"
                   "noise: {sigma_a_ug: 10, arw_deg_rth: 0.001, sigma_set_arcsec: 10}\n"
                   "schemes:\n  short: {dwell_s: 6, positions: [[45, 0, 167], [350, 0, 325], [209, 0, 182]]}\n",
                   ["--scheme", "short"]),
    "multiposition": ("rig: multiposition\nschemes: {small: {dwell_s: 6, positions: [[0, 0, 0], [90, 30, 0], "
                      "[180, -30, 90], [270, 20, 180], [45, 0, 270]]}}\n", ["--scheme", "small"]),
    "sled": ("rig: sled\ntrajectory: {static_after_s: 10}\n", []),
    "lowprec_centrifuge": ("rig: lowprec_centrifuge\nseed: 3\nplatforms: {P1: {kA_x: -40, k2_x: -8, kA_y: 25, k2_y: -5}}\n"
                           "runs: {P1: {run1: [4, 6]}}\nprofile: {rest_first_s: 10, rest_between_s: 20}\n"
                           "traditional: {levels_g: [4, 6], hold_s: 30, rest_last_s: 10}\n", []),
}
"""Small records of the rigs (as tests/test_fit_rigs.py's)."""
SIMULATE_ONLY = {"lowprec_centrifuge": ["--platform", "P1", "--run", "run1"]}
"""Options of a rig's simulate that its identify does not take (which run to write)."""


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
@pytest.mark.parametrize("rig", sorted(SMALL))
def test_an_identify_whole_and_streamed_loads_no_pandas(rig, suffix, tmp_path):
    """A whole identify of each rig and a streamed one (chunks of 500 rows) run in a fresh
    interpreter, CSV and Parquet, and leave pandas unloaded; both give the same estimates.csv."""
    text, opts = SMALL[rig]
    cfg = tmp_path / "config.yaml"
    cfg.write_text(text)
    rec = tmp_path / f"rec{suffix}"
    subprocess.run([sys.executable, "-m", "platcal.cli", "simulate", "--config", str(cfg), *opts,
                    *SIMULATE_ONLY.get(rig, []), "--seed", "1", "--out", str(rec)], check=True, capture_output=True)
    outs = []
    for chunks in ("0", "500"):
        out = tmp_path / f"id{chunks}"
        res = subprocess.run([sys.executable, "-c", IDENTIFY_PROBE, "identify", "--config", str(cfg), *opts,
                              "--data", str(rec), "--chunk-rows", chunks, "--out", str(out)],
                             capture_output=True, text=True)
        assert res.returncode == 0, res.stderr
        assert res.stdout.split() == ["False"], (chunks, res.stdout)
        outs.append((out / "estimates.csv").read_text())
    assert outs[0] == outs[1]


@pytest.mark.parametrize("rig", RIGS)
def test_command_and_extra_paths_resolve_inside_the_rig(rig):
    r = get_rig(rig)
    own = rig_modules()[rig]
    paths = [p for p in list(r.commands.values()) + list(r.extras.values()) if isinstance(p, str)]
    for p in paths:
        assert p.startswith(own + "."), p  # a rig names only its own modules (no rig imports another)
    for name in r.commands:
        assert callable(r.command(name))
    assert r.extra("claims") is None or hasattr(r.extra("claims"), "MEASURES")
    assert r.extra("no such capability", default="x") == "x"


def test_resolve_names_a_module_or_its_attribute():
    assert resolve("platcal.estimation.consistency:chi2_quantile") is chi2_quantile
    assert resolve("platcal.estimation.consistency").normal_quantile is normal_quantile
    assert resolve(len) is len


def test_quantiles_are_scipy_stats_bit_for_bit():
    qs = np.concatenate([np.linspace(1e-6, 1 - 1e-6, 401), [0.999, 0.975, 1 - 0.01 / 18]])
    for dof in (1, 2, 3, 6, 24, 45, 48, 1000, 350_000):
        assert [chi2_quantile(q, dof) for q in qs] == [float(stats.chi2.ppf(q, dof)) for q in qs]
    assert [normal_quantile(q) for q in qs] == [float(stats.norm.ppf(q)) for q in qs]


READ_PROBE = """
import json, sys
from platcal.records import iter_table
rows = sum(len(df) for df in iter_table(sys.argv[1], ("t", "a", "k"), ("s",), text=("s",), chunk_rows=1000))
print(json.dumps([rows, "pandas" in sys.modules]))
"""


def test_reading_a_record_does_not_load_pandas(tmp_path):
    """The streamed reader (platcal.records.iter_table, CSV and Parquet) in a fresh interpreter:
    pandas, some 40 MB of a command's floor, stays out."""
    n = 5000
    path = tmp_path / "log.csv"
    pd.DataFrame({"t": np.arange(n) * 0.005, "a": np.sin(np.arange(n)), "k": np.arange(n) // 700 + 1,
                  "s": np.where(np.arange(n) % 3 == 0, "on", "off")}).to_csv(path, index=False)
    parquet = tmp_path / "log.parquet"
    pd.read_csv(path).to_parquet(parquet, index=False)
    for p in (path, parquet):
        out = subprocess.run([sys.executable, "-c", READ_PROBE, str(p)], check=True, capture_output=True, text=True)
        assert json.loads(out.stdout) == [5000, False]


JOB_PROBE = """
import json, os, sys, tempfile
import numpy as np
import {module}
from platcal.io import atomic_write_csv
from platcal.lighttable import Table
from platcal.study.montecarlo import write_cell
with tempfile.TemporaryDirectory() as d:  # what the job writes: a series' CSV, a cell's Parquet
    atomic_write_csv(os.path.join(d, "s.csv"), {{"t": np.arange(3.0), "a": np.full(3, np.nan)}}, float_format="%.10g")
    write_cell(d, Table({{"x": np.ones(2)}}), Table({{"nees": np.ones(2), "estimator": ["a", "b"]}}), {{"wall_s": 1.0}})
print(json.dumps(sorted(m for m in {heavy!r} if m in sys.modules)))
"""


@pytest.mark.parametrize("module", ["platcal.rigs.sled.series", "platcal.rigs.centrifuge.compare_cells"])
def test_the_sled_series_and_comparison_cell_jobs_load_no_pandas_figure_or_stats_library(module):
    """Rule sled_series (one job per case) imports platcal.rigs.sled.series, not the study module
    with its figures: 0.7 s of CPU less per job; it and the centrifuge's comparison cells
    (platcal.rigs.centrifuge.compare_cells, 16 jobs) write their tables without pandas, about
    0.5 s of CPU less per job (issue 22 item 4)."""
    probe = JOB_PROBE.format(module=module, heavy=HEAVY + ("pandas",))
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True)
    assert json.loads(out.stdout) == []


CELL_PROBE = """
import json, os, sys, tempfile
import numpy as np
from platcal.lighttable import Table
from platcal.rig import ReplicateBatch, get_rig, rig_config
from platcal.study.montecarlo import cell_job, tidy_tables, write_cell  # the imports of montecarlo_cell.py
from platcal.io import read_config

name = sys.argv[1]
hooks = get_rig(name).montecarlo
cfg = hooks.check(rig_config(read_config("config/config.yaml", "config"), name))
case = hooks.case(cfg, hooks.cases(cfg)[0], None)
q = Table({"name": ["a", "b"], "group": ["g", "g"], "unit": ["m", "s"], "truth": [1.0, 2.0]})
batch = ReplicateBatch(quantities=q, estimate=np.ones((2, 2)), sigma=np.ones((2, 2)), nees=np.ones(2), nees_dof=2,
                       mean_nis=np.ones(2), failed_updates=np.zeros(2, int), passes=1, extra={"ok": np.ones(2, bool)})
coef, runs = tidy_tables(batch, case.name, 1.0, "kf", [0, 1])
with tempfile.TemporaryDirectory() as d:
    write_cell(d, coef, runs, {"wall_s": 1.0})
print(json.dumps(sorted(m for m in HEAVY_NAMES if m in sys.modules)))
"""
CELL_HEAVY = HEAVY + ("pandas", "pyarrow.compute", "scipy.special", "scipy.linalg", "scipy.interpolate", "scipy.optimize",
                      "pint", "pymap3d", "joblib")
SCIPY_IN_FILTER = {"centrifuge": {"scipy.special", "scipy.linalg"}, "sled": {"scipy.special", "scipy.linalg"}}
"""What a rig's own cell code loads at its modules' top (the centrifuge's identify: the fit check's
chi-square quantiles and the ML's scipy.linalg; the sled's simulation and fit check): allowed
there, and nowhere else. Not joblib: the runner's ``joblib`` backend only (issue 22 item 4)."""


@pytest.mark.parametrize("rig", RIGS)
def test_a_monte_carlo_cell_job_loads_no_pandas_and_only_its_rigs_scipy(rig):
    """A Monte Carlo cell job (workflow/scripts/montecarlo_cell.py: the rig registered, its config
    checked, its case built, tidy tables written to Parquet) in a fresh interpreter: no pandas (some
    0.3 s of CPU per job, issue 22 item 4), no figure, design or stats library, and scipy or pint only
    where the rig's own filter code imports them."""
    out = subprocess.run([sys.executable, "-c", CELL_PROBE.replace("HEAVY_NAMES", repr(CELL_HEAVY)), rig], check=True,
                         capture_output=True, text=True, cwd=ROOT)
    loaded = set(json.loads(out.stdout))
    assert loaded <= SCIPY_IN_FILTER.get(rig, set()), sorted(loaded)
    assert "pandas" not in loaded


def test_registering_a_rig_imports_its_commands_only_when_read():
    """``Rig.commands``/``options``/``sizes``/``campaign`` given by module path import nothing until read."""
    probe = ("import json, sys; from platcal.rig import get_rig; r = get_rig('multiposition'); "
             "m = 'platcal.rigs.multiposition.commands'; before = m in sys.modules; r.options; "
             "print(json.dumps([before, m in sys.modules, 'platcal.rigs.multiposition.campaign' in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True)
    assert json.loads(out.stdout) == [False, True, False]


def test_validating_a_campaign_loads_no_optimiser_or_figures():
    """The workflow's start (workflow/rules/common.smk) validates the campaign before any job:
    through :mod:`platcal.study.campaign_file`, without the planner's pymoo, matplotlib and
    scipy.stats (about 1.5 s of every ``snakemake`` start)."""
    probe = ("import json, sys\nfrom platcal.study.campaign_file import campaign_content, load_campaign\n"
             f"load_campaign(campaign_content({str(ROOT / 'config' / 'campaign.yaml')!r}))\n"
             f"print(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))")
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True, cwd=ROOT)
    assert json.loads(out.stdout) == []


SCRIPT_HEAD = importlib.util.spec_from_file_location("script_imports", ROOT / "benchmarks" / "script_imports.py")
script_imports = importlib.util.module_from_spec(SCRIPT_HEAD)
SCRIPT_HEAD.loader.exec_module(script_imports)
FIGURES_STATS_SYMPY = ("matplotlib", "scipy.stats", "sympy")
JOBS_WITHOUT_FIGURES = {
    "report_index": FIGURES_STATS_SYMPY + ("pymoo",),
    "centrifuge_report": FIGURES_STATS_SYMPY + ("pymoo",),
    "centrifuge_tables": FIGURES_STATS_SYMPY + ("pymoo",),
    "multiposition_design": FIGURES_STATS_SYMPY,
    "multiposition_extension": FIGURES_STATS_SYMPY + ("pymoo",),
    "multiposition_lie_cache": FIGURES_STATS_SYMPY + ("pymoo", "pandas"),
    "multiposition_observability": FIGURES_STATS_SYMPY + ("pymoo",),
    "multiposition_report": ("sympy", "pymoo"),
    "lowprec_trace": FIGURES_STATS_SYMPY + ("pymoo", "pandas"),
    "lowprec_report": ("scipy.stats", "sympy", "pymoo"),
    "sled_summary": ("scipy.stats", "sympy", "pymoo"),
}
"""Workflow jobs that draw no figure (or, the multi-position report, build no Lie derivative; the
low-precision and sled reports, no NEES histogram: :mod:`platcal.study.nees_figure`) and the
libraries their script's imports must not load: each is a fresh process per job, and these
cost 0.4-1 s of CPU apiece (issue 22 item 4; ``benchmarks/script_imports.py`` times them)."""


@pytest.mark.parametrize("script", sorted(JOBS_WITHOUT_FIGURES))
def test_a_job_that_draws_nothing_imports_no_figure_library(script):
    """The imports of ``workflow/scripts/<script>.py`` (its lines before the first that reads
    ``snakemake``) in a fresh interpreter leave the libraries of :data:`JOBS_WITHOUT_FIGURES`
    unloaded: the tables, reports and index read modules that draw nothing (the figures are in
    their own modules: ``platcal.rigs.centrifuge.figures``, ``.compare_figures``,
    ``platcal.rigs.multiposition.report``, ``platcal.study.generic_report``), and the
    multi-position rank test loads sympy only to build a Lie Jacobian the disk cache lacks."""
    head = script_imports.head_of(ROOT / "workflow" / "scripts" / f"{script}.py")
    heavy = JOBS_WITHOUT_FIGURES[script]
    probe = head + f"\nimport json, sys\nprint(json.dumps(sorted(m for m in {heavy!r} if m in sys.modules)))\n"
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True, cwd=ROOT)
    assert json.loads(out.stdout.splitlines()[-1]) == []


def test_the_claims_of_a_rig_load_no_figure_library():
    """The claims job resolves its rig's claims module at run time: none of them loads matplotlib,
    scipy.stats or sympy (the centrifuge's read the paper's cell from its report module, which
    draws nothing now; the multi-position rig's read §13's ranges without the Lie build)."""
    probe = ("import json, sys\nfrom platcal.rig import get_rig, rig_names\n"
             "for name in rig_names():\n    get_rig(name).extra('claims')\n"
             f"print(json.dumps(sorted(m for m in {FIGURES_STATS_SYMPY!r} if m in sys.modules)))")
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True, cwd=ROOT)
    assert json.loads(out.stdout) == []
