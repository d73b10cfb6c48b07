# Genetic-algorithm scheme design (issue 4): design -> Monte Carlo, and the design studies.
#   results/design/ga_<criterion>.yaml      GA optimum of each criterion (J, A, D, maxrel)
#   results/design/ga_<criterion>_n<N>.yaml GA optimum with N positions
#   results/design/ga_doo.yaml              two-g-level scheme for the 51-state (D_OO) filter
#   results/design/report.md                criteria vs Monte Carlo, N, 1 g, D_OO
# The sweep (montecarlo.smk) reads the ga_* schemes it lists from results/design/<name>.yaml.
# `snakemake --cores 2 design_all` builds the design report; with design.study.report: true
# and a ga_* scheme in study.schemes (the default config) it is part of `all` as well.
from platcal.design import design_config

try:
    DESIGN = design_config(config)
except InputError as exc:
    raise WorkflowError(f"invalid configuration: {exc.field}: {exc.message}")
DSTUDY = DESIGN["study"]
GA_CRITERIA = ["ga_" + c for c in DSTUDY["criteria"]]
GA_NPOS = [
    "ga_" + c if n == DESIGN["positions"] else "ga_%s_n%d" % (c, n)
    for c in DSTUDY["n_criteria"]
    for n in DSTUDY["n_positions"]
]
# the design report (or only the criteria comparison) joins `all` when asked for and the sweep
# uses a designed scheme (ga_*)
_USES_GA = any(s.startswith("ga_") for s in SCHEMES)
DESIGN_TARGETS = (
    ["results/design/report.md"]
    if DSTUDY["report"] and _USES_GA
    else (
        [
            "results/design/compare/schemes.csv",
            "results/design/compare/spearman.csv",
            "results/design/compare/criteria_vs_accuracy.png",
        ]
        if DSTUDY["compare"] and _USES_GA
        else []
    )
)


wildcard_constraints:
    design=r"ga_[A-Za-z0-9_]+",


# what every design number depends on (model, filter, truth, schemes, design section)
DESIGN_PARAMS = {
    k: config.get(k)
    for k in ("site", "centrifuge", "sampling", "truth", "noise", "filter", "seed", "schemes", "design")
}


rule design_all:
    input:
        "results/design/report.md",


rule design_scheme:
    output:
        scheme="results/design/{design}.yaml",
        history="results/design/{design}.history.csv",
        population="results/design/{design}.population.csv",
        summary="results/design/{design}.json",
    params:
        model=DESIGN_PARAMS,
        code=CODE_COMPUTE,
    threads: 2
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/design/{design}.log",
    script:
        "../scripts/design_scheme.py"


rule design_compare:
    input:
        schemes=expand("results/design/{d}.yaml", d=GA_CRITERIA),
    output:
        summary="results/design/compare/schemes.csv",
        spearman="results/design/compare/spearman.csv",
        figure=report(
            "results/design/compare/criteria_vs_accuracy.png",
            category="Design",
            caption="../report/design_scatter.rst",
        ),
    params:
        model=DESIGN_PARAMS,
        code=CODE_COMPUTE,
    threads: 2
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/design/compare.log",
    script:
        "../scripts/design_compare.py"


rule design_npos:
    input:
        schemes=expand("results/design/{d}.yaml", d=GA_NPOS),
    output:
        table="results/design/npos/n_positions.csv",
        figure=report(
            "results/design/npos/n_positions.png",
            category="Design",
            caption="../report/design_npos.rst",
        ),
    params:
        model=DESIGN_PARAMS,
        code=CODE_COMPUTE,
    threads: 2
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/design/npos.log",
    script:
        "../scripts/design_npos.py"


rule design_static:
    input:
        schemes=expand("results/design/{d}.yaml", d=GA_CRITERIA[:1]),
    output:
        table="results/design/static/static_vs_centrifuge.csv",
        summary="results/design/static/static_vs_centrifuge_summary.csv",
    params:
        model=DESIGN_PARAMS,
        code=CODE_COMPUTE,
    threads: 1
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/design/static.log",
    script:
        "../scripts/design_static.py"


rule design_doo:
    input:
        scheme="results/design/ga_doo.yaml",
    output:
        covariance="results/design/doo/doo_covariance.csv",
        aliasing="results/design/doo/doo_aliasing.csv",
    params:
        model=DESIGN_PARAMS,
        code=CODE_COMPUTE,
    threads: 2
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/design/doo.log",
    script:
        "../scripts/design_doo.py"


rule design_report:
    input:
        compare="results/design/compare/schemes.csv",
        npos="results/design/npos/n_positions.csv",
        static="results/design/static/static_vs_centrifuge.csv",
        doo="results/design/doo/doo_covariance.csv",
        schemes=expand("results/design/{d}.yaml", d=GA_CRITERIA),
    output:
        report(
            "results/design/report.md",
            category="Design",
            caption="../report/design_report.rst",
        ),
    params:
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/design/report.log",
    script:
        "../scripts/design_report.py"
