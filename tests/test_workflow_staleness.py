"""No stale result, one config path (issue 19 item 2), for every rig of the default study.

Each case marks a study of one rig as done (every output created and ``snakemake --touch``, which
records each job's params), edits one value of the rig's config and asks Snakemake which outputs'
jobs it would rerun (``snakemake -n``): exactly the outputs that depend on the value must be
listed, and an edited comment lists none. The same rig given inline in the index instead of by
path must give the same jobs with the same params (nothing listed after the switch).
"""

import re
from pathlib import Path

import pytest
import yaml

from platcal.rig import rig_names
from workflow_copy import copy_workflow, needs_snakemake, snakemake

pytestmark = needs_snakemake


def smk(d: Path, *args) -> str:
    p = snakemake(d, *args, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    return p.stdout


def study_of(tmp_path: Path, rig: str, entry) -> Path:
    """A copy of the workflow whose index holds ``rig`` only (``entry``: a path or a mapping)."""
    d = tmp_path / "wf"
    if not d.exists():
        copy_workflow(d)
    write_index(d, rig, entry)
    return d


def write_index(d: Path, rig: str, entry) -> None:
    # key order kept: it can carry meaning (the order of platforms keys their random streams)
    (d / "index.yaml").write_text(yaml.safe_dump({"rigs": {r: (entry if r == rig else None) for r in rig_names()}},
                                                sort_keys=False))


def scheduled(dry: str, kinds=("output:",)) -> list[str]:
    """The outputs (``kinds``: and e.g. the benchmark files) of the jobs a dry run schedules."""
    return sorted({o.strip() for line in dry.splitlines() for k in kinds if line.strip().startswith(k)
                   for o in line.split(k, 1)[1].split(",")})


DIRECTORY_OUTPUTS = re.compile(r"^rule montecarlo_cell:\n(?:    .*\n)*?    output: (\S+)$", re.M)


def mark_done(d: Path) -> list[str]:
    """Create every output of the study and record every job as done with its params
    (``--touch --forceall``); the outputs, sorted."""
    dry = smk(d, "-n", "--configfile", "index.yaml")
    outs = scheduled(dry)
    folders = set(DIRECTORY_OUTPUTS.findall(dry))  # a Monte Carlo cell's output is its folder
    for o in scheduled(dry, ("output:", "benchmark:")):  # a job's benchmark file is one of its products
        if o in folders:
            (d / o).mkdir(parents=True, exist_ok=True)
        else:
            (d / o).parent.mkdir(parents=True, exist_ok=True)
            (d / o).touch()
    smk(d, "--touch", "--forceall", "--cores", "1", "--configfile", "index.yaml")
    return outs


def changed(d: Path) -> set[str]:
    """The outputs that ``snakemake`` would rerun now (a dry run)."""
    return set(scheduled(smk(d, "-n", "--configfile", "index.yaml")))


def edit(d: Path, rig: str, old: str, new: str) -> None:
    f = d / "config" / f"{rig}.yaml"
    text = f.read_text()
    assert re.search(old, text, flags=re.M), f"{old!r} not in {f.name}"
    f.write_text(re.sub(old, new, text, count=1, flags=re.M))


# (rig, regex of the value in config/<rig>.yaml, its replacement, outputs that must be listed
#  (regex), outputs that must not be listed (regex))
EDITS = [
    ("lowprec_centrifuge", r"k0_ug: 20", "k0_ug: 21", r"lowprec_centrifuge/runs/(default|worst|rate-0\.001)/", r"^$"),
    ("lowprec_centrifuge", r"kA_x: -40", "kA_x: -41", r"lowprec_centrifuge/runs/default/|tables/table1\.csv", r"^$"),
    # the default scenario and the arm sweep use the base rate; the rate sweep overrides it
    ("lowprec_centrifuge", r"rate_error: 3\.0e-4", "rate_error: 2.0e-4", r"lowprec_centrifuge/runs/(default|arm-5mm)/",
     r"lowprec_centrifuge/runs/rate-0\.001/"),
    # ROLL4 is a rank-table scheme only: the rank table reruns, no Monte Carlo cell does
    ("multiposition", r"ROLL4: \{dwell_s: 60", "ROLL4: {dwell_s: 50", r"observability/ROLL4/observability\.json",
     r"/runs/|extension/|design/"),
    ("multiposition", r"^seed: 1 ", "seed: 2 ", r"/runs/S8/", r"observability/|extension/"),
    # one estimator's setting reruns the cells it runs in (every estimator of a (case, level) cell
    # runs in one job; and, through the kernels job they wait for, the other cells: Snakemake's
    # ancient() would spare them but then also skip the edited cells' own params check, a stale
    # result - Snakemake 9 masks a job downstream of a rerun job)
    ("multiposition", r"ekf2: \{estimator: ekf, passes: 2\}", "ekf2: {estimator: ekf, passes: 3}",
     r"/runs/S8/noise5$", r"^$"),
    ("sled", r"sigma_arcsec: \[30, 30, 180\]", "sigma_arcsec: [31, 30, 180]", r"runs/default/", r"rank_table"),
    ("centrifuge", r"sigma_set_arcsec: 10\}", "sigma_set_arcsec: 12}", r"/runs/table1/", r"^$"),
]


@pytest.mark.slow
@pytest.mark.parametrize("rig,old,new,must,must_not", EDITS)
def test_an_edit_reruns_exactly_what_depends_on_it(tmp_path, rig, old, new, must, must_not):
    d = study_of(tmp_path, rig, f"config/{rig}.yaml")
    outs = mark_done(d)
    assert changed(d) == set(), "a finished study must list no params change"
    edit(d, rig, r"^(#.*)$", r"\1 (edited comment)")  # the first comment line of the file
    assert changed(d) == set(), "an edited comment must rerun nothing"
    edit(d, rig, old, new)
    listed = changed(d)
    assert any(re.search(must, o) for o in listed), f"nothing matching {must!r} reruns: {sorted(listed)[:10]}"
    if must_not != "^$":
        assert not any(re.search(must_not, o) for o in listed), sorted(listed)
        assert set(outs) - listed, "an edit of one value must not rerun the whole study"


@pytest.mark.slow
@pytest.mark.parametrize("rig", sorted(rig_names()))
def test_inline_and_path_give_the_same_jobs_and_params(tmp_path, rig):
    d = study_of(tmp_path, rig, f"config/{rig}.yaml")
    outs = mark_done(d)
    write_index(d, rig, yaml.safe_load((d / "config" / f"{rig}.yaml").read_text()))
    assert changed(d) == set(), "the inline form must give the same jobs with the same params"
    assert outs
