# Configuration: validated (with field names) before any job runs; sweep axes; rule params.
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from platcal.errors import InputError
from platcal.montecarlo import (
    builtin_scheme,
    check_study,
    code_hash,
    compute_code_hash,
    is_generated,
    noise_label,
    normalise_numbers,
    scheme_names,
)
from platcal.report import FIGURES, TABLES

# Snakemake's YAML 1.1 loader reads 1.0e4 as a string; platcal reads it as a number
normalise_numbers(config)
# 1. platcal's validation: names the field (study.sigma_a_ug[0], study.schemes[2], ...)
try:
    check_study(config)
except InputError as exc:
    raise WorkflowError(f"invalid configuration: {exc.field}: {exc.message}")
# 2. Snakemake's own, against the same schema: fills the defaults into `config`
validate(config, "../schemas/config.schema.yaml")

RESULTS = "results"  # also used by design.smk
STUDY = config["study"]
SCHEMES = scheme_names(config)
NOISE = {noise_label(v): float(v) for v in STUDY["sigma_a_ug"]}
ESTIMATORS = list(STUDY["estimators"])
# package code as a param: an edit under src/ reruns the jobs whose outputs it can change
CODE_COMPUTE = compute_code_hash()
CODE_ALL = code_hash()

CELLS = expand(
    "results/runs/{scheme}/sa{sigma}/{estimator}",
    scheme=SCHEMES,
    sigma=list(NOISE),
    estimator=ESTIMATORS,
)
REPORT_MD = "results/report.md"
ALL_TABLES = expand(
    "results/tables/{table}.{ext}", table=TABLES, ext=["csv", "md", "html"]
)
ALL_FIGURES = expand("results/figures/{name}", name=list(FIGURES.values()))


wildcard_constraints:
    scheme=r"[A-Za-z0-9_.-]+",
    sigma=r"[0-9][0-9.e+-]*",
    estimator=r"[A-Za-z0-9_-]+",


def scheme_input(wildcards):
    """A generated scheme's file (the design rule writes it); none for the config's schemes."""
    if is_generated(wildcards.scheme, STUDY):
        return f"results/design/{wildcards.scheme}.yaml"
    return []


def _model_params():
    """The config sections that every run's numbers depend on (not batch, backend, threads)."""
    return {
        k: config[k]
        for k in ("site", "centrifuge", "sampling", "truth", "noise", "filter", "seed")
    }


def cell_params(wildcards):
    """Everything a cell's numbers depend on: a change reruns that cell only."""
    p = _model_params()
    p["sigma_a_ug"] = NOISE[wildcards.sigma]
    p["estimator"] = STUDY["estimators"][wildcards.estimator]
    p["replicates"] = STUDY["replicates"]
    if not is_generated(wildcards.scheme, STUDY):
        p["scheme"] = builtin_scheme(config, wildcards.scheme).as_dict()
    return p


def single_params(wildcards):
    p = _model_params()
    p["single"] = STUDY["single"]
    p["estimators"] = STUDY["estimators"]
    p["scheme"] = builtin_scheme(config, STUDY["single"]["scheme"]).as_dict()
    return p
