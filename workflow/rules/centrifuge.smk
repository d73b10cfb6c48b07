# The precision centrifuge (docs/centrifuge-model.md): its Monte Carlo sweep runs through the
# generic rules (montecarlo.smk); here its own stages, all under results/centrifuge/:
#   single/      the single run behind Table 2 and the convergence figure
#   tables/      Table 2 (one run, Monte Carlo) and the summary; figures/; report.md
#   design/      GA schemes (ga_*.yaml, read by the sweep) and the design studies
# `snakemake --cores 2 design_all` builds the full design report (design/report.md).
from platcal.rigs.centrifuge.design import design_config
from platcal.rigs.centrifuge.report import FIGURES, TABLES
from platcal.rigs.centrifuge.study import MODEL_KEYS, builtin_scheme

CEN = MC_CONFIG.get("centrifuge")  # None: the centrifuge is not in the study index
CEN_RES = "results/centrifuge"


def cen_design():
    try:
        return design_config(CEN)
    except InputError as exc:
        raise WorkflowError(f"invalid configuration: {exc.field}: {exc.message} (rigs.centrifuge)")


def cen_keys(*keys):
    """The centrifuge config's sections ``keys`` (pypsa-eur's config_provider): a rule's params."""
    return {k: CEN.get(k) for k in keys}


if CEN is None:
    CENTRIFUGE_TARGETS = []
    CEN_DESIGN = {"study": {"criteria": [], "n_criteria": [], "n_positions": []}, "positions": 6}
else:
    CEN_DESIGN = cen_design()
CEN_DSTUDY = CEN_DESIGN["study"]
GA_CRITERIA = ["ga_" + c for c in CEN_DSTUDY["criteria"]]
GA_NPOS = [
    "ga_" + c if n == CEN_DESIGN["positions"] else "ga_%s_n%d" % (c, n)
    for c in CEN_DSTUDY["n_criteria"]
    for n in CEN_DSTUDY["n_positions"]
]
if CEN is not None:
    _uses_ga = any(s.startswith("ga_") for s in MC_HOOKS["centrifuge"].cases(CEN))
    if CEN_DSTUDY["report"] and _uses_ga:
        CEN_DESIGN_TARGETS = [f"{CEN_RES}/design/report.md"]
    elif CEN_DSTUDY["compare"] and _uses_ga:
        CEN_DESIGN_TARGETS = expand(
            "{res}/design/compare/{f}",
            res=CEN_RES,
            f=["schemes.csv", "spearman.csv", "criteria_vs_accuracy.png"],
        )
    else:
        CEN_DESIGN_TARGETS = []
    CENTRIFUGE_TARGETS = (
        expand(f"{CEN_RES}/tables/{{table}}.{{ext}}", table=TABLES, ext=["csv", "md", "html"])
        + [f"{CEN_RES}/figures/{f}" for f in FIGURES.values()]
        + CEN_DESIGN_TARGETS
        + [f"{CEN_RES}/report.md"]
    )


wildcard_constraints:
    design=r"ga_[A-Za-z0-9_]+",


def cen_single_params(wildcards):
    p = cen_keys(*MODEL_KEYS)
    p["single"] = CEN["study"]["single"]
    p["estimators"] = CEN["study"]["estimators"]
    p["scheme"] = builtin_scheme(CEN, CEN["study"]["single"]["scheme"]).as_dict()
    return p


def cen_design_params(wildcards):
    """What every design number depends on (model, filter, truth, schemes, design section)."""
    return cen_keys(*MODEL_KEYS, "schemes", "design")


rule centrifuge_single_run:
    output:
        estimates=f"{CEN_RES}/single/estimates.csv",
        covariance=f"{CEN_RES}/single/covariance.csv",
        history=f"{CEN_RES}/single/history.parquet",
        info=f"{CEN_RES}/single/run.json",
        timing=f"{CEN_RES}/single/timing.json",
    params:
        single=cen_single_params,
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 1
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/single_run.log",
    script:
        "../scripts/centrifuge_single_run.py"


rule centrifuge_tables:
    input:
        coef=f"{CEN_RES}/montecarlo/coef.parquet",
        runs=f"{CEN_RES}/montecarlo/runs.parquet",
        timing=f"{CEN_RES}/montecarlo/timing.csv",
        single=rules.centrifuge_single_run.output,
    output:
        csv=expand(f"{CEN_RES}/tables/{{table}}.csv", table=TABLES),
        md=expand(f"{CEN_RES}/tables/{{table}}.md", table=TABLES),
        table2_single=report(
            f"{CEN_RES}/tables/table2_single.html",
            caption="../report/table2_single.rst",
            category="Centrifuge tables",
        ),
        table2_montecarlo=report(
            f"{CEN_RES}/tables/table2_montecarlo.html",
            caption="../report/table2_montecarlo.rst",
            category="Centrifuge tables",
        ),
        summary=report(
            f"{CEN_RES}/tables/summary.html",
            caption="../report/summary.rst",
            category="Centrifuge tables",
        ),
        timing=f"{CEN_RES}/tables/summary_timing.csv",
    params:
        study=lambda w: cen_keys("study", "noise", "seed"),
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/tables.log",
    script:
        "../scripts/centrifuge_tables.py"


rule centrifuge_figures:
    input:
        coef=f"{CEN_RES}/montecarlo/coef.parquet",
        runs=f"{CEN_RES}/montecarlo/runs.parquet",
        t2mc=f"{CEN_RES}/tables/table2_montecarlo.csv",
        single=rules.centrifuge_single_run.output,
    output:
        boxplot=report(
            f"{CEN_RES}/figures/rel_err_boxplot.png",
            caption="../report/boxplot.rst",
            category="Centrifuge figures",
        ),
        rms_vs_noise=report(
            f"{CEN_RES}/figures/rms_vs_noise.png",
            caption="../report/rms_vs_noise.rst",
            category="Centrifuge figures",
        ),
        convergence=report(
            f"{CEN_RES}/figures/convergence.png",
            caption="../report/convergence.rst",
            category="Centrifuge figures",
        ),
        correlation=report(
            f"{CEN_RES}/figures/correlation.png",
            caption="../report/correlation.rst",
            category="Centrifuge figures",
        ),
        nees=report(
            f"{CEN_RES}/figures/nees_hist.png",
            caption="../report/nees.rst",
            category="Centrifuge figures",
        ),
        paper_vs_mc=report(
            f"{CEN_RES}/figures/paper_vs_montecarlo.png",
            caption="../report/paper_vs_mc.rst",
            category="Centrifuge figures",
        ),
    params:
        study=lambda w: cen_keys("study", "noise"),
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/figures.log",
    script:
        "../scripts/centrifuge_figures.py"


rule centrifuge_report:
    input:
        tables=rules.centrifuge_tables.output,
        figures=rules.centrifuge_figures.output,
        timing=f"{CEN_RES}/montecarlo/timing.csv",
    output:
        f"{CEN_RES}/report.md",
    params:
        study=lambda w: cen_keys("study", "noise", "seed"),
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/report_md.log",
    script:
        "../scripts/centrifuge_report.py"


# ---- scheme design (issue 4): GA schemes, criteria against Monte Carlo, N, 1 g, D_OO


rule centrifuge_design_all:
    input:
        f"{CEN_RES}/design/report.md",


rule centrifuge_design_scheme:
    output:
        scheme=f"{CEN_RES}/design/{{design}}.yaml",
        history=f"{CEN_RES}/design/{{design}}.history.csv",
        population=f"{CEN_RES}/design/{{design}}.population.csv",
        summary=f"{CEN_RES}/design/{{design}}.json",
    params:
        model=cen_design_params,
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 2
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/design/{{design}}.log",
    script:
        "../scripts/centrifuge_design_scheme.py"


rule centrifuge_design_compare:
    input:
        schemes=expand(f"{CEN_RES}/design/{{d}}.yaml", d=GA_CRITERIA),
    output:
        summary=f"{CEN_RES}/design/compare/schemes.csv",
        spearman=f"{CEN_RES}/design/compare/spearman.csv",
        figure=report(
            f"{CEN_RES}/design/compare/criteria_vs_accuracy.png",
            category="Centrifuge design",
            caption="../report/design_scatter.rst",
        ),
    params:
        model=cen_design_params,
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 2
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/design/compare.log",
    script:
        "../scripts/centrifuge_design_compare.py"


rule centrifuge_design_npos:
    input:
        schemes=expand(f"{CEN_RES}/design/{{d}}.yaml", d=GA_NPOS),
    output:
        table=f"{CEN_RES}/design/npos/n_positions.csv",
        figure=report(
            f"{CEN_RES}/design/npos/n_positions.png",
            category="Centrifuge design",
            caption="../report/design_npos.rst",
        ),
    params:
        model=cen_design_params,
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 2
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/design/npos.log",
    script:
        "../scripts/centrifuge_design_npos.py"


rule centrifuge_design_static:
    input:
        schemes=expand(f"{CEN_RES}/design/{{d}}.yaml", d=GA_CRITERIA[:1]),
    output:
        table=f"{CEN_RES}/design/static/static_vs_centrifuge.csv",
        summary=f"{CEN_RES}/design/static/static_vs_centrifuge_summary.csv",
    params:
        model=cen_design_params,
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 1
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/design/static.log",
    script:
        "../scripts/centrifuge_design_static.py"


rule centrifuge_design_doo:
    input:
        scheme=f"{CEN_RES}/design/ga_doo.yaml",
    output:
        covariance=f"{CEN_RES}/design/doo/doo_covariance.csv",
        aliasing=f"{CEN_RES}/design/doo/doo_aliasing.csv",
    params:
        model=cen_design_params,
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 2
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/design/doo.log",
    script:
        "../scripts/centrifuge_design_doo.py"


rule centrifuge_design_report:
    input:
        compare=f"{CEN_RES}/design/compare/schemes.csv",
        npos=f"{CEN_RES}/design/npos/n_positions.csv",
        static=f"{CEN_RES}/design/static/static_vs_centrifuge.csv",
        doo=f"{CEN_RES}/design/doo/doo_covariance.csv",
        schemes=expand(f"{CEN_RES}/design/{{d}}.yaml", d=GA_CRITERIA),
    output:
        report(
            f"{CEN_RES}/design/report.md",
            category="Centrifuge design",
            caption="../report/design_report.rst",
        ),
    params:
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        f"{CEN_RES}/logs/design/report.log",
    script:
        "../scripts/centrifuge_design_report.py"
