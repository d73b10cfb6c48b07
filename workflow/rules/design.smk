# Genetic-algorithm scheme design (issue 4): design -> Monte Carlo, and the design studies.
#   results/design/ga_<criterion>.yaml      GA optimum of each criterion (J, A, D, maxrel)
#   results/design/ga_<criterion>_n<N>.yaml GA optimum with N positions
#   results/design/ga_doo.yaml              two-g-level scheme for the 51-state (D_OO) filter
#   results/design/report.md                comparisons: criteria vs Monte Carlo, N, 1 g, D_OO
# The sweep (montecarlo.smk) reads ga_* schemes it lists from results/design/<name>.yaml.
from platcal.design import design_config

DESIGN = design_config(config)
DSTUDY = DESIGN["study"]
DESIGN_DIR = RESULTS + "/design"
GA_CRITERIA = [f"ga_{c}" for c in DSTUDY["criteria"]]
GA_NPOS = [
    f"ga_{c}" if n == DESIGN["positions"] else f"ga_{c}_n{n}"
    for c in DSTUDY["n_criteria"]
    for n in DSTUDY["n_positions"]
]
DESIGN_TARGETS = [DESIGN_DIR + "/report.md"]


wildcard_constraints:
    design=r"ga_[A-Za-z0-9_]+",


def design_params(wildcards=None):
    """What every design number depends on (model, filter, truth, design section)."""
    return {
        k: config.get(k)
        for k in ("site", "centrifuge", "sampling", "truth", "noise", "filter", "seed", "schemes", "design")
    }


rule design_scheme:
    output:
        scheme=DESIGN_DIR + "/{design}.yaml",
        history=DESIGN_DIR + "/{design}.history.csv",
        population=DESIGN_DIR + "/{design}.population.csv",
        summary=DESIGN_DIR + "/{design}.json",
    params:
        model=design_params,
        code=CODE_COMPUTE,
    threads: 2
    log:
        RESULTS + "/logs/design/{design}.log",
    script:
        "../scripts/design_scheme.py"


rule design_compare:
    input:
        schemes=expand(DESIGN_DIR + "/{d}.yaml", d=GA_CRITERIA),
    output:
        summary=DESIGN_DIR + "/compare/schemes.csv",
        spearman=DESIGN_DIR + "/compare/spearman.csv",
        figure=report(DESIGN_DIR + "/compare/criteria_vs_accuracy.png", category="Design",
                      caption="../report/design_scatter.rst"),
    params:
        model=design_params,
        code=CODE_COMPUTE,
    threads: 2
    log:
        RESULTS + "/logs/design/compare.log",
    script:
        "../scripts/design_compare.py"


rule design_npos:
    input:
        schemes=expand(DESIGN_DIR + "/{d}.yaml", d=GA_NPOS),
    output:
        table=DESIGN_DIR + "/npos/n_positions.csv",
        figure=report(DESIGN_DIR + "/npos/n_positions.png", category="Design",
                      caption="../report/design_npos.rst"),
    params:
        model=design_params,
        code=CODE_COMPUTE,
    threads: 2
    log:
        RESULTS + "/logs/design/npos.log",
    script:
        "../scripts/design_npos.py"


rule design_static:
    input:
        schemes=expand(DESIGN_DIR + "/{d}.yaml", d=GA_CRITERIA[:1]),
    output:
        table=DESIGN_DIR + "/static/static_vs_centrifuge.csv",
        summary=DESIGN_DIR + "/static/static_vs_centrifuge_summary.csv",
    params:
        model=design_params,
        code=CODE_COMPUTE,
    threads: 1
    log:
        RESULTS + "/logs/design/static.log",
    script:
        "../scripts/design_static.py"


rule design_doo:
    input:
        scheme=DESIGN_DIR + "/ga_doo.yaml",
    output:
        covariance=DESIGN_DIR + "/doo/doo_covariance.csv",
        aliasing=DESIGN_DIR + "/doo/doo_aliasing.csv",
    params:
        model=design_params,
        code=CODE_COMPUTE,
    threads: 2
    log:
        RESULTS + "/logs/design/doo.log",
    script:
        "../scripts/design_doo.py"


rule design_report:
    input:
        compare=rules.design_compare.output.summary,
        npos=rules.design_npos.output.table,
        static=rules.design_static.output.table,
        doo=rules.design_doo.output.covariance,
        schemes=expand(DESIGN_DIR + "/{d}.yaml", d=GA_CRITERIA),
    output:
        report(DESIGN_DIR + "/report.md", category="Design", caption="../report/design_report.rst"),
    params:
        code=CODE_ALL,
    log:
        RESULTS + "/logs/design/report.log",
    script:
        "../scripts/design_report.py"
